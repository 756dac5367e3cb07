"""Figures 2-4 of the paper: hand shapes beside their quasi-eigen faces, captured frames beside their
reconstructions, and one frame's reconstruction error at the markers.

The functions here only draw: they take arrays the report prepared from a run record (shapes, frames,
reconstructions, per-frame alpha) and text that labels them. Arrays are flattened point sets
``[x0, y0, z0, x1, ...]`` in millimetres, the convention of :class:`workbench.dataset.capture.Capture`.
"""

from __future__ import annotations

from typing import Mapping, Sequence

import numpy as np
from matplotlib.cm import ScalarMappable
from matplotlib.colors import Normalize
from matplotlib.figure import Figure

from workbench.reporting.figures import basis_colour, basis_label, new_figure, wrap_title
from workbench.reporting.figures.render import MeshView, crop_background, render_meshes

DISPLACEMENT_CMAP = "YlGnBu"
NORMAL_CMAP = "RdBu_r"  # diverging, white at zero: red out of the face, blue into it
ERROR_CMAP = "YlOrRd"
CAPTURED_RED, RECONSTRUCTED_BLUE = "#d62728", "#1f5fbf"


def point_norms(flat: np.ndarray) -> np.ndarray:
    """Length of each 3-D point of flattened point sets.

    Parameters
    ----------
    flat : ndarray of shape (..., 3 * n_points)

    Returns
    -------
    ndarray of shape (..., n_points)
    """
    flat = np.asarray(flat)
    return np.linalg.norm(flat.reshape(*flat.shape[:-1], -1, 3), axis=-1)


