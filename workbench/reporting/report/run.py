"""The report of one run: its sections (findings, facts, alpha beside the paper, the faces, figures, left and
right, the full tables, paired comparisons, choices, provenance, versions) and the folder that holds them."""

from __future__ import annotations

from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Mapping, Sequence

import pandas as pd

from workbench.core.files import inside, write_atomic
from workbench.record.record import RunRecord
from workbench.reporting.figures.headline import headline_spec
from workbench.reporting.findings.run import fit_findings
from workbench.reporting.report.bases import bases_figure_rows, other_bases, with_bases_section
from workbench.reporting.report.data import dataset_label, figure_bases, qe_label, record_inputs
from workbench.reporting.report.faces import FacesBlock, build_faces
from workbench.reporting.report.page import write_documents
from workbench.reporting.report.rig_panel import with_rig_panel
from workbench.reporting.report.run_figures import (
    FIGURE_FORMATS,
    FIGURES_SECTION,
    RUN_FIGURES,
    FigureEntry,
    clear_figures,
    make_figures,
    minimum_norm_text,
    placed,
)
from workbench.reporting.report.sections import (
    GLOSSARY_NOTE,
    Section,
    choices_rows,
    headline_table,
    provenance_section,
    report_versions,
    versions_section,
)
from workbench.study.summary import headline_column


def run_facts(record: RunRecord) -> list:
    """The run's facts once: a table with a row per data variant, the notes all variants share, then each
    variant's own notes, and the paper's values."""
    from workbench.reporting.findings.run import facts_frame, shared_notes

    shared, own = shared_notes(record.metrics)
    lines = [*shared, *[f"{data} only: {note}" for data, notes in own.items() for note in notes]]
    paper = record.settings.paper
    if paper is not None:
        lines.append(
            f"paper: m = {paper.m} at coverage {paper.coverage}; alpha "
            + ", ".join(f"{k} {v}" for k, v in asdict(paper.alpha).items())
            + " (absolute, QP with unstated constraints)"
        )
    return [facts_frame(record.metrics), lines]


@dataclass
class LeftRight:
    """Where the left/right pairs of hand shapes and their quasi-eigen faces act (:mod:`workbench.reporting.report.sides`):
    one finding per data variant and the table behind them."""

    findings: list = field(default_factory=list)
    table: pd.DataFrame | None = None


def left_right(record: RunRecord, cache: dict) -> LeftRight:
    """The left/right pairs of every data variant whose inputs the run saved."""
    from workbench.reporting.report.sides import pair_sides, shared_term, sides_finding, sides_frame

    found, frames = LeftRight(), []
    for data in record.data_variants:
        inputs = record_inputs(record, data, cache)
        if inputs is None:
            continue
        names = [str(name) for name in inputs["hand_names"]]
        bases = figure_bases(record, data, inputs, cache, every=True)
        bases = {label: shapes[: len(names)] for label, shapes in bases.items()}  # appended eigenfaces are no pair
        support = inputs.get("point_support")
        pairs = pair_sides(inputs["neutral"], inputs["eval"], inputs["components"], names, bases, support)
        if not pairs:
            continue
        term = (
            shared_term(inputs["neutral"], inputs["components"], inputs["mean"], names, inputs["hand"], support)
            if "QE" in bases
            else None
        )
        found.findings.append(sides_finding(data, pairs, term, qe_label(record)))
        frames.append(sides_frame(pairs).assign(data=data))
    if frames:
        table = pd.concat(frames, ignore_index=True)
        found.table = table[["data", *[column for column in table.columns if column != "data"]]]
    return found


def left_right_section(found: LeftRight) -> Section:
    """What the left/right pairs show, per data variant (said here, beside their table, not among the findings),
    then the table."""
    return Section(
        "Left and right",
        [
            found.findings,
            "Each left/right pair of hand shapes: how together the capture moves the two sides of the face (correlation "
            "over the evaluated frames of the motion at the _L and _R hand shapes' peaks, along their directions), the "
            "share |P e| / |e| of each shape, of their sum L+R and of their difference L-R that the eigenfaces span, "
            "and, for each basis, the largest displacement of the _L and the _R face on its own side of the face and on "
            "the other (mm; `!`: the other side moves over 10 % more). The sides are told apart by the hand shapes' "
            "peaks.",
            found.table,
        ],
    )


