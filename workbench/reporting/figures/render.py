"""Off-screen mesh rendering with pyvista, for figures composed in matplotlib.

Each mesh is rendered to an RGB image, either plain shaded (the geometry alone, as the paper shows faces) or
coloured by per-vertex scalars with a colour map over a fixed range; the figure then shows the images in
matplotlib axes and draws the colour bar there (same map, same range), so labels and colour bars stay vector text.
Where a capture has no data (points beyond the markers' reach), the colour fades into the plain shade over a band
of the surface: such regions are drawn as plain geometry, never as holes or masks. Rendering needs no display:
pyvista runs off-screen and VTK picks EGL or OSMesa when there is no X server. VTK's own log (such as its warning
about the missing X server connection, expected and harmless) would reach the terminal with colour codes; it goes to
Python logging instead, one plain line per message (:func:`pass_vtk_log`).
"""

from __future__ import annotations

import logging
import os
import re
import tempfile
from dataclasses import dataclass
from typing import Sequence

import numpy as np

from workbench.core.errors import WorkbenchError

# Camera direction of every face render: straight in front of the face (+z), a little above, so both sides of the
# face (the _L and _R shapes) are seen alike.
FRONT_VIEW = (0.0, 0.15, 1.0)
VIEW_UP = (0.0, 1.0, 0.0)
BACKGROUND = "white"
# Openings of the mesh (eyes, mouth) are closed by dark caps, so they read as the inside of the head, not as holes
# to the background. Plain shaded surfaces, and points without data, take one light neutral colour.
CAP_COLOUR = "#2e2e2e"
PLAIN_COLOUR = "#d2d2d2"
# White lights (a key light above left of the camera, a fill light below right) on a grey material: a clay render
# whose red, green and blue are equal, which a lossless image codec stores in a third of the bytes of a tinted one.
# Dim enough that no lit surface, not even a map's white, reaches the white of the background.
LIGHTS = (((-0.4, 0.6, 1.0), 0.6), ((0.7, -0.1, 0.7), 0.25))
AMBIENT, SPECULAR = 0.12, 0.05
FADE_BAND = 0.04
"""Width of the band, as a fraction of the face's size, over which colour fades into the plain shade towards the
points without data."""


@dataclass(frozen=True)
class MeshView:
    """How a set of meshes is rendered: image size in pixels, colour map and its range (no map: plain shaded),
    camera direction."""

    cmap: str | None = None
    clim: tuple[float, float] = (0.0, 1.0)
    window_size: tuple[int, int] = (480, 560)
    view: tuple[float, float, float] = FRONT_VIEW


def support_weight(points: np.ndarray, support: np.ndarray | None, band: float = FADE_BAND) -> np.ndarray | None:
    """How much colour each point shows: 0 where the capture has no data, rising linearly to 1 over a band of
    the surface away from those points, so the colour fades out smoothly instead of ending at a jagged edge.

    Parameters
    ----------
    points : ndarray of shape (n_points, 3) or (3 * n_points,)
        The neutral face.
    support : ndarray of shape (n_points,) of bool, or None
        False where the capture has no data.
    band : float
        Width of the fade as a fraction of the face's size (largest extent).

    Returns
    -------
    ndarray of shape (n_points,) in [0, 1], or None when every point has data
    """
    if support is None or np.all(support):
        return None
    from scipy.spatial import cKDTree

    points = np.asarray(points, dtype=float).reshape(-1, 3)
    support = np.asarray(support, dtype=bool)
    width = band * float(np.ptp(points, axis=0).max())
    distance = cKDTree(points[~support]).query(points)[0]
    return np.where(support, np.clip(distance / max(width, 1e-12), 0.0, 1.0), 0.0)


def vertex_colours(
    values: np.ndarray | None, view: MeshView, weight: np.ndarray | None = None, n_points: int | None = None
) -> np.ndarray:
    """RGB colour of every point: the colour map over ``view.clim`` blended into the plain shade by ``weight``
    (NaN values take the plain shade too); the plain shade everywhere when ``view.cmap`` is None.

    Parameters
    ----------
    values : ndarray of shape (n_points,) or None
    view : MeshView
    weight : ndarray of shape (n_points,) in [0, 1], optional
        Share of colour at each point (:func:`support_weight`); 1 everywhere when None.
    n_points : int, optional
        Needed when ``values`` is None.

    Returns
    -------
    ndarray of shape (n_points, 3) of uint8
    """
    from matplotlib import colormaps
    from matplotlib.colors import to_rgb

    plain = np.array(to_rgb(PLAIN_COLOUR))
    if view.cmap is None or values is None:
        return np.tile(np.round(255 * plain).astype(np.uint8), (n_points if values is None else len(values), 1))
    values = np.asarray(values, dtype=float)
    low, high = view.clim
    coloured = colormaps[view.cmap](np.clip((np.nan_to_num(values, nan=low) - low) / max(high - low, 1e-12), 0, 1))
    share = np.ones(len(values)) if weight is None else np.asarray(weight, dtype=float)
    share = np.where(np.isfinite(values), share, 0.0)[:, None]
    return np.round(255 * (share * coloured[:, :3] + (1 - share) * plain)).astype(np.uint8)