def vertex_normals(points: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Unit normals at the vertices of a triangle mesh (area-weighted face normals), oriented out of the face.

    Parameters
    ----------
    points : ndarray of shape (3 * n_vertices,) or (n_vertices, 3)
    faces : ndarray of shape (n_faces, 3) of int

    Returns
    -------
    ndarray of shape (n_vertices, 3)
        Pointing away from the mesh's centroid on average (the triangles' winding is not relied on).
    """
    points = np.asarray(points, dtype=float).reshape(-1, 3)
    corners = points[faces]
    face_normals = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    normals = np.zeros_like(points)
    for k in range(3):
        np.add.at(normals, faces[:, k], face_normals)
    normals /= np.maximum(np.linalg.norm(normals, axis=1, keepdims=True), 1e-12)
    outward = np.einsum("ij,ij->i", normals, points - points.mean(axis=0)).mean()
    return normals if outward >= 0 else -normals


def normal_displacement(shape: np.ndarray, normals: np.ndarray) -> np.ndarray:
    """Signed displacement along the surface normal of each vertex (positive: out of the face).

    Parameters
    ----------
    shape : ndarray of shape (3 * n_vertices,)
    normals : ndarray of shape (n_vertices, 3)

    Returns
    -------
    ndarray of shape (n_vertices,)
    """
    return np.einsum("ij,ij->i", np.asarray(shape).reshape(-1, 3), normals)


def spread_by_rank(values: Sequence[float], n: int) -> list[int]:
    """Indices of ``n`` entries spread evenly over the ranks of ``values`` (lowest, ..., highest).

    Parameters
    ----------
    values : sequence of float
    n : int

    Returns
    -------
    list of int
        Distinct indices, in ascending order of their value.
    """
    order = np.argsort(np.asarray(values), kind="stable")
    if n >= len(order):
        return [int(i) for i in order]
    return [int(order[k]) for k in np.round(np.linspace(0, len(order) - 1, n)).astype(int)]


def expressive_frames(captured: np.ndarray, n: int) -> list[int]:
    """The frame with the largest displacement in each of ``n`` equal stretches of the take.

    Parameters
    ----------
    captured : ndarray of shape (n_frames, 3 * n_points)
        Captured displacements.
    n : int

    Returns
    -------
    list of int
        Ascending frame indices.
    """
    norms = np.linalg.norm(captured, axis=1)
    edges = np.linspace(0, len(norms), n + 1).astype(int)
    return [int(start + np.argmax(norms[start:stop])) for start, stop in zip(edges[:-1], edges[1:]) if stop > start]


def _upper_limit(values: Sequence[np.ndarray], percentile: float = 99.5) -> float:
    """A colour-range top shared by several panels: a high percentile of every value (NaN left out), never
    zero."""
    top = float(np.nanpercentile(np.concatenate([np.ravel(v) for v in values]), percentile))
    return top if top > 0 else 1.0


def masked(values: np.ndarray, support: np.ndarray | None) -> np.ndarray:
    """Per-vertex values with NaN where ``support`` is False (drawn grey, left out of colour ranges)."""
    return values if support is None else np.where(support, values, np.nan)


def _show(ax, image: np.ndarray) -> None:
    ax.imshow(image)
    ax.set_xticks([])
    ax.set_yticks([])
    for spine in ax.spines.values():
        spine.set_visible(False)


def figure_hand_vs_quasi_eigen(neutral: np.ndarray, faces: np.ndarray, hand: np.ndarray, quasi_eigen: np.ndarray,
                               names: Sequence[str], relative_distance: Sequence[float],
                               cosine: Sequence[float], *, title: str, qe_label: str,
                               support: np.ndarray | None = None) -> Figure:
    """Figure 2: hand shapes (top row) above their quasi-eigen faces (bottom row), rendered meshes coloured by
    the signed displacement along the surface normal (a diverging map centred at zero, so raising and lowering
    differ), with each pair's intuitiveness numbers.

    Each pair (column) has its own colour range and colour bar: hand shapes differ in size by a factor of
    several (a jaw opening against a brow), and one shared range would leave the small ones blank.

    Parameters
    ----------
    neutral : ndarray of shape (3 * n_vertices,)
    faces : ndarray of shape (n_faces, 3)
    hand, quasi_eigen : ndarray of shape (n_shown, 3 * n_vertices)
        Displacements from neutral.
    names : sequence of str
        One per shown shape.
    relative_distance, cosine : sequence of float
        ``|e^QE - e^H| / |e^H|`` and the cosine between them, one per shown shape.
    title : str
        Figure title (dataset, data variant, m).
    qe_label : str
        Label of the quasi-eigen row, e.g. naming the projection.
    support : ndarray of shape (n_vertices,) of bool, optional
        False at extrapolated vertices, drawn grey.

    Returns
    -------
    matplotlib.figure.Figure
    """
    n = len(names)
    normals = vertex_normals(neutral, faces)
    images, views = [], []
    for k in range(n):
        pair = (hand[k], quasi_eigen[k])
        signed = [masked(normal_displacement(shape, normals), support) for shape in pair]
        limit = _upper_limit([np.abs(values) for values in signed])
        views.append(MeshView(cmap=NORMAL_CMAP, clim=(-limit, limit)))
        images += render_meshes([neutral + shape for shape in pair], faces, signed, views[-1])
    images = crop_background(images)
    width = 2.5 * n + 0.4
    figure = new_figure(width, 7.6)
    axes = figure.subplots(2, n, squeeze=False)
    for k in range(n):
        _show(axes[0, k], images[2 * k])
        _show(axes[1, k], images[2 * k + 1])
        axes[0, k].set_title(names[k], fontsize=11)
        axes[1, k].set_xlabel(f"rel. distance {relative_distance[k]:.2f}, cosine {cosine[k]:.3f}", fontsize=10)
        figure.colorbar(ScalarMappable(Normalize(*views[k].clim), NORMAL_CMAP), ax=axes[:, k],
                        location="bottom", shrink=0.85, aspect=14, label="d . normal (mm)")
    axes[0, 0].set_ylabel("hand $e_i^H$", fontsize=11)
    axes[1, 0].set_ylabel(qe_label, fontsize=11)
    figure.suptitle(wrap_title(title, width), fontsize=11)
    return figure


def figure_reconstructions(neutral: np.ndarray, faces: np.ndarray, captured: np.ndarray,
                           reconstructed: Mapping[str, np.ndarray], row_labels: Sequence[str],
                           panel_notes: Mapping[str, Sequence[str]], *, title: str,
                           support: np.ndarray | None = None) -> Figure:
    """Figure 3: captured frames (left column) beside their reconstructions with each basis.

    The captured column is coloured by displacement length; the reconstructions by their per-vertex error
    against the captured frame, on one shared scale.

    Parameters
    ----------
    neutral : ndarray of shape (3 * n_vertices,)
    faces : ndarray of shape (n_faces, 3)
    captured : ndarray of shape (n_shown, 3 * n_vertices)
        Captured displacements of the shown frames.
    reconstructed : mapping
        Basis label -> ndarray of shape (n_shown, 3 * n_vertices), reconstructed displacements.
    row_labels : sequence of str
        One per shown frame (frame index, time).
    panel_notes : mapping
        Basis label -> one text per shown frame (its alpha), written under the panel.
    title : str
    support : ndarray of shape (n_vertices,) of bool, optional
        False at extrapolated vertices: drawn grey and left out of the colour ranges.

    Returns
    -------
    matplotlib.figure.Figure
    """
    labels = list(reconstructed)
    n_rows, n_cols = len(captured), 1 + len(labels)
    lengths = [masked(values, support) for values in point_norms(captured)]
    errors = {label: [masked(values, support) for values in point_norms(frames - captured)]
              for label, frames in reconstructed.items()}
    captured_view = MeshView(cmap=DISPLACEMENT_CMAP, clim=(0.0, _upper_limit(lengths)))
    error_view = MeshView(cmap=ERROR_CMAP, clim=(0.0, _upper_limit([e for v in errors.values() for e in v])))
    images = render_meshes(neutral + captured, faces, lengths, captured_view)
    for label in labels:
        images += render_meshes(neutral + reconstructed[label], faces, errors[label], error_view)
    images = crop_background(images)

    width = 2.4 * n_cols + 0.5
    figure = new_figure(width, 2.8 * n_rows + 1.6)
    axes = figure.subplots(n_rows, n_cols, squeeze=False)
    for i in range(n_rows):
        _show(axes[i, 0], images[i])
        axes[i, 0].set_ylabel(row_labels[i], fontsize=10)
        for j, label in enumerate(labels, start=1):
            _show(axes[i, j], images[n_rows * j + i])
            axes[i, j].set_xlabel(panel_notes[label][i], fontsize=9)
    axes[0, 0].set_title("captured", fontsize=11)
    for j, label in enumerate(labels, start=1):
        axes[0, j].set_title(f"reconstructed with\n{basis_label(label)}", fontsize=10, color=basis_colour(label))
    figure.colorbar(ScalarMappable(Normalize(*captured_view.clim), DISPLACEMENT_CMAP), ax=axes[:, 0],
                    location="bottom", shrink=0.9, label="captured |d*| (mm)")
    figure.colorbar(ScalarMappable(Normalize(*error_view.clim), ERROR_CMAP), ax=axes[:, 1:], location="bottom",
                    shrink=0.6, label="reconstruction error |d - d*| per vertex (mm)")
    figure.suptitle(wrap_title(title, width), fontsize=11)
    return figure


def nice_exaggeration(largest_error: float, target: float) -> int:
    """The factor from 1, 2, 5, 10, 20, ... that draws ``largest_error`` closest to, and at most, ``target``."""
    if largest_error <= 0:
        return 1
    factors = [base * 10 ** power for power in range(4) for base in (1, 2, 5)]
    fitting = [f for f in factors if f * largest_error <= target]
    return fitting[-1] if fitting else 1


def _padded_range(values: np.ndarray, pad: float) -> tuple[float, float]:
    return float(np.min(values)) - pad, float(np.max(values)) + pad


def figure_marker_errors(neutral: np.ndarray, captured: np.ndarray, reconstructed: Mapping[str, np.ndarray],
                         panel_titles: Mapping[str, str], *, title: str, units: str = "mm",
                         target_fraction: float = 0.1) -> Figure:
    """Figure 4: one frame's reconstruction error at the markers, captured (red) and reconstructed (blue),
    for each basis a front view (x-y) and a side view (z-y).

    Offsets between captured and reconstructed markers are drawn magnified by one factor for every panel
    (stated in the legend), because sub-millimetre errors are invisible at face scale.

    Parameters
    ----------
    neutral : ndarray of shape (3 * n_markers,)
    captured : ndarray of shape (3 * n_markers,)
        Captured displacement of the frame.
    reconstructed : mapping
        Basis label -> ndarray of shape (3 * n_markers,), the reconstructed displacement.
    panel_titles : mapping
        Basis label -> title (its alpha and RMS error on this frame).
    title : str
    units : str
    target_fraction : float
        The largest offset is drawn at most this fraction of the face's height.

    Returns
    -------
    matplotlib.figure.Figure
    """
    captured_points = (neutral + captured).reshape(-1, 3)
    offsets = {label: (shape - captured).reshape(-1, 3) for label, shape in reconstructed.items()}
    largest = max(float(np.max(np.linalg.norm(o, axis=1))) for o in offsets.values())
    factor = nice_exaggeration(largest, target_fraction * float(np.ptp(captured_points[:, 1])))
    labels = list(reconstructed)
    width = 5.4 * len(labels) + 0.4
    figure = new_figure(width, 5.8)
    # Panel widths follow the data's extent in x and z, so equal aspect needs no clipping.
    reach = factor * largest
    extents = [float(np.ptp(captured_points[:, axis])) + 2 * reach + 10.0 for axis in (0, 2)]
    axes = figure.subplots(1, 2 * len(labels), squeeze=False, width_ratios=extents * len(labels),
                           sharey=True)[0]
    views = (("front", 0, "x"), ("side", 2, "z"))
    for j, label in enumerate(labels):
        drawn = captured_points + factor * offsets[label]
        for i, (view, horizontal, name) in enumerate(views):
            ax = axes[2 * j + i]
            ax.plot(np.c_[captured_points[:, horizontal], drawn[:, horizontal]].T,
                    np.c_[captured_points[:, 1], drawn[:, 1]].T, color="0.45", linewidth=0.9)
            ax.scatter(captured_points[:, horizontal], captured_points[:, 1], s=9, color=CAPTURED_RED, zorder=3,
                       label="captured")
            ax.scatter(drawn[:, horizontal], drawn[:, 1], s=9, color=RECONSTRUCTED_BLUE, zorder=3,
                       label=f"reconstructed (offset from captured drawn x{factor})")
            ax.set_xlim(*_padded_range(captured_points[:, horizontal], reach + 5.0))
            ax.set_ylim(*_padded_range(captured_points[:, 1], reach + 5.0))
            ax.set_aspect("equal", adjustable="box")
            ax.set_xlabel(f"{name} ({units}), {view} view")
            ax.grid(alpha=0.3)
        axes[2 * j].set_ylabel(f"y ({units})")
        axes[2 * j].set_title(panel_titles[label], fontsize=10, color=basis_colour(label), loc="left")
    handles, legend_labels = axes[0].get_legend_handles_labels()
    figure.legend(handles, legend_labels, loc="outside lower center", ncols=2, fontsize=9, frameon=False)
    figure.suptitle(wrap_title(title, width), fontsize=11)
    return figure


def figure_vertex_rms(neutral: np.ndarray, faces: np.ndarray, rms: Mapping[str, np.ndarray], *, title: str,
                      support: np.ndarray | None = None) -> Figure:
    """Per-vertex RMS reconstruction error over the whole take, one face per basis, on one shared colour bar.

    Parameters
    ----------
    neutral : ndarray of shape (3 * n_vertices,)
    faces : ndarray of shape (n_faces, 3)
    rms : mapping
        Basis label -> ndarray of shape (n_vertices,), RMS over the evaluated frames of the 3-D error (mm).
    title : str
    support : ndarray of shape (n_vertices,) of bool, optional
        False at extrapolated vertices: grey, left out of the colour range.

    Returns
    -------
    matplotlib.figure.Figure
    """
    labels = list(rms)
    values = [masked(np.asarray(rms[label]), support) for label in labels]
    view = MeshView(cmap=ERROR_CMAP, clim=(0.0, _upper_limit(values)))
    images = crop_background(render_meshes([neutral] * len(labels), faces, values, view))
    width = 2.5 * len(labels) + 0.4
    figure = new_figure(width, 4.6)
    axes = figure.subplots(1, len(labels), squeeze=False)[0]
    for ax, label, image, value in zip(axes, labels, images, values):
        _show(ax, image)
        ax.set_title(f"{basis_label(label)}", fontsize=10, color=basis_colour(label))
        ax.set_xlabel(f"median {np.nanmedian(value):.2f} mm, max {np.nanmax(value):.2f} mm", fontsize=9)
    figure.colorbar(ScalarMappable(Normalize(*view.clim), ERROR_CMAP), ax=axes, location="bottom", shrink=0.6,
                    label="RMS error over the take per vertex (mm)")
    figure.suptitle(wrap_title(title, width), fontsize=11)
    return figure
