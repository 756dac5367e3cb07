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
from importlib import metadata
from pathlib import Path
from typing import Callable, Mapping, Sequence

import numpy as np
import pandas as pd

from workbench.errors import WorkbenchError
from workbench.record import (DONE, RunRecord, find_records, inside, is_complete, load_record, plain_name,
                              write_atomic)
from workbench.reporting.runs import is_replicate_key, runs_table, summarise, t_interval, varying_keys, wide
from workbench.tables import html_frame, markdown_frame

ANALOGY_SEED = 1
FIGURE_FORMATS = ("png", "svg")
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
    from workbench.pipeline import check_solver_config

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


def headline_column(config: Mapping) -> str:
    metric = config.get("metric", {})
    short = {"absolute": "abs", "displacement": "disp"}[metric.get("headline_normalisation", "absolute")]
    return f"alpha_{short}_{metric.get('headline_aggregate', 'mean')}"


def _mesh_variant(record: RunRecord) -> tuple[str, dict] | None:
    """The data variant whose points are mesh vertices (saved with triangles), preferring ``mesh``."""
    for data in sorted(record.data_variants, key=lambda d: d != "mesh"):
        inputs = record.load_inputs(data)
        if inputs is not None and "faces" in inputs:
            return data, inputs
    return None


def _marker_variant(record: RunRecord) -> tuple[str, dict] | None:
    """The data variant of markers (no triangles), preferring ``markers``."""
    for data in sorted(record.data_variants, key=lambda d: d != "markers"):
        inputs = record.load_inputs(data)
        if inputs is not None and "faces" not in inputs:
            return data, inputs
    return None


def _qe_label(record: RunRecord) -> str:
    projections = record.config["basis"]["projections"]
    return "QE" if "affine" in projections else "QE-linear"


def _appended_axes(record: RunRecord, data: str, label: str) -> list[int]:
    return record.metrics["data"][data]["quasi_eigen"][QE_PROJECTIONS[label]]["appended_axes"]


def draw_analogy():
    from workbench.reporting.figures.analogy import figure_analogy, make_analogy_example

    return figure_analogy(make_analogy_example(np.random.default_rng(ANALOGY_SEED)))


def draw_hand_vs_quasi_eigen(record: RunRecord, shapes: Sequence[str] | None = None):
    """Figure 2 from a record, or the reason it cannot be drawn."""
    from workbench.reporting.figures.faces import figure_hand_vs_quasi_eigen, spread_by_rank

    found = _mesh_variant(record)
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
        title=(f"Figure 2 (reproduced): hand shapes above their quasi-eigen faces\n{dataset_label(record)}, "
               f"data: {data}, m = {m}, {projection} projection"),
        qe_label=f"quasi-eigen $e_i^{{QE}}$ ({projection})")


def draw_reconstructions(record: RunRecord, n_frames: int = 3):
    """Figure 3 from a record, or the reason it cannot be drawn."""
    from workbench.reporting.figures.faces import expressive_frames, figure_reconstructions

    found = _mesh_variant(record)
    if found is None:
        return "needs a mesh data variant saved with save_inputs=true (e.g. dataset.train_on=[markers,mesh])"
    data, inputs = found
    solver_name, solver = figure_solver(record.config)
    label = _qe_label(record)
    frames = expressive_frames(inputs["eval"], n_frames)
    captured = inputs["eval"][frames]
    bases = {"H": inputs["hand"],
             label: quasi_eigen_shapes(inputs, QE_PROJECTIONS[label], _appended_axes(record, data, label))}
    reconstructed = {name: reconstruct_frames(shapes, captured, solver) for name, shapes in bases.items()}
    notes = {}
    for name, frames_out in reconstructed.items():
        alpha = frame_alpha(inputs["neutral"], captured, frames_out)
        notes[name] = [f"alpha abs {a:.3f} %, disp {d:.1f} %" for a, d in zip(alpha["absolute"],
                                                                            alpha["displacement"])]
    rate = record.metrics["dataset"]["frame_rate"]
    return figure_reconstructions(
        inputs["neutral"], inputs["faces"], captured, reconstructed,
        [f"frame {f} (t = {f / rate:.2f} s)" for f in frames], notes,
        title=(f"Figure 3 (reproduced): captured frames and their reconstructions\n{dataset_label(record)}, "
               f"data: {data}, solver {solver_name}; the most displaced frame of each third of the take"))


