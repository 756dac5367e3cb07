"""``workbench report <run or sweep folder>``: an HTML page and a README.md with the alpha tables, the paper's
figures and the study plots, rebuilt from run records only.

A *run* folder holds a complete record (``done`` written last, see :mod:`workbench.record`); a *sweep* folder
holds run folders at any depth. The report of a run has the alpha tables beside the paper's values, figures 1-4
(figures 2-4 need the inputs a run writes with ``save_inputs=true``), the coverage curve, alpha per frame over
time and marker versus mesh; the report of a sweep has the tidy table of means and 95 % confidence intervals over
seeds and alpha against every swept setting. Both state the dataset's provenance and licence, the choices the run
made, and the versions and commit that made it.

Figures 2-4 show a few frames and shapes; they are recomputed from the saved inputs with the core's own
functions (eq. 3-4 and the run's solver), which keeps records small. Nothing else is recomputed.
"""

from __future__ import annotations

import argparse
import html
import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Mapping, Sequence

import numpy as np
import pandas as pd

from workbench.dataset.capture import Timeline
from workbench.errors import WorkbenchError
from workbench.files import inside, plain_name, write_atomic
from workbench.record import DONE, RunRecord, find_records, is_complete, load_record
from workbench.reporting.runs import (interval_label, is_replicate_key, level_statistics, paired_comparisons,
                                      runs_table, summarise, sweep_comparisons, varying_keys, wide)
from workbench.statistics import GEOMETRIC
from workbench.tables import html_frame, markdown_frame

ANALOGY_SEED = 1
FIGURE_FORMATS: tuple[str, ...] = ()
"""Copies of each figure a report writes besides the one it shows (WebP renders, SVG line plots)."""
QE_PROJECTIONS = {"QE": "affine", "QE-linear": "linear"}
REPORT_PACKAGES = ("matplotlib", "pyvista", "vtk", "pandas", "numpy")


def hand_basis_size(summary: pd.DataFrame, by: Sequence[str]) -> pd.Series:
    """Size of the hand basis beside every row of a tidy table: the ``n`` of the ``H`` row with the same swept
    values and data variant (the x of "alpha against basis count"; PCA's own ``n`` is m)."""
    keys = [*by, "data"]
    hand = summary[summary["basis"] == "H"].groupby(keys, sort=False, dropna=False)["n"].first()
    index = pd.MultiIndex.from_frame(summary[keys].astype(object)) if len(keys) > 1 else summary[keys[0]]
    return pd.Series(hand.reindex(index).to_numpy(), index=summary.index, name="n_hand")


# ---------------------------------------------------------------------------------------------------------------
# Arrays behind figures 2-4, recomputed from saved inputs with the core
# ---------------------------------------------------------------------------------------------------------------


def quasi_eigen_shapes(inputs: Mapping[str, np.ndarray], projection: str,
                       appended_axes: Sequence[int] = ()) -> np.ndarray:
    """The run's quasi-eigen basis from its saved inputs (eq. 3-4), with any appended eigenfaces.

    Parameters
    ----------
    inputs : mapping
        ``hand`` (n_shapes, n_dims), ``mean`` (n_dims,), ``components`` (m, n_dims).
    projection : {"affine", "linear"}
    appended_axes : sequence of int
        1-based eigenface axes the post-treatment appended (``metrics.json``).

    Returns
    -------
    ndarray of shape (n_shapes + n_appended, n_dims)
    """
    from workbench.bases import pca_to_qe_weights, quasi_eigen_faces

    components, mean = inputs["components"], inputs["mean"]
    weights = pca_to_qe_weights(inputs["hand"], components, mean, projection)
    shapes = quasi_eigen_faces(weights, components, mean, projection)
    appended = [components[j - 1] for j in appended_axes]
    return np.vstack([shapes, *appended]) if appended else shapes


def figure_solver(config: Mapping) -> tuple[str, dict]:
    """The solver figures 2-4 use: ``lstsq`` when the run had it, else the first configured one."""
    from workbench.study.run import check_solver_config

    solvers = config["solver"]
    name = "lstsq" if "lstsq" in solvers else next(iter(solvers))
    return name, check_solver_config(name, solvers[name])


def reconstruct_frames(shapes: np.ndarray, frames: np.ndarray, solver: Mapping) -> np.ndarray:
    """Reconstructions of some frames in a basis with the run's solver (eq. 5).

    Parameters
    ----------
    shapes : ndarray of shape (n_shapes, n_dims)
    frames : ndarray of shape (n_frames, n_dims)
        Captured displacements.
    solver : mapping
        Keyword arguments of :func:`workbench.solve.solve_weights`.

    Returns
    -------
    ndarray of shape (n_frames, n_dims)
    """
    from workbench.solve import reconstruct, solve_weights

    return reconstruct(shapes, solve_weights(shapes, frames, **solver).weights)


def frame_alpha(neutral: np.ndarray, captured: np.ndarray, reconstructed: np.ndarray) -> dict:
    """Per-frame absolute and displacement alpha (eq. 6) and RMS error of some frames.

    Parameters
    ----------
    neutral : ndarray of shape (n_dims,)
    captured, reconstructed : ndarray of shape (n_frames, n_dims)

    Returns
    -------
    dict
        ``absolute``, ``displacement``, ``rms`` : ndarray of shape (n_frames,).
    """
    from workbench.metrics import alpha_per_frame

    squared = (captured - reconstructed) ** 2
    return {"absolute": alpha_per_frame(neutral + captured, neutral + reconstructed),
            "displacement": alpha_per_frame(captured, reconstructed),
            "rms": np.sqrt(squared.reshape(len(squared), -1, 3).sum(axis=2).mean(axis=1))}


# ---------------------------------------------------------------------------------------------------------------
# Figures of a report
# ---------------------------------------------------------------------------------------------------------------


@dataclass
class FigureEntry:
    """One figure of a report: where it is, what it shows, or why it could not be drawn."""

    stem: str
    title: str
    caption: str
    files: list = field(default_factory=list)
    missing: str = ""


def dataset_label(record: RunRecord) -> str:
    provenance = record.metrics["dataset"].get("provenance", {})
    if provenance.get("kind") == "synthetic":
        return "synthetic actor (generated, not real capture)"
    return record.metrics["dataset"]["name"]


SHORT_DATASET_LABELS = {"synthetic": "synthetic actor (generated)",
                        "ict_livelink": "ICT FaceKit face, real Live Link Face take",
                        "animface": "AnimFace capture, ICT FaceKit hand shapes (another face)"}


def short_label(record: RunRecord) -> str:
    """The dataset in a few words, for figure titles."""
    kind = record.metrics["dataset"].get("provenance", {}).get("kind")
    return SHORT_DATASET_LABELS.get(kind, record.metrics["dataset"]["name"])


def headline_column(config: Mapping) -> str:
    metric = config.get("metric", {})
    short = {"absolute": "abs", "displacement": "disp"}[metric.get("headline_normalisation", "absolute")]
    return f"alpha_{short}_{metric.get('headline_aggregate', 'mean')}"


def _inputs(record: RunRecord, data: str, cache: dict) -> dict | None:
    key = ("inputs", data)
    if key not in cache:
        cache[key] = record.load_inputs(data)
    return cache[key]


def _mesh_variant(record: RunRecord, cache: dict) -> tuple[str, dict] | None:
    """The data variant whose points are mesh vertices (saved with triangles), preferring ``mesh``."""
    for data in sorted(record.data_variants, key=lambda d: d != "mesh"):
        inputs = _inputs(record, data, cache)
        if inputs is not None and "faces" in inputs:
            return data, inputs
    return None


def _marker_variant(record: RunRecord, cache: dict) -> tuple[str, dict] | None:
    """The data variant of markers (no triangles), preferring ``markers``."""
    for data in sorted(record.data_variants, key=lambda d: d != "markers"):
        inputs = _inputs(record, data, cache)
        if inputs is not None and "faces" not in inputs:
            return data, inputs
    return None


def _qe_label(record: RunRecord) -> str:
    projections = record.config["basis"]["projections"]
    return "QE" if "affine" in projections else "QE-linear"


def _appended_axes(record: RunRecord, data: str, label: str) -> list[int]:
    return record.metrics["data"][data]["quasi_eigen"][QE_PROJECTIONS[label]]["appended_axes"]


def record_timeline(record: RunRecord, inputs: Mapping) -> Timeline:
    """The evaluated frames' take, frame number in the file and time (saved inputs), or frames of one take at the
    record's frame rate for records written before runs saved them."""
    found = Timeline.from_arrays(inputs, "eval_")
    return found if found is not None else Timeline.uniform(
        "take", np.arange(len(inputs["eval"])), record.metrics["dataset"]["frame_rate"])


def training_variants(record: RunRecord) -> list[str]:
    """The data variants scored on their training frames (the paper's protocol), not on held-out frames."""
    return [data for data, values in record.metrics["data"].items()
            if values.get("protocol", "training frames") == "training frames"]


def figure_bases(record: RunRecord, data: str, inputs: Mapping, cache: dict, *, every: bool = False) -> dict:
    """Basis label -> shapes: H and the run's quasi-eigen basis (with ``every``: both projections the run had)."""
    key = ("bases", data, every)
    if key not in cache:
        labels = [label for label, projection in QE_PROJECTIONS.items()
                  if projection in record.config["basis"]["projections"]]
        labels = labels if every else [_qe_label(record)]
        cache[key] = {"H": inputs["hand"], **{label: quasi_eigen_shapes(inputs, QE_PROJECTIONS[label],
                                                                         _appended_axes(record, data, label))
                                              for label in labels}}
    return cache[key]


def frame_weights(record: RunRecord, data: str, label: str, cache: dict) -> tuple[np.ndarray, np.ndarray]:
    """Weights of every evaluated frame that saw every point, in a basis, with the figures' solver.

    Returns
    -------
    weights : ndarray of shape (n_complete, n_shapes)
    complete : ndarray of shape (n_eval_frames,) of bool
    """
    from workbench.solve import solve_weights

    key = ("weights", data, label)
    if key not in cache:
        inputs = _inputs(record, data, cache)
        _, solver = figure_solver(record.config)
        complete = np.isfinite(inputs["eval"]).all(axis=1)
        shapes = figure_bases(record, data, inputs, cache, every=True)[label]
        cache[key] = solve_weights(shapes, inputs["eval"][complete], **solver).weights, complete
    return cache[key]


def negative_weight_share(record: RunRecord) -> dict:
    """Data variant -> (basis -> share of evaluated frames whose least-squares weights include a negative one), as
    the run recorded it (rows' ``weights``); empty for records without weight statistics."""
    shares = {}
    for row in record.rows():
        if row.get("solver") == "lstsq" and row.get("weights"):
            shares.setdefault(row["data"], {})[row["basis"]] = float(row["weights"]["negative_share"])
    return shares


def figure3_frames(record: RunRecord, inputs: Mapping) -> list[tuple[str, int]]:
    """The frames of figure 3: the most displaced frame of each region of the face its hand shapes act on (brows,
    eyes, mouth, jaw), at least a second apart, or the most displaced frame when no region is found.

    Returns
    -------
    list of (str, int)
        (region, index among the evaluated frames), top of the face first.
    """
    from workbench.reporting.figures.faces import face_regions, point_norms, region_frames

    names = [str(name) for name in inputs["hand_names"]]
    timeline = record_timeline(record, inputs)
    regions = face_regions(inputs["hand"], names, inputs.get("point_support"))
    chosen = region_frames(inputs["eval"], regions, timeline.seconds, timeline.take)
    if not chosen:
        lengths = np.nan_to_num(point_norms(inputs["eval"]))
        chosen = [("face", int(np.argmax((lengths ** 2).sum(axis=1))))]
    return chosen


