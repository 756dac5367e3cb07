"""Other bases (``basis.alternatives``) in a report: alpha against intuitiveness, a section and a figure."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Mapping, Sequence

import pandas as pd

from workbench.record.record import RunRecord
from workbench.reporting.report.data import dataset_label, figure_solver
from workbench.reporting.report.run_figures import FigureEntry, minimum_norm_text, placed
from workbench.reporting.report.sections import Section, range_column
from workbench.reporting.tables.runs import (
    config_columns,
    flatten,
    interval_label,
    is_replicate_key,
    level_statistics,
    paired_comparisons,
    typed_columns,
    varying_keys,
)
from workbench.stats.replicates import pseudo_replicate_reason
from workbench.stats.statistics import GEOMETRIC
from workbench.study.summary import headline_column

INTUITIVENESS_COLUMNS = ("matched_abs_cosine", "locality", "usage")
COMPARED_INTUITIVENESS = ("matched_abs_cosine", "locality")
"""The measures of the bases compared pair by pair over the replicates (usage depends on the solver: not compared)."""
NO_SOLVER = "-"
"""The solver of a comparison of closeness or locality: a property of the basis, not of a solver's weights."""
BASES_SECTION = "Other bases: alpha against intuitiveness"
"""The report section of the other bases, and of their figure."""


def basis_intuitiveness_rows(record: RunRecord) -> pd.DataFrame:
    """Per data variant and basis of a run that scored other bases: its headline alpha with the figures' solver
    (PCA: its projection) beside the basis's closeness, locality and usage (usage with that solver's weights).

    Returns
    -------
    pandas.DataFrame
        Columns ``data``, ``basis``, ``n``, the headline alpha column, :data:`INTUITIVENESS_COLUMNS` and
        ``usage_rank`` and ``usage_n_shapes`` (the basis's rank and size where the usage counts the minimum-norm
        least-squares weights of a rank-deficient basis, else NaN); empty when the run scored no other bases.
    """
    column = headline_column(record.config)
    solver, _ = figure_solver(record.config)
    conditioning = {(row["data"], row["basis"], row["solver"]): row for row in record.rows()}
    rows = []
    for data, values in record.metrics["data"].items():
        table = record.table[record.table["data"] == data]
        for entry in (values.get("basis_intuitiveness") or {}).get("bases", []):
            alpha = table.loc[(table["basis"] == entry["basis"]) & table["solver"].isin([solver, "projection"]), column]
            rows.append(
                {
                    "data": data,
                    "basis": entry["basis"],
                    "n": entry["n"],
                    column: float(alpha.iloc[0]) if len(alpha) else math.nan,
                    "matched_abs_cosine": entry["matched_abs_cosine"],
                    "locality": entry["locality"],
                    "usage": entry["usage"].get(solver, entry["usage"].get("projection", math.nan)),
                    **usage_rank(conditioning.get((data, entry["basis"], solver)) or {}),
                }
            )
    return pd.DataFrame.from_records(rows)


def summarise_intuitiveness(per_run: pd.DataFrame, columns: Sequence[str]) -> pd.DataFrame:
    """Geometric mean and its 95 % interval over runs (seeds) per data variant and basis
    (:func:`workbench.reporting.tables.runs.level_statistics`).

    Returns
    -------
    pandas.DataFrame
        ``data``, ``basis``, ``n_min``, ``n_max`` (PCA's m can differ between takes), ``n_seeds``, ``ci_method``,
        then per column its geometric mean, ``<column>_ci_low`` and ``<column>_ci_high`` (NaN with a single run).
    """
    records = []
    for (data, basis), group in per_run.groupby(["data", "basis"], sort=False):
        row = {
            "data": data,
            "basis": basis,
            "n_min": int(group["n"].min()),
            "n_max": int(group["n"].max()),
            "n_seeds": len(group),
            "ci_method": GEOMETRIC,
        }
        for column in columns:
            statistics = level_statistics(group[column].to_numpy(float))
            row.update(
                {
                    column: statistics["geomean"],
                    f"{column}_ci_low": statistics["ci95_low"],
                    f"{column}_ci_high": statistics["ci95_high"],
                }
            )
        if "usage_rank" in group.columns:
            row["usage_weights"] = usage_weights_text(group["usage_rank"], group["usage_n_shapes"])
        records.append(row)
    return pd.DataFrame.from_records(records)


