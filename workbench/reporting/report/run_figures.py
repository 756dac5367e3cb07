"""The figures of a run's report: each drawn from the record (and the inputs :mod:`workbench.reporting.report.data`
gives), saved in the report's ``figures/``, or listed with the reason it could not be drawn."""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Mapping, Sequence

import numpy as np

from workbench.core.errors import WorkbenchError
from workbench.dataset.capture import Timeline
from workbench.record.record import RunRecord
from workbench.reporting.report.data import (
    QE_PROJECTIONS,
    FaceData,
    face_data,
    figure3_frames,
    figure_bases,
    figure_m,
    figure_order,
    figure_solver,
    frame_alpha,
    frame_caption,
    frame_weights,
    marker_variant,
    mesh_variant,
    missing_reason,
    most_displaced,
    negative_weight_share,
    qe_label,
    quasi_eigen_shapes,
    reconstruct_frames,
    record_alpha_per_frame,
    record_timeline,
    short_label,
    training_variants,
    vertex_rms,
)
from workbench.study.summary import headline_column

ANALOGY_SEED = 1
FIGURE_FORMATS: tuple[str, ...] = ()
"""Copies of each figure a report writes besides the one it shows (WebP renders, SVG line plots)."""


def needs(text: str, cache: dict | None) -> str:
    """Why a figure is not drawn: what it needs, and why the run's data could not be read again when it saved no
    inputs (the file that is missing)."""
    reason = missing_reason(cache or {})
    return f"{text}; {reason}" if reason else text


def drawn_from(record: RunRecord, data: str) -> str:
    """The sentence a figure's caption adds to say which data variant and which m it draws."""
    return f"Drawn from the data variant '{data}', {figure_m(record, data)}."


def with_caption(figure, record: RunRecord, face: FaceData, numbers: str):
    """A drawn face figure with what its caption adds (a (figure, text) pair that :func:`make_figures` reads): the
    variant and m it draws (:func:`drawn_from`), and, when its faces are carried markers,
    :meth:`FaceData.caption`."""
    return figure, " ".join(filter(None, [drawn_from(record, face.data), face.caption(numbers)]))


def carried_title(face: FaceData, numbers: str) -> str:
    """The line a face figure's title adds when its faces are carried markers (``""`` otherwise)."""
    return f"\n{face.note}\n({numbers} the markers' own)" if face.carried else ""


FIGURES_SECTION = "Figures"
"""The report section a figure goes in unless its row names another (the row's last column)."""


@dataclass
class FigureEntry:
    """One figure of a report: where it is, what it shows, or why it could not be drawn, and the section it goes in."""

    stem: str
    title: str
    caption: str
    files: list = field(default_factory=list)
    missing: str = ""
    section: str = FIGURES_SECTION


def placed(entries: Sequence[FigureEntry], section: str) -> list[FigureEntry]:
    """The figures of ``entries`` that go in the section ``section``, in their order."""
    return [entry for entry in entries if entry.section == section]


def draw_analogy():
    from workbench.reporting.figures.analogy import analogy_colours, figure_analogy, make_analogy_example

    return figure_analogy(make_analogy_example(np.random.default_rng(ANALOGY_SEED))), analogy_colours()


def draw_hand_vs_quasi_eigen(record: RunRecord, shapes: Sequence[str] | None = None, cache: dict | None = None):
    """Figure 2 from a record, or the reason it cannot be drawn."""
    from workbench.reporting.figures.faces import figure_hand_vs_quasi_eigen, spread_by_rank

    cache = {} if cache is None else cache
    face = face_data(record, cache)
    if isinstance(face, str):
        return needs(face, cache)
    data, inputs = face.data, face.inputs
    label = qe_label(record)
    projection = QE_PROJECTIONS[label]
    names = [str(name) for name in inputs["hand_names"]]
    rows = [row for row in record.metrics["data"][data]["intuitiveness"] if row["projection"] == projection]
    distance = {row["shape"]: row["relative_distance"] for row in rows}
    cosine = {row["shape"]: row["cosine"] for row in rows}
    if shapes:
        unknown = [name for name in shapes if name not in names]
        if unknown:
            raise WorkbenchError(f"--shapes names unknown hand shapes {unknown}; the run has {names}")
        chosen = [names.index(name) for name in shapes]
    else:
        chosen = spread_by_rank([distance[name] for name in names], 4)
    quasi_eigen = quasi_eigen_shapes(inputs, projection)
    figure = figure_hand_vs_quasi_eigen(
        face.neutral,
        face.faces,
        face.carry(inputs["hand"][chosen]),
        face.carry(quasi_eigen[chosen]),
        [names[i] for i in chosen],
        [distance[names[i]] for i in chosen],
        [cosine[names[i]] for i in chosen],
        title=(
            f"Figure 2 (reproduced): hand shapes above their quasi-eigen faces\n{short_label(record)}; "
            f"data {data}, {figure_m(record, data)}, {projection} projection"
            + carried_title(face, "distance and cosine are")
        ),
        qe_label=f"quasi-eigen $e_i^{{QE}}$ ({projection})",
        support=face.support,
    )
    return with_caption(figure, record, face, "the relative distance and cosine under each pair are the markers' own")