def render_meshes(
    positions: Sequence[np.ndarray],
    faces: np.ndarray,
    scalars: Sequence[np.ndarray] | None,
    view: MeshView,
    weight: np.ndarray | None = None,
) -> list[np.ndarray]:
    """Render meshes of one topology off-screen, plain shaded or each coloured by its own per-vertex scalars.

    Parameters
    ----------
    positions : sequence of ndarray of shape (n_vertices, 3) or (3 * n_vertices,)
        Vertex positions of each mesh.
    faces : ndarray of shape (n_faces, 3) of int
        Triangles, shared by every mesh.
    scalars : sequence of ndarray of shape (n_vertices,), or None
        One per mesh, coloured with ``view.cmap`` over ``view.clim`` (:func:`vertex_colours`); None, or a view
        without a colour map, renders plain shaded meshes.
    view : MeshView
    weight : ndarray of shape (n_vertices,) in [0, 1], optional
        Share of colour at each vertex (:func:`support_weight`): the plain shade where 0.

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
    plotter = pyvista.Plotter(off_screen=True, window_size=list(view.window_size), lighting="none")
    try:
        for position, intensity in LIGHTS:
            plotter.add_light(pyvista.Light(position=position, light_type="camera light", intensity=intensity))
        plotter.set_background(BACKGROUND)
        images, camera, actors = [], None, []
        for k, points in enumerate(positions):
            points = np.asarray(points, dtype=float).reshape(-1, 3)
            mesh = pyvista.PolyData(points, cells)
            mesh.point_data["colour"] = vertex_colours(
                None if scalars is None else scalars[k], view, weight, n_points=len(points)
            )
            # render=False: each addition and removal would render the scene again (172 renders for the 95 images
            # of a synthetic run's report); an image needs the one render below
            for actor in actors:
                plotter.remove_actor(actor, render=False)  # not plotter.clear(): that also removes the lights
            actors = [
                plotter.add_mesh(
                    mesh,
                    render=False,
                    scalars="colour",
                    rgb=True,
                    show_scalar_bar=False,
                    smooth_shading=True,
                    specular=SPECULAR,
                    specular_power=20,
                    ambient=AMBIENT,
                )
            ]
            if loops:
                centres = np.array([points[loop].mean(axis=0) for loop in loops])
                caps = pyvista.PolyData(np.vstack([points, centres]), cap_cells)
                actors.append(plotter.add_mesh(caps, color=CAP_COLOUR, smooth_shading=False, ambient=0.3, render=False))
            if camera is None:
                plotter.view_vector(view.view, viewup=VIEW_UP)
                plotter.camera.zoom(1.35)
                camera = plotter.camera_position
            else:
                plotter.camera_position = camera
            plotter.render()  # the scene as it now is (before the first screenshot, which renders itself, a no-op)
            images.append(np.asarray(plotter.screenshot(None, return_img=True))[..., :3].copy())
        return images
    finally:
        plotter.close()
        pass_vtk_log()


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
    cells = [
        np.column_stack([np.full(len(loop), 3), loop, np.roll(loop, -1), np.full(len(loop), n_vertices + k)])
        for k, loop in enumerate(loops)
    ]
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
        from workbench.core.extras import install_hint

        raise WorkbenchError(f"rendering meshes needs pyvista ({error}): {install_hint('report')}") from None
    pyvista.OFF_SCREEN = True
    route_vtk_log()
    return pyvista


VTK_LOG = logging.getLogger("workbench.render.vtk")
VTK_LINE = re.compile(r"^\d{4}-\d\d-\d\d [^\]]*\]\s*(?P<source>\S+?)[.:]*\d*\s+(?P<level>\w+)\|\s*(?P<message>.*)$")
"""A line of VTK's log file: ``date time (uptime) [thread]source:line  WARN| message``."""
_vtk_log: dict = {}


def route_vtk_log() -> None:
    """Send VTK's log (once per process) to an unnamed plain file that :func:`pass_vtk_log` reads, instead of the
    terminal, where VTK writes it with raw colour codes even into a pipe or a file."""
    if _vtk_log:
        return
    from vtkmodules.vtkCommonCore import vtkLogger

    vtkLogger.SetStderrVerbosity(vtkLogger.VERBOSITY_OFF)  # first: opening the file is logged too
    handle, path = tempfile.mkstemp(prefix="workbench-vtk-", suffix=".log")
    os.close(handle)
    try:
        vtkLogger.LogToFile(path, vtkLogger.TRUNCATE, vtkLogger.VERBOSITY_WARNING)
        _vtk_log["reader"] = open(path, encoding="utf-8", errors="replace")  # noqa: SIM115 (read for the process)
    finally:
        os.unlink(path)  # both ends keep it open: no file is left behind


def pass_vtk_log() -> None:
    """Pass the messages VTK logged since the last call to Python logging, one plain line each: its warnings at
    INFO (shown by ``--verbose``; the X server one is expected off-screen), its errors at WARNING."""
    reader = _vtk_log.get("reader")
    if reader is None:
        return
    for line in reader.read().splitlines():
        found = VTK_LINE.search(line)
        if found:
            level = logging.WARNING if found["level"].startswith("ERR") else logging.INFO
            VTK_LOG.log(level, f"VTK ({found['source']}): {found['message'].strip()}")