def usage_rank(row: Mapping) -> dict:
    """``usage_rank`` and ``usage_n_shapes`` of a ``metrics.json`` row whose weights are the minimum-norm choice of a
    rank-deficient basis (:func:`workbench.reporting.report.run_figures.minimum_norm_text` decides), else NaN."""
    if not minimum_norm_text(row):
        return {"usage_rank": math.nan, "usage_n_shapes": math.nan}
    conditioning = row["basis_conditioning"]
    return {"usage_rank": conditioning["rank"], "usage_n_shapes": conditioning["n_shapes"]}


def usage_weights_text(ranks: pd.Series, sizes: pd.Series) -> str:
    """``minimum-norm, rank r of n`` over the runs of one basis (``r`` a range where the runs differ, with how many
    runs when not all are rank-deficient), or ``-`` when every run's weights are unique."""
    labelled = ranks.notna()
    if not labelled.any():
        return "-"
    low, high, size = int(ranks[labelled].min()), int(ranks[labelled].max()), int(sizes[labelled].max())
    text = f"minimum-norm, rank {low if low == high else f'{low}-{high}'} of {size}"
    return text if labelled.all() else f"{text} in {int(labelled.sum())} of {len(ranks)} runs"


def minimum_norm_note(summary: pd.DataFrame, solver: str) -> str:
    """The caption's words on the bases whose usage counts minimum-norm weights, or empty."""
    if "usage_weights" not in summary.columns:
        return ""
    labelled = summary[summary["usage_weights"] != "-"]
    named = list(
        dict.fromkeys(f"{basis} ({text})" for basis, text in zip(labelled["basis"], labelled["usage_weights"]))
    )
    if not named:
        return ""
    return f" Usage with {solver} weights that are minimum-norm, not unique: {', '.join(named)}."


def measure_notes(settings: Mapping, solver: str) -> list[str]:
    """What the bases table's closeness, locality and usage columns mean, with the settings they were measured
    with (``basis_intuitiveness`` of ``metrics.json``)."""
    energy, threshold = settings["locality_energy"], settings["usage_threshold"]
    return [
        "`matched_abs_cosine`: the elements matched one-to-one to the hand shapes by the Hungarian method on "
        "|cosine|, the mean |cosine| of the matched pairs (1: each element is a hand shape up to scale).",
        f"`locality`: the fraction of the face's area ({settings['point_weights']}) holding {energy * 100:g} % of an "
        "element's squared displacement, mean over elements (small: local).",
        f"`usage`: elements whose contribution |w_i| |e_i| to a frame exceeds {threshold:g} of the frame's "
        f"largest, mean over the evaluated frames (weights of solver {solver}); `usage_weights`: "
        "'minimum-norm, rank r of n' where those are least-squares weights of a basis whose n shapes have "
        "rank r < n (many weight vectors give its error; the usage is that of the shortest, not of the basis).",
    ]


def intuitiveness_comparisons(records: Sequence[RunRecord], runs: pd.DataFrame, over: Sequence[str]) -> pd.DataFrame:
    """The bases' closeness and locality compared pair by pair over the replicates, per condition and data variant
    (:func:`workbench.reporting.tables.runs.paired_comparisons`), in the layout of a sweep's comparisons table so that
    they are rows of it (solver :data:`NO_SOLVER`). Orderings by construction are about errors, never these.

    Parameters
    ----------
    records : sequence of RunRecord
    runs : pandas.DataFrame
        The sweep's runs table: its config columns are the conditions and replicates.
    over : sequence of str
        The replicate columns.

    Returns
    -------
    pandas.DataFrame
        Empty when no run scored other bases.
    """
    keys = config_columns(runs)
    frames = []
    for record in records:
        found = basis_intuitiveness_rows(record)
        if found.empty:
            continue
        flat = flatten(record.config)
        scored = {row["data"]: row for row in record.rows()}  # the points fitted on and scored, as the runs table
        frames.append(
            found.assign(
                study=record.study,
                train_on=[scored[data]["train_on"] for data in found["data"]],
                eval_on=[scored[data]["eval_on"] for data in found["data"]],
                solver=NO_SOLVER,
                **{key: flat.get(key) for key in keys},
            )
        )
    if not frames:
        return pd.DataFrame()
    frame = typed_columns(pd.concat(frames, ignore_index=True), keys)
    return pd.concat([paired_comparisons(frame, name, over=over) for name in COMPARED_INTUITIVENESS], ignore_index=True)