def draw_reconstructions(record: RunRecord, cache: dict | None = None):
    """Figure 3 from a record, or the reason it cannot be drawn."""
    from workbench.reporting.figures import fixed_decimals
    from workbench.reporting.figures.faces import figure_reconstructions

    cache = {} if cache is None else cache
    face = face_data(record, cache)
    if isinstance(face, str):
        return needs(face, cache)
    data, inputs = face.data, face.inputs
    solver_name, solver = figure_solver(record.config)
    chosen = figure3_frames(record, inputs)
    frames = [frame for _, frame in chosen]
    captured = inputs["eval"][frames]
    reconstructed = {
        name: reconstruct_frames(shapes, captured, solver)
        for name, shapes in figure_bases(record, data, inputs, cache).items()
    }
    alphas = {name: frame_alpha(inputs["neutral"], captured, frames_out) for name, frames_out in reconstructed.items()}
    absolute = fixed_decimals([a for alpha in alphas.values() for a in alpha["absolute"]], significant=3)
    displacement = fixed_decimals([a for alpha in alphas.values() for a in alpha["displacement"]], significant=3)
    notes = {
        name: [
            f"alpha {a:.{absolute}f} % abs., {d:.{displacement}f} % disp."
            for a, d in zip(alpha["absolute"], alpha["displacement"])
        ]
        for name, alpha in alphas.items()
    }
    timeline = record_timeline(record, inputs)
    labels = [
        f"most displaced {region}\n{timeline.label(frame).replace(' (', chr(10) + '(')}" for region, frame in chosen
    ]
    figure = figure_reconstructions(
        face.neutral,
        face.faces,
        face.carry(captured),
        {name: face.carry(frames_out) for name, frames_out in reconstructed.items()},
        labels,
        notes,
        title=(
            f"Figure 3 (reproduced): captured frames and their reconstructions\n{short_label(record)}; data "
            f"{data}, {figure_m(record, data)}, solver {solver_name}; the most displaced frame of each region of the face"
            + carried_title(face, "alpha values are")
        ),
        support=face.support,
    )
    return with_caption(
        figure, record, face, "the alphas under the reconstructions are the markers' own (eq. 6 on the markers)"
    )


def figure4_frame(record: RunRecord, inputs: Mapping, cache: dict) -> tuple[int, str]:
    """The frame of figure 4 in a marker variant: the most displaced of figure 3's frames (the same take and file
    frame; figure 3 shows a mesh variant, or the markers carried onto the mesh), or, when figure 3 has no frames or
    that frame misses a marker, the most displaced frame that saw every marker.

    Returns
    -------
    index : int
        Index among the variant's evaluated frames.
    why : str
        How it was chosen, for the title.
    """
    timeline = record_timeline(record, inputs)
    seen_all = (
        inputs["eval_visible"].all(axis=1) if "eval_visible" in inputs else np.ones(len(inputs["eval"]), dtype=bool)
    )
    face = face_data(record, cache)
    if not isinstance(face, str):
        first = most_displaced(face.inputs, [frame for _, frame in figure3_frames(record, face.inputs)])
        other = record_timeline(record, face.inputs)
        match = np.flatnonzero((timeline.take == other.take[first]) & (timeline.frame == other.frame[first]))
        if match.size and seen_all[match[0]]:
            return int(match[0]), "the most displaced of figure 3's frames"
    candidates = np.flatnonzero(seen_all)
    if candidates.size == 0:
        return -1, ""
    return most_displaced(inputs, candidates), "the most displaced frame that saw every marker"