def draw_marker_errors(record: RunRecord):
    """Figure 4 from a record, or the reason it cannot be drawn."""
    from workbench.reporting.figures import basis_label
    from workbench.reporting.figures.faces import expressive_frames, figure_marker_errors

    found = _marker_variant(record)
    if found is None:
        return "needs a marker data variant saved with save_inputs=true"
    data, inputs = found
    solver_name, solver = figure_solver(record.config)
    label = _qe_label(record)
    # with capture gaps (gap_policy masked) the figure shows a frame that saw every marker
    seen_all = (np.flatnonzero(inputs["eval_visible"].all(axis=1)) if "eval_visible" in inputs
                else np.arange(len(inputs["eval"])))
    if seen_all.size == 0:
        return "needs an evaluated frame that saw every marker (every frame has a gap)"
    frame = int(seen_all[expressive_frames(inputs["eval"][seen_all], 1)[0]])
    captured = inputs["eval"][[frame]]
    bases = {"H": inputs["hand"],
             label: quasi_eigen_shapes(inputs, QE_PROJECTIONS[label], _appended_axes(record, data, label))}
    reconstructed, titles = {}, {}
    for name, shapes in bases.items():
        reconstructed[name] = reconstruct_frames(shapes, captured, solver)[0]
        alpha = frame_alpha(inputs["neutral"], captured, reconstructed[name][None])
        titles[name] = (f"{basis_label(name)}\nalpha abs {alpha['absolute'][0]:.3f} %, disp "
                        f"{alpha['displacement'][0]:.1f} %, RMS {alpha['rms'][0]:.3f} mm")
    rate = record.metrics["dataset"]["frame_rate"]
    n_markers = inputs["neutral"].size // 3
    return figure_marker_errors(
        inputs["neutral"], captured[0], reconstructed, titles, units=record.metrics["dataset"]["units"],
        title=(f"Figure 4 (reproduced): reconstruction error at the {n_markers} markers, frame {frame} "
               f"(t = {frame / rate:.2f} s, the most displaced)\n{dataset_label(record)}, data: {data}, "
               f"solver {solver_name}; captured red, reconstructed blue"))


def draw_coverage_curve(record: RunRecord):
    from workbench.reporting.figures.studies import plot_coverage_curve

    pca = {data: values["pca"] for data, values in record.metrics["data"].items()}
    basis = record.config["basis"]
    threshold = basis["coverage"] if basis.get("n_components") is None else None
    return plot_coverage_curve(
        {data: np.asarray(p["explained_variance_ratio"]) for data, p in pca.items()},
        {data: p["m"] for data, p in pca.items()}, threshold=threshold,
        title=f"Coverage: cumulative explained variance of the leading eigenvalues\n{dataset_label(record)}")


def draw_alpha_over_time(record: RunRecord):
    from workbench.reporting.figures.studies import plot_alpha_over_time

    arrays = record.load_alpha_per_frame()
    if arrays is None:
        return "needs alpha_per_frame.npz, written by runs with save_inputs=true"
    solver_name, _ = figure_solver(record.config)
    normalisation = record.config.get("metric", {}).get("headline_normalisation", "absolute")
    series = {}
    for data in record.data_variants:
        bases, solvers = arrays[f"{data}.basis"], arrays[f"{data}.solver"]
        values = arrays[f"{data}.{normalisation}"]
        series[data] = {str(b): values[i] for i, (b, s) in enumerate(zip(bases, solvers))
                        if s == solver_name or b == "PCA"}
    return plot_alpha_over_time(series, record.metrics["dataset"]["frame_rate"],
                                ylabel=f"alpha, {normalisation} (%)",
                                title=f"Alpha of every frame over the take, solver {solver_name}\n"
                                      f"{dataset_label(record)}")


def draw_marker_vs_mesh(record: RunRecord):
    from workbench.reporting.figures.studies import plot_marker_vs_mesh

    if record.table["data"].nunique() < 2:
        return "needs a run on two data variants (dataset.train_on=[markers,mesh])"
    solver_name, _ = figure_solver(record.config)
    return plot_marker_vs_mesh(record.table, headline_column(record.config), solver=solver_name,
                               title=f"Marker versus mesh data: the method on each\n{dataset_label(record)}")