@dataclass
class OtherBases:
    """The other bases the runs of a report scored: the first run that did, each such run with its rows
    (:func:`basis_intuitiveness_rows`), those rows of every run in one table, and their summary over the runs
    (geometric means, :func:`summarise_intuitiveness`)."""

    first: RunRecord
    found: list
    per_run: pd.DataFrame
    summary: pd.DataFrame


def other_bases(records: Sequence[RunRecord]) -> OtherBases | None:
    """The other bases of ``records``, or None when no run scored any."""
    found = [(record, basis_intuitiveness_rows(record)) for record in records]
    found = [(record, frame) for record, frame in found if not frame.empty]
    if not found:
        return None
    first = found[0][0]
    column = headline_column(first.config)
    per_run = pd.concat(
        [frame.assign(study=record.study, run=str(record.folder)) for record, frame in found], ignore_index=True
    )
    return OtherBases(first, found, per_run, summarise_intuitiveness(per_run, [column, *INTUITIVENESS_COLUMNS]))


def bases_figure_rows(bases: OtherBases | None) -> list[tuple]:
    """The figure row (stem, title, caption, draw, section) of alpha against closeness, locality and usage of every
    basis (geometric means over the runs), in the section :data:`BASES_SECTION`; none without other bases."""
    from workbench.reporting.figures.bases import plot_alpha_against_intuitiveness

    if bases is None:
        return []
    record, summary = bases.first, bases.summary
    column = headline_column(record.config)
    solver, _ = figure_solver(record.config)
    settings = intuitiveness_settings(record)
    note = interval_label(summary, "runs")
    seeds = [key for key in varying_keys([item.config for item, _ in bases.found]) if is_replicate_key(key)]
    pseudo = pseudo_replicate_reason(seeds, flatten(record.config))
    caption = (
        f"`{column}` (solver {solver}; PCA by projection) of every basis against its closeness to the hand "
        f"shapes, its locality and its usage"
        + (f", geometric means over runs; error bars: {note}." if int(summary["n_seeds"].max()) > 1 else ".")
        + minimum_norm_note(summary, solver)
    )
    title = f"Alpha against intuitiveness, every basis at its size n\n{dataset_label(record)}"
    return [
        (
            "alpha_vs_intuitiveness",
            "Alpha against intuitiveness",
            caption,
            lambda _, options: plot_alpha_against_intuitiveness(
                summary,
                column,
                energy=settings["locality_energy"],
                threshold=settings["usage_threshold"],
                title=title,
                not_replicates=pseudo,
            ),
            BASES_SECTION,
        )
    ]


def intuitiveness_settings(record: RunRecord) -> Mapping:
    """The settings the run measured its bases' intuitiveness with (``metrics.json``: locality energy, usage
    threshold, point weights), from its first data variant that has them."""
    return next(
        values["basis_intuitiveness"] for values in record.metrics["data"].values() if values.get("basis_intuitiveness")
    )


def intuitiveness_table(summary: pd.DataFrame, column: str) -> pd.DataFrame:
    """The section's table: per data variant and basis, its size n (a range over the runs), alpha with its
    interval where there are several runs, closeness, locality and usage."""
    several = int(summary["n_seeds"].max()) > 1
    shown = summary[
        [
            "data",
            "basis",
            "n_seeds",
            column,
            *([f"{column}_ci_low", f"{column}_ci_high"] if several else []),
            *INTUITIVENESS_COLUMNS,
            *(["usage_weights"] if "usage_weights" in summary.columns else []),
        ]
    ]
    shown.insert(2, "n", range_column(summary, "n"))
    return shown