SUMMARY_SECTION = "Summary"
"""The section a run's report opens with, and the section of its headline figure."""


def run_sections(
    record: RunRecord,
    figures: list[FigureEntry],
    command: str,
    faces: "FacesBlock | None" = None,
    sides: LeftRight | None = None,
) -> tuple[str, list[Section]]:
    from workbench.reporting.findings.run import run_findings
    from workbench.reporting.findings.run_summary import run_summary

    column = headline_column(record.config)
    title = f"Study '{record.settings.study}' on the {dataset_label(record)}"
    intuitiveness = {data: values["intuitiveness"] for data, values in record.metrics["data"].items()}
    has_sides = sides is not None and sides.table is not None
    summary = run_summary(record.table, column, record.metrics, record.config.get("solver"))
    sections = [
        *([Section(SUMMARY_SECTION, [summary, *placed(figures, SUMMARY_SECTION)])] if summary else []),
        Section(
            "Findings",
            [
                f"Generated from the run's numbers (`{column}`, %). "
                + (
                    "The data are synthetic: generated by the workbench, not a real capture. "
                    if record.metrics["dataset"]["provenance"].get("kind") == "synthetic"
                    else ""
                ),
                run_findings(
                    record.table,
                    column,
                    {} if record.settings.paper is None else asdict(record.settings.paper),
                    intuitiveness,
                    record.metrics,
                    record.config,
                ),
            ],
        ),
        Section("Run facts", run_facts(record)),
        Section(
            "Alpha beside the paper",
            [
                f"`{column}` (the run's headline alpha) under every solver, beside Kim & Ko's reported values. The "
                "absolute alpha depends on the coordinate origin; ratios between rows do not, but they move with the "
                "alpha variant on the same data (the findings give them under each), so no one ratio compares across "
                "datasets.",
                headline_table(record.table, column),
            ],
        ),
        *protocol_sections(record, column),
        *([Section("Faces you can turn", [faces])] if faces is not None else []),
        Section(FIGURES_SECTION, placed(figures, FIGURES_SECTION)),
        *([left_right_section(sides)] if has_sides else []),
        Section("Full alpha table", [alpha_columns(record.table)]),
        *error_and_weight_sections(record),
        *comparison_sections(record),
        Section("Choices the run made", [pd.DataFrame(choices_rows(record.settings), columns=["question", "choice"])]),
        provenance_section(record.metrics),
        versions_section(record.metrics, report_versions()),
        Section(
            "About this report",
            [f"Rebuilt from the run record `{record.folder.name}` only, by `{command}`. {GLOSSARY_NOTE}"],
        ),
    ]
    return title, sections


def alpha_columns(table: pd.DataFrame) -> pd.DataFrame:
    """The alpha table's naming and alpha columns (the per-frame error and weight columns go in their section)."""
    from workbench.study.table import FRAME_COLUMNS

    return table[[column for column in table.columns if column not in FRAME_COLUMNS]]


def error_and_weight_sections(record: RunRecord) -> list[Section]:
    """The per-frame error in millimetres and the weights' statistics of every row, with what each column means
    and the face region of each data variant; nothing for records without them."""
    from workbench.study.table import FRAME_COLUMNS, ROW_NAME_COLUMNS

    columns = [column for column in FRAME_COLUMNS if column in record.table.columns]
    if not columns:
        return []
    regions = [
        f"{data}: {values['face_region']}"
        for data, values in record.metrics["data"].items()
        if values.get("face_region")
    ]
    shown = record.table[[*ROW_NAME_COLUMNS, *columns]]
    labels = weights_labels(record)
    if any(label != "-" for label in labels):
        shown = shown.assign(weights=labels)
    return [
        Section(
            "Error in millimetres and the weights",
            [
                "`err_mm_*`: each evaluated frame's RMS 3-D point error over the face region, in mm; its median, 95th "
                "percentile and maximum over the frames. `w_max_abs`: the largest |w|; `w_outside_01`: the share of frames "
                "with a weight below 0 or above 1; `w_sparsity`: Hoyer's sparsity (sqrt(n) - |w|_1/|w|_2) / (sqrt(n) - 1), "
                "mean over frames (1: one shape per frame, 0: all equal); `w_roughness`: the mean squared second time "
                "derivative of the weights, 1/s^4, from second differences over the frames' times within each take. PCA's "
                "coefficients are no animator's weights (`-`). `weights`: 'minimum-norm, rank r of n' where the basis's "
                "n shapes have rank r < n on the scored points: least squares then has many weight vectors with the "
                "same error and returns the shortest, so the w_ columns describe that choice, not the basis. The face "
                "region of each data variant:",
                regions,
                shown,
            ],
        )
    ]


