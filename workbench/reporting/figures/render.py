"""Off-screen mesh rendering with pyvista, for figures composed in matplotlib.

Each mesh is rendered to an RGB image with a colour map over per-vertex scalars and a fixed colour range; the
figure then shows the images in matplotlib axes and draws the colour bar there (same map, same range), so labels
and colour bars stay vector text. Rendering needs no display: pyvista runs off-screen and VTK picks EGL or OSMesa
when there is no X server (a warning about the X server connection is expected and harmless).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np

from workbench.errors import WorkbenchError

# Camera direction of every face render: in front of the face (+z), a little to the actor's left and above.
FRONT_VIEW = (0.45, 0.2, 1.0)
VIEW_UP = (0.0, 1.0, 0.0)
BACKGROUND = "white"


@dataclass(frozen=True)
class MeshView:
    """How a set of meshes is rendered: image size in pixels, colour map and its range, camera direction."""

    cmap: str
    clim: tuple[float, float]
    window_size: tuple[int, int] = (330, 390)
    view: tuple[float, float, float] = FRONT_VIEW


def render_meshes(positions: Sequence[np.ndarray], faces: np.ndarray, scalars: Sequence[np.ndarray],
                  view: MeshView) -> list[np.ndarray]:
    """Render meshes of one topology off-screen, each coloured by its own per-vertex scalars.

    Parameters
    ----------
    positions : sequence of ndarray of shape (n_vertices, 3) or (3 * n_vertices,)
        Vertex positions of each mesh.
    faces : ndarray of shape (n_faces, 3) of int
        Triangles, shared by every mesh.
    scalars : sequence of ndarray of shape (n_vertices,)
        One per mesh, coloured with ``view.cmap`` over ``view.clim``.
    view : MeshView

    Returns
    -------
    list of ndarray of shape (height, width, 3) of uint8
        One image per mesh. The camera is fitted to the first mesh and kept for the others, so the images
        share one scale.
    """
    pyvista = _pyvista()
    faces = np.asarray(faces)
    if faces.ndim != 2 or faces.shape[1] != 3:
        raise WorkbenchError(f"faces must be triangles of shape (n_faces, 3), got {faces.shape}")
    cells = np.hstack([np.full((len(faces), 1), 3), faces]).ravel()
    plotter = pyvista.Plotter(off_screen=True, window_size=list(view.window_size))
    try:
        plotter.set_background(BACKGROUND)
        images, camera, actor = [], None, None
        for points, values in zip(positions, scalars):
            mesh = pyvista.PolyData(np.asarray(points, dtype=float).reshape(-1, 3), cells)
            mesh.point_data["value"] = np.asarray(values, dtype=float)
            if actor is not None:
                plotter.remove_actor(actor)  # not plotter.clear(): that also removes the lights
            actor = plotter.add_mesh(mesh, scalars="value", cmap=view.cmap, clim=view.clim,
                                     show_scalar_bar=False, smooth_shading=True, specular=0.2)
            if camera is None:
                plotter.view_vector(view.view, viewup=VIEW_UP)
                plotter.camera.zoom(1.35)
                camera = plotter.camera_position
            else:
                plotter.camera_position = camera
            images.append(np.asarray(plotter.screenshot(None, return_img=True))[..., :3].copy())
        return images
    finally:
        plotter.close()


def crop_background(images: Sequence[np.ndarray], margin: int = 4) -> list[np.ndarray]:
    """Crop every image to the common box that holds all non-background pixels, so panels share one frame.

    Parameters
    ----------
    images : sequence of ndarray of shape (height, width, 3) of uint8
        Same size, white background.
    margin : int
        Pixels kept around the box.

    Returns
    -------
    list of ndarray
    """
    covered = np.zeros(images[0].shape[:2], dtype=bool)
    for image in images:
        covered |= np.any(image < 250, axis=2)
    if not covered.any():
        return list(images)
    rows, cols = np.flatnonzero(covered.any(axis=1)), np.flatnonzero(covered.any(axis=0))
    top, bottom = max(rows[0] - margin, 0), min(rows[-1] + margin + 1, covered.shape[0])
    left, right = max(cols[0] - margin, 0), min(cols[-1] + margin + 1, covered.shape[1])
    return [image[top:bottom, left:right] for image in images]


def _pyvista():
    try:
        import pyvista
    except ImportError as error:  # a dependency of the workbench, but say what to do if it is missing
        raise WorkbenchError(f"rendering meshes needs pyvista ({error}); install it with 'pip install pyvista'")
    pyvista.OFF_SCREEN = True
    return pyvista
