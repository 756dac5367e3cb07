"""Figures 2-4 of the paper: hand shapes beside their quasi-eigen faces, captured frames beside their
reconstructions, and one frame's reconstruction error at the markers.

As in the paper, faces are plain shaded renders of the geometry; colour maps (displacement, error) are separate
panels beside them, with colour bars that show where they clip (extend arrows). The functions here only draw: they
take arrays the report prepared from a run record (shapes, frames, reconstructions, per-frame alpha) and text that
labels them. Arrays are flattened point sets ``[x0, y0, z0, x1, ...]`` in millimetres, the convention of
:class:`workbench.dataset.capture.Capture`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping, Sequence

import numpy as np
from matplotlib.cm import ScalarMappable
from matplotlib.collections import LineCollection
from matplotlib.colors import Normalize
from matplotlib.figure import Figure

from workbench.numerics.metrics import point_norms
from workbench.reporting.figures import OKABE_ITO, basis_colour, basis_label, fixed_decimals, new_figure, wrap_title
from workbench.reporting.figures.render import MeshView, crop_background, render_meshes, support_weight

DISPLACEMENT_CMAP = "YlGnBu"
NORMAL_CMAP = "RdBu_r"  # diverging, white at zero: red out of the face, blue into it
ERROR_CMAP = "YlOrRd"
CAPTURED_RED, RECONSTRUCTED_BLUE = OKABE_ITO["vermillion"], OKABE_ITO["blue"]  # the plots' one palette


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


# Regions of the face, top to bottom, and the words of the hand shapes that act there; a shape named by none of
# them acts on the mouth (lips, corners, cheeks).
REGIONS = (
    ("brows", ("brow", "frontalis", "corrugator")),
    ("eyes", ("eye", "blink", "squint", "lid", "oculi")),
    ("mouth", ()),
    ("jaw", ("jaw",)),
)
REGION_REACH = 0.3
"""A point belongs to the region whose hand shapes move it most, relative to their largest displacement, when that
share reaches this."""


def shape_region(name: str) -> str:
    """The region of the face a hand shape acts on, from its name (:data:`REGIONS`)."""
    lower = name.lower()
    return next((region for region, words in REGIONS if any(word in lower for word in words)), "mouth")


def face_regions(hand: np.ndarray, names: Sequence[str], support: np.ndarray | None = None) -> dict:
    """The points of each region of the face: those its hand shapes move most, relative to their own largest
    displacement (at least :data:`REGION_REACH` of it).

    Parameters
    ----------
    hand : ndarray of shape (n_shapes, 3 * n_points)
    names : sequence of str
    support : ndarray of shape (n_points,) of bool, optional
        Points without data belong to no region.

    Returns
    -------
    dict
        Region name -> ndarray of shape (n_points,) of bool, in the order of :data:`REGIONS`, for the regions
        some hand shape acts on.
    """
    reach = {}
    for region, _ in REGIONS:
        members = [k for k, name in enumerate(names) if shape_region(name) == region]
        if members:
            largest = point_norms(np.asarray(hand)[members]).max(axis=0)
            reach[region] = largest / max(float(largest.max()), 1e-12)
    if not reach:
        return {}
    stacked = np.vstack(list(reach.values()))
    strongest = np.argmax(stacked, axis=0)
    inside = stacked.max(axis=0) >= REGION_REACH
    if support is not None:
        inside &= np.asarray(support, dtype=bool)
    return {region: inside & (strongest == k) for k, region in enumerate(reach)}


def region_frames(
    captured: np.ndarray,
    regions: Mapping[str, np.ndarray],
    seconds: np.ndarray | None = None,
    takes: np.ndarray | None = None,
    apart_s: float = 1.0,
) -> list[tuple[str, int]]:
    """The most displaced frame of each region of the face (RMS displacement over its points), each at least
    ``apart_s`` from the frames chosen before it in the same take, so that the frames cover the face.

    Parameters
    ----------
    captured : ndarray of shape (n_frames, 3 * n_points)
        Captured displacements (NaN where a marker was missing).
    regions : mapping
        Region name -> ndarray of shape (n_points,) of bool (:func:`face_regions`).
    seconds, takes : ndarray of shape (n_frames,), optional
        Time and take of every frame; without them frames are only kept distinct.
    apart_s : float

    Returns
    -------
    list of (str, int)
        (region, frame index), in the regions' order.
    """
    lengths = np.nan_to_num(point_norms(np.asarray(captured, dtype=float)))
    chosen: list[tuple[str, int]] = []
    for region, points in regions.items():
        if not np.any(points):
            continue
        strength = np.sqrt((lengths[:, points] ** 2).mean(axis=1))
        for frame in np.argsort(-strength, kind="stable"):
            near = [
                f
                for _, f in chosen
                if f == frame
                or (
                    seconds is not None
                    and (takes is None or takes[f] == takes[frame])
                    and abs(seconds[f] - seconds[frame]) < apart_s
                )
            ]
            if not near:
                chosen.append((region, int(frame)))
                break
    return chosen


@dataclass(frozen=True)
class ColourRange:
    """The range of a colour bar and whether the data go beyond it.

    Attributes
    ----------
    low, high : float
    largest : float
        The largest value (in size) of the data, NaN left out.
    extend : {"neither", "max", "both"}
        Colour bar arrows where the data go beyond the range (matplotlib's ``extend``).
    """

    low: float
    high: float
    largest: float
    extend: str = "neither"


def colour_range(
    values: Sequence[np.ndarray], *, symmetric: bool = False, percentile: float | None = None
) -> ColourRange:
    """A colour range shared by several panels: up to the largest value, or, with ``percentile``, up to that
    percentile of the values (a few extreme points then do not wash out the rest) with extend arrows where the
    data go beyond it. NaN values (no data) are left out.

    Parameters
    ----------
    values : sequence of ndarray
    symmetric : bool
        Centred on zero (signed data, a diverging map), over the values' sizes.
    percentile : float, optional
        In (0, 100].

    Returns
    -------
    ColourRange
    """
    every = np.concatenate([np.ravel(v) for v in values])
    every = every[np.isfinite(every)]
    if every.size == 0:
        return ColourRange(-1.0 if symmetric else 0.0, 1.0, 0.0)
    sizes = np.abs(every) if symmetric else every
    largest = float(sizes.max())
    top = largest if percentile is None else float(np.percentile(sizes, percentile))
    top = top if top > 0 else (largest if largest > 0 else 1.0)
    clipped = largest > top * (1 + 1e-9)
    if symmetric:
        return ColourRange(-top, top, largest, "both" if clipped else "neither")
    return ColourRange(0.0, top, largest, "max" if clipped else "neither")


def colour_bar(figure: Figure, axes, cmap: str, span: ColourRange, label: str, **options) -> None:
    """A horizontal colour bar under ``axes`` for ``span``, with arrows where the data go beyond it, and the
    data's largest value in its label when they do."""
    note = f"; largest {span.largest:.{fixed_decimals([span.high])}f}" if span.extend != "neither" else ""
    figure.colorbar(
        ScalarMappable(Normalize(span.low, span.high), cmap),
        ax=axes,
        location="bottom",
        extend=span.extend,
        label=label + note,
        **options,
    )


def masked(values: np.ndarray, support: np.ndarray | None) -> np.ndarray:
    """Per-vertex values with NaN where ``support`` is False (shown plain, left out of colour ranges)."""
    return values if support is None else np.where(support, values, np.nan)


def _show(ax, image: np.ndarray) -> None:
    ax.imshow(image)
    ax.set_xticks([])
    ax.set_yticks([])
    for spine in ax.spines.values():
        spine.set_visible(False)


def figure_hand_vs_quasi_eigen(
    neutral: np.ndarray,
    faces: np.ndarray,
    hand: np.ndarray,
    quasi_eigen: np.ndarray,
    names: Sequence[str],
    relative_distance: Sequence[float],
    cosine: Sequence[float],
    *,
    title: str,
    qe_label: str,
    support: np.ndarray | None = None,
) -> Figure:
    """Figure 2: hand shapes above their quasi-eigen faces as plain shaded renders (as the paper shows them), and
    under them each one's signed displacement along the surface normal (a diverging map centred at zero, so
    raising and lowering differ), with each pair's intuitiveness numbers.

    Each pair (column) has its own colour range, up to its largest value (no clipping): hand shapes differ in
    size by a factor of several (a jaw opening against a brow), and one shared range would leave the small ones
    blank.

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
        Label of the quasi-eigen rows, e.g. naming the projection.
    support : ndarray of shape (n_vertices,) of bool, optional
        False where the capture has no data: plain in the quasi-eigen maps and left out of their ranges (the hand
        shapes are drawn everywhere).

    Returns
    -------
    matplotlib.figure.Figure
    """
    n = len(names)
    normals = vertex_normals(neutral, faces)
    weight = support_weight(neutral, support)
    meshes = [neutral + shape for k in range(n) for shape in (hand[k], quasi_eigen[k])]
    images = render_meshes(meshes, faces, None, MeshView())
    spans = []
    for k in range(n):
        # the hand shape is sculpted everywhere; its quasi-eigen face comes from the capture, plain where that
        # has no data
        signed = [normal_displacement(hand[k], normals), masked(normal_displacement(quasi_eigen[k], normals), support)]
        spans.append(colour_range(signed, symmetric=True))
        view = MeshView(cmap=NORMAL_CMAP, clim=(spans[-1].low, spans[-1].high))
        images += render_meshes(meshes[2 * k : 2 * k + 1], faces, signed[:1], view)
        images += render_meshes(meshes[2 * k + 1 : 2 * k + 2], faces, signed[1:], view, weight)
    images = crop_background(images)
    width = 2.3 * n + 0.7
    figure = new_figure(width, 11.4)
    axes = figure.subplots(4, n, squeeze=False)
    for k in range(n):
        for row, image in enumerate(
            (images[2 * k], images[2 * k + 1], images[2 * n + 2 * k], images[2 * n + 2 * k + 1])
        ):
            _show(axes[row, k], image)
        axes[0, k].set_title(names[k], fontsize=11)
        axes[1, k].set_xlabel(f"rel. distance {relative_distance[k]:.2f}, cosine {cosine[k]:.2f}", fontsize=9)
        colour_bar(figure, axes[2:, k], NORMAL_CMAP, spans[k], "along the normal (mm)", shrink=0.9, aspect=14)
    for row, label in enumerate(("hand $e_i^H$", qe_label, "$e_i^H$ along the normal", "$e_i^{QE}$ along the normal")):
        axes[row, 0].set_ylabel(label, fontsize=10)
    figure.suptitle(wrap_title(title, width), fontsize=11)
    return figure


def figure_reconstructions(
    neutral: np.ndarray,
    faces: np.ndarray,
    captured: np.ndarray,
    reconstructed: Mapping[str, np.ndarray],
    row_labels: Sequence[str],
    panel_notes: Mapping[str, Sequence[str]],
    *,
    title: str,
    support: np.ndarray | None = None,
) -> Figure:
    """Figure 3: captured frames (left) beside their reconstructions with each basis, plain shaded as the paper
    shows them, then the per-vertex error of each reconstruction as separate panels (drawn on the captured face),
    on one error scale.

    Parameters
    ----------
    neutral : ndarray of shape (3 * n_vertices,)
    faces : ndarray of shape (n_faces, 3)
    captured : ndarray of shape (n_shown, 3 * n_vertices)
        Captured displacements of the shown frames.
    reconstructed : mapping
        Basis label -> ndarray of shape (n_shown, 3 * n_vertices), reconstructed displacements.
    row_labels : sequence of str
        One per shown frame (why it was chosen, take, frame, time).
    panel_notes : mapping
        Basis label -> one text per shown frame (its alpha), written under the reconstruction.
    title : str
    support : ndarray of shape (n_vertices,) of bool, optional
        False where the capture has no data: plain in the error maps, left out of their range.

    Returns
    -------
    matplotlib.figure.Figure
    """
    labels = list(reconstructed)
    n_rows, n_cols = len(captured), 1 + 2 * len(labels)
    errors = {
        label: [masked(values, support) for values in point_norms(frames - captured)]
        for label, frames in reconstructed.items()
    }
    span = colour_range([e for per_frame in errors.values() for e in per_frame], percentile=99.5)
    error_view = MeshView(cmap=ERROR_CMAP, clim=(span.low, span.high))
    weight = support_weight(neutral, support)
    images = render_meshes(neutral + captured, faces, None, MeshView())
    for label in labels:
        images += render_meshes(neutral + reconstructed[label], faces, None, MeshView())
    for label in labels:
        images += render_meshes(neutral + captured, faces, errors[label], error_view, weight)
    images = crop_background(images)

    width = 2.15 * n_cols + 0.9
    figure = new_figure(width, 2.75 * n_rows + 1.7)
    axes = figure.subplots(n_rows, n_cols, squeeze=False)
    for i in range(n_rows):
        for j in range(n_cols):
            _show(axes[i, j], images[n_rows * j + i])
        axes[i, 0].set_ylabel(row_labels[i], fontsize=9)
        for j, label in enumerate(labels, start=1):
            axes[i, j].set_xlabel(panel_notes[label][i], fontsize=8.5)
    axes[0, 0].set_title("captured", fontsize=10)
    for j, label in enumerate(labels, start=1):
        axes[0, j].set_title(f"reconstructed with\n{basis_label(label)}", fontsize=9.5, color=basis_colour(label))
        axes[0, j + len(labels)].set_title(f"error of\n{basis_label(label)}", fontsize=9.5, color=basis_colour(label))
    colour_bar(
        figure,
        axes[:, 1 + len(labels) :],
        ERROR_CMAP,
        span,
        "reconstruction error |d - d*| per vertex (mm)",
        shrink=0.9,
        aspect=18,
    )
    figure.suptitle(wrap_title(title, width), fontsize=11)
    return figure


def nice_exaggeration(largest_error: float, target: float) -> int:
    """The factor from 1, 2, 5, 10, 20, ... that draws ``largest_error`` closest to, and at most, ``target``."""
    if largest_error <= 0:
        return 1
    factors = [base * 10**power for power in range(4) for base in (1, 2, 5)]
    fitting = [f for f in factors if f * largest_error <= target]
    return fitting[-1] if fitting else 1


def _padded_range(values: np.ndarray, pad: float) -> tuple[float, float]:
    return float(np.min(values)) - pad, float(np.max(values)) + pad


def figure_marker_errors(
    neutral: np.ndarray,
    captured: np.ndarray,
    reconstructed: Mapping[str, np.ndarray],
    panel_titles: Mapping[str, str],
    *,
    title: str,
    units: str = "mm",
    target_fraction: float = 0.1,
) -> Figure:
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
    axes = figure.subplots(1, 2 * len(labels), squeeze=False, width_ratios=extents * len(labels), sharey=True)[0]
    views = (("front", 0, "x"), ("side", 2, "z"))
    for j, label in enumerate(labels):
        drawn = captured_points + factor * offsets[label]
        for i, (view, horizontal, name) in enumerate(views):
            ax = axes[2 * j + i]
            ax.add_collection(
                LineCollection(  # one element for every offset: a small SVG
                    np.stack([captured_points[:, [horizontal, 1]], drawn[:, [horizontal, 1]]], axis=1),
                    colors="0.45",
                    linewidths=0.9,
                )
            )
            ax.scatter(
                captured_points[:, horizontal],
                captured_points[:, 1],
                s=9,
                color=CAPTURED_RED,
                zorder=3,
                label="captured",
            )
            ax.scatter(
                drawn[:, horizontal],
                drawn[:, 1],
                s=9,
                color=RECONSTRUCTED_BLUE,
                zorder=3,
                label=f"reconstructed (offset from captured drawn x{factor})",
            )
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


def figure_vertex_rms(
    neutral: np.ndarray,
    faces: np.ndarray,
    rms: Mapping[str, np.ndarray],
    *,
    title: str,
    support: np.ndarray | None = None,
) -> Figure:
    """Per-vertex RMS reconstruction error over the whole take, one face per basis, on one shared colour bar (up to
    the 99.5th percentile, with an arrow when a few vertices go beyond).

    Parameters
    ----------
    neutral : ndarray of shape (3 * n_vertices,)
    faces : ndarray of shape (n_faces, 3)
    rms : mapping
        Basis label -> ndarray of shape (n_vertices,), RMS over the evaluated frames of the 3-D error (mm).
    title : str
    support : ndarray of shape (n_vertices,) of bool, optional
        False where the capture has no data: plain, left out of the colour range and of the numbers.

    Returns
    -------
    matplotlib.figure.Figure
    """
    labels = list(rms)
    values = [masked(np.asarray(rms[label]), support) for label in labels]
    span = colour_range(values, percentile=99.5)
    view = MeshView(cmap=ERROR_CMAP, clim=(span.low, span.high))
    images = crop_background(
        render_meshes([neutral] * len(labels), faces, values, view, support_weight(neutral, support))
    )
    # the RMS over the face's vertices and the largest one, in one number format
    summary = [(float(np.sqrt(np.nanmean(value**2))), float(np.nanmax(value))) for value in values]
    decimals = fixed_decimals([number for pair in summary for number in pair])
    width = 2.5 * len(labels) + 0.4
    figure = new_figure(width, 4.8)
    axes = figure.subplots(1, len(labels), squeeze=False)[0]
    for ax, label, image, (overall, top) in zip(axes, labels, images, summary):
        _show(ax, image)
        ax.set_title(f"{basis_label(label)}", fontsize=10, color=basis_colour(label))
        ax.set_xlabel(f"RMS over the face {overall:.{decimals}f} mm\nlargest vertex {top:.{decimals}f} mm", fontsize=9)
    colour_bar(figure, axes, ERROR_CMAP, span, "RMS error over the take per vertex (mm)", shrink=0.6)
    figure.suptitle(wrap_title(title, width), fontsize=11)
    return figure