def comparisons_blocks(comparisons: pd.DataFrame, own: bool, column: str) -> list:
    """What the section says of its paired comparisons: its own table (a report of several runs without a sweep's
    table), where the sweep's one table holds them, or, for one run, that there is nothing to pair over runs."""
    if not own:
        return [
            f"Their paired comparisons over the replicates, `{column}` and closeness and locality alike, are rows of "
            "the table 'Paired comparisons' (Holm within its families there)."
        ]
    from workbench.reporting.findings.sweep import INTERVAL_NOTE

    if comparisons.empty or int(comparisons["n"].max()) < 2:  # one run: no interval, no test, so no second table
        return [
            "One run: nothing to pair over runs; the run's paired per-frame comparisons are in the table 'Paired "
            "comparisons within the run'."
        ]
    method = comparisons["method"].iloc[0] if len(comparisons) else "-"
    return [
        f"Paired comparisons over the runs: the geometric mean of the per-run ratio first / second ({method}; "
        f"{INTERVAL_NOTE}); the smaller first; `p_holm`: its p-value Holm-adjusted within its family (every tested "
        "row: QE/H and QE/PCA among them are comparisons at the runs' m, not the paper's claims, which each run "
        "stored at m = n); '<' only where p_holm is below 0.05.",
        comparisons.drop(columns=["study", "method"]),
    ]


def with_bases_section(
    sections: list,
    bases: OtherBases | None,
    figures: Sequence[FigureEntry],
    ordering: bool = True,
    comparisons: pd.DataFrame | None = None,
) -> list:
    """The report's sections with one on the other bases inserted before its figures: the table of alpha,
    closeness, locality and usage of every basis (geometric means over the runs), the figure of alpha against
    each, and their paired comparisons: with ``comparisons`` (a sweep's one table, closeness and locality among
    its rows, :func:`intuitiveness_comparisons`) those, else a table of its own; the findings gain the sizes,
    closeness and locality (and, with ``ordering``, the bases' ordering by alpha, which a sweep's own findings state
    already). The figure is the report's figure in :data:`BASES_SECTION` (:func:`bases_figure_rows`). Unchanged
    when no run scored other bases."""
    from workbench.reporting.findings.sweep import bases_findings, holm_verdicts

    if bases is None:
        return sections
    first, found, per_run, summary = bases.first, bases.found, bases.per_run, bases.summary
    column = headline_column(first.config)
    solver, _ = figure_solver(first.config)
    settings = intuitiveness_settings(first)
    own = comparisons is None
    if own:
        compared = [
            paired_comparisons(per_run, name, over=["run"], row_keys=("data", "basis"))
            for name in (column, *COMPARED_INTUITIVENESS)
        ]
        comparisons = holm_verdicts(pd.concat(compared, ignore_index=True))
    several = int(summary["n_seeds"].max()) > 1
    findings = next((item for item in sections if item.heading == "Findings"), None)
    if findings is not None:  # one run: its ordering from its paired per-frame comparisons
        run_comparisons = (
            {data: values.get("comparisons") or [] for data, values in first.metrics["data"].items()}
            if len(found) == 1
            else None
        )
        findings.blocks.append(bases_findings(summary, comparisons, column, ordering, run_comparisons, solver))
    section = Section(
        BASES_SECTION,
        [
            f"Every basis of the table at its size n (a range where it differs between runs: PCA keeps the m of each "
            f"take), fitted on the training frames and scored alike; `{column}` with solver {solver} (PCA: "
            "projection), "
            + (
                f"geometric means over {int(summary['n_seeds'].max())} runs; {interval_label(summary, 'runs')}."
                if several
                else "one run."
            ),
            measure_notes(settings, solver),
            intuitiveness_table(summary, column),
            *comparisons_blocks(comparisons, own, column),
            *placed(figures, BASES_SECTION),
        ],
    )
    headings = [item.heading for item in sections]
    at = headings.index("Figures") if "Figures" in headings else len(sections)
    return [*sections[:at], section, *sections[at:]]
