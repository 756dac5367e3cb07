"""The report of a sweep folder: the tidy table of means and 95 % confidence intervals over seeds, the paired
comparisons, alpha against every swept setting, and the runs it rests on."""

from __future__ import annotations

from pathlib import Path
from typing import Sequence

import pandas as pd

from workbench.core.errors import WorkbenchError
from workbench.core.files import inside, write_atomic
from workbench.record.record import DONE, RunRecord, find_records, load_record
from workbench.reporting.findings.run import fit_findings
from workbench.reporting.findings.sweep import holm_verdicts
from workbench.reporting.report.bases import (
    bases_figure_rows,
    intuitiveness_comparisons,
    other_bases,
    with_bases_section,
)
from workbench.reporting.report.data import dataset_label, figure_solver, training_variants
from workbench.reporting.report.page import write_documents
from workbench.reporting.report.run_figures import (
    FIGURE_FORMATS,
    FIGURES_SECTION,
    FigureEntry,
    clear_figures,
    draw_coverage_curve,
    make_figures,
    placed,
)
from workbench.reporting.report.sections import (
    GLOSSARY_NOTE,
    Section,
    choices_rows,
    provenance_section,
    range_column,
    report_versions,
    versions_section,
)
from workbench.reporting.tables.runs import (
    interval_label,
    is_replicate_key,
    not_replicates_reason,
    runs_table,
    summarise,
    sweep_comparisons,
    varying_keys,
    wide,
)
from workbench.study.regime import is_paper_regime
from workbench.study.summary import headline_column