def draw_marker_errors(record: RunRecord, cache: dict | None = None):
    """Figure 4 from a record, or the reason it cannot be drawn."""
    from workbench.reporting.figures import basis_label
    from workbench.reporting.figures.faces import figure_marker_errors

    cache = {} if cache is None else cache
    found = marker_variant(record, cache)
    if found is None:
        return needs("needs a marker data variant saved with save_inputs=true", cache)
    data, inputs = found
    solver_name, solver = figure_solver(record.config)
    frame, why = figure4_frame(record, inputs, cache)
    if frame < 0:
        return "needs an evaluated frame that saw every marker (every frame has a gap)"
    captured = inputs["eval"][[frame]]
    reconstructed, titles = {}, {}
    for name, shapes in figure_bases(record, data, inputs, cache).items():
        reconstructed[name] = reconstruct_frames(shapes, captured, solver)[0]
        alpha = frame_alpha(inputs["neutral"], captured, reconstructed[name][None])
        titles[name] = (
            f"{basis_label(name)}\nalpha abs {alpha['absolute'][0]:.3f} %, disp "
            f"{alpha['displacement'][0]:.1f} %, RMS {alpha['rms'][0]:.3f} mm"
        )
    n_markers = inputs["neutral"].size // 3
    figure = figure_marker_errors(
        inputs["neutral"],
        captured[0],
        reconstructed,
        titles,
        units=record.metrics["dataset"]["units"],
        title=(
            f"Figure 4 (reproduced): reconstruction error at the {n_markers} markers, "
            f"{record_timeline(record, inputs).label(frame)}, {why}\n{short_label(record)}; data {data}, "
            f"{figure_m(record, data)}, solver {solver_name}; captured red, reconstructed blue"
        ),
    )
    return figure, drawn_from(record, data)


def draw_vertex_rms(record: RunRecord, cache: dict):
    """Per-vertex RMS error over the whole take for H, the quasi-eigen bases and PCA, or why not drawn."""
    from workbench.reporting.figures.faces import figure_vertex_rms

    face = face_data(record, cache)
    if isinstance(face, str):
        return needs(face, cache)
    data, inputs = face.data, face.inputs
    solver_name, _ = figure_solver(record.config)
    operator = face.operator
    rms = {}
    for label, shapes in figure_bases(record, data, inputs, cache, every=True).items():
        weights, complete = frame_weights(record, data, label, cache)
        rms[label] = vertex_rms(
            inputs["eval"][complete], lambda rows, w=weights, e=shapes: w[rows] @ e, operator=operator
        )
    complete = np.isfinite(inputs["eval"]).all(axis=1)
    mean, components, evaluated = inputs["mean"], inputs["components"], inputs["eval"][complete]
    rms["PCA"] = vertex_rms(
        evaluated, lambda rows: mean + ((evaluated[rows] - mean) @ components.T) @ components, operator=operator
    )
    figure = figure_vertex_rms(
        face.neutral,
        face.faces,
        rms,
        support=face.support,
        title=(
            f"Per-vertex RMS error over the take ({int(complete.sum())} frames)\n{short_label(record)}; data "
            f"{data}, {figure_m(record, data)}, solver {solver_name} (PCA: projection)"
            + ("\n" + face.note if face.carried else "")
        ),
    )
    return with_caption(figure, record, face, "each vertex's RMS is that of the markers' errors carried onto the mesh")


def draw_alpha_per_solver(record: RunRecord, cache: dict):
    from workbench.reporting.figures.studies import plot_alpha_per_solver

    column = headline_column(record.config)
    return plot_alpha_per_solver(
        record.table[record.table["data"].isin(training_variants(record))],
        column,
        negative_weight_share(record),
        title=(
            "Alpha per solver: constraints on the weights, and how many frames have a negative weight "
            f"without them\n{short_label(record)}"
        ),
        settings=record.config.get("solver"),
    )