RUN_FIGURES: tuple[tuple[str, str, str, Callable], ...] = (
    ("fig1_analogy", "Figure 1: the analogical drawing",
     "A seeded cloud of 300 points near a plane; PCA axes (red) from Eigenfaces, hand vectors (blue) off the "
     "plane and their affine quasi-eigen projections (purple, eq. 3-4), all computed by the workbench core.",
     lambda record, options: draw_analogy()),
    ("fig2_hand_vs_quasi_eigen", "Figure 2: hand shapes beside their quasi-eigen faces",
     "Four hand shapes (top) and their quasi-eigen faces (bottom) on the mesh, coloured by displacement length; "
     "under each pair its relative distance |e^QE - e^H| / |e^H| and cosine. The four are spread over the "
     "ranks of the relative distance (least to most changed) unless --shapes names them.",
     lambda record, options: draw_hand_vs_quasi_eigen(record, options.get("shapes"))),
    ("fig3_reconstructions", "Figure 3: captured frames and their reconstructions",
     "Left: captured frames, coloured by displacement length. Right: their reconstructions with the hand basis "
     "and the quasi-eigen basis (the run's solver), coloured by per-vertex error against the captured frame.",
     lambda record, options: draw_reconstructions(record)),
    ("fig4_marker_errors", "Figure 4: one frame's reconstruction error at the markers",
     "Captured markers (red) and reconstructed markers (blue) of the most displaced frame, front and side "
     "views; the offsets are magnified by the stated factor so that sub-millimetre errors show.",
     lambda record, options: draw_marker_errors(record)),
    ("coverage_curve", "Coverage curve",
     "Cumulative explained variance against the number of eigenfaces m (the first 60 eigenvalues kept in the "
     "record), with the coverage threshold and the chosen m of each data variant.",
     lambda record, options: draw_coverage_curve(record)),
    ("alpha_over_time", "Alpha per frame over time",
     "Per-frame alpha (the headline normalisation) of each basis over the take.",
     lambda record, options: draw_alpha_over_time(record)),
    ("marker_vs_mesh", "Marker versus mesh",
     "The headline alpha of each basis when the method runs on the markers and on the dense mesh.",
     lambda record, options: draw_marker_vs_mesh(record)),
)


def make_figures(specs, argument, folder: Path, formats: Sequence[str], options: Mapping) -> list[FigureEntry]:
    """Draw and save each figure of ``specs``; a figure that cannot be drawn is listed with the reason."""
    from workbench.reporting.figures import save_figure

    entries = []
    for stem, title, caption, draw in specs:
        entry = FigureEntry(stem=stem, title=title, caption=caption)
        result = draw(argument, options)
        if isinstance(result, str):
            entry.missing = result
        else:
            entry.files = [path.name for path in save_figure(result, folder, stem, formats)]
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


def provenance_value(value, limit: int = 240) -> str:
    """A provenance entry as one line of text; long nested entries are cut (the record holds them whole)."""
    text = value if isinstance(value, str) else json.dumps(value, separators=(", ", ": "))
    return text if len(text) <= limit else text[:limit] + " ... (in metrics.json)"


def report_versions() -> dict:
    from workbench.config import REPO_ROOT
    from workbench.record import git_state

    found = {}
    for package in REPORT_PACKAGES:
        try:
            found[package] = metadata.version(package)
        except metadata.PackageNotFoundError:
            found[package] = None
    return {"packages": found, "git": git_state(REPO_ROOT)}


def provenance_section(metrics: Mapping, heading: str = "Dataset provenance and licence") -> Section:
    dataset = metrics["dataset"]
    # The record keeps the first data variant's train_on here; the variants are listed under the choices.
    provenance = {key: value for key, value in dataset.get("provenance", {}).items() if key != "train_on"}
    return Section(heading, [
        f"**{dataset['name']}**; units {dataset['units']}; coordinate origin: {dataset['origin']}; "
        f"{dataset['frame_rate']} frames per second.",
        f"Licence: {licence_text(provenance)}.",
        pd.DataFrame({"key": list(provenance), "value": [provenance_value(v) for v in provenance.values()]}),
    ])


