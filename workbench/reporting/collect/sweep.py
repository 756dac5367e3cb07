"""``workbench collect``: gather run records into tidy tables, summaries over seeds, paired comparisons, alpha
tables and findings.

Reads only complete records of one or many sweeps (through :mod:`workbench.record.record`), never recomputes; the tables
come from :mod:`workbench.reporting.tables.runs`, as those of ``workbench report`` do, and the intervals from
:mod:`workbench.stats.statistics`. Writes into the output folder:

- ``runs.csv`` / ``runs.parquet``: one row per run and alpha-table row (data, basis, projection, solver), with
  the config keys that differ between runs as columns, its metrics, sizes and stage timings;
- ``summary.csv`` / ``summary.parquet``: long form, one row per condition, table row and metric, with the mean,
  standard deviation, range, and the geometric mean with its 95 % interval over the replicate (seed) settings;
- ``comparisons.csv`` / ``comparisons.md``: every pair of bases per condition, the geometric mean of their
  per-seed ratio with its 95 % interval and the verdict it allows (``<``, ``>`` or not distinguishable);
- ``alpha_table.md`` / ``alpha_table.tex``: one metric as ``geometric mean [95 % interval]`` with conditions as
  rows and bases as columns;
- ``findings.md``: the findings stated from those tables (:func:`workbench.reporting.findings.sweep.sweep_findings`).

The parquet copies need pyarrow (the parquet extra); without it they are left out, said in one line with
``--verbose`` only (the CSV files hold the same tables).
"""

from __future__ import annotations

import io
import logging
import math
from pathlib import Path
from typing import Iterable, Mapping, Sequence

import numpy as np
import pandas as pd

from workbench.core.errors import WorkbenchError
from workbench.core.extras import has_module, install_hint
from workbench.core.files import inside, output_folder, write_atomic
from workbench.reporting.tables.cells import FLOAT_FORMATS, frame_cells, is_missing, latex_table, markdown_table
from workbench.reporting.tables.runs import (
    PCA_SOLVER,
    STATISTICS,
    collect_records,
    condition_keys,
    summarise,
    sweep_comparisons,
    wide,
)
from workbench.reporting.tables.width import printed
from workbench.stats.statistics import GEOMETRIC

EXTRA_FORMATS = {"m": "{:.0f}", "n": "{:.0f}", "coverage": "{:.4f}", "n_points": "{:.0f}", "time_total": "{:.1f}"}
ALPHA_METRICS = ("alpha_abs_mean", "alpha_abs_pooled", "alpha_disp_mean", "alpha_disp_pooled")


def format_value(value) -> str:
    """Text of a condition value in a table: ``-`` for missing, ``:g`` for floats."""
    if is_missing(value):
        return "-"
    if isinstance(value, (bool, np.bool_)):
        return "true" if value else "false"
    if isinstance(value, (float, np.floating)):
        return f"{value:g}"
    return str(value)


def format_estimate(estimate: float, low: float, high: float, number_format: str) -> str:
    """``estimate [low, high]`` in a column's number format; just the estimate when there is no interval."""
    if math.isnan(estimate):
        return "-"
    if math.isnan(low) or math.isnan(high):
        return number_format.format(estimate)
    return f"{number_format.format(estimate)} [{number_format.format(low)}, {number_format.format(high)}]"


def format_range(low: float, high: float, number_format: str) -> str:
    """``low-high`` of a value over the runs, or the one value when every run had it (never an average)."""
    if math.isnan(low):
        return "-"
    low_text, high_text = number_format.format(low), number_format.format(high)
    return low_text if low_text == high_text else f"{low_text}-{high_text}"