def most_displaced(inputs: Mapping, frames: Sequence[int]) -> int:
    """The frame of ``frames`` with the largest captured displacement (over every point)."""
    captured = np.nan_to_num(inputs["eval"][list(frames)])
    return int(list(frames)[int(np.argmax(np.linalg.norm(captured, axis=1)))])


def frame_caption(region: str, timeline: Timeline, frame: int) -> str:
    """How a frame of figure 3 is named: the region it is the most displaced frame of, take, file frame, time."""
    return f"most displaced {region}: {timeline.label(frame)}"


def draw_analogy():
    from workbench.reporting.figures.analogy import figure_analogy, make_analogy_example

    return figure_analogy(make_analogy_example(np.random.default_rng(ANALOGY_SEED)))


def draw_hand_vs_quasi_eigen(record: RunRecord, shapes: Sequence[str] | None = None, cache: dict | None = None):
    """Figure 2 from a record, or the reason it cannot be drawn."""
    from workbench.reporting.figures.faces import figure_hand_vs_quasi_eigen, spread_by_rank

    found = _mesh_variant(record, {} if cache is None else cache)
    if found is None:
        return "needs a mesh data variant saved with save_inputs=true (e.g. dataset.train_on=[markers,mesh])"
    data, inputs = found
    label = _qe_label(record)
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
    m = record.metrics["data"][data]["pca"]["m"]
    return figure_hand_vs_quasi_eigen(
        inputs["neutral"], inputs["faces"], inputs["hand"][chosen], quasi_eigen[chosen],
        [names[i] for i in chosen], [distance[names[i]] for i in chosen], [cosine[names[i]] for i in chosen],
        title=(f"Figure 2 (reproduced): hand shapes above their quasi-eigen faces\n{short_label(record)}; "
               f"data {data}, m = {m}, {projection} projection"),
        qe_label=f"quasi-eigen $e_i^{{QE}}$ ({projection})", support=inputs.get("point_support"))


def draw_reconstructions(record: RunRecord, cache: dict | None = None):
    """Figure 3 from a record, or the reason it cannot be drawn."""
    from workbench.reporting.figures import fixed_decimals
    from workbench.reporting.figures.faces import figure_reconstructions

    cache = {} if cache is None else cache
    found = _mesh_variant(record, cache)
    if found is None:
        return "needs a mesh data variant saved with save_inputs=true (e.g. dataset.train_on=[markers,mesh])"
    data, inputs = found
    solver_name, solver = figure_solver(record.config)
    chosen = figure3_frames(record, inputs)
    frames = [frame for _, frame in chosen]
    captured = inputs["eval"][frames]
    reconstructed = {name: reconstruct_frames(shapes, captured, solver)
                     for name, shapes in figure_bases(record, data, inputs, cache).items()}
    alphas = {name: frame_alpha(inputs["neutral"], captured, frames_out) for name, frames_out in reconstructed.items()}
    absolute = fixed_decimals([a for alpha in alphas.values() for a in alpha["absolute"]], significant=3)
    displacement = fixed_decimals([a for alpha in alphas.values() for a in alpha["displacement"]], significant=3)
    notes = {name: [f"alpha {a:.{absolute}f} % abs., {d:.{displacement}f} % disp."
                    for a, d in zip(alpha["absolute"], alpha["displacement"])] for name, alpha in alphas.items()}
    timeline = record_timeline(record, inputs)
    labels = [f"most displaced {region}\n{timeline.label(frame).replace(' (', chr(10) + '(')}"
              for region, frame in chosen]
    return figure_reconstructions(
        inputs["neutral"], inputs["faces"], captured, reconstructed, labels, notes,
        title=(f"Figure 3 (reproduced): captured frames and their reconstructions\n{short_label(record)}; data "
               f"{data}, solver {solver_name}; the most displaced frame of each region of the face"),
        support=inputs.get("point_support"))


def figure4_frame(record: RunRecord, inputs: Mapping, cache: dict) -> tuple[int, str]:
    """The frame of figure 4 in a marker variant: the most displaced of figure 3's frames (the same take and file
    frame), or, without a mesh variant or when that frame misses a marker, the most displaced frame that saw every
    marker.

    Returns
    -------
    index : int
        Index among the variant's evaluated frames.
    why : str
        How it was chosen, for the title.
    """
    timeline = record_timeline(record, inputs)
    seen_all = (inputs["eval_visible"].all(axis=1) if "eval_visible" in inputs
                else np.ones(len(inputs["eval"]), dtype=bool))
    mesh = _mesh_variant(record, cache)
    if mesh is not None:
        first = most_displaced(mesh[1], [frame for _, frame in figure3_frames(record, mesh[1])])
        other = record_timeline(record, mesh[1])
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
    found = _marker_variant(record, cache)
    if found is None:
        return "needs a marker data variant saved with save_inputs=true"
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
        titles[name] = (f"{basis_label(name)}\nalpha abs {alpha['absolute'][0]:.3f} %, disp "
                        f"{alpha['displacement'][0]:.1f} %, RMS {alpha['rms'][0]:.3f} mm")
    n_markers = inputs["neutral"].size // 3
    return figure_marker_errors(
        inputs["neutral"], captured[0], reconstructed, titles, units=record.metrics["dataset"]["units"],
        title=(f"Figure 4 (reproduced): reconstruction error at the {n_markers} markers, "
               f"{record_timeline(record, inputs).label(frame)}, {why}\n{short_label(record)}; data {data}, solver "
               f"{solver_name}; captured red, reconstructed blue"))


def draw_vertex_rms(record: RunRecord, cache: dict):
    """Per-vertex RMS error over the whole take for H, the quasi-eigen bases and PCA, or why not drawn."""
    from workbench.reporting.figures.faces import figure_vertex_rms

    found = _mesh_variant(record, cache)
    if found is None:
        return "needs a mesh data variant saved with save_inputs=true"
    data, inputs = found
    solver_name, _ = figure_solver(record.config)
    rms = {}
    for label, shapes in figure_bases(record, data, inputs, cache, every=True).items():
        weights, complete = frame_weights(record, data, label, cache)
        rms[label] = vertex_rms(inputs["eval"][complete], lambda rows, w=weights, e=shapes: w[rows] @ e)
    complete = np.isfinite(inputs["eval"]).all(axis=1)
    mean, components = inputs["mean"], inputs["components"]
    rms["PCA"] = vertex_rms(inputs["eval"][complete], lambda rows: mean + (
        (inputs["eval"][complete][rows] - mean) @ components.T) @ components)
    return figure_vertex_rms(
        inputs["neutral"], inputs["faces"], rms, support=inputs.get("point_support"),
        title=(f"Per-vertex RMS error over the take ({int(complete.sum())} frames)\n{short_label(record)}; data "
               f"{data}, solver {solver_name} (PCA: projection)"))