def hand_basis_size(summary: pd.DataFrame, by: Sequence[str]) -> pd.Series:
    """Size of the hand basis beside every row of a tidy table: the ``n`` of the ``H`` row with the same swept
    values and data variant (the x of "alpha against basis count"; PCA's own ``n`` is m)."""
    keys = [*by, "data"]
    hand = summary[summary["basis"] == "H"].groupby(keys, sort=False, dropna=False)["n"].first()
    index = pd.MultiIndex.from_frame(summary[keys].astype(object)) if len(keys) > 1 else summary[keys[0]]
    return pd.Series(hand.reindex(index).to_numpy(), index=summary.index, name="n_hand")


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
        As :func:`workbench.reporting.tables.runs.wide`, with the condition column ``m`` (an integer).
    """
    others = [key for key in swept if key != "basis.coverage"]
    rows = per_run.drop(columns=["basis.coverage"]).assign(**{"pca.m": per_run["m"].astype(int)})
    rows = rows.drop_duplicates([*others, *over, "pca.m", "data", "basis", "solver"])
    summary = wide(
        summarise(
            rows.drop(columns=[c for c in rows.columns if "." in c and c not in (*others, *over, "pca.m")]),
            over=list(over),
        )
    )
    return summary.drop(columns=["m"]).rename(columns={"pca.m": "m"})


def sweep_figures(
    records: Sequence[RunRecord],
    summary: pd.DataFrame,
    swept: Sequence[str],
    per_run: pd.DataFrame | None = None,
    over: Sequence[str] = (),
) -> list:
    """Figure specs of a sweep report: the first run's coverage curve, alpha against each swept setting (and
    against m for a coverage sweep, runs grouped by m) with every run's own value as a point, alpha scored against
    the clean frames where the runs did, and marker versus mesh when the runs scored several data variants."""
    from workbench.reporting.figures.studies import axis_label, plot_alpha_against, plot_marker_vs_mesh

    first = records[0]
    column = headline_column(first.config)
    solver, _ = figure_solver(first.config)
    label = dataset_label(first)
    pseudo = not_replicates_reason(per_run, over) if per_run is not None and over else ""
    specs = [
        (
            "coverage_curve",
            "Coverage curve (first run)",
            f"Cumulative explained variance against m for the run {first.folder.name}.",
            lambda _, options: draw_coverage_curve(first),
            FIGURES_SECTION,
        )
    ]
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
            specs.append(
                (
                    stem,
                    f"Alpha{against} against {axis_label(x)}",
                    f"`{y}` (geometric mean over seeds) of each basis against {axis_label(x)}; "
                    f"{interval_label(table)}{grouped}"
                    + (f"; one line per value of {', '.join(others)}." if others else "."),
                    lambda _, options, x=x, y=y, others=others, table=table: plot_alpha_against(
                        table,
                        x,
                        y,
                        solver=solver,
                        by=others,
                        panels=[p for p in panels if p != x],
                        points=per_run if per_run is not None and x in per_run.columns else None,
                        not_replicates=pseudo,
                        title=f"Alpha{' scored on the clean frames,' if y != column else ''} against "
                        f"{axis_label(x)}\n{label}",
                    ),
                    FIGURES_SECTION,
                )
            )
    # held-out frames are no data variant, and a paper-regime variant (m = n) differs in m, not in the points
    compared = [data for data in training_variants(first) if not is_paper_regime(data)]
    trained = summary[summary["data"].isin(compared)]
    if "eval_on" in trained.columns and trained["train_on"].nunique() > 1:
        fixed = [key for key in swept if key != "dataset.train_on"]
        for values, part in trained.groupby(fixed, sort=False) if fixed else [((), trained)]:
            values = values if isinstance(values, tuple) else (values,)
            setting = ", ".join(f"{key} = {value}" for key, value in zip(fixed, values))
            stem = "marker_vs_mesh" + "".join(f"_{value}" for value in values).replace(".", "_")
            specs.append(
                (
                    stem,
                    f"Marker versus mesh{': ' + setting if setting else ''}",
                    "Each basis fitted on each data variant and scored on the common evaluation sets, in "
                    f"millimetres and `alpha_disp_pooled`; error bars: {interval_label(part)}.",
                    lambda _, options, part=part, setting=setting: plot_marker_vs_mesh(
                        part,
                        ("rms_mm", "alpha_disp_pooled"),
                        solver=solver,
                        title=f"Marker versus mesh{': ' + setting if setting else ''}\n{label}",
                        not_replicates=pseudo,
                    ),
                    FIGURES_SECTION,
                )
            )
    return specs


def _natural(text: str):
    return (0, float(text)) if text.replace(".", "", 1).lstrip("-").isdigit() else (1, text)


def sweep_sections(
    root: Path,
    records: Sequence[RunRecord],
    per_run: pd.DataFrame,
    summary: pd.DataFrame,
    comparisons: pd.DataFrame,
    swept: Sequence[str],
    figures: list[FigureEntry],
    command: str,
    over: Sequence[str] = (),
) -> tuple[str, list[Section]]:
    from workbench.reporting.findings.sweep import cell_claims, holm_text, replicate_caveat, sweep_statements
    from workbench.reporting.findings.sweep_summary import summary_lead, sweep_summary

    first = records[0]
    column = headline_column(first.config)
    solver = figure_solver(first.config)[0]
    title = f"Study '{first.settings.study}': sweep over {', '.join(swept) or 'seeds'} on the {dataset_label(first)}"
    replicates = "; ".join(
        f"{key} " + ", ".join(sorted({str(value) for value in per_run[key].dropna()}, key=_natural))
        for key in per_run.columns
        if is_replicate_key(key)
    )
    columns = [column] + ([f"clean_{column}"] if f"clean_{column}" in summary.columns else [])
    shown = summary[[*swept, "data", "basis", "solver", "n_seeds"]].assign(
        m=range_column(summary, "m"), n=range_column(summary, "n")
    )
    for name in columns:
        shown = shown.assign(
            **{
                name: summary[name],
                f"{name}_ci_low": summary[f"{name}_ci_low"],
                f"{name}_ci_high": summary[f"{name}_ci_high"],
            }
        )
    shown = shown.assign(paper_alpha=summary["paper_alpha"])
    solvers = [name for name in dict.fromkeys(per_run["solver"]) if name != "projection"]
    hidden = ("study", "method", "train_on", "dataset.train_on", *(("solver",) if len(solvers) < 2 else ()))
    compared = comparisons.drop(columns=[key for key in hidden if key in comparisons.columns])
    runs = per_run.drop_duplicates("run")[["run", *[k for k in per_run.columns if "." in k]]]
    claims = cell_claims(records, swept, summary_lead(per_run, comparisons))
    findings = [
        holm_text(comparisons),
        *replicate_caveat([key for key in per_run.columns if is_replicate_key(key)]),
    ] + [
        line
        for name in [solver, *(other for other in solvers if other != solver)]
        for line in sweep_statements(summary, comparisons, swept, columns, name, claims)
    ]
    summary_text = sweep_summary(records, per_run, comparisons, swept, over, column)
    sections = [
        Section("Summary", [summary_text]),
        Section("Findings", ["Generated from the tables below (each solver; PCA by projection).", findings]),
        Section(
            "About this report",
            [
                f"Rebuilt from {len(records)} complete run records under `{root.name}` only, by `{command}`. "
                f"Swept: {', '.join(swept) or 'nothing but the seed'}; replicates over "
                f"{replicates or 'nothing (one run each)'}. Levels: geometric means; {interval_label(summary)} (it stays "
                f"positive, as alpha does); m and n are ranges over the runs, never averaged. {GLOSSARY_NOTE}",
            ],
        ),
        Section(f"{column} over seeds", [f"Geometric means; {interval_label(summary)}.", shown]),
        Section("Paired comparisons", [comparisons_caption(comparisons, column), compared]),
        Section(FIGURES_SECTION, placed(figures, FIGURES_SECTION)),
        Section("Runs", [runs.astype(str)]),
        Section(
            "Choices the runs made (first run)",
            [pd.DataFrame(choices_rows(first.settings), columns=["question", "choice"])],
        ),
        provenance_section(first.metrics, "Dataset provenance and licence (first run)"),
        versions_section(first.metrics, report_versions()),
    ]
    return title, sections


def comparisons_caption(comparisons: pd.DataFrame, column: str) -> str:
    """The paragraph above a sweep's one comparisons table: what a row is, which interval is shown, and the
    families its verdicts are decided in with their sizes (:func:`workbench.reporting.findings.sweep.holm_verdicts`)."""
    from workbench.reporting.findings.sweep import IDENTITY, INTERVAL_NOTE, SECONDARY, family_sizes, rows_text

    method = comparisons["method"].iloc[0] if len(comparisons) else "-"
    metrics = ", ".join(f"`{name}`" for name in dict.fromkeys(comparisons["metric"])) if len(comparisons) else "-"
    sizes = family_sizes(comparisons)
    return (
        f"Per condition, solver and pair of bases (PCA by projection), for each of {metrics}: the geometric mean "
        f"of the per-seed ratio first / second ({method}); the smaller first; `ratio_low`, `ratio_high`: "
        f"{INTERVAL_NOTE}. `p`: the p-value of the same test; `p_holm`: Holm's adjustment within the row's "
        f"`family`: '{SECONDARY}' (every tested row, QE/H and QE/PCA among them: comparisons at the row's m, not "
        f"the paper's claims, which each run stored at m = n: {rows_text(sizes[SECONDARY])}), '{IDENTITY}' (holds "
        f"by construction, its reason in `by_construction`: no test and no p-value, only its size: "
        f"{rows_text(sizes[IDENTITY])}); 'verdict' '<' only where p_holm is below 0.05."
    )


def build_sweep_report(
    root: Path, out: Path, *, formats: Sequence[str] = FIGURE_FORMATS, command: str = "workbench report"
) -> Path:
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
    # one table, one pair of Holm families: the bases' closeness and locality are rows beside alpha
    compared = sweep_comparisons(per_run, [column, f"clean_{column}"], over)
    intuitiveness = intuitiveness_comparisons(records, per_run, over)
    if len(intuitiveness):
        compared = pd.concat([compared, intuitiveness], ignore_index=True)
    comparisons = holm_verdicts(compared)
    figures_dir = inside(out, "figures")
    clear_figures(figures_dir)
    bases = other_bases(records)
    rows = [*sweep_figures(records, summary, swept, per_run, over), *bases_figure_rows(bases)]
    entries = make_figures(rows, None, figures_dir, formats, {})
    title, sections = sweep_sections(root, records, per_run, summary, comparisons, swept, entries, command, over)
    sections = fit_findings(with_bases_section(sections, bases, entries, ordering=False, comparisons=comparisons))
    write_documents(out, title, sections)
    write_atomic(inside(out, "summary.csv"), summary.to_csv(index=False))
    write_atomic(inside(out, "comparisons.csv"), comparisons.to_csv(index=False))
    write_atomic(inside(out, "runs.csv"), per_run.to_csv(index=False))
    return out / "index.html"


def sweep_records(root: Path) -> list[RunRecord]:
    """The complete run records under a sweep folder (the folder itself excluded), in natural order."""
    folders = [folder for folder in find_records([root])[0] if folder != Path(root)]
    if not folders:
        raise WorkbenchError(f"{root} holds no complete run record (folders with a '{DONE}' file)")
    return [load_record(folder, check_archives=True) for folder in folders]