def draw_error_cdf(record: RunRecord, cache: dict | None = None):
    """The cumulative per-frame error curve of every basis and solver, from the record's error quantiles."""
    from workbench.numerics.metrics import ERROR_QUANTILES
    from workbench.reporting.figures.distributions import plot_error_cdf

    curves = {}
    for row in record.rows():
        if row.get("error_mm_quantiles"):
            curves.setdefault(row["data"], {})[(row["basis"], row["solver"])] = np.asarray(row["error_mm_quantiles"])
    if not curves:
        return "needs per-frame errors in the record (runs made before they were recorded have none)"
    regions = {data: values["face_region"] for data, values in record.metrics["data"].items()}
    return plot_error_cdf(
        curves,
        ERROR_QUANTILES,
        regions=regions,
        settings=record.config.get("solver"),
        title=f"Per-frame error in millimetres, cumulative, every basis and solver\n{short_label(record)}",
    )


def minimum_norm_text(row: Mapping) -> str:
    """``minimum-norm, rank r of n`` for a ``metrics.json`` row whose least-squares weights are the minimum-norm
    choice of a rank-deficient basis (:func:`workbench.reporting.findings.run.minimum_norm_label`), else empty."""
    from workbench.reporting.findings.run import minimum_norm_label

    return minimum_norm_label(row, row.get("solver", "")).strip().removeprefix("(").removesuffix(")")


def draw_weight_statistics(record: RunRecord, cache: dict | None = None):
    """Range, bounds, sparsity and roughness of every basis's weights under every solver, from the record."""
    from workbench.reporting.figures.distributions import plot_weight_statistics

    statistics, minimum_norm = {}, {}
    for row in record.rows():
        if row.get("weights"):
            statistics.setdefault(row["data"], {})[(row["basis"], row["solver"])] = row["weights"]
            label = minimum_norm_text(row)
            if label:
                minimum_norm.setdefault(row["data"], {})[row["basis"]] = label
    if not statistics:
        return "needs weight statistics in the record (runs made before they were recorded have none)"
    return plot_weight_statistics(
        statistics,
        title=f"The weights an animator would get, per basis and solver\n{short_label(record)}",
        minimum_norm=minimum_norm,
    )


def draw_weight_curves(record: RunRecord, cache: dict, seconds_around: float = 3.0, per_frame: int = 3):
    """w_i(t) of H and the quasi-eigen basis around each of figure 3's frames (marked), for the hand shapes that
    contribute most there (and their left/right partners)."""
    from workbench.reporting.figures.shapes import plot_weight_curves
    from workbench.reporting.report.sides import side_pairs

    found = mesh_variant(record, cache) or marker_variant(record, cache)
    if found is None:
        return needs("needs inputs saved with save_inputs=true", cache)
    data, inputs = found
    solver_name, _ = figure_solver(record.config)
    timeline = record_timeline(record, inputs)
    labels = ["H", qe_label(record)]
    weights = {}
    for label in labels:
        values, complete = frame_weights(record, data, label, cache)
        weights[label] = np.full((len(complete), values.shape[1]), np.nan)
        weights[label][complete] = values
    sizes = np.linalg.norm(inputs["hand"], axis=1)
    names = [str(name) for name in inputs["hand_names"]]
    windows, shown = [], []
    for region, frame in figure3_frames(record, inputs):
        contribution = np.nan_to_num(np.abs(weights["H"][frame]) * sizes)
        shown += [int(k) for k in np.argsort(-contribution)[:per_frame] if contribution[k] > 0]
        rows = np.flatnonzero(
            (timeline.take == timeline.take[frame])
            & (np.abs(timeline.seconds - timeline.seconds[frame]) <= seconds_around)
        )
        windows.append(
            {
                "label": frame_caption(region, timeline, frame),
                "seconds": timeline.seconds[rows],
                "marked": float(timeline.seconds[frame]),
                "take": str(timeline.take[frame]),
                "weights": {label: weights[label][rows] for label in labels},
            }
        )
    # a pair's two shapes one after the other, _L first (they share a column of the legend), pairs first
    pairs = {index: (left, right) for _, left, right in side_pairs(names) for index in (left, right)}
    shown = list(
        dict.fromkeys(
            [k for index in shown if index in pairs for k in pairs[index]]
            + [index for index in shown if index not in pairs]
        )
    )
    figure = plot_weight_curves(
        windows,
        names,
        shown,
        title=(
            f"Weights w_i(t) around figure 3's frames (marked), solver {solver_name}\n{short_label(record)}; "
            f"data {data}, {figure_m(record, data)}; the {per_frame} hand shapes contributing most at each frame, with their left/right "
            "partners"
        ),
    )
    return figure, drawn_from(record, data)