def alpha_grid(
    summary: pd.DataFrame,
    *,
    metric: str = "alpha_abs_mean",
    columns: str = "basis",
    where: Mapping[str, str] | None = None,
    extra: Sequence[str] = ("m",),
) -> tuple[list, list, int]:
    """Lay a summary out as a grid: conditions down, ``columns`` across, ``geometric mean [95 % interval]`` in the
    cells.

    Rows are the condition columns and table-row keys that vary (``projection`` is implied by the basis label;
    ``train_on``/``eval_on`` by ``data``). PCA has no solver, so a ``solver`` filter or a ``solver`` row keeps
    PCA's value beside every solver.

    Parameters
    ----------
    summary : pandas.DataFrame
        From :func:`summarise`.
    metric : str
        The metric in the cells (ignored when ``columns`` is ``metric``).
    columns : str
        The key whose values become columns: ``basis``, or ``metric`` for the four alpha variants side by side.
    where : mapping, optional
        Keep rows whose column has this value (text comparison), e.g. ``{"solver": "lstsq"}``.
    extra : sequence of str
        Metrics shown as columns after the row keys, as their range over the runs of the row's first cell, e.g.
        ``m`` (never averaged: runs with different m are different bases).

    Returns
    -------
    header : list of str
    rows : list of list of str
    n_row_keys : int
        How many leading columns are row keys (text, left-aligned).
    """
    if columns != "metric" and columns not in summary.columns:
        keys = [key for key in summary.columns if key not in STATISTICS + ("metric",)]
        raise WorkbenchError(f"collect --columns must be 'metric' or a key of the runs {keys}, got {columns!r}")
    available = list(dict.fromkeys(summary["metric"]))
    shown = [name for name in ALPHA_METRICS if name in available] if columns == "metric" else [metric]
    if not shown or any(name not in available for name in shown):
        raise WorkbenchError(f"collect --metric must be one of {available}, got {metric!r}")
    table = summary
    for key, value in (where or {}).items():
        if key not in table.columns:
            raise WorkbenchError(f"collect --where: {key!r} is not a column of the summary")
        keep = table[key].map(format_value) == str(value)
        if key == "solver":
            keep |= table["solver"] == PCA_SOLVER
        table = table[keep]
    if table.empty:
        raise WorkbenchError(f"collect --where {dict(where or {})} leaves no rows")
    table = _pca_beside_every_solver(table)
    candidates = [
        key for key in table.columns if key not in STATISTICS + (columns, "metric", "projection", "train_on", "eval_on")
    ]
    row_keys = [key for key in candidates if table[key].map(format_value).nunique() > 1] or candidates[:1]
    extras = [name for name in extra if name in available]
    column_values = shown if columns == "metric" else list(dict.fromkeys(table[columns]))
    header = row_keys + extras + [format_value(value) for value in column_values]
    rows = []
    for values, group in table.groupby(row_keys, sort=False, dropna=False):
        values = values if isinstance(values, tuple) else (values,)
        line = [format_value(value) for value in values]
        for name in extras:
            found = group[group["metric"] == name]
            line.append(
                format_range(found["min"].iloc[0], found["max"].iloc[0], EXTRA_FORMATS.get(name, "{:.3f}"))
                if len(found)
                else "-"
            )
        for value in column_values:
            name = value if columns == "metric" else metric
            found = group[(group["metric"] == name) & ((columns == "metric") | (group[columns] == value))]
            line.append(
                format_estimate(*found[["geomean", "ci95_low", "ci95_high"]].iloc[0], FLOAT_FORMATS.get(name, "{:.3f}"))
                if len(found)
                else "-"
            )
        rows.append(line)
    return header, rows, len(row_keys)


def _pca_beside_every_solver(table: pd.DataFrame) -> pd.DataFrame:
    solvers = [solver for solver in dict.fromkeys(table["solver"]) if solver != PCA_SOLVER]
    pca = table[table["solver"] == PCA_SOLVER]
    if not solvers or pca.empty:
        return table
    parts = [table[table["solver"] != PCA_SOLVER]] + [pca.assign(solver=solver) for solver in solvers]
    combined = pd.concat(parts, ignore_index=True)
    # keep the solvers' order and, within one, the conditions' order of the summary
    combined["_solver_rank"] = combined["solver"].map({solver: i for i, solver in enumerate(solvers)})
    combined["_row"] = range(len(combined))
    return combined.sort_values(["_solver_rank", "_row"], kind="stable").drop(columns=["_solver_rank", "_row"])


def caption(
    summary: pd.DataFrame,
    metric: str,
    columns: str,
    where: Mapping[str, str] | None,
    over: Sequence[str],
    extra: Sequence[str] = (),
) -> str:
    """One line naming the metric, the filters, the interval's method and how many replicates each cell has."""
    counted = ALPHA_METRICS[0] if columns == "metric" else metric
    counts = summary.loc[summary["metric"] == counted, "n"]
    n_text = f"{counts.min()}" if counts.min() == counts.max() else f"{counts.min()}-{counts.max()}"
    what = "alpha (%) by metric" if columns == "metric" else f"{metric} (%)" if metric.startswith("alpha") else metric
    filters = "".join(f", {key} = {value}" for key, value in (where or {}).items())
    replicates = ", ".join(over) if over else "no replicate key"
    ranges = f"; {', '.join(extra)}: range over the runs" if extra else ""
    return (
        f"{what}{filters}; cells: geometric mean over {replicates} [95 % interval] ({GEOMETRIC}, "
        f"n = {n_text} per cell){ranges}"
    )


