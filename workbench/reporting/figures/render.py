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

# Camera direction of every face render: straight in front of the face (+z), a little above, so both sides of the
# face (the _L and _R shapes) are seen alike.
FRONT_VIEW = (0.0, 0.15, 1.0)
VIEW_UP = (0.0, 1.0, 0.0)
BACKGROUND = "white"
# Openings of the mesh (eyes, mouth) are closed by dark caps, so they read as the inside of the head, not as holes
# to the background; points without data (NaN scalars, e.g. extrapolated regions) are drawn grey.
CAP_COLOUR = "#3b2f2f"
NAN_COLOUR = "#d4d4d4"


@dataclass(frozen=True)
class MeshView:
    """How a set of meshes is rendered: image size in pixels, colour map and its range, camera direction."""

    cmap: str
    clim: tuple[float, float]
    window_size: tuple[int, int] = (480, 560)
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
        One per mesh, coloured with ``view.cmap`` over ``view.clim``; NaN is drawn grey.
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
    loops = hole_loops(faces)
    cap_cells = _fan_cells(loops, int(faces.max()) + 1)
    plotter = pyvista.Plotter(off_screen=True, window_size=list(view.window_size))
    try:
        plotter.set_background(BACKGROUND)
        images, camera, actors = [], None, []
        for points, values in zip(positions, scalars):
            points = np.asarray(points, dtype=float).reshape(-1, 3)
            mesh = pyvista.PolyData(points, cells)
            mesh.point_data["value"] = np.asarray(values, dtype=float)
            for actor in actors:
                plotter.remove_actor(actor)  # not plotter.clear(): that also removes the lights
            actors = [plotter.add_mesh(mesh, scalars="value", cmap=view.cmap, clim=view.clim, nan_color=NAN_COLOUR,
                                       show_scalar_bar=False, smooth_shading=True, specular=0.2)]
            if loops:
                centres = np.array([points[loop].mean(axis=0) for loop in loops])
                caps = pyvista.PolyData(np.vstack([points, centres]), cap_cells)
                actors.append(plotter.add_mesh(caps, color=CAP_COLOUR, smooth_shading=False, ambient=0.3))
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


def hole_loops(faces: np.ndarray) -> list[np.ndarray]:
    """The boundary loops of a triangle mesh except the longest (its outer edge): its openings, such as eyes and
    mouth.

    Parameters
    ----------
    faces : ndarray of shape (n_faces, 3) of int

    Returns
    -------
    list of ndarray of int
        Vertex indices around each opening, in order.
    """
    faces = np.asarray(faces)
    edges = np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]), axis=1)
    unique, counts = np.unique(edges, axis=0, return_counts=True)
    neighbours: dict[int, list[int]] = {}
    for a, b in unique[counts == 1].tolist():
        neighbours.setdefault(a, []).append(b)
        neighbours.setdefault(b, []).append(a)
    loops, seen = [], set()
    for start in neighbours:
        if start in seen:
            continue
        loop, previous, current = [start], None, start
        seen.add(start)
        while True:
            following = [n for n in neighbours[current] if n != previous and n not in seen]
            if not following:
                break
            previous, current = current, following[0]
            seen.add(current)
            loop.append(current)
        loops.append(np.array(loop))
    loops.sort(key=len)
    return loops[:-1]


def _fan_cells(loops: Sequence[np.ndarray], n_vertices: int) -> np.ndarray:
    """Cells of triangle fans closing each loop at an extra vertex (``n_vertices + k`` for loop k)."""
    cells = [np.column_stack([np.full(len(loop), 3), loop, np.roll(loop, -1), np.full(len(loop), n_vertices + k)])
             for k, loop in enumerate(loops)]
    return np.concatenate(cells).ravel() if cells else np.zeros(0, dtype=int)


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
    except ImportError as error:  # the report extra
        from workbench.extras import install_hint

        raise WorkbenchError(f"rendering meshes needs pyvista ({error}): {install_hint('report')}") from None
    pyvista.OFF_SCREEN = True
    return pyvista