def draw_intuitiveness_bars(record: RunRecord, cache: dict):
    from workbench.reporting.figures.shapes import plot_intuitiveness_bars

    data = next(iter(figure_order(training_variants(record), "mesh")), None)
    rows = record.metrics["data"][data]["intuitiveness"]
    names = list(dict.fromkeys(row["shape"] for row in rows))
    projections = list(dict.fromkeys(row["projection"] for row in rows))
    values = {(row["projection"], row["shape"]): row for row in rows}
    figure = plot_intuitiveness_bars(
        names,
        {p: [values[p, n]["cosine"] for n in names] for p in projections},
        {p: [values[p, n]["relative_distance"] for n in names] for p in projections},
        title=f"How far each hand shape moves when projected (data {data}, {figure_m(record, data)})\n{short_label(record)}",
    )
    return figure, drawn_from(record, data)


def draw_coverage_curve(record: RunRecord):
    from workbench.reporting.figures.studies import plot_coverage_curve

    pca = {data: values["pca"] for data, values in record.metrics["data"].items()}
    settings = record.settings
    threshold = settings.basis.coverage if settings.basis.n_components is None else None
    hand = record.table[record.table["basis"] == "H"]
    return plot_coverage_curve(
        {data: np.asarray(p["explained_variance_ratio"]) for data, p in pca.items()},
        {data: p["m"] for data, p in pca.items()},
        threshold=threshold,
        paper_m=None if settings.paper is None else settings.paper.m,
        basis_size=int(hand["n"].iloc[0]) if len(hand) else None,
        title=f"Coverage: cumulative explained variance of the leading eigenvalues\n{short_label(record)}",
    )


def draw_alpha_over_time(record: RunRecord, cache: dict | None = None):
    from workbench.reporting.figures.studies import plot_alpha_over_time

    arrays = record_alpha_per_frame(record, {} if cache is None else cache)
    if arrays is None:
        return needs("needs alpha_per_frame.npz, written by runs with save_inputs=true", cache)
    solver_name, _ = figure_solver(record.config)
    normalisation = record.settings.metric.headline_normalisation
    series = {}
    for data in training_variants(record):  # held-out frames are another timeline
        bases, solvers = arrays[f"{data}.basis"], arrays[f"{data}.solver"]
        values = arrays[f"{data}.{normalisation}"]
        series[data] = {
            str(b): values[i] for i, (b, s) in enumerate(zip(bases, solvers)) if s == solver_name or b == "PCA"
        }
    first = training_variants(record)[0]
    timeline = Timeline.from_arrays(arrays, f"{first}.") or Timeline.uniform(
        "take", np.arange(len(arrays[f"{first}.absolute"][0])), record.metrics["dataset"]["frame_rate"]
    )
    elapsed = timeline.elapsed()
    takes = [(str(timeline.take[start]), float(elapsed[start])) for start, _ in timeline.take_spans()]
    return plot_alpha_over_time(
        series,
        elapsed,
        ylabel=f"alpha, {normalisation} (%)",
        takes=takes,
        title=f"Alpha of every frame over the take, solver {solver_name}\n{short_label(record)}",
    )


def draw_marker_vs_mesh(record: RunRecord):
    from workbench.reporting.figures.studies import plot_marker_vs_mesh
    from workbench.study.regime import is_paper_regime

    # one m per panel: the paper's regime (m = n, the variants the summary's verdict is about) when the run has it
    # on both point sets, else the coverage rule's m (a paper-regime variant differs in m, not in the points)
    variants = training_variants(record)
    paper = [data for data in variants if is_paper_regime(data)]
    compared = paper if len(paper) >= 2 else [data for data in variants if not is_paper_regime(data)]
    which = "m = n, the paper's regime" if compared is paper else "the coverage rule's m"
    table = record.table[record.table["data"].isin(compared)]
    if len(compared) == 1:
        return None  # a run on one data variant: no figure of it, not a missing one
    if table["data"].nunique() < 2:
        return "needs a run on two data variants (dataset.train_on=[markers,mesh])"
    solver_name, _ = figure_solver(record.config)
    figure = plot_marker_vs_mesh(
        table,
        ("rms_mm", "alpha_disp_pooled"),
        solver=solver_name,
        title=f"Marker versus mesh data: the method on each, at {which}\n{short_label(record)}",
    )
    return figure, f"Drawn from the data variants {', '.join(repr(data) for data in compared)}, at {which}."