def parquet_bytes(table: pd.DataFrame) -> bytes:
    buffer = io.BytesIO()
    table.to_parquet(buffer, index=False)
    return buffer.getvalue()


COLLECTED = "collected"
"""The default output folder of collect, inside the one folder collected (and a study's sweep folder)."""
COLLECTED_FILES = (
    "runs.csv",
    "summary.csv",
    "comparisons.csv",
    "comparisons.md",
    "alpha_table.md",
    "alpha_table.tex",
    "findings.md",
    "runs.parquet",
    "summary.parquet",
)
"""What collect writes: accepted without the output marker in ``<sweep>/collected``, as tables collected before
folders were marked hold them."""
WRITER = "collect"


def collect_and_write(
    paths: Iterable[Path],
    out: Path,
    *,
    metric: str = "alpha_abs_mean",
    where: Mapping[str, str] | None = None,
    columns: str = "basis",
    extra: Sequence[str] = ("m",),
    over: Sequence[str] | None = None,
    known: Sequence[str] = (),
    force: bool = False,
) -> dict:
    """Collect the records under ``paths`` and write the runs table, the summary, the paired comparisons, the
    alpha table and the findings to ``out``.

    Parameters
    ----------
    paths : iterable of pathlib.Path
        Sweep folders (or run folders, or folders holding several sweeps).
    out : pathlib.Path
        Output folder: new, empty or one collect wrote before (replaced as a whole); written in a temporary folder
        beside it and moved into place when complete (:func:`workbench.core.files.output_folder`).
    metric, where, columns, extra
        Layout of the alpha table (see :func:`alpha_grid`); ``metric`` and ``where`` also choose what the
        comparisons and findings are about.
    over : sequence of str, optional
        Replicate columns (default: config columns naming a seed).
    known : sequence of str
        Names accepted in ``out`` without the output marker (:func:`workbench.core.files.check_output_folder`):
        :data:`COLLECTED_FILES` where the workbench chose the folder itself (``<sweep>/collected``).
    force : bool
        Replace files of an earlier collect in ``out`` that were changed since (``--force``).

    Returns
    -------
    dict
        ``n_runs``, ``n_incomplete``, ``markdown`` (the alpha table's text), ``findings`` (lines) and ``files``
        (paths written).
    """
    from workbench.reporting.findings.sweep import (
        cell_claims,
        holm_text,
        holm_verdicts,
        replicate_caveat,
        sweep_statements,
    )

    paths = [Path(path) for path in paths]
    runs, incomplete, records = collect_records(paths)
    conditions, over = condition_keys(runs, over)
    summary = summarise(runs, over)
    header, rows, n_text = alpha_grid(summary, metric=metric, columns=columns, where=where, extra=extra)
    title = caption(summary, metric, columns, where, over, [name for name in extra if name in set(summary["metric"])])
    numeric = [i >= n_text for i in range(len(header))]
    markdown = title + "\n\n" + markdown_table(header, rows, numeric)
    compared = [name for name in (metric, f"clean_{metric}") if name in runs.columns]
    comparisons = holm_verdicts(filtered(sweep_comparisons(runs, compared, over), where))
    solvers = (
        [(where or {}).get("solver")]
        if (where or {}).get("solver")
        else [solver for solver in dict.fromkeys(runs["solver"]) if solver != PCA_SOLVER] or [PCA_SOLVER]
    )
    swept = [key for key in conditions if key != "dataset.train_on"]
    lead = next(iter(comparisons["data"].dropna()), None) if "data" in comparisons.columns else None
    claims = cell_claims(records, swept, lead if lead is not None else str(runs["data"].iloc[0]))
    findings = [holm_text(comparisons), *replicate_caveat(over)] + [
        line
        for solver in solvers
        for line in sweep_statements(wide(summary), comparisons, swept, compared, solver, claims)
    ]
    out = Path(out)
    files = {
        "runs.csv": runs.to_csv(index=False),
        "summary.csv": summary.to_csv(index=False),
        "comparisons.csv": comparisons.to_csv(index=False),
        "comparisons.md": comparisons_markdown(comparisons, over),
        "alpha_table.md": markdown,
        "alpha_table.tex": latex_table(header, rows, numeric, title),
        "findings.md": "".join(f"- {line}\n" for line in findings),
    }
    if has_module("pyarrow"):
        files.update({"runs.parquet": parquet_bytes(runs), "summary.parquet": parquet_bytes(summary)})
    else:  # the CSV files hold the same tables
        logging.getLogger("workbench").debug(f"parquet copies of the tables left out: {install_hint('parquet')}")
    with output_folder(out, "--out", writer=WRITER, known=known, force=force) as staging:
        for name, content in files.items():
            write_atomic(inside(staging, name), content)
    n_runs = int(runs.groupby(["sweep", "run"]).ngroups)
    return {
        "n_runs": n_runs,
        "n_incomplete": len(incomplete),
        "markdown": markdown,
        "findings": findings,
        "files": [out / name for name in files],
    }