def vertex_rms(frames: np.ndarray, reconstruct: Callable[[slice], np.ndarray], chunk: int = 256) -> np.ndarray:
    """RMS over frames of the 3-D error at every point, in chunks of frames.

    Parameters
    ----------
    frames : ndarray of shape (n_frames, 3 * n_points)
    reconstruct : callable
        Rows (a slice) -> their reconstructions, ndarray of shape (n_rows, 3 * n_points).
    chunk : int

    Returns
    -------
    ndarray of shape (n_points,)
    """
    total = np.zeros(frames.shape[1] // 3)
    for start in range(0, len(frames), chunk):
        rows = slice(start, start + chunk)
        error = (reconstruct(rows) - frames[rows]).reshape(-1, frames.shape[1] // 3, 3)
        total += (error ** 2).sum(axis=(0, 2))
    return np.sqrt(total / max(len(frames), 1))


def draw_alpha_per_solver(record: RunRecord, cache: dict):
    from workbench.reporting.figures.studies import plot_alpha_per_solver

    column = headline_column(record.config)
    return plot_alpha_per_solver(
        record.table[record.table["data"].isin(training_variants(record))], column, negative_weight_share(record),
        title=("Alpha per solver: constraints on the weights, and how many frames have a negative weight "
               f"without them\n{short_label(record)}"))


def draw_error_cdf(record: RunRecord, cache: dict | None = None):
    """The cumulative per-frame error curve of every basis and solver, from the record's error quantiles."""
    from workbench.metrics import ERROR_QUANTILES
    from workbench.reporting.figures.distributions import plot_error_cdf

    curves = {}
    for row in record.rows():
        if row.get("error_mm_quantiles"):
            curves.setdefault(row["data"], {})[(row["basis"], row["solver"])] = np.asarray(row["error_mm_quantiles"])
    if not curves:
        return "needs per-frame errors in the record (runs made before they were recorded have none)"
    regions = {data: values.get("face_region", "") for data, values in record.metrics["data"].items()}
    return plot_error_cdf(curves, ERROR_QUANTILES, regions=regions,
                          title=f"Per-frame error in millimetres, cumulative, every basis and solver\n"
                                f"{short_label(record)}")


def draw_weight_statistics(record: RunRecord, cache: dict | None = None):
    """Range, bounds, sparsity and roughness of every basis's weights under every solver, from the record."""
    from workbench.reporting.figures.distributions import plot_weight_statistics

    statistics = {}
    for row in record.rows():
        if row.get("weights"):
            statistics.setdefault(row["data"], {})[(row["basis"], row["solver"])] = row["weights"]
    if not statistics:
        return "needs weight statistics in the record (runs made before they were recorded have none)"
    return plot_weight_statistics(statistics, title=f"The weights an animator would get, per basis and solver\n"
                                                    f"{short_label(record)}")


def draw_weight_curves(record: RunRecord, cache: dict, seconds_around: float = 3.0, per_frame: int = 3):
    """w_i(t) of H and the quasi-eigen basis around each of figure 3's frames (marked), for the hand shapes that
    contribute most there (and their left/right partners)."""
    from workbench.reporting.figures.studies import plot_weight_curves
    from workbench.reporting.sides import side_pairs

    found = _mesh_variant(record, cache) or _marker_variant(record, cache)
    if found is None:
        return "needs inputs saved with save_inputs=true"
    data, inputs = found
    solver_name, _ = figure_solver(record.config)
    timeline = record_timeline(record, inputs)
    labels = ["H", _qe_label(record)]
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
        rows = np.flatnonzero((timeline.take == timeline.take[frame])
                              & (np.abs(timeline.seconds - timeline.seconds[frame]) <= seconds_around))
        windows.append({"label": frame_caption(region, timeline, frame), "seconds": timeline.seconds[rows],
                        "marked": float(timeline.seconds[frame]), "take": str(timeline.take[frame]),
                        "weights": {label: weights[label][rows] for label in labels}})
    # a pair's two shapes one after the other, _L first (they share a column of the legend), pairs first
    pairs = {index: (left, right) for _, left, right in side_pairs(names) for index in (left, right)}
    shown = list(dict.fromkeys([k for index in shown if index in pairs for k in pairs[index]]
                               + [index for index in shown if index not in pairs]))
    return plot_weight_curves(
        windows, names, shown,
        title=(f"Weights w_i(t) around figure 3's frames (marked), solver {solver_name}\n{short_label(record)}; "
               f"data {data}; the {per_frame} hand shapes contributing most at each frame, with their left/right "
               "partners"))


def draw_intuitiveness_bars(record: RunRecord, cache: dict):
    from workbench.reporting.figures.studies import plot_intuitiveness_bars

    data = next((d for d in sorted(record.data_variants, key=lambda d: d != "mesh")), None)
    rows = record.metrics["data"][data]["intuitiveness"]
    names = list(dict.fromkeys(row["shape"] for row in rows))
    projections = list(dict.fromkeys(row["projection"] for row in rows))
    values = {(row["projection"], row["shape"]): row for row in rows}
    return plot_intuitiveness_bars(
        names, {p: [values[p, n]["cosine"] for n in names] for p in projections},
        {p: [values[p, n]["relative_distance"] for n in names] for p in projections},
        title=f"How far each hand shape moves when projected (data {data})\n{short_label(record)}")


def draw_coverage_curve(record: RunRecord):
    from workbench.reporting.figures.studies import plot_coverage_curve

    pca = {data: values["pca"] for data, values in record.metrics["data"].items()}
    basis = record.config["basis"]
    threshold = basis["coverage"] if basis.get("n_components") is None else None
    hand = record.table[record.table["basis"] == "H"]
    return plot_coverage_curve(
        {data: np.asarray(p["explained_variance_ratio"]) for data, p in pca.items()},
        {data: p["m"] for data, p in pca.items()}, threshold=threshold,
        paper_m=record.config.get("paper", {}).get("m"), basis_size=int(hand["n"].iloc[0]) if len(hand) else None,
        title=f"Coverage: cumulative explained variance of the leading eigenvalues\n{short_label(record)}")


def draw_alpha_over_time(record: RunRecord, cache: dict | None = None):
    from workbench.reporting.figures.studies import plot_alpha_over_time

    arrays = record.load_alpha_per_frame()
    if arrays is None:
        return "needs alpha_per_frame.npz, written by runs with save_inputs=true"
    solver_name, _ = figure_solver(record.config)
    normalisation = record.config.get("metric", {}).get("headline_normalisation", "absolute")
    series = {}
    for data in training_variants(record):  # held-out frames are another timeline
        bases, solvers = arrays[f"{data}.basis"], arrays[f"{data}.solver"]
        values = arrays[f"{data}.{normalisation}"]
        series[data] = {str(b): values[i] for i, (b, s) in enumerate(zip(bases, solvers))
                        if s == solver_name or b == "PCA"}
    first = training_variants(record)[0]
    timeline = Timeline.from_arrays(arrays, f"{first}.") or Timeline.uniform(
        "take", np.arange(len(arrays[f"{first}.absolute"][0])), record.metrics["dataset"]["frame_rate"])
    elapsed = timeline.elapsed()
    takes = [(str(timeline.take[start]), float(elapsed[start])) for start, _ in timeline.take_spans()]
    return plot_alpha_over_time(series, elapsed, ylabel=f"alpha, {normalisation} (%)", takes=takes,
                                title=f"Alpha of every frame over the take, solver {solver_name}\n"
                                      f"{short_label(record)}")


def draw_marker_vs_mesh(record: RunRecord):
    from workbench.reporting.figures.studies import plot_marker_vs_mesh

    table = record.table[record.table["data"].isin(training_variants(record))]
    if table["data"].nunique() < 2:
        return "needs a run on two data variants (dataset.train_on=[markers,mesh])"
    solver_name, _ = figure_solver(record.config)
    return plot_marker_vs_mesh(table, ("rms_mm", "alpha_disp_pooled"), solver=solver_name,
                               title=f"Marker versus mesh data: the method on each\n{short_label(record)}")


RUN_FIGURES: tuple[tuple[str, str, str, Callable], ...] = (
    ("fig1_analogy", "Figure 1: the analogical drawing",
     "A seeded cloud of 300 points near a plane; PCA axes (red) from Eigenfaces, hand vectors (blue) off the "
     "plane and their affine quasi-eigen projections (purple, eq. 3-4), all computed by the workbench core.",
     lambda record, options: draw_analogy()),
    ("fig2_hand_vs_quasi_eigen", "Figure 2: hand shapes beside their quasi-eigen faces",
     "Four hand shapes (first row) above their quasi-eigen faces (second row), plain shaded as in the paper, "
     "with their relative distance |e^QE - e^H| / |e^H| and cosine; below, each one's signed displacement along "
     "the surface normal (red: out of the face, blue: into it; zero white), one colour bar per pair reaching its "
     "largest value. The four are spread over the ranks of the relative distance (least to most changed) unless "
     "--shapes names them. Where the capture has no data (beyond the markers' reach) the quasi-eigen maps fade "
     "into the plain shade.",
     lambda record, options: draw_hand_vs_quasi_eigen(record, options.get("shapes"), options["cache"])),
    ("fig3_reconstructions", "Figure 3: captured frames and their reconstructions",
     "The most displaced frame of each region of the face the hand shapes act on (brows, eyes, mouth, jaw; "
     "named by take, frame of the source file and time), plain shaded as in the paper: captured, and "
     "reconstructed with the hand basis and the quasi-eigen basis (the run's solver, alpha under each); then the "
     "per-vertex error of each reconstruction on the captured face, on one colour bar (an arrow: a few vertices "
     "go beyond it). Eyes and mouth are closed by dark caps; where the capture has no data the error maps fade "
     "into the plain shade and stay out of the scale.",
     lambda record, options: draw_reconstructions(record, options["cache"])),
    ("fig4_marker_errors", "Figure 4: one frame's reconstruction error at the markers",
     "Captured markers (red) and reconstructed markers (blue) of the most displaced of figure 3's frames, front "
     "and side views; "
     "the offsets are magnified by the stated factor so that sub-millimetre errors show.",
     lambda record, options: draw_marker_errors(record, options["cache"])),
    ("vertex_rms", "Where each basis errs over the whole take",
     "Per-vertex RMS reconstruction error over every evaluated frame, for the hand basis, the quasi-eigen bases "
     "and PCA, on one shared colour bar (an arrow: a few vertices go beyond it), with the RMS over the face and "
     "the largest vertex.",
     lambda record, options: draw_vertex_rms(record, options["cache"])),
    ("alpha_per_solver", "Alpha per solver",
     "The headline alpha of each basis under least squares, non-negative and box weights (PCA's projection as a "
     "dashed line), with the share of frames whose least-squares weights include a negative one (from the "
     "record). That share alone does not say what a constraint costs: the findings give the numbers that do.",
     lambda record, options: draw_alpha_per_solver(record, options["cache"])),
    ("error_cdf", "Per-frame error in millimetres, as a distribution",
     "For each error in millimetres, the share of evaluated frames whose RMS point error over the face region is "
     "at most that (the cumulative distribution over frames), for every basis and solver; the median and the "
     "95th percentile are the grey lines. From the error quantiles the run recorded.",
     lambda record, options: draw_error_cdf(record, options["cache"])),
    ("weight_statistics", "The weights an animator would get",
     "Per basis and solver: the largest |w|, the share of frames with a weight outside [0, 1], Hoyer's sparsity "
     "(sqrt(n) - |w|_1/|w|_2) / (sqrt(n) - 1), mean over frames (1: one shape per frame), and the roughness, the "
     "mean squared second time derivative of the weights (1/s^4, second differences over the frames' times within "
     "each take). PCA's coefficients are no animator's weights and are left out.",
     lambda record, options: draw_weight_statistics(record, options["cache"])),
    ("weight_curves", "Weight curves w_i(t) of H and QE",
     "The weights around each of figure 3's frames (dotted vertical line), in the hand basis and in the "
     "quasi-eigen basis: the hand shapes that contribute most at those frames, with their left/right partners "
     "(a pair shares a colour, _L solid, _R dashed); dotted horizontal: w = 1, a shape fully on.",
     lambda record, options: draw_weight_curves(record, options["cache"])),
    ("intuitiveness", "How far each hand shape moves when projected",
     "Cosine (1: same direction) and relative distance |e^QE - e^H| / |e^H| (0: unchanged) between each hand "
     "shape and its quasi-eigen face, per projection.",
     lambda record, options: draw_intuitiveness_bars(record, options["cache"])),
    ("coverage_curve", "Coverage curve",
     "Cumulative explained variance against the number of eigenfaces m (the first 60 eigenvalues kept in the "
     "record), with the coverage threshold, the chosen m of each data variant, the paper's m = 18 and the hand "
     "basis size n.",
     lambda record, options: draw_coverage_curve(record)),
    ("alpha_over_time", "Alpha per frame over time",
     "Per-frame alpha (the headline normalisation) of each basis over the take; takes concatenated in time are "
     "drawn one after another with their boundaries named.",
     lambda record, options: draw_alpha_over_time(record)),
    ("marker_vs_mesh", "Marker versus mesh",
     "RMS error (mm) and pooled displacement alpha of each basis when the method runs on the markers and on the "
     "dense mesh, one panel per evaluated point set (values compare within a panel only).",
     lambda record, options: draw_marker_vs_mesh(record)),
)


@dataclass
class FacesBlock:
    """The interactive 3-D view (HTML) and its animation (both documents), or why they are missing."""

    html: str = ""
    animation: str = ""
    caption: str = ""
    missing: str = ""


VIEW_CAPTION = ("Figure 3's frames you can turn (drag; scroll to zoom): the captured frame (left) beside its "
                "reconstruction with the basis you pick (right), both under one camera; coloured by the captured "
                "displacement and by the per-vertex error (one error scale for every basis and frame), or plain "
                "shaded. Regions without data are shown as plain geometry. Everything the view needs is in this "
                "report's folder: it works from the file, with no network, wherever the folder is copied.")
VIEW_VERTICES = 4000
"""The interactive view's mesh is decimated to about this many vertices (kept at their places, so every value
shown is the run's own at that vertex): enough for a face at screen size, and half the data of the ICT face."""
BASIS_NAMES = {"H": "H, the hand shapes", "QE": "QE, quasi-eigen faces (affine projection)",
               "QE-linear": "QE-linear, quasi-eigen faces (linear projection)", "PCA": "PCA, the m eigenfaces"}


def moving_stretch(inputs: Mapping, timeline: Timeline, n_frames: int) -> np.ndarray:
    """The ``n_frames`` consecutive evaluated frames of one take in which the face moves most (the summed RMS
    change of the displacement between consecutive frames), or the longest take when every take is shorter.

    Returns
    -------
    ndarray of int
        Consecutive frame indices.
    """
    frames = np.nan_to_num(inputs["eval"])
    change = np.zeros(len(frames))
    change[1:] = np.sqrt(((frames[1:] - frames[:-1]) ** 2).mean(axis=1))
    best, best_key = None, None
    for start, stop in timeline.take_spans():
        change[start] = 0.0  # no motion across a take boundary
        length = min(n_frames, stop - start)
        # motion of the window [first, first + length): the changes into its frames after the first
        summed = np.concatenate([[0.0], np.cumsum(change[start:stop])])
        motion = summed[length:] - summed[1:len(summed) - length + 1]
        first = int(np.argmax(motion))
        key = (length, float(motion[first]))  # a full-length window first, then the most motion
        if best_key is None or key > best_key:
            best, best_key = np.arange(start + first, start + first + length), key
    return best


def build_faces(record: RunRecord, out: Path, cache: dict, seconds: float = 2.0, most_fps: float = 10.0) -> FacesBlock:
    """Write the interactive view's data (``figures/view3d.js``) and the animation (``figures/animation.webp``) of a
    run's mesh variant.

    Parameters
    ----------
    record : RunRecord
    out : pathlib.Path
        The report folder.
    cache : dict
        Arrays shared with the figures.
    seconds : float
        Length of the animation: the stretch of a take where the face moves most, played in real time.
    most_fps : float
        Frames of a faster capture are skipped down to about this rate (fewer frames: a smaller file).
    """
    from workbench.dataset.decimate import decimate
    from workbench.reporting.figures import fixed_decimals
    from workbench.reporting.figures.faces import (DISPLACEMENT_CMAP, ERROR_CMAP, colour_range, masked,
                                                   point_norms)
    from workbench.reporting.figures.interactive import DATA_FILE, ViewFrame, view_payload, viewer_html, \
        write_animation, write_view_data
    from workbench.reporting.figures.render import (PLAIN_COLOUR, MeshView, crop_background, render_meshes,
                                                    support_weight)

    found = _mesh_variant(record, cache)
    if found is None:
        return FacesBlock(missing="needs a mesh data variant saved with save_inputs=true")
    data, inputs = found
    solver_name, solver = figure_solver(record.config)
    support = inputs.get("point_support")
    weight = support_weight(inputs["neutral"], support)
    timeline = record_timeline(record, inputs)
    chosen = figure3_frames(record, inputs)
    frames = [frame for _, frame in chosen]
    captured = inputs["eval"][frames]
    shown = {name: reconstruct_frames(shapes, captured, solver)
             for name, shapes in figure_bases(record, data, inputs, cache, every=True).items()}
    mean, components = inputs["mean"], inputs["components"]
    shown["PCA"] = mean + ((captured - mean) @ components.T) @ components
    alphas = {name: frame_alpha(inputs["neutral"], captured, frames_out) for name, frames_out in shown.items()}
    decimals = fixed_decimals([a for alpha in alphas.values() for a in alpha["absolute"]], significant=3)
    lengths = colour_range([masked(values, support) for values in point_norms(captured)], percentile=99.5)
    errors = colour_range([masked(values, support) for frames_out in shown.values()
                           for values in point_norms(frames_out - captured)], percentile=99.5)
    # the view's mesh: about VIEW_VERTICES of the vertices, kept where they are (a decimation selects rows)
    points = inputs["neutral"].reshape(-1, 3)
    mesh = decimate(points, inputs["faces"], min(1.0, VIEW_VERTICES / len(points)))
    rows = (3 * mesh.kept[:, None] + np.arange(3)).ravel()
    view_frames = [ViewFrame(frame_caption(region, timeline, frame), captured[i][rows],
                             {name: frames_out[i][rows] for name, frames_out in shown.items()},
                             {name: f"alpha {alpha['absolute'][i]:.{decimals}f} % (abs.), solver "
                                    f"{'projection' if name == 'PCA' else solver_name}"
                              for name, alpha in alphas.items()})
                   for i, (region, frame) in enumerate(chosen)]
    write_view_data(out / "figures" / DATA_FILE, view_payload(
        inputs["neutral"][rows], mesh.faces, view_frames, bases={name: BASIS_NAMES.get(name, name) for name in shown},
        displacement_range=(lengths.low, lengths.high, lengths.extend != "neither"),
        error_range=(errors.low, errors.high, errors.extend != "neither"), cmaps=(DISPLACEMENT_CMAP, ERROR_CMAP),
        weight=None if weight is None else weight[mesh.kept], title=f"{short_label(record)}; data {data}",
        plain_colour=PLAIN_COLOUR))

    rate = float(record.metrics["dataset"]["frame_rate"])
    stretch = moving_stretch(inputs, timeline, int(round(seconds * rate)))
    step = max(1, int(round(rate / most_fps)))
    steps = stretch[::step]
    moving = inputs["eval"][steps]
    qe = _qe_label(record)
    bases = figure_bases(record, data, inputs, cache)
    moved = {name: reconstruct_frames(bases[name], moving, solver) for name in ("H", qe)}
    errors_moving = {name: [masked(values, support) for values in point_norms(frames_out - moving)]
                     for name, frames_out in moved.items()}
    span = colour_range([values for per_frame in errors_moving.values() for values in per_frame], percentile=99.5)
    size = (420, 490)
    panels = [render_meshes(inputs["neutral"] + moving, inputs["faces"], None, MeshView(window_size=size))]
    for name, frames_out in moved.items():
        panels.append(render_meshes(inputs["neutral"] + frames_out, inputs["faces"], errors_moving[name],
                                    MeshView(cmap=ERROR_CMAP, clim=(span.low, span.high), window_size=size), weight))
    cropped = crop_background([image for panel in panels for image in panel])
    panels = [cropped[k * len(steps):(k + 1) * len(steps)] for k in range(len(panels))]
    fps = rate / step
    speed = f"real time: {fps:.3g} frames per second"
    write_animation(out / "figures" / "animation.webp", panels, ["captured", f"H (error)", f"{qe} (error)"],
                    [timeline.label(int(frame)) for frame in steps], fps=fps, speed=speed,
                    colour=(ERROR_CMAP, (span.low, span.high), span.extend, "reconstruction error per vertex (mm)"))
    first, last = int(steps[0]), int(steps[-1])
    caption = (f"The {len(steps) / fps:.1f} s of the take where the face moves most "
               f"({timeline.take[first]}, t = {timeline.seconds[first]:.2f} to {timeline.seconds[last]:.2f} s), "
               f"played in {speed}: captured (plain shaded), and reconstructed with H and {qe} (solver "
               f"{solver_name}), coloured by the per-vertex error.")
    return FacesBlock(html=viewer_html(f"figures/{DATA_FILE}", VIEW_CAPTION), animation="animation.webp",
                      caption=caption)


SHARED_FIGURES = ("fig1_analogy",)
"""Figures that do not depend on the run (figure 1 is drawn from a fixed seed): the reference reports share one
copy (``reports/shared/``); any other report holds its own."""


def make_figures(specs, argument, folder: Path, formats: Sequence[str], options: Mapping) -> list[FigureEntry]:
    """Draw and save each figure of ``specs`` in ``folder`` (the report's ``figures/``), or the figures of
    :data:`SHARED_FIGURES` in ``options["shared"]`` when given; a figure that cannot be drawn is listed with the
    reason. Files are named relative to the report folder (``folder``'s parent)."""
    import os

    from workbench.reporting.figures import save_figure

    entries = []
    for stem, title, caption, draw in specs:
        entry = FigureEntry(stem=stem, title=title, caption=caption)
        result = draw(argument, options)
        if isinstance(result, str):
            entry.missing = result
        else:
            target = options.get("shared") if stem in SHARED_FIGURES and options.get("shared") else folder
            entry.files = [Path(os.path.relpath(path, folder.parent)).as_posix()
                           for path in save_figure(result, target, stem, formats)]
        entries.append(entry)
    return entries


# ---------------------------------------------------------------------------------------------------------------
# Documents
# ---------------------------------------------------------------------------------------------------------------


@dataclass
class Section:
    """A report section: a heading and blocks, each a paragraph, a bullet list or a table."""

    heading: str
    blocks: list = field(default_factory=list)


def headline_table(table: pd.DataFrame, column: str) -> pd.DataFrame:
    """Per data variant and basis: the paper's alpha beside the measured one under every solver.

    Parameters
    ----------
    table : pandas.DataFrame
        An alpha table (``workbench.run_text.TABLE_COLUMNS``).
    column : str
        The measured alpha column.

    Returns
    -------
    pandas.DataFrame
        Columns ``data``, ``basis``, ``paper_alpha``, then one per solver (``<column> <solver>``).
    """
    solvers = [s for s in dict.fromkeys(table["solver"]) if s != "projection"]
    records = []
    for (data, basis), part in table.groupby(["data", "basis"], sort=False):
        by_solver = dict(zip(part["solver"], part[column]))
        record = {"data": data, "basis": basis, "paper_alpha": float(part["paper_alpha"].iloc[0])}
        for solver in solvers:
            record[f"{column} {solver}"] = float(by_solver.get(solver, by_solver.get("projection", math.nan)))
        records.append(record)
    return pd.DataFrame.from_records(records)


def choices_rows(config: Mapping) -> list[tuple[str, str]]:
    """The settings a run chose where the paper is silent, as (question, choice) pairs."""
    basis, dataset, metric = config["basis"], config["dataset"], config.get("metric", {})
    solvers = ", ".join(
        f"{name} ({spec['kind']}" + (f", bounds [{spec.get('lower')}, {spec.get('upper')}]"
                                     if spec["kind"] != "lstsq" else "") + ")"
        for name, spec in config["solver"].items())
    rule = (f"coverage {basis['coverage']}" if basis.get("n_components") is None
            else f"fixed m = {basis['n_components']}")
    return [
        ("projection of the hand shapes (eq. 3-4)", ", ".join(basis["projections"])
         + " (affine: through the capture mean, as written; linear: through the neutral face)"),
        ("mu", "mean displacement from neutral"),
        ("solver of eq. 5", solvers),
        ("alpha normalisation and aggregation in the headline",
         f"{metric.get('headline_normalisation', 'absolute')}, {metric.get('headline_aggregate', 'mean')} "
         "(every variant is in the full table)"),
        ("eigenfaces kept", rule),
        ("post-treatment", f"empty axis if sum_i |w_ij| < {basis['empty_axis_eps']} x {basis['empty_axis_scale']}; "
                           f"append empty axes: {basis['append_empty_axes']}"),
        ("frames trained on / evaluated", f"split {dataset.get('split', 'same')}"
         + (f", eval fraction {dataset.get('eval_fraction')}" if dataset.get("split") == "tail" else "")),
        ("data variants", str(dataset.get("train_on"))),
    ]


def licence_text(provenance: Mapping) -> str:
    """The licence of the data as the record states it (``licence`` or the ``credits`` of each source)."""
    for key in ("licence", "license"):
        if provenance.get(key):
            return str(provenance[key])
    if provenance.get("credits"):
        credits = provenance["credits"]
        return "; ".join(credits) if isinstance(credits, list) else str(credits)
    if provenance.get("kind") == "synthetic":
        return "not applicable: generated by the workbench from a seed (no third-party data)"
    return "not stated in the run record"


def provenance_value(value, limit: int = 200) -> str:
    """A provenance entry as one line of text: an absolute path by its last parts (the machine's folders say
    nothing to a reader), a long nested entry by its keys (the record holds it whole)."""
    if isinstance(value, str):
        return _display_path(value)
    text = json.dumps(_display_paths(value), separators=(", ", ": "))
    if len(text) <= limit:
        return text
    if isinstance(value, Mapping):
        keys = list(value)
        return (f"{len(keys)} entries: " + ", ".join(map(str, keys[:8])) + (", ..." if len(keys) > 8 else "")
                + " (in full in metrics.json)")
    return f"{len(value)} items (in full in metrics.json)"


def _display_paths(value):
    """A nested provenance entry with every absolute path in it shown by its last parts."""
    if isinstance(value, str):
        return _display_path(value)
    if isinstance(value, Mapping):
        return {key: _display_paths(item) for key, item in value.items()}
    if isinstance(value, (list, tuple)):
        return [_display_paths(item) for item in value]
    return value


def _display_path(text: str) -> str:
    """An absolute path as ``.../<parent>/<name>``; other text unchanged."""
    path = Path(text)
    if not path.is_absolute() or len(path.parts) < 3:
        return text
    return ".../" + "/".join(path.resolve().parts[-2:])


def report_versions() -> dict:
    from workbench.config import CHECKOUT
    from workbench.record import git_state, package_versions

    return {"packages": package_versions(REPORT_PACKAGES), "git": git_state(CHECKOUT)}


def provenance_section(metrics: Mapping, heading: str = "Dataset provenance and licence") -> Section:
    dataset = metrics["dataset"]
    # The record keeps the first data variant's train_on here; the variants are listed under the choices.
    provenance = {key: value for key, value in dataset.get("provenance", {}).items()
                  if key not in ("train_on", "data_root", "data_files")}
    files = dataset.get("provenance", {}).get("data_files") or {}
    return Section(heading, [
        f"**{dataset['name']}**; units {dataset['units']}; coordinate origin: {dataset['origin']}; "
        f"{float(dataset['frame_rate']):.4g} frames per second in the frames used"
        + (f" (the file's {float(provenance['frame_rate_in_file']):.4g} Hz, every {provenance['frame_step']} "
           "frame)" if provenance.get("frame_rate_in_file") and provenance.get("frame_step") else "") + ".",
        f"Licence: {licence_text(provenance)}.",
        pd.DataFrame({"key": list(provenance), "value": [provenance_value(v) for v in provenance.values()]}),
        *(["The data the run read, with their SHA-256 checksums when it read them (a folder: of its files' "
           "`<sha256>  <name>` lines sorted by name, as `LC_ALL=C sha256sum * | sha256sum` prints them there); "
           "the files stay in the data folder, never in the repository:",
           pd.DataFrame({"path": list(files),
                         "what": [f"folder of {item['files']} files" if "files" in item else "file"
                                  for item in files.values()],
                         "bytes": [item["bytes"] for item in files.values()],
                         "sha256": [item["sha256"] for item in files.values()]})] if files else []),
    ])


def _when(iso: str | None) -> str:
    """An ISO time as ``YYYY-MM-DD HH:MM UTC``, or ``unknown``."""
    from datetime import datetime, timezone

    if not iso:
        return "unknown (a record written before runs stated it)"
    return datetime.fromisoformat(iso).astimezone(timezone.utc).strftime("%Y-%m-%d %H:%M UTC")


def versions_section(metrics: Mapping, builder: Mapping) -> Section:
    from datetime import datetime, timezone

    git = metrics.get("git", {})
    record_versions = metrics.get("versions", {})
    return Section("Versions and commit", [
        f"Run made on {_when(metrics.get('started_at'))} at commit `{git.get('commit')}` (uncommitted changes: "
        f"{git.get('dirty')}), config hash `{metrics.get('config_hash')}`.",
        pd.DataFrame({"package": list(record_versions), "version": [str(v) for v in record_versions.values()]}),
        f"Report built on {_when(datetime.now(timezone.utc).isoformat())} at commit "
        f"`{builder['git'].get('commit')}` (uncommitted changes: {builder['git'].get('dirty')}) with "
        + ", ".join(f"{name} {version}" for name, version in builder["packages"].items()) + ".",
    ])


def run_facts(record: RunRecord) -> list:
    """The run's facts once: a table with a row per data variant, the notes all variants share, then each
    variant's own notes, and the paper's values."""
    from workbench.reporting.findings import facts_frame, shared_notes

    shared, own = shared_notes(record.metrics)
    lines = [*shared, *[f"{data} only: {note}" for data, notes in own.items() for note in notes]]
    paper = record.config.get("paper", {})
    if paper:
        lines.append(f"paper: m = {paper.get('m')} at coverage {paper.get('coverage')}; alpha "
                     + ", ".join(f"{k} {v}" for k, v in paper.get("alpha", {}).items())
                     + " (absolute, QP with unstated constraints)")
    return [facts_frame(record.metrics), lines]


@dataclass
class LeftRight:
    """Where the left/right pairs of hand shapes and their quasi-eigen faces act (:mod:`workbench.reporting.sides`):
    one finding per data variant and the table behind them."""

    findings: list = field(default_factory=list)
    table: pd.DataFrame | None = None


def left_right(record: RunRecord, cache: dict) -> LeftRight:
    """The left/right pairs of every data variant whose inputs the run saved."""
    from workbench.reporting.sides import pair_sides, shared_term, sides_finding, sides_frame

    found, frames = LeftRight(), []
    for data in record.data_variants:
        inputs = _inputs(record, data, cache)
        if inputs is None:
            continue
        names = [str(name) for name in inputs["hand_names"]]
        bases = figure_bases(record, data, inputs, cache, every=True)
        bases = {label: shapes[:len(names)] for label, shapes in bases.items()}  # appended eigenfaces are no pair
        support = inputs.get("point_support")
        pairs = pair_sides(inputs["neutral"], inputs["eval"], inputs["components"], names, bases, support)
        if not pairs:
            continue
        term = (shared_term(inputs["neutral"], inputs["components"], inputs["mean"], names, inputs["hand"], support)
                if "QE" in bases else None)
        found.findings.append(sides_finding(data, pairs, term, _qe_label(record)))
        frames.append(sides_frame(pairs).assign(data=data))
    if frames:
        table = pd.concat(frames, ignore_index=True)
        found.table = table[["data", *[column for column in table.columns if column != "data"]]]
    return found


def left_right_section(found: LeftRight) -> Section:
    return Section("Left and right", [
        "Each left/right pair of hand shapes: how together the capture moves the two sides of the face (correlation "
        "over the evaluated frames of the motion at the _L and _R hand shapes' peaks, along their directions), the "
        "share |P e| / |e| of each shape, of their sum L+R and of their difference L-R that the eigenfaces span, "
        "and, for each basis, the largest displacement of the _L and the _R face on its own side of the face and on "
        "the other (mm; `!`: the other side moves over 10 % more). The sides are told apart by the hand shapes' "
        "peaks.",
        found.table])


def run_sections(record: RunRecord, figures: list[FigureEntry], command: str, faces: "FacesBlock | None" = None,
                 sides: LeftRight | None = None) -> tuple[str, list[Section]]:
    from workbench.reporting.findings import run_findings

    column = headline_column(record.config)
    title = f"Study '{record.config['study']}' on the {dataset_label(record)}"
    intuitiveness = {data: values["intuitiveness"] for data, values in record.metrics["data"].items()}
    has_sides = sides is not None and sides.table is not None
    sections = [
        Section("Findings", [
            f"Generated from the run's numbers (`{column}`, %). "
            + ("The data are synthetic: generated by the workbench, not a real capture. "
               if record.metrics["dataset"].get("provenance", {}).get("kind") == "synthetic" else "")
            + ("In an ordering, '<' means that the paired per-frame difference of the two bases has a 95 % interval "
               "(block bootstrap over time) that excludes 0, '~' that it does not: they are not distinguishable on "
               "these frames; every interval is in the table 'Paired comparisons within the run'. "
               if any(values.get("comparisons") for values in record.metrics["data"].values()) else ""),
            run_findings(record.table, column, record.config.get("paper", {}), intuitiveness, record.metrics,
                         record.config),
            *([sides.findings] if has_sides else [])]),
        Section("Run facts", run_facts(record)),
        Section("Alpha beside the paper", [
            f"`{column}` (the run's headline alpha) under every solver, beside Kim & Ko's reported values. The "
            "absolute alpha depends on the coordinate origin; ratios between rows do not, but they move with the "
            "alpha variant on the same data (the findings give them under each), so no one ratio compares across "
            "datasets.",
            headline_table(record.table, column),
        ]),
        *protocol_sections(record, column),
        *([Section("Faces you can turn", [faces])] if faces is not None else []),
        Section("Figures", figures),
        *([left_right_section(sides)] if has_sides else []),
        Section("Full alpha table", [alpha_columns(record.table)]),
        *error_and_weight_sections(record),
        *comparison_sections(record),
        Section("Choices the run made", [pd.DataFrame(choices_rows(record.config), columns=["question", "choice"])]),
        provenance_section(record.metrics),
        versions_section(record.metrics, report_versions()),
        Section("About this report", [f"Rebuilt from the run record `{record.folder.name}` only, by `{command}`."]),
    ]
    return title, sections


def alpha_columns(table: pd.DataFrame) -> pd.DataFrame:
    """The alpha table's naming and alpha columns (the per-frame error and weight columns go in their section)."""
    from workbench.run_text import FRAME_COLUMNS

    return table[[column for column in table.columns if column not in FRAME_COLUMNS]]


def error_and_weight_sections(record: RunRecord) -> list[Section]:
    """The per-frame error in millimetres and the weights' statistics of every row, with what each column means
    and the face region of each data variant; nothing for records without them."""
    from workbench.run_text import FRAME_COLUMNS, ROW_NAME_COLUMNS

    columns = [column for column in FRAME_COLUMNS if column in record.table.columns]
    if not columns:
        return []
    regions = [f"{data}: {values['face_region']}" for data, values in record.metrics["data"].items()
               if values.get("face_region")]
    return [Section("Error in millimetres and the weights", [
        "`err_mm_*`: each evaluated frame's RMS 3-D point error over the face region, in mm; its median, 95th "
        "percentile and maximum over the frames. `w_max_abs`: the largest |w|; `w_outside_01`: the share of frames "
        "with a weight below 0 or above 1; `w_sparsity`: Hoyer's sparsity (sqrt(n) - |w|_1/|w|_2) / (sqrt(n) - 1), "
        "mean over frames (1: one shape per frame, 0: all equal); `w_roughness`: the mean squared second time "
        "derivative of the weights, 1/s^4, from second differences over the frames' times within each take. PCA's "
        "coefficients are no animator's weights (`-`). The face region of each data variant:",
        regions,
        record.table[[*ROW_NAME_COLUMNS, *columns]]])]


def comparison_frame(record: RunRecord) -> pd.DataFrame:
    """Every paired comparison the run made: per data variant, rows ``a`` and ``b``, the difference ``a - b`` of
    the headline alpha with its 95 % interval, the frames and block length it rests on, and the verdict."""
    from workbench.statistics import Interval

    records = []
    for data, values in record.metrics["data"].items():
        for entry in values.get("comparisons") or []:
            interval = Interval.from_dict(entry)
            verdict = {-1: "a < b", 1: "a > b", 0: "not distinguishable"}[interval.sign]
            records.append({"data": data, "a": " ".join(entry["a"]), "b": " ".join(entry["b"]),
                            "a - b": interval.estimate, "ci95_low": interval.low, "ci95_high": interval.high,
                            "frames": interval.n, "block (frames)": interval.block_frames,
                            "block (s)": interval.block_seconds, "verdict": verdict})
    return pd.DataFrame.from_records(records)


def comparison_sections(record: RunRecord) -> list[Section]:
    """The table every ``<`` of the findings comes from, with how its intervals were made."""
    from workbench.statistics import RESAMPLES, SEED, SIGNED, Interval, interval_text

    frame = comparison_frame(record)
    if frame.empty:
        return []
    entries = [entry for values in record.metrics["data"].values() for entry in values.get("comparisons") or []]
    example = next((entry for entry in entries if entry.get("block_frames")), entries[0])
    metric = record.config.get("metric") or {}
    interval = Interval.from_dict(example)
    return [Section("Paired comparisons within the run", [
        f"Every '<' of the findings and of the printed headline is a row here whose interval excludes 0. The "
        f"difference is that of `{example['column']}` between two rows of the alpha table on the same evaluated "
        "frames; its 95 % interval comes from a circular block bootstrap over time: blocks of consecutive frames "
        "that never cross from one take into another, their length chosen from the data (Politis & White 2004, "
        "with the correction of Patton, Politis & White 2009, on each difference's own autocorrelation), "
        f"{metric.get('bootstrap_resamples', RESAMPLES)} resamples drawn with seed "
        f"{metric.get('bootstrap_seed', SEED)}. For example, {' '.join(example['a'])} against "
        f"{' '.join(example['b'])}: {interval_text(interval, 'a - b', SIGNED)}.",
        frame])]


def protocol_sections(record: RunRecord, column: str) -> list[Section]:
    """Training frames (the paper's protocol) beside held-out frames (``dataset.held_out``): per data variant,
    basis and solver, the headline alpha and median error of each protocol; nothing without held-out frames."""
    protocols = {data: values.get("protocol", "training frames") for data, values in record.metrics["data"].items()}
    held = [data for data, protocol in protocols.items() if protocol != "training frames"]
    if not held:
        return []
    table = record.table
    rows = []
    for data in held:
        base = next(row["train_on"] for row in record.rows() if row["data"] == data)
        for (basis, solver), part in table[table["data"] == data].groupby(["basis", "solver"], sort=False):
            own = table[(table["data"] == base) & (table["basis"] == basis) & (table["solver"] == solver)]
            if own.empty:
                continue
            entry = {"data": base, "held out": protocols[data].removeprefix("held-out "), "basis": basis,
                     "solver": solver, f"{column} training": float(own[column].iloc[0]),
                     f"{column} held out": float(part[column].iloc[0])}
            entry["held out / training"] = entry[f"{column} held out"] / entry[f"{column} training"]
            if "err_mm_median" in table.columns:
                entry["err_mm_median training"] = float(own["err_mm_median"].iloc[0])
                entry["err_mm_median held out"] = float(part["err_mm_median"].iloc[0])
            rows.append(entry)
    notes = [f"{data}: {next(note for note in record.metrics['data'][data]['notes'] if note.startswith('held out'))}"
             for data in held if any(note.startswith("held out") for note in record.metrics["data"][data]["notes"])]
    return [Section("Training frames and held-out frames", [
        "The paper scores the frames its bases were fitted on (the training frames, split 'same'). Beside it, the "
        "same method with the bases fitted without some frames and scored on those (`dataset.held_out`); the "
        "held-out rows are data variants of their own in every table, with their own m and paired comparisons.",
        notes, pd.DataFrame.from_records(rows)])]


# ---------------------------------------------------------------------------------------------------------------
# Rendering documents
# ---------------------------------------------------------------------------------------------------------------


def render_markdown(title: str, sections: Sequence[Section]) -> str:
    """README.md of a report."""
    out = [f"# {title}", ""]
    for section in sections:
        out += [f"## {section.heading}", ""]
        for block in section.blocks:
            if isinstance(block, FigureEntry):
                out += _markdown_figure(block)
            elif isinstance(block, FacesBlock):
                out += _markdown_faces(block)
            elif isinstance(block, pd.DataFrame):
                out += [markdown_frame(block)]
            elif isinstance(block, list):
                out += [f"- {line}" for line in block] + [""]
            else:
                out += [block, ""]
    return "\n".join(out).rstrip() + "\n"


def _markdown_figure(entry: FigureEntry) -> list[str]:
    if entry.missing:
        return [f"**{entry.title}**: not drawn ({entry.missing}).", ""]
    shown, *copies = entry.files
    others = ", ".join(f"[{name.rsplit('.', 1)[1].upper()}]({name})" for name in copies)
    return [f"### {entry.title}", "", f"![{entry.title}]({shown})", "",
            entry.caption + (f" Also as {others}." if others else ""), ""]


def _markdown_faces(block: FacesBlock) -> list[str]:
    if block.missing:
        return [f"Not drawn ({block.missing}).", ""]
    return ["The interactive 3-D view (turn the captured and reconstructed faces, pick a frame and a basis) is in "
            "`index.html`; open it in a browser.", "",
            f"![captured, H and QE over the stretch of the take where the face moves most](figures/{block.animation})",
            "", block.caption, ""]


def _html_faces(block: FacesBlock) -> str:
    if block.missing:
        return f"<p class=\"missing\">Not drawn ({html.escape(block.missing)}).</p>"
    return (block.html + f"<figure><img src=\"figures/{block.animation}\" alt=\"captured, H and QE over the "
            f"stretch of the take where the face moves most\"><figcaption>{_inline_markdown(block.caption)}"
            "</figcaption></figure>")


def _inline_markdown(text: str) -> str:
    """Escape text for HTML and turn Markdown's `code` and **bold** into tags."""
    import re

    text = html.escape(text)
    text = re.sub(r"`([^`]+)`", r"<code>\1</code>", text)
    return re.sub(r"\*\*([^*]+)\*\*", r"<strong>\1</strong>", text)


def _html_figure(entry: FigureEntry) -> str:
    if entry.missing:
        return (f"<p class=\"missing\"><strong>{html.escape(entry.title)}</strong>: not drawn "
                f"({html.escape(entry.missing)}).</p>")
    links = " ".join(f"<a href=\"{name}\">{name.rsplit('.', 1)[1].upper()}</a>" for name in entry.files)
    return (f"<figure id=\"{entry.stem}\"><img src=\"{entry.files[0]}\" alt=\"{html.escape(entry.title)}\">"
            f"<figcaption><strong>{html.escape(entry.title)}.</strong> {_inline_markdown(entry.caption)} "
            f"<span class=\"links\">{links}</span></figcaption></figure>")


STYLE = """
body { font-family: system-ui, -apple-system, "Segoe UI", sans-serif; max-width: 1400px; margin: 2em auto;
       padding: 0 1.5em; color: #1d1d1f; line-height: 1.45; }
h1 { font-size: 1.6em; } h2 { border-bottom: 1px solid #ccc; padding-bottom: .2em; margin-top: 1.8em; }
table { border-collapse: collapse; margin: .8em 0; font-size: .88em; }
th, td { border: 1px solid #d0d0d0; padding: .25em .6em; } th { background: #f2f2f2; }
td { white-space: nowrap; } td.txt { white-space: normal; } .scroll { overflow-x: auto; }
td.num { text-align: right; font-variant-numeric: tabular-nums; }
tbody tr:nth-child(even) { background: #fafafa; }
figure { margin: 1.5em 0; } figure img { max-width: 100%; border: 1px solid #e3e3e3; }
figcaption { font-size: .9em; color: #333; max-width: 1100px; } .links a { margin-left: .4em; }
code { background: #f4f4f4; padding: 0 .25em; } .missing { color: #8a4b00; }
"""


# Marks every figure whether it loaded (``data-loaded``), and says so under one that did not: a report folder
# copied without its figures (or a reference report without ``../shared``) shows what is missing instead of a
# broken image; the browser test reads the marks.
FIGURE_CHECK = """
window.addEventListener("load", () => {
  for (const img of document.querySelectorAll("img")) {
    const loaded = img.complete && img.naturalWidth > 0;
    img.setAttribute("data-loaded", loaded ? "yes" : "no");
    if (!loaded) {
      const note = document.createElement("p");
      note.className = "missing";
      note.textContent = "Figure file not found beside this page: " + img.getAttribute("src");
      img.after(note);
    }
  }
});
"""


def render_html(title: str, sections: Sequence[Section]) -> str:
    """index.html of a report: one self-contained page, figures beside it in ``figures/``."""
    body = [f"<h1>{html.escape(title)}</h1>"]
    for section in sections:
        body.append(f"<h2>{html.escape(section.heading)}</h2>")
        for block in section.blocks:
            if isinstance(block, FigureEntry):
                body.append(_html_figure(block))
            elif isinstance(block, FacesBlock):
                body.append(_html_faces(block))
            elif isinstance(block, pd.DataFrame):
                body.append(html_frame(block))
            elif isinstance(block, list):
                body.append("<ul>" + "".join(f"<li>{_inline_markdown(line)}</li>" for line in block) + "</ul>")
            else:
                body.append(f"<p>{_inline_markdown(block)}</p>")
    return ("<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">"
            f"<title>{html.escape(title)}</title><style>{STYLE}</style></head>\n<body>\n"
            + "\n".join(body) + f"\n<script>{FIGURE_CHECK}</script>\n</body></html>\n")


# ---------------------------------------------------------------------------------------------------------------
# Sweeps
# ---------------------------------------------------------------------------------------------------------------


def by_m(per_run: pd.DataFrame, swept: Sequence[str], over: Sequence[str]) -> pd.DataFrame:
    """The wide summary with runs grouped by the m they kept instead of by the coverage that chose it: runs with
    different m are different bases and are never averaged. A seed's runs that kept the same m at several
    thresholds are the same run and count once.

    Parameters
    ----------
    per_run : pandas.DataFrame
        The runs table (its ``m`` column: eigenfaces of each run and data variant).
    swept : sequence of str
        The swept keys; ``basis.coverage`` is replaced by m, the others stay conditions.
    over : sequence of str
        The replicate columns.

    Returns
    -------
    pandas.DataFrame
        As :func:`workbench.reporting.runs.wide`, with the condition column ``m`` (an integer).
    """
    others = [key for key in swept if key != "basis.coverage"]
    rows = per_run.drop(columns=["basis.coverage"]).assign(**{"pca.m": per_run["m"].astype(int)})
    rows = rows.drop_duplicates([*others, *over, "pca.m", "data", "basis", "solver"])
    summary = wide(summarise(rows.drop(columns=[c for c in rows.columns if "." in c and c not in
                                               (*others, *over, "pca.m")]), over=list(over)))
    return summary.drop(columns=["m"]).rename(columns={"pca.m": "m"})


def sweep_figures(records: Sequence[RunRecord], summary: pd.DataFrame, swept: Sequence[str],
                  per_run: pd.DataFrame | None = None, over: Sequence[str] = ()) -> list:
    """Figure specs of a sweep report: the first run's coverage curve, alpha against each swept setting (and
    against m for a coverage sweep, runs grouped by m) with every run's own value as a point, alpha scored against
    the clean frames where the runs did, and marker versus mesh when the runs scored several data variants."""
    from workbench.reporting.figures.studies import axis_label, plot_alpha_against, plot_marker_vs_mesh

    first = records[0]
    column = headline_column(first.config)
    solver, _ = figure_solver(first.config)
    label = dataset_label(first)
    specs = [("coverage_curve", "Coverage curve (first run)",
              f"Cumulative explained variance against m for the run {first.folder.name}.",
              lambda _, options: draw_coverage_curve(first))]
    # (x, the swept setting it stands for): m stands for the coverage, the hand-basis size for the subset.
    targets = []
    for key in swept:
        targets.append((key, key))
        if key == "basis.coverage" and per_run is not None:
            targets.append(("m", key))
    if swept and summary["n_hand"].nunique() > 1:
        targets.append(("n_hand", "basis.hand_subset" if "basis.hand_subset" in swept else None))
    columns = [column] + ([f"clean_{column}"] if f"clean_{column}" in summary.columns else [])
    panels = ["data"] + [key for key in swept if key == "basis.coverage_on"]
    for y in columns:
        for x, setting in targets:
            others = [key for key in swept if key not in (x, setting, *panels)]
            table = by_m(per_run, swept, over) if x == "m" else summary
            stem = "alpha_vs_" + x.replace(".", "_") + ("_clean" if y != column else "")
            against = " scored on the clean frames," if y != column else ""
            grouped = "; runs grouped by the m they kept (never averaged over different m)" if x == "m" else ""
            specs.append((stem, f"Alpha{against} against {axis_label(x)}",
                          f"`{y}` (geometric mean over seeds) of each basis against {axis_label(x)}; "
                          f"{interval_label(table)}{grouped}"
                          + (f"; one line per value of {', '.join(others)}." if others else "."),
                          lambda _, options, x=x, y=y, others=others, table=table: plot_alpha_against(
                              table, x, y, solver=solver, by=others, panels=[p for p in panels if p != x],
                              points=per_run if per_run is not None and x in per_run.columns else None,
                              title=f"Alpha{' scored on the clean frames,' if y != column else ''} against "
                                    f"{axis_label(x)}\n{label}")))
    trained = summary[summary["data"].isin(training_variants(first))]  # held-out frames are no data variant
    if "eval_on" in trained.columns and trained["train_on"].nunique() > 1:
        fixed = [key for key in swept if key != "dataset.train_on"]
        for values, part in (trained.groupby(fixed, sort=False) if fixed else [((), trained)]):
            values = values if isinstance(values, tuple) else (values,)
            setting = ", ".join(f"{key} = {value}" for key, value in zip(fixed, values))
            stem = "marker_vs_mesh" + "".join(f"_{value}" for value in values).replace(".", "_")
            specs.append((stem, f"Marker versus mesh{': ' + setting if setting else ''}",
                          "Each basis fitted on each data variant and scored on the common evaluation sets, in "
                          f"millimetres and `alpha_disp_pooled`; error bars: {interval_label(part)}.",
                          lambda _, options, part=part, setting=setting: plot_marker_vs_mesh(
                              part, ("rms_mm", "alpha_disp_pooled"), solver=solver,
                              title=f"Marker versus mesh{': ' + setting if setting else ''}\n{label}")))
    return specs


def _natural(text: str):
    return (0, float(text)) if text.replace(".", "", 1).lstrip("-").isdigit() else (1, text)


def range_column(table: pd.DataFrame, column: str) -> pd.Series:
    """``8-12`` (or ``10``) per row: a column's range over the runs behind each row of a wide summary."""
    def text(low, high):
        if pd.isna(low):
            return "-"
        return f"{low:g}" if low == high else f"{low:g}-{high:g}"
    return pd.Series([text(low, high) for low, high in zip(table[f"{column}_min"], table[f"{column}_max"])],
                     index=table.index, name=column)


def sweep_sections(root: Path, records: Sequence[RunRecord], per_run: pd.DataFrame, summary: pd.DataFrame,
                   comparisons: pd.DataFrame, swept: Sequence[str], figures: list[FigureEntry],
                   command: str) -> tuple[str, list[Section]]:
    from workbench.reporting.findings import replicate_caveat, sweep_statements

    first = records[0]
    column = headline_column(first.config)
    solver = figure_solver(first.config)[0]
    title = f"Study '{first.config['study']}': sweep over {', '.join(swept) or 'seeds'} on the {dataset_label(first)}"
    replicates = "; ".join(
        f"{key} " + ", ".join(sorted({str(value) for value in per_run[key].dropna()}, key=_natural))
        for key in per_run.columns if is_replicate_key(key))
    columns = [column] + ([f"clean_{column}"] if f"clean_{column}" in summary.columns else [])
    shown = summary[[*swept, "data", "basis", "solver", "n_seeds"]].assign(
        m=range_column(summary, "m"), n=range_column(summary, "n"))
    for name in columns:
        shown = shown.assign(**{name: summary[name], f"{name}_ci_low": summary[f"{name}_ci_low"],
                                f"{name}_ci_high": summary[f"{name}_ci_high"]})
    shown = shown.assign(paper_alpha=summary["paper_alpha"])
    solvers = [name for name in dict.fromkeys(per_run["solver"]) if name != "projection"]
    hidden = ("study", "method", "train_on", "dataset.train_on", *(("solver",) if len(solvers) < 2 else ()))
    compared = comparisons.drop(columns=[key for key in hidden if key in comparisons.columns])
    runs = per_run.drop_duplicates("run")[["run", *[k for k in per_run.columns if "." in k]]]
    findings = replicate_caveat([key for key in per_run.columns if is_replicate_key(key)]) + [
        line for name in [solver, *(other for other in solvers if other != solver)]
        for line in sweep_statements(summary, comparisons, swept, columns, name)]
    method = comparisons["method"].iloc[0] if len(comparisons) else "-"
    sections = [
        Section("Findings", [f"Generated from the tables below (each solver; PCA by projection): levels are "
                             "geometric means over the seeds; \"A < B\" only where the 95 % interval of the "
                             f"per-seed ratio A/B ({method}) excludes 1.", findings]),
        Section("About this report", [
            f"Rebuilt from {len(records)} complete run records under `{root.name}` only, by `{command}`. "
            f"Swept: {', '.join(swept) or 'nothing but the seed'}; replicates over "
            f"{replicates or 'nothing (one run each)'}. Levels: geometric means; {interval_label(summary)} (it stays "
            "positive, as alpha does); m and n are ranges over the runs, never averaged.",
        ]),
        Section(f"{column} over seeds", [f"Geometric means; {interval_label(summary)}.", shown]),
        Section("Paired comparisons", [
            f"Per condition, solver and pair of bases (PCA by projection): the geometric mean of the "
            f"per-seed ratio first / second of `{', '.join(columns)}` and its 95 % interval ({method}); "
            "the smaller first; '<' only where the interval excludes 1.", compared]),
        Section("Figures", figures),
        Section("Runs", [runs.astype(str)]),
        Section("Choices the runs made (first run)",
                [pd.DataFrame(choices_rows(first.config), columns=["question", "choice"])]),
        provenance_section(first.metrics, "Dataset provenance and licence (first run)"),
        versions_section(first.metrics, report_versions()),
    ]
    return title, sections


# ---------------------------------------------------------------------------------------------------------------
# Other bases (basis.alternatives): alpha against intuitiveness
# ---------------------------------------------------------------------------------------------------------------

INTUITIVENESS_COLUMNS = ("matched_abs_cosine", "locality", "usage")


def basis_intuitiveness_rows(record: RunRecord) -> pd.DataFrame:
    """Per data variant and basis of a run that scored other bases: its headline alpha with the figures' solver
    (PCA: its projection) beside the basis's closeness, locality and usage (usage with that solver's weights).

    Returns
    -------
    pandas.DataFrame
        Columns ``data``, ``basis``, ``n``, the headline alpha column and :data:`INTUITIVENESS_COLUMNS`; empty
        when the run scored no other bases.
    """
    column = headline_column(record.config)
    solver, _ = figure_solver(record.config)
    rows = []
    for data, values in record.metrics["data"].items():
        table = record.table[record.table["data"] == data]
        for entry in (values.get("basis_intuitiveness") or {}).get("bases", []):
            alpha = table.loc[(table["basis"] == entry["basis"]) & table["solver"].isin([solver, "projection"]),
                              column]
            rows.append({"data": data, "basis": entry["basis"], "n": entry["n"],
                         column: float(alpha.iloc[0]) if len(alpha) else math.nan,
                         "matched_abs_cosine": entry["matched_abs_cosine"], "locality": entry["locality"],
                         "usage": entry["usage"].get(solver, entry["usage"].get("projection", math.nan))})
    return pd.DataFrame.from_records(rows)


def summarise_intuitiveness(per_run: pd.DataFrame, columns: Sequence[str]) -> pd.DataFrame:
    """Geometric mean and its 95 % interval over runs (seeds) per data variant and basis
    (:func:`workbench.reporting.runs.level_statistics`).

    Returns
    -------
    pandas.DataFrame
        ``data``, ``basis``, ``n_min``, ``n_max`` (PCA's m can differ between takes), ``n_seeds``, ``ci_method``,
        then per column its geometric mean, ``<column>_ci_low`` and ``<column>_ci_high`` (NaN with a single run).
    """
    records = []
    for (data, basis), group in per_run.groupby(["data", "basis"], sort=False):
        row = {"data": data, "basis": basis, "n_min": int(group["n"].min()), "n_max": int(group["n"].max()),
               "n_seeds": len(group), "ci_method": GEOMETRIC}
        for column in columns:
            statistics = level_statistics(group[column].to_numpy(float))
            row.update({column: statistics["geomean"], f"{column}_ci_low": statistics["ci95_low"],
                        f"{column}_ci_high": statistics["ci95_high"]})
        records.append(row)
    return pd.DataFrame.from_records(records)


def with_bases_section(sections: list, records: Sequence[RunRecord], figures_dir: Path,
                       formats: Sequence[str], ordering: bool = True) -> list:
    """The report's sections with one on the other bases inserted before its figures: the table of alpha,
    closeness, locality and usage of every basis (geometric means over the runs), their paired comparisons and the
    figure of alpha against each; the findings gain the sizes, closeness and locality (and, with ``ordering``,
    the bases' ordering by alpha, which a sweep's own findings state already). Unchanged when no run scored other
    bases."""
    from workbench.reporting.figures.studies import plot_alpha_against_intuitiveness

    found = [(record, basis_intuitiveness_rows(record)) for record in records]
    found = [(record, frame) for record, frame in found if not frame.empty]
    if not found:
        return sections
    first = found[0][0]
    column = headline_column(first.config)
    solver, _ = figure_solver(first.config)
    settings = next(values["basis_intuitiveness"] for values in first.metrics["data"].values()
                    if values.get("basis_intuitiveness"))
    energy, threshold = settings["locality_energy"], settings["usage_threshold"]
    per_run = pd.concat([frame.assign(study=record.study, run=str(record.folder)) for record, frame in found],
                        ignore_index=True)
    summary = summarise_intuitiveness(per_run, [column, *INTUITIVENESS_COLUMNS])
    comparisons = pd.concat([paired_comparisons(per_run, name, over=["run"], row_keys=("data", "basis"))
                             for name in (column, "matched_abs_cosine", "locality")], ignore_index=True)
    several = int(summary["n_seeds"].max()) > 1
    note = interval_label(summary, "runs")
    caption = (f"`{column}` (solver {solver}; PCA by projection) of every basis against its closeness to the hand "
               f"shapes, its locality and its usage" + (f", geometric means over runs; error bars: {note}."
                                                         if several else "."))
    title = f"Alpha against intuitiveness, every basis at its size n\n{dataset_label(first)}"
    entry = make_figures([("alpha_vs_intuitiveness", "Alpha against intuitiveness", caption,
                           lambda _, options: plot_alpha_against_intuitiveness(
                               summary, column, energy=energy, threshold=threshold, title=title))],
                         None, figures_dir, formats, {})[0]
    shown = summary[["data", "basis", "n_seeds", column, *([f"{column}_ci_low", f"{column}_ci_high"]
                                                           if several else []), *INTUITIVENESS_COLUMNS]]
    shown.insert(2, "n", range_column(summary, "n"))
    from workbench.reporting.findings import bases_findings

    findings = next((item for item in sections if item.heading == "Findings"), None)
    if findings is not None:  # one run: its ordering from its paired per-frame comparisons
        run_comparisons = ({data: values.get("comparisons") or [] for data, values in first.metrics["data"].items()}
                           if len(found) == 1 else None)
        findings.blocks.append(bases_findings(summary, comparisons, column, ordering, run_comparisons, solver))
    section = Section("Other bases: alpha against intuitiveness", [
        f"Every basis of the table at its size n (a range where it differs between runs: PCA keeps the m of each "
        f"take), fitted on the training frames and scored alike; `{column}` with solver {solver} (PCA: "
        "projection), " + (f"geometric means over {int(summary['n_seeds'].max())} runs; {note}." if several
                           else "one run."),
        ["`matched_abs_cosine`: the elements matched one-to-one to the hand shapes by the Hungarian method on "
         "|cosine|, the mean |cosine| of the matched pairs (1: each element is a hand shape up to scale).",
         f"`locality`: the fraction of the face's area ({settings['point_weights']}) holding {energy * 100:g} % of an "
         "element's squared displacement, mean over elements (small: local).",
         f"`usage`: elements whose contribution |w_i| |e_i| to a frame exceeds {threshold:g} of the frame's "
         f"largest, mean over the evaluated frames (weights of solver {solver})."],
        shown,
        f"Paired comparisons over the runs: the geometric mean of the per-run ratio first / second and its 95 % "
        f"interval ({comparisons['method'].iloc[0] if len(comparisons) else '-'}); the smaller first; '<' only where "
        "it excludes 1.",
        comparisons.drop(columns=["study", "method"]), entry])
    headings = [item.heading for item in sections]
    at = headings.index("Figures") if "Figures" in headings else len(sections)
    return [*sections[:at], section, *sections[at:]]


# ---------------------------------------------------------------------------------------------------------------
# The command
# ---------------------------------------------------------------------------------------------------------------


def default_report_name(config: Mapping) -> str:
    """``<study>`` for the synthetic actor, ``<study>-<dataset kind>`` for other data."""
    kind = config.get("dataset", {}).get("kind", "synthetic")
    return config["study"] if kind == "synthetic" else f"{config['study']}-{kind}"


def _clear_figures(folder: Path) -> None:
    if folder.is_dir():
        for path in folder.iterdir():
            if path.suffix in (".png", ".svg", ".pdf", ".gif", ".webp", ".js"):
                path.unlink()


def build_run_report(record: RunRecord, out: Path, *, formats: Sequence[str] = FIGURE_FORMATS,
                     options: Mapping | None = None, command: str = "workbench report") -> Path:
    """Write the report of one run into ``out``: index.html, README.md, figures/, alpha_table.csv and the
    run's config as run_config.yaml.

    Parameters
    ----------
    record : RunRecord
    out : pathlib.Path
        The report folder (created; figures it holds are replaced).
    formats : sequence of str
        Copies of each figure besides the one the report shows: ``png``, ``svg``, ``pdf``.
    options : mapping
        ``shapes``: names of the four hand shapes of figure 2; ``shared``: the folder of the figures reference
        reports share (:data:`SHARED_FIGURES`).
    command : str
        The command shown as having built the report.

    Returns
    -------
    pathlib.Path
        ``out / "index.html"``.
    """
    out = Path(out)
    figures_dir = inside(out, "figures")
    _clear_figures(figures_dir)
    cache: dict = {}
    entries = make_figures(RUN_FIGURES, record, figures_dir, formats, {**(options or {}), "cache": cache})
    faces = build_faces(record, out, cache)
    title, sections = run_sections(record, entries, command, faces, left_right(record, cache))
    sections = with_bases_section(sections, [record], figures_dir, formats)
    _write_documents(out, title, sections)
    write_atomic(inside(out, "alpha_table.csv"), (record.folder / "alpha_table.csv").read_bytes())
    write_atomic(inside(out, "run_config.yaml"), (record.folder / "config.yaml").read_bytes())
    return out / "index.html"


def build_sweep_report(root: Path, out: Path, *, formats: Sequence[str] = FIGURE_FORMATS,
                       command: str = "workbench report") -> Path:
    """Write the report of every complete run under ``root`` into ``out``: index.html, README.md, figures/,
    summary.csv (the tidy table), comparisons.csv (the paired comparisons) and runs.csv (every row of every run).

    Returns
    -------
    pathlib.Path
        ``out / "index.html"``.
    """
    root, out = Path(root), Path(out)
    records = sweep_records(root)
    per_run = runs_table(records, root)
    keys = varying_keys([record.config for record in records])
    swept = [key for key in keys if not is_replicate_key(key) and key != "dataset.train_on"]
    over = [key for key in keys if is_replicate_key(key)]
    summary = wide(summarise(per_run, over=over))
    paper = per_run.groupby("basis", sort=False)["paper_alpha"].first()
    summary["paper_alpha"] = summary["basis"].map(paper)
    summary["n_hand"] = hand_basis_size(summary, swept)
    column = headline_column(records[0].config)
    comparisons = sweep_comparisons(per_run, [column, f"clean_{column}"], over)
    figures_dir = inside(out, "figures")
    _clear_figures(figures_dir)
    entries = make_figures(sweep_figures(records, summary, swept, per_run, over), None, figures_dir,
                           formats, {})
    title, sections = sweep_sections(root, records, per_run, summary, comparisons, swept, entries, command)
    sections = with_bases_section(sections, records, figures_dir, formats, ordering=False)
    _write_documents(out, title, sections)
    write_atomic(inside(out, "summary.csv"), summary.to_csv(index=False))
    write_atomic(inside(out, "comparisons.csv"), comparisons.to_csv(index=False))
    write_atomic(inside(out, "runs.csv"), per_run.to_csv(index=False))
    return out / "index.html"


def _write_documents(out: Path, title: str, sections: Sequence[Section]) -> None:
    write_atomic(inside(out, "index.html"), render_html(title, sections))
    write_atomic(inside(out, "README.md"), render_markdown(title, sections))


def sweep_records(root: Path) -> list[RunRecord]:
    """The complete run records under a sweep folder (the folder itself excluded), in natural order."""
    folders = [folder for folder in find_records([root])[0] if folder != Path(root)]
    if not folders:
        raise WorkbenchError(f"{root} holds no complete run record (folders with a '{DONE}' file)")
    return [load_record(folder, check_archives=True) for folder in folders]


REPORT_FOLDER = "report"
"""Default report folder, inside the run or sweep folder it reports on."""
SHARED_FOLDER = "shared"
"""Folder of the figures the reference reports share, beside them (``reports/shared``)."""


def report_folder(folder: Path, config: Mapping, *, out: Path | None, reference: bool, name: str | None) -> Path:
    """Where a report goes: ``--out`` as given, the checkout's ``reports/<name>`` with ``--reference``, else
    ``<folder>/report`` beside the runs."""
    from workbench.config import CHECKOUT

    if out is not None and reference:
        raise WorkbenchError("give either --out or --reference, not both")
    if name is not None and not reference:
        raise WorkbenchError("--name names a reference report; it goes with --reference")
    if reference:
        name = name or default_report_name(config)
        if not plain_name(name):
            raise WorkbenchError(f"--name must be a plain folder name (no path), got {name!r}")
        if CHECKOUT is None:
            raise WorkbenchError("--reference rewrites the committed reports of the workbench's checkout, and this "
                                 "workbench is an installed package: use --out DIR, or run from a checkout")
        return inside(CHECKOUT / "reports", name)
    return Path(out) if out is not None else inside(folder, REPORT_FOLDER)


def parse_args(argv: Sequence[str]) -> argparse.Namespace:
    parser = argparse.ArgumentParser(
        prog="workbench report", description="Build the report of a run record or of a sweep folder, from its "
        "records only. It goes into <folder>/report unless --out or --reference says otherwise.")
    parser.add_argument("folder", type=Path, help=f"a run record (holds '{DONE}') or a folder of run records")
    parser.add_argument("--out", type=Path, help="the report folder (default: <folder>/report)")
    parser.add_argument("--reference", action="store_true",
                        help="(re)write the workbench's committed reference report reports/<name> of the checkout")
    parser.add_argument("--name", help="with --reference: the report's folder name (default: the study, plus the "
                                       "dataset unless synthetic)")
    parser.add_argument("--formats", default=",".join(FIGURE_FORMATS),
                        help="copies of each figure besides the one the report shows (faces as WebP, line plots as "
                             "SVG), comma-separated: png, svg, pdf (default: none)")
    parser.add_argument("--shapes", help="figure 2: four hand-shape names, comma-separated")
    return parser.parse_args(list(argv))


FIGURE_2_SHAPES = 4
"""Hand shapes figure 2 shows (the paper's figure 2)."""


def figure_2_shapes(text: str, record: RunRecord) -> list[str]:
    """``--shapes``: four distinct hand shapes of the run, checked before the report is written."""
    names = [name.strip() for name in text.split(",") if name.strip()]
    if len(names) != FIGURE_2_SHAPES or len(set(names)) != len(names):
        raise WorkbenchError(f"--shapes takes {FIGURE_2_SHAPES} distinct hand-shape names (figure 2 shows "
                             f"{FIGURE_2_SHAPES}), got {names}")
    known = list(record.metrics["dataset"].get("hand_names") or [])
    unknown = [name for name in names if known and name not in known]
    if unknown:
        raise WorkbenchError(f"--shapes names unknown hand shapes {unknown}; the run has {known}")
    return names


def main(argv: Sequence[str]) -> int:
    """``workbench report <folder> [--out DIR | --reference [--name NAME]] [--formats png,pdf] [--shapes a,b,c,d]``."""
    args = parse_args(argv)
    formats = [fmt.strip() for fmt in args.formats.split(",") if fmt.strip()]
    unknown = sorted(set(formats) - {"png", "svg", "pdf"})
    if unknown:
        raise WorkbenchError(f"--formats takes png, svg, pdf; got {unknown}")
    folder = args.folder
    if not folder.is_dir():
        raise WorkbenchError(f"{folder} is not a folder")
    command = "workbench report " + " ".join(argv)
    if is_complete(folder):
        record = load_record(folder, check_archives=True)
        out = report_folder(folder, record.config, out=args.out, reference=args.reference, name=args.name)
        options = {"shapes": figure_2_shapes(args.shapes, record) if args.shapes is not None else None,
                   "shared": out.parent / SHARED_FOLDER if args.reference else None}
        index = build_run_report(record, out, formats=formats, options=options, command=command)
    else:
        first = sweep_records(folder)[0]
        out = report_folder(folder, first.config, out=args.out, reference=args.reference, name=args.name)
        index = build_sweep_report(folder, out, formats=formats, command=command)
    print(f"report: {index}")
    return 0