RUN_FIGURES: tuple[tuple[str, str, str, Callable, str], ...] = (
    (
        "fig1_analogy",
        "Figure 1: the analogical drawing",
        "A seeded cloud of 300 points near a plane; PCA axes from Eigenfaces, hand vectors off the plane and their "
        "affine quasi-eigen projections (eq. 3-4), all computed by the workbench core.",
        lambda record, options: draw_analogy(),
        FIGURES_SECTION,
    ),
    (
        "fig2_hand_vs_quasi_eigen",
        "Figure 2: hand shapes beside their quasi-eigen faces",
        "Four hand shapes (first row) above their quasi-eigen faces (second row), plain shaded as in the paper, "
        "with their relative distance |e^QE - e^H| / |e^H| and cosine; below, each one's signed displacement along "
        "the surface normal (red: out of the face, blue: into it; zero white), one colour bar per pair reaching its "
        "largest value. The four are spread over the ranks of the relative distance (least to most changed) unless "
        "--shapes names them. Where the capture has no data (beyond the markers' reach) the quasi-eigen maps fade "
        "into the plain shade.",
        lambda record, options: draw_hand_vs_quasi_eigen(record, options.get("shapes"), options["cache"]),
        FIGURES_SECTION,
    ),
    (
        "fig3_reconstructions",
        "Figure 3: captured frames and their reconstructions",
        "The most displaced frame of each region of the face the hand shapes act on (brows, eyes, mouth, jaw; "
        "named by take, frame of the source file and time), plain shaded as in the paper: captured, and "
        "reconstructed with the hand basis and the quasi-eigen basis (the run's solver, alpha under each); then the "
        "per-vertex error of each reconstruction on the captured face, on one colour bar (an arrow: a few vertices "
        "go beyond it). Eyes and mouth are closed by dark caps; where the capture has no data the error maps fade "
        "into the plain shade and stay out of the scale.",
        lambda record, options: draw_reconstructions(record, options["cache"]),
        FIGURES_SECTION,
    ),
    (
        "fig4_marker_errors",
        "Figure 4: one frame's reconstruction error at the markers",
        "Captured markers (red) and reconstructed markers (blue) of the most displaced of figure 3's frames, front "
        "and side views; "
        "the offsets are magnified by the stated factor so that sub-millimetre errors show.",
        lambda record, options: draw_marker_errors(record, options["cache"]),
        FIGURES_SECTION,
    ),
    (
        "vertex_rms",
        "Where each basis errs over the whole take",
        "Per-vertex RMS reconstruction error over every evaluated frame, for the hand basis, the quasi-eigen bases "
        "and PCA, on one shared colour bar (an arrow: a few vertices go beyond it), with the RMS over the face and "
        "the largest vertex.",
        lambda record, options: draw_vertex_rms(record, options["cache"]),
        FIGURES_SECTION,
    ),
    (
        "alpha_per_solver",
        "Alpha per solver",
        "The headline alpha of each basis under least squares, non-negative and box weights (PCA's projection as a "
        "dashed line), with the share of frames whose least-squares weights include a negative one (from the "
        "record). That share alone does not say what a constraint costs: the findings give the numbers that do.",
        lambda record, options: draw_alpha_per_solver(record, options["cache"]),
        FIGURES_SECTION,
    ),
    (
        "error_cdf",
        "Per-frame error in millimetres, as a distribution",
        "For each error in millimetres, the share of evaluated frames whose RMS point error over the face region is "
        "at most that (the cumulative distribution over frames), for every basis and solver; the median and the "
        "95th percentile are the grey lines. From the error quantiles the run recorded.",
        lambda record, options: draw_error_cdf(record, options["cache"]),
        FIGURES_SECTION,
    ),
    (
        "weight_statistics",
        "The weights an animator would get",
        "Per basis and solver: the largest |w|, the share of frames with a weight outside [0, 1], Hoyer's sparsity "
        "(sqrt(n) - |w|_1/|w|_2) / (sqrt(n) - 1), mean over frames (1: one shape per frame), and the roughness, the "
        "mean squared second time derivative of the weights (1/s^4, second differences over the frames' times within "
        "each take). PCA's coefficients are no animator's weights and are left out. A * marks a basis whose n shapes "
        "have rank r < n on the scored points (the note under its row gives r): its least-squares weights are the "
        "minimum-norm choice among many with the same error, so their bars describe that choice, not the basis.",
        lambda record, options: draw_weight_statistics(record, options["cache"]),
        FIGURES_SECTION,
    ),
    (
        "weight_curves",
        "Weight curves w_i(t) of H and QE",
        "The weights around each of figure 3's frames (dotted vertical line), in the hand basis and in the "
        "quasi-eigen basis: the hand shapes that contribute most at those frames, with their left/right partners "
        "(a pair shares a colour, _L solid, _R dashed); dotted horizontal: w = 1, a shape fully on.",
        lambda record, options: draw_weight_curves(record, options["cache"]),
        FIGURES_SECTION,
    ),
    (
        "intuitiveness",
        "How far each hand shape moves when projected",
        "Cosine (1: same direction) and relative distance |e^QE - e^H| / |e^H| (0: unchanged) between each hand "
        "shape and its quasi-eigen face, per projection.",
        lambda record, options: draw_intuitiveness_bars(record, options["cache"]),
        FIGURES_SECTION,
    ),
    (
        "coverage_curve",
        "Coverage curve",
        "Cumulative explained variance against the number of eigenfaces m (the first 60 eigenvalues kept in the "
        "record), with the coverage threshold, the chosen m of each data variant, the paper's m = 18 and the hand "
        "basis size n.",
        lambda record, options: draw_coverage_curve(record),
        FIGURES_SECTION,
    ),
    (
        "alpha_over_time",
        "Alpha per frame over time",
        "Per-frame alpha (the headline normalisation) of each basis over the take; takes concatenated in time are "
        "drawn one after another with their boundaries named.",
        lambda record, options: draw_alpha_over_time(record, options["cache"]),
        FIGURES_SECTION,
    ),
    (
        "marker_vs_mesh",
        "Marker versus mesh",
        "RMS error (mm) and pooled displacement alpha of each basis when the method runs on the markers and on the "
        "dense mesh, one panel per evaluated point set (values compare within a panel only).",
        lambda record, options: draw_marker_vs_mesh(record),
        FIGURES_SECTION,
    ),
)