def filtered(table: pd.DataFrame, where: Mapping[str, str] | None) -> pd.DataFrame:
    """The rows whose columns have the ``where`` values (text comparison; keys the table lacks are ignored)."""
    for key, value in (where or {}).items():
        if key in table.columns:
            table = table[table[key].map(format_value) == str(value)]
    return table


def comparisons_markdown(comparisons: pd.DataFrame, over: Sequence[str]) -> str:
    """The paired comparisons as a Markdown table under a caption naming the method, the replicates, which
    interval is shown and the families the verdicts are decided in."""
    from workbench.reporting.findings.sweep import INTERVAL_NOTE

    shown = comparisons.drop(columns=["study", "method"])
    shown = shown.loc[
        :,
        [
            column
            for column in shown.columns
            if shown[column].map(format_value).nunique() > 1
            or column in ("first", "second", "ratio", "ratio_low", "ratio_high", "n", "verdict")
        ],
    ]
    header, rows, numeric = frame_cells(shown)
    method = comparisons["method"].iloc[0] if len(comparisons) else "-"
    metrics = ", ".join(f"`{name}`" for name in dict.fromkeys(comparisons["metric"]))
    return (
        f"{metrics}: per pair of bases, the geometric mean of the per-replicate ratio first / second and its "
        f"interval ({method} over {', '.join(over) or 'no replicate key'}; {INTERVAL_NOTE}), the smaller first; "
        "'<' only where p_holm, Holm's adjustment within the row's family, is below 0.05: 'secondary' (every tested "
        "row, QE/H and QE/PCA among them: comparisons at the row's m, not the paper's claims, which each run stored "
        "at m = n and findings.md counts); 'identity', '<= by construction': holds in every replicate whatever the "
        "data, not tested, no p-value (the reason in by_construction)\n\n" + markdown_table(header, rows, numeric)
    )


def findings_text(findings: Sequence[str]) -> str:
    """The findings as printed after the alpha table."""
    return "\nFindings (comparisons.md has every pair):\n" + "".join(f"- {line}\n" for line in findings)


try:
    from hydra.experimental.callback import Callback
except ImportError:  # pragma: no cover - Hydra is a dependency; this keeps the module importable without it
    Callback = object


class CollectSweep(Callback):
    """Hydra callback: when a study's sweep ends, collect its records into tables (the study's report step).

    Configured in a study's ``hydra.callbacks.collect`` with the layout of its alpha table; the arguments are
    those of :func:`collect_and_write`.
    """

    def __init__(self, **layout):
        self.layout = layout

    def on_multirun_end(self, config, **kwargs) -> None:
        import sys

        sweep_dir = Path(str(config.hydra.sweep.dir))
        try:
            written = collect_and_write([sweep_dir], inside(sweep_dir, COLLECTED), **self.layout, known=COLLECTED_FILES)
        except WorkbenchError as error:  # the records are complete; say why the tables are not, and how to retry
            print(
                printed(f"workbench collect: error: {error} (records kept; rerun 'workbench collect {sweep_dir}')"),
                file=sys.stderr,
            )
            return
        print(printed(f"collected {written['n_runs']} runs into {sweep_dir / 'collected'}"))
        print(printed(written["markdown"] + findings_text(written["findings"])), end="")