def versions_section(metrics: Mapping, builder: Mapping) -> Section:
    git = metrics.get("git", {})
    record_versions = metrics.get("versions", {})
    return Section("Versions and commit", [
        f"Run made at commit `{git.get('commit')}` (uncommitted changes: {git.get('dirty')}), config hash "
        f"`{metrics.get('config_hash')}`.",
        pd.DataFrame({"package": list(record_versions), "version": [str(v) for v in record_versions.values()]}),
        f"Report built at commit `{builder['git'].get('commit')}` (uncommitted changes: "
        f"{builder['git'].get('dirty')}) with "
        + ", ".join(f"{name} {version}" for name, version in builder["packages"].items()) + ".",
    ])


def run_facts(record: RunRecord) -> list:
    """Bullet lines per data variant: frames, points, m and coverage, empty axes, notes."""
    lines = []
    for data, values in record.metrics["data"].items():
        pca = values["pca"]
        empty = "; ".join(f"{projection}: {qe['empty_axes'] or 'none'}"
                          for projection, qe in values["quasi_eigen"].items())
        lines.append(f"**{data}**: {values['n_train_frames']} training frames, {values['n_eval_frames']} evaluated, "
                     f"{values['n_points']} points; m = {pca['m']} eigenfaces reach coverage "
                     f"{pca['coverage_reached']:.4f} ({pca['method']}); empty PCA axes: {empty}")
        lines += [f"{data}: {note}" for note in values.get("notes", [])]
    paper = record.config.get("paper", {})
    if paper:
        lines.append(f"paper: m = {paper.get('m')} at coverage {paper.get('coverage')}; alpha "
                     + ", ".join(f"{k} {v}" for k, v in paper.get("alpha", {}).items())
                     + " (absolute, QP with unstated constraints)")
    return lines


def intuitiveness_frame(metrics: Mapping) -> pd.DataFrame:
    """Per data variant and hand shape: relative distance and cosine to its quasi-eigen face, per projection."""
    records = {}
    for data, values in metrics["data"].items():
        for row in values["intuitiveness"]:
            entry = records.setdefault((data, row["shape"]), {"data": data, "shape": row["shape"]})
            entry[f"relative distance ({row['projection']})"] = row["relative_distance"]
            entry[f"cosine ({row['projection']})"] = row["cosine"]
    return pd.DataFrame.from_records(list(records.values()))


def run_sections(record: RunRecord, figures: list[FigureEntry], command: str) -> tuple[str, list[Section]]:
    column = headline_column(record.config)
    title = f"Study '{record.config['study']}' on the {dataset_label(record)}"
    sections = [
        Section("About this report", [
            f"Rebuilt from the run record `{record.folder.name}` only, by `{command}`. "
            + ("The data are synthetic: generated by the workbench, not a real capture. "
               if record.metrics["dataset"].get("provenance", {}).get("kind") == "synthetic" else ""),
            "Alpha is in percent (eq. 6); only ratios between rows compare across datasets, since the absolute "
            "alpha depends on the coordinate origin.",
        ]),
        Section("Alpha beside the paper", [
            f"`{column}` (the run's headline alpha) under every solver, beside Kim & Ko's reported values.",
            headline_table(record.table, column),
        ]),
        Section("Full alpha table", [record.table]),
        Section("Run facts", [run_facts(record)]),
        Section("Figures", figures),
        Section("Choices the run made", [pd.DataFrame(choices_rows(record.config), columns=["question", "choice"])]),
        Section("Intuitiveness of the quasi-eigen faces", [
            "Relative distance |e^QE - e^H| / |e^H| (0: unchanged) and cosine (1: same direction) of each hand "
            "shape and its quasi-eigen face.", intuitiveness_frame(record.metrics)]),
        provenance_section(record.metrics),
        versions_section(record.metrics, report_versions()),
    ]
    return title, sections


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
    png = next(name for name in entry.files if name.endswith(".png"))
    others = ", ".join(f"[{name.rsplit('.', 1)[1].upper()}](figures/{name})" for name in entry.files
                       if not name.endswith(".png"))
    return [f"### {entry.title}", "", f"![{entry.title}](figures/{png})", "",
            entry.caption + (f" Also as {others}." if others else ""), ""]


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
    png = next(name for name in entry.files if name.endswith(".png"))
    links = " ".join(f"<a href=\"figures/{name}\">{name.rsplit('.', 1)[1].upper()}</a>" for name in entry.files)
    return (f"<figure id=\"{entry.stem}\"><img src=\"figures/{png}\" alt=\"{html.escape(entry.title)}\">"
            f"<figcaption><strong>{html.escape(entry.title)}.</strong> {_inline_markdown(entry.caption)} "
            f"<span class=\"links\">{links}</span></figcaption></figure>")