def weights_labels(record: RunRecord) -> list[str]:
    """Per alpha-table row, ``minimum-norm, rank r of n`` for least-squares weights of a rank-deficient basis
    (:func:`workbench.reporting.report.run_figures.minimum_norm_text`, from the row's ``basis_conditioning`` in
    ``metrics.json``), else ``-``."""
    found = {(row["data"], row["basis"], row["solver"]): row for row in record.rows()}
    return [
        minimum_norm_text(found.get(key) or {}) or "-"
        for key in record.table[["data", "basis", "solver"]].itertuples(index=False, name=None)
    ]


def comparison_sections(record: RunRecord) -> list[Section]:
    """The table every ``<`` of the findings comes from, with how its intervals, identities, ties and adjustment
    are made (:func:`workbench.reporting.findings.comparisons.comparison_table`)."""
    from workbench.reporting.findings.comparisons import comparison_method_text, comparison_table

    frame = comparison_table(record.metrics, solvers=record.config.get("solver"))
    if frame.empty:
        return []
    return [Section("Paired comparisons within the run", [comparison_method_text(record.metrics), frame])]


def protocol_sections(record: RunRecord, column: str) -> list[Section]:
    """Training frames (the paper's protocol) beside held-out frames (``dataset.held_out``): per data variant,
    basis and solver, the headline alpha and median error of each protocol; nothing without held-out frames."""
    protocols = {data: values["protocol"] for data, values in record.metrics["data"].items()}
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
            entry = {
                "data": base,
                "held out": protocols[data].removeprefix("held-out "),
                "basis": basis,
                "solver": solver,
                f"{column} training": float(own[column].iloc[0]),
                f"{column} held out": float(part[column].iloc[0]),
            }
            entry["held out / training"] = entry[f"{column} held out"] / entry[f"{column} training"]
            if "err_mm_median" in table.columns:
                entry["err_mm_median training"] = float(own["err_mm_median"].iloc[0])
                entry["err_mm_median held out"] = float(part["err_mm_median"].iloc[0])
            rows.append(entry)
    notes = [
        f"{data}: {next(note for note in record.metrics['data'][data]['notes'] if note.startswith('held out'))}"
        for data in held
        if any(note.startswith("held out") for note in record.metrics["data"][data]["notes"])
    ]
    return [
        Section(
            "Training frames and held-out frames",
            [
                "The paper scores the frames its bases were fitted on (the training frames, split 'same'). Beside it, the "
                "same method with the bases fitted without some frames and scored on those (`dataset.held_out`); the "
                "held-out rows are data variants of their own in every table, with their own m and paired comparisons.",
                notes,
                pd.DataFrame.from_records(rows),
            ],
        )
    ]


def build_run_report(
    record: RunRecord,
    out: Path,
    *,
    formats: Sequence[str] = FIGURE_FORMATS,
    options: Mapping | None = None,
    command: str = "workbench report",
) -> Path:
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
    clear_figures(figures_dir)
    cache: dict = {}
    bases = other_bases([record])
    headline = (*headline_spec(record, headline_column(record.config), dataset_label(record)), SUMMARY_SECTION)
    rows = [*RUN_FIGURES, headline, *bases_figure_rows(bases)]
    entries = make_figures(rows, record, figures_dir, formats, {**(options or {}), "cache": cache})
    faces = build_faces(record, out, cache)
    title, sections = run_sections(record, entries, command, faces, left_right(record, cache))
    sections = with_rig_panel(sections, record, out, cache, (options or {}).get("shared"))
    sections = fit_findings(with_bases_section(sections, bases, entries))
    write_documents(out, title, sections)
    write_atomic(inside(out, "alpha_table.csv"), (record.folder / "alpha_table.csv").read_bytes())
    write_atomic(inside(out, "run_config.yaml"), (record.folder / "config.yaml").read_bytes())
    return out / "index.html"