SHARED_FIGURES = ("fig1_analogy",)
"""Figures that do not depend on the run (figure 1 is drawn from a fixed seed): the reference reports share one
copy (``reports/shared/``); any other report holds its own."""


def make_figures(specs, argument, folder: Path, formats: Sequence[str], options: Mapping) -> list[FigureEntry]:
    """Draw and save each figure of ``specs`` (rows of stem, title, caption, draw and the report section it goes in)
    in ``folder`` (the report's ``figures/``), or the figures of :data:`SHARED_FIGURES` in ``options["shared"]``
    when given; a figure that cannot be drawn is listed with the reason; a figure that is none of the run's (a draw
    returning None) is left out. A draw may return a
    (figure, text) pair: the text is added to the caption (:func:`with_caption`). Files are named relative to the
    report folder (``folder``'s parent)."""
    from workbench.reporting.figures import save_figure

    entries = []
    for stem, title, caption, draw, section in specs:
        entry = FigureEntry(stem=stem, title=title, caption=caption, section=section)
        result = draw(argument, options)
        if result is None:
            continue
        if isinstance(result, tuple):
            result, more = result
            entry.caption = f"{caption} {more}"
        if isinstance(result, str):
            entry.missing = result
        else:
            target = options.get("shared") if stem in SHARED_FIGURES and options.get("shared") else folder
            entry.files = [
                Path(os.path.relpath(path, folder.parent)).as_posix()
                for path in save_figure(result, target, stem, formats)
            ]
        entries.append(entry)
    return entries


def clear_figures(folder: Path) -> None:
    """Remove the figures a report folder's ``figures/`` holds from an earlier report."""
    if folder.is_dir():
        for path in folder.iterdir():
            if path.suffix in (".png", ".svg", ".pdf", ".gif", ".webp", ".js"):
                path.unlink()