STYLE = """
body { font-family: system-ui, -apple-system, "Segoe UI", sans-serif; max-width: 1400px; margin: 2em auto;
       padding: 0 1.5em; color: #1d1d1f; line-height: 1.45; }
h1 { font-size: 1.6em; } h2 { border-bottom: 1px solid #ccc; padding-bottom: .2em; margin-top: 1.8em; }
table { border-collapse: collapse; margin: .8em 0; font-size: .88em; }
th, td { border: 1px solid #d0d0d0; padding: .25em .6em; } th { background: #f2f2f2; }
td.num, td.short { white-space: nowrap; } .scroll { overflow-x: auto; }
td.num { text-align: right; font-variant-numeric: tabular-nums; }
tbody tr:nth-child(even) { background: #fafafa; }
figure { margin: 1.5em 0; } figure img { max-width: 100%; border: 1px solid #e3e3e3; }
figcaption { font-size: .9em; color: #333; max-width: 1100px; } .links a { margin-left: .4em; }
code { background: #f4f4f4; padding: 0 .25em; } .missing { color: #8a4b00; }
"""


def render_html(title: str, sections: Sequence[Section]) -> str:
    """index.html of a report: one self-contained page, figures beside it in ``figures/``."""
    body = [f"<h1>{html.escape(title)}</h1>"]
    for section in sections:
        body.append(f"<h2>{html.escape(section.heading)}</h2>")
        for block in section.blocks:
            if isinstance(block, FigureEntry):
                body.append(_html_figure(block))
            elif isinstance(block, pd.DataFrame):
                body.append(html_frame(block))
            elif isinstance(block, list):
                body.append("<ul>" + "".join(f"<li>{_inline_markdown(line)}</li>" for line in block) + "</ul>")
            else:
                body.append(f"<p>{_inline_markdown(block)}</p>")
    return ("<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">"
            f"<title>{html.escape(title)}</title><style>{STYLE}</style></head>\n<body>\n"
            + "\n".join(body) + "\n</body></html>\n")


# ---------------------------------------------------------------------------------------------------------------
# Sweeps
# ---------------------------------------------------------------------------------------------------------------


def sweep_figures(records: Sequence[RunRecord], summary: pd.DataFrame, swept: Sequence[str]) -> list:
    """Figure specs of a sweep report: the first run's coverage curve, alpha against each swept setting (and
    against m for a coverage sweep), and marker versus mesh when the sweep ran on two data variants."""
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
        if key == "basis.coverage":
            targets.append(("m", key))
    if swept and summary["n_hand"].nunique() > 1:
        targets.append(("n_hand", "basis.hand_subset" if "basis.hand_subset" in swept else None))
    for x, setting in targets:
        others = [key for key in swept if key not in (x, setting)]
        stem = "alpha_vs_" + x.replace(".", "_")
        specs.append((stem, f"Alpha against {axis_label(x)}",
                      f"`{column}` (mean over seeds) of each basis against {axis_label(x)}, with the 95 % "
                      "confidence band over seeds where there are several"
                      + (f"; one line per value of {', '.join(others)}." if others else "."),
                      lambda _, options, x=x, others=others: plot_alpha_against(
                          summary, x, column, solver=solver, by=others,
                          title=f"Alpha against {axis_label(x)}\n{label}")))
    if summary["data"].nunique() > 1 and not targets:
        specs.append(("marker_vs_mesh", "Marker versus mesh",
                      f"`{column}` (mean over seeds, 95 % CI) of each basis on each data variant.",
                      lambda _, options: plot_marker_vs_mesh(summary, column, solver=solver,
                                                             title=f"Marker versus mesh data\n{label}")))
    return specs


def _natural(text: str):
    return (0, float(text)) if text.replace(".", "", 1).lstrip("-").isdigit() else (1, text)


def sweep_sections(root: Path, records: Sequence[RunRecord], per_run: pd.DataFrame, summary: pd.DataFrame,
                   swept: Sequence[str], figures: list[FigureEntry], command: str) -> tuple[str, list[Section]]:
    first = records[0]
    column = headline_column(first.config)
    title = f"Study '{first.config['study']}': sweep over {', '.join(swept) or 'seeds'} on the {dataset_label(first)}"
    replicates = "; ".join(
        f"{key} " + ", ".join(sorted({str(value) for value in per_run[key].dropna()}, key=_natural))
        for key in per_run.columns if is_replicate_key(key))
    shown = summary[[*swept, "data", "basis", "solver", "n_seeds", "m", column, f"{column}_ci_low",
                     f"{column}_ci_high", "paper_alpha"]]
    runs = per_run.drop_duplicates("run")[["run", *[k for k in per_run.columns if "." in k]]]
    sections = [
        Section("About this report", [
            f"Rebuilt from {len(records)} complete run records under `{root.name}` only, by `{command}`. "
            f"Swept: {', '.join(swept) or 'nothing but the seed'}; replicates over "
            f"{replicates or 'nothing (one run each)'}. Means and Student-t 95 % confidence intervals over the "
            "replicates (\"seeds\").",
        ]),
        Section(f"Mean {column} over seeds", [shown]),
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
    """Mean and Student-t 95 % confidence interval over runs (seeds) per data variant and basis.

    Returns
    -------
    pandas.DataFrame
        ``data``, ``basis``, ``n`` (mean: PCA's m can differ between takes), ``n_seeds``, then per column its
        mean, ``<column>_ci_low`` and ``<column>_ci_high`` (NaN with a single run).
    """
    records = []
    for (data, basis), group in per_run.groupby(["data", "basis"], sort=False):
        row = {"data": data, "basis": basis, "n": float(group["n"].mean()), "n_seeds": len(group)}
        for column in columns:
            interval = t_interval(group[column].to_numpy(float))
            row.update({column: interval["mean"], f"{column}_ci_low": interval["ci95_low"],
                        f"{column}_ci_high": interval["ci95_high"]})
        records.append(row)
    return pd.DataFrame.from_records(records)


def with_bases_section(sections: list, records: Sequence[RunRecord], figures_dir: Path,
                       formats: Sequence[str]) -> list:
    """The report's sections with one on the other bases inserted before its figures: the table of alpha,
    closeness, locality and usage of every basis (means over the runs) and the figure of alpha against each.
    Unchanged when no run scored other bases."""
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
    summary = summarise_intuitiveness(pd.concat([frame for _, frame in found], ignore_index=True),
                                      [column, *INTUITIVENESS_COLUMNS])
    several = int(summary["n_seeds"].max()) > 1
    caption = (f"`{column}` (solver {solver}; PCA by projection) of every basis against its closeness to the hand "
               f"shapes, its locality and its usage" + (", means over runs with 95 % confidence intervals as error "
                                                         "bars." if several else "."))
    title = f"Alpha against intuitiveness, every basis at its size n\n{dataset_label(first)}"
    entry = make_figures([("alpha_vs_intuitiveness", "Alpha against intuitiveness", caption,
                           lambda _, options: plot_alpha_against_intuitiveness(
                               summary, column, energy=energy, threshold=threshold, title=title))],
                         None, figures_dir, formats, {})[0]
    shown = summary[["data", "basis", "n", "n_seeds", column, *([f"{column}_ci_low", f"{column}_ci_high"]
                                                                if several else []), *INTUITIVENESS_COLUMNS]]
    section = Section("Other bases: alpha against intuitiveness", [
        f"Every basis of the table at its size n, fitted on the training frames and scored alike; `{column}` with "
        f"solver {solver} (PCA: projection), " + (f"mean over {int(summary['n_seeds'].max())} runs." if several
                                                  else "one run."),
        ["`matched_abs_cosine`: the elements matched one-to-one to the hand shapes by the Hungarian method on "
         "|cosine|, the mean |cosine| of the matched pairs (1: each element is a hand shape up to scale).",
         f"`locality`: the fraction of the face's area ({settings['point_weights']}) holding {energy * 100:g} % of an "
         "element's squared displacement, mean over elements (small: local).",
         f"`usage`: elements whose contribution |w_i| |e_i| to a frame exceeds {threshold:g} of the frame's "
         f"largest, mean over the evaluated frames (weights of solver {solver})."],
        shown, entry])
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
            if path.suffix in (".png", ".svg", ".pdf"):
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
        Figure formats; PNG is always written.
    options : mapping
        ``shapes``: names of the four hand shapes of figure 2.
    command : str
        The command shown as having built the report.

    Returns
    -------
    pathlib.Path
        ``out / "index.html"``.
    """
    out = Path(out)
    figures_dir = out / "figures"
    _clear_figures(figures_dir)
    entries = make_figures(RUN_FIGURES, record, figures_dir, _with_png(formats), options or {})
    title, sections = run_sections(record, entries, command)
    sections = with_bases_section(sections, [record], figures_dir, _with_png(formats))
    _write_documents(out, title, sections)
    write_atomic(inside(out, "alpha_table.csv"), (record.folder / "alpha_table.csv").read_bytes())
    write_atomic(inside(out, "run_config.yaml"), (record.folder / "config.yaml").read_bytes())
    return out / "index.html"


def build_sweep_report(root: Path, out: Path, *, formats: Sequence[str] = FIGURE_FORMATS,
                       command: str = "workbench report") -> Path:
    """Write the report of every complete run under ``root`` into ``out``: index.html, README.md, figures/,
    summary.csv (the tidy table) and runs.csv (every row of every run).

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
    summary = wide(summarise(per_run, over=[key for key in keys if key not in swept]))
    paper = per_run.groupby("basis", sort=False)["paper_alpha"].first()
    summary["paper_alpha"] = summary["basis"].map(paper)
    summary["n_hand"] = hand_basis_size(summary, swept)
    figures_dir = out / "figures"
    _clear_figures(figures_dir)
    entries = make_figures(sweep_figures(records, summary, swept), None, figures_dir, _with_png(formats), {})
    title, sections = sweep_sections(root, records, per_run, summary, swept, entries, command)
    sections = with_bases_section(sections, records, figures_dir, _with_png(formats))
    _write_documents(out, title, sections)
    write_atomic(inside(out, "summary.csv"), summary.to_csv(index=False))
    write_atomic(inside(out, "runs.csv"), per_run.to_csv(index=False))
    return out / "index.html"


def _with_png(formats: Sequence[str]) -> list[str]:
    return ["png", *[fmt for fmt in formats if fmt != "png"]]


def _write_documents(out: Path, title: str, sections: Sequence[Section]) -> None:
    write_atomic(inside(out, "index.html"), render_html(title, sections))
    write_atomic(inside(out, "README.md"), render_markdown(title, sections))


def sweep_records(root: Path) -> list[RunRecord]:
    """The complete run records under a sweep folder (the folder itself excluded), in natural order."""
    folders = [folder for folder in find_records([root])[0] if folder != Path(root)]
    if not folders:
        raise WorkbenchError(f"{root} holds no complete run record (folders with a '{DONE}' file)")
    return [load_record(folder) for folder in folders]


REPORT_FOLDER = "report"
"""Default report folder, inside the run or sweep folder it reports on."""


def report_folder(folder: Path, config: Mapping, *, out: Path | None, reference: bool, name: str | None) -> Path:
    """Where a report goes: ``--out`` as given, the checkout's ``reports/<name>`` with ``--reference``, else
    ``<folder>/report`` beside the runs."""
    from workbench.config import REPO_ROOT

    if out is not None and reference:
        raise WorkbenchError("give either --out or --reference, not both")
    if name is not None and not reference:
        raise WorkbenchError("--name names a reference report; it goes with --reference")
    if reference:
        name = name or default_report_name(config)
        if not plain_name(name):
            raise WorkbenchError(f"--name must be a plain folder name (no path), got {name!r}")
        return inside(REPO_ROOT / "reports", name)
    return Path(out) if out is not None else Path(folder) / REPORT_FOLDER


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
                        help="figure formats besides PNG, comma-separated: svg, pdf (default: png,svg)")
    parser.add_argument("--shapes", help="figure 2: four hand-shape names, comma-separated")
    return parser.parse_args(list(argv))


def main(argv: Sequence[str]) -> int:
    """``workbench report <folder> [--out DIR | --reference [--name NAME]] [--formats png,svg] [--shapes a,b,c,d]``."""
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
        record = load_record(folder)
        out = report_folder(folder, record.config, out=args.out, reference=args.reference, name=args.name)
        options = {"shapes": [s.strip() for s in args.shapes.split(",")] if args.shapes else None}
        index = build_run_report(record, out, formats=formats, options=options, command=command)
    else:
        first = sweep_records(folder)[0]
        out = report_folder(folder, first.config, out=args.out, reference=args.reference, name=args.name)
        index = build_sweep_report(folder, out, formats=formats, command=command)
    print(f"report: {index}")
    return 0
