"""``workbench collect``: gather run records into tidy tables, summaries over seeds and alpha tables.

Reads only records (folders with a ``done`` marker) of one or many sweeps, never recomputes. Writes into the
output folder:

- ``runs.csv`` / ``runs.parquet``: one row per run and alpha-table row (data, basis, projection, solver), with
  the run's overrides as columns, its metrics, sizes and stage timings;
- ``summary.csv`` / ``summary.parquet``: long form, one row per condition, table row and metric, with the mean,
  standard deviation and 95 % t-interval over the replicate (seed) overrides;
- ``alpha_table.md`` / ``alpha_table.tex``: one metric as ``mean ± half-width`` with conditions as rows and
  bases as columns.
"""

from __future__ import annotations

import argparse
import io
import json
import math
import re
from pathlib import Path
from typing import Iterable, Mapping, Sequence

import numpy as np
import pandas as pd

from workbench.errors import WorkbenchError
from workbench.progress import progress
from workbench.record import write_atomic
from workbench.report import FLOAT_FORMATS
from workbench.tracking import DONE

ROW_KEYS = ("data", "train_on", "eval_on", "basis", "projection", "solver")
"""Columns that name one row of a run's alpha table."""
SUMMARY_METRICS = ("alpha_abs_mean", "alpha_abs_pooled", "alpha_disp_mean", "alpha_disp_pooled", "rms_mm", "m",
                   "coverage", "n", "n_points", "time_total")
"""Columns of the runs table summarised over seeds (those present)."""
EXTRA_FORMATS = {"m": "{:.1f}", "n": "{:.1f}", "coverage": "{:.4f}", "n_points": "{:.0f}", "time_total": "{:.1f}"}
ALPHA_METRICS = ("alpha_abs_mean", "alpha_abs_pooled", "alpha_disp_mean", "alpha_disp_pooled")
STATISTICS = ("n", "mean", "std", "ci95_half", "ci95_low", "ci95_high")
PCA_SOLVER = "projection"
CONFIDENCE = 0.95


def find_records(paths: Iterable[Path]) -> tuple[list[Path], list[Path]]:
    """Run folders under the given paths (each a run folder, a sweep folder or any folder above them).

    Returns
    -------
    complete : list of pathlib.Path
        Folders with a ``done`` marker, sorted.
    incomplete : list of pathlib.Path
        Folders that look like runs (they hold a ``config.yaml`` or ``metrics.json``) but have no marker.
    """
    complete, candidates = set(), set()
    for path in map(Path, paths):
        if not path.exists():
            raise WorkbenchError(f"collect: {path} does not exist")
        complete.update(marker.parent for marker in path.rglob(DONE) if marker.is_file())
        for name in ("config.yaml", "metrics.json"):
            # Hydra's own .hydra/config.yaml is not a run; a folder inside a complete record is part of it
            candidates.update(found.parent for found in path.rglob(name)
                              if not any(part.startswith(".") for part in found.relative_to(path).parts))
    incomplete = {folder for folder in candidates
                  if folder not in complete and not any(parent in complete for parent in folder.parents)}
    return sorted(complete), sorted(incomplete)


def parse_overrides(overrides: Sequence[str]) -> dict:
    """``key=value`` overrides as ``{key: value}`` with Hydra's own parsing (numbers, booleans, null); lists and
    dicts stay as their override text."""
    from hydra.core.override_parser.overrides_parser import OverridesParser

    parsed = {}
    for override in OverridesParser.create().parse_overrides(list(overrides)):
        value = override.value()
        parsed[override.key_or_group] = (override.get_value_element_as_str() if isinstance(value, (list, dict))
                                         else value)
    return parsed


def load_run(folder: Path) -> pd.DataFrame:
    """One run's record as rows of the runs table.

    Parameters
    ----------
    folder : pathlib.Path
        A run folder with ``metrics.json`` and ``timings.json``.

    Returns
    -------
    pandas.DataFrame
        One row per alpha-table row.
    """
    folder = Path(folder)
    try:
        metrics = json.loads((folder / "metrics.json").read_text())
        timings = json.loads((folder / "timings.json").read_text())
    except (OSError, ValueError) as error:
        raise WorkbenchError(f"collect: the record in {folder} is unreadable ({error})") from None
    run = {"study": metrics.get("study"), "sweep": str(folder.parent), "run": folder.name,
           "job_num": metrics.get("job_num"),
           "config_hash": metrics.get("config_hash"), "git_commit": (metrics.get("git") or {}).get("commit"),
           "git_dirty": (metrics.get("git") or {}).get("dirty")}
    # where data is read from and records written to are no conditions of a run
    run.update({key if "." in key else f"cfg.{key}": value
                for key, value in parse_overrides(metrics.get("overrides", [])).items()
                if not key.startswith("paths.")})
    records = []
    for row in metrics["rows"]:
        data = metrics.get("data", {}).get(row.get("data"), {})
        record = dict(run)
        record.update(row)
        record.setdefault("train_on", row.get("data"))
        record.setdefault("eval_on", row.get("data"))
        record.update(n_points=data.get("n_points"), n_train_frames=data.get("n_train_frames"),
                      n_eval_frames=data.get("n_eval_frames"))
        record.update({f"time_{stage}": seconds for stage, seconds in timings.items()})
        records.append(record)
    return pd.DataFrame.from_records(records)


def override_columns(runs: pd.DataFrame) -> list[str]:
    """Columns that came from overrides: their config keys have dots (``basis.coverage``); a key without one (a
    config-group choice such as ``solver=lstsq``) is named ``cfg.<key>``. No other column has a dot."""
    return [column for column in runs.columns if "." in column]


def replicate_columns(columns: Iterable[str]) -> list[str]:
    """Override columns that are replicates (averaged over): those whose last key part names a seed."""
    return [column for column in columns if column.split(".")[-1].endswith("seed")]


def natural_key(value) -> tuple:
    """Sort key: numbers by value, text with embedded numbers naturally (``random3`` before ``random12``),
    missing values last."""
    if _missing(value):
        return (2, ())
    if isinstance(value, (bool, np.bool_)):
        return (0, (float(value),))
    if isinstance(value, (int, float, np.integer, np.floating)):
        return (0, (float(value),))
    return (1, tuple((0, int(part), "") if part.isdigit() else (1, 0, part)
                     for part in re.findall(r"\d+|\D+", str(value))))


def typed_columns(runs: pd.DataFrame, columns: Iterable[str]) -> pd.DataFrame:
    """Give override columns one type each (numbers, booleans or text) so the table writes to Parquet."""
    runs = runs.copy()
    for column in columns:
        values = [value for value in runs[column] if not _missing(value)]
        if values and all(isinstance(value, (bool, np.bool_)) for value in values):
            runs[column] = runs[column].astype("boolean")
        elif values and all(isinstance(value, (int, float, np.integer, np.floating))
                            and not isinstance(value, (bool, np.bool_)) for value in values):
            runs[column] = pd.to_numeric(runs[column])
        else:
            runs[column] = [None if _missing(value) else str(value) for value in runs[column]]
    return runs


def _missing(value) -> bool:
    return value is None or value is pd.NA or (isinstance(value, float) and math.isnan(value))


def collect_runs(paths: Iterable[Path]) -> tuple[pd.DataFrame, list[Path]]:
    """The runs table of every complete record under ``paths``, sorted by condition (natural order).

    Returns
    -------
    runs : pandas.DataFrame
    incomplete : list of pathlib.Path
        Run folders without a completion marker (left out).
    """
    complete, incomplete = find_records(paths)
    if not complete:
        raise WorkbenchError(f"collect: no complete run record (a folder with '{DONE}') under "
                             f"{', '.join(map(str, paths))}")
    runs = pd.concat([load_run(folder) for folder in progress(complete, desc="records")], ignore_index=True)
    # sweep order (Hydra's job numbers follow the study's ranges as written), then natural order of conditions
    sweeps = {sweep: i for i, sweep in enumerate(dict.fromkeys(runs["sweep"]))}
    keys = ["study", "sweep", "job_num"] + override_columns(runs)
    order = sorted(range(len(runs)), key=lambda i: tuple(
        (0, (sweeps[runs["sweep"].iloc[i]],)) if key == "sweep" else natural_key(runs[key].iloc[i])
        for key in keys))
    runs = runs.iloc[order].reset_index(drop=True)
    return typed_columns(runs, override_columns(runs)), incomplete


def t_interval(values: Sequence[float], confidence: float = CONFIDENCE) -> dict:
    """Mean and two-sided Student-t confidence interval of the mean of replicate values (NaNs left out).

    Parameters
    ----------
    values : sequence of float
    confidence : float

    Returns
    -------
    dict
        ``n``, ``mean``, ``std`` (sample, ddof 1), ``ci95_half`` (``t_{(1+c)/2, n-1} std / sqrt(n)``),
        ``ci95_low``, ``ci95_high``; the spread is NaN with fewer than two values.
    """
    from scipy import stats

    values = np.asarray(values, dtype=np.float64)
    values = values[~np.isnan(values)]
    n = int(values.size)
    mean = float(values.mean()) if n else math.nan
    if n < 2:
        std = half = math.nan
    else:
        std = float(values.std(ddof=1))
        half = float(stats.t.ppf(0.5 + confidence / 2.0, n - 1) * std / math.sqrt(n))
    return {"n": n, "mean": mean, "std": std, "ci95_half": half, "ci95_low": mean - half, "ci95_high": mean + half}


def summarise(runs: pd.DataFrame, over: Sequence[str] | None = None) -> pd.DataFrame:
    """Mean and 95 % t-interval of every metric over the replicate overrides, per condition and table row.

    Parameters
    ----------
    runs : pandas.DataFrame
        From :func:`collect_runs`.
    over : sequence of str, optional
        Replicate columns; default the override columns naming a seed (:func:`replicate_columns`).

    Returns
    -------
    pandas.DataFrame
        Long form: the condition columns, :data:`ROW_KEYS`, ``metric``, ``n``, ``mean``, ``std``,
        ``ci95_half``, ``ci95_low``, ``ci95_high``.
    """
    overrides = override_columns(runs)
    over = replicate_columns(overrides) if over is None else list(over)
    unknown = [column for column in over if column not in runs.columns]
    if unknown:
        raise WorkbenchError(f"collect --over: {unknown} are not override columns of these runs ({overrides})")
    keys = ["study"] + [column for column in overrides if column not in over] + list(ROW_KEYS)
    metrics = [column for column in SUMMARY_METRICS if column in runs.columns]
    records = []
    for group_values, group in runs.groupby(keys, sort=False, dropna=False):
        for metric in metrics:
            records.append(dict(zip(keys, group_values), metric=metric,
                                **t_interval(pd.to_numeric(group[metric], errors="coerce").to_numpy(float))))
    return pd.DataFrame.from_records(records)


def format_value(value) -> str:
    """Text of a condition value in a table: ``-`` for missing, ``:g`` for floats."""
    if _missing(value):
        return "-"
    if isinstance(value, (bool, np.bool_)):
        return "true" if value else "false"
    if isinstance(value, (float, np.floating)):
        return f"{value:g}"
    return str(value)


def format_estimate(mean: float, half: float, number_format: str) -> str:
    """``mean ± half`` in a column's number format; just the mean when there is no interval."""
    if math.isnan(mean):
        return "-"
    if math.isnan(half):
        return number_format.format(mean)
    return f"{number_format.format(mean)} ± {number_format.format(half)}"


def alpha_grid(summary: pd.DataFrame, *, metric: str = "alpha_abs_mean", columns: str = "basis",
               where: Mapping[str, str] | None = None, extra: Sequence[str] = ("m",)) -> tuple[list, list, int]:
    """Lay a summary out as a grid: conditions down, ``columns`` across, ``mean ± half-width`` in the cells.

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
        Metrics shown as columns after the row keys (their value in the row's first cell), e.g. ``m``.

    Returns
    -------
    header : list of str
    rows : list of list of str
    n_row_keys : int
        How many leading columns are row keys (text, left-aligned).
    """
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
    candidates = [key for key in table.columns if key not in STATISTICS + (columns, "metric", "projection",
                                                                           "train_on", "eval_on")]
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
            half = found["ci95_half"].iloc[0] if len(found) else math.nan
            line.append(format_estimate(found["mean"].iloc[0], math.nan if half == 0 else half,
                                        EXTRA_FORMATS.get(name, "{:.3f}")) if len(found) else "-")
        for value in column_values:
            name = value if columns == "metric" else metric
            found = group[(group["metric"] == name) & ((columns == "metric") | (group[columns] == value))]
            line.append(format_estimate(found["mean"].iloc[0], found["ci95_half"].iloc[0],
                                        FLOAT_FORMATS.get(name, "{:.3f}")) if len(found) else "-")
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


def caption(summary: pd.DataFrame, metric: str, columns: str, where: Mapping[str, str] | None,
            over: Sequence[str]) -> str:
    """One line naming the metric, the filters and how many replicates each cell averages."""
    counted = ALPHA_METRICS[0] if columns == "metric" else metric
    counts = summary.loc[summary["metric"] == counted, "n"]
    n_text = f"{counts.min()}" if counts.min() == counts.max() else f"{counts.min()}-{counts.max()}"
    what = "alpha (%) by metric" if columns == "metric" else f"{metric} (%)" if metric.startswith("alpha") \
        else metric
    filters = "".join(f", {key} = {value}" for key, value in (where or {}).items())
    replicates = ", ".join(over) if over else "no replicate key"
    return f"{what}{filters}; mean ± half-width of the 95 % t-interval over {replicates} (n = {n_text} per cell)"


def markdown_grid(header: Sequence[str], rows: Sequence[Sequence[str]], n_text: int) -> str:
    """GitHub Markdown of a grid: the first ``n_text`` columns left-aligned, the others right-aligned."""
    widths = [max([len(name)] + [len(row[i]) for row in rows]) for i, name in enumerate(header)]

    def line(values):
        return "| " + " | ".join(value.ljust(width) if i < n_text else value.rjust(width)
                                 for i, (value, width) in enumerate(zip(values, widths))) + " |"

    rule = "|" + "|".join("-" * (width + 2) if i < n_text else "-" * (width + 1) + ":"
                          for i, width in enumerate(widths)) + "|"
    return "\n".join([line(header), rule] + [line(row) for row in rows]) + "\n"


LATEX_SPECIAL = {"\\": r"\textbackslash{}", "&": r"\&", "%": r"\%", "$": r"\$", "#": r"\#", "_": r"\_",
                 "{": r"\{", "}": r"\}", "~": r"\textasciitilde{}", "^": r"\textasciicircum{}"}


def latex_escape(text: str) -> str:
    return "".join(LATEX_SPECIAL.get(character, character) for character in text).replace("±", r"$\pm$")


def latex_grid(header: Sequence[str], rows: Sequence[Sequence[str]], n_text: int, title: str = "") -> str:
    """A booktabs ``tabular`` of a grid (text columns ``l``, value columns ``r``), with ``title`` as a comment."""
    spec = "l" * n_text + "r" * (len(header) - n_text)
    lines = ([f"% {title}"] if title else []) + [
        rf"\begin{{tabular}}{{{spec}}}", r"\toprule",
        " & ".join(latex_escape(name) for name in header) + r" \\", r"\midrule"]
    lines += [" & ".join(latex_escape(cell) for cell in row) + r" \\" for row in rows]
    lines += [r"\bottomrule", r"\end{tabular}"]
    return "\n".join(lines) + "\n"


def parquet_bytes(table: pd.DataFrame) -> bytes:
    buffer = io.BytesIO()
    table.to_parquet(buffer, index=False)
    return buffer.getvalue()


def collect_and_write(paths: Iterable[Path], out: Path, *, metric: str = "alpha_abs_mean",
                      where: Mapping[str, str] | None = None, columns: str = "basis",
                      extra: Sequence[str] = ("m",), over: Sequence[str] | None = None) -> dict:
    """Collect the records under ``paths`` and write the runs table, the summary and the alpha table to ``out``.

    Parameters
    ----------
    paths : iterable of pathlib.Path
        Sweep folders (or run folders, or folders holding several sweeps).
    out : pathlib.Path
    metric, where, columns, extra
        Layout of the alpha table (see :func:`alpha_grid`).
    over : sequence of str, optional
        Replicate columns (default: override columns naming a seed).

    Returns
    -------
    dict
        ``n_runs``, ``n_incomplete``, ``markdown`` (the alpha table's text) and ``files`` (paths written).
    """
    paths = [Path(path) for path in paths]
    runs, incomplete = collect_runs(paths)
    over = replicate_columns(override_columns(runs)) if over is None else list(over)
    summary = summarise(runs, over)
    header, rows, n_text = alpha_grid(summary, metric=metric, columns=columns, where=where, extra=extra)
    title = caption(summary, metric, columns, where, over)
    markdown = title + "\n\n" + markdown_grid(header, rows, n_text)
    out = Path(out)
    files = {"runs.csv": runs.to_csv(index=False), "runs.parquet": parquet_bytes(runs),
             "summary.csv": summary.to_csv(index=False), "summary.parquet": parquet_bytes(summary),
             "alpha_table.md": markdown, "alpha_table.tex": latex_grid(header, rows, n_text, title)}
    for name, content in files.items():
        write_atomic(out / name, content)
    n_runs = int(runs.groupby(["sweep", "run"]).ngroups)
    return {"n_runs": n_runs, "n_incomplete": len(incomplete), "markdown": markdown,
            "files": [out / name for name in files]}


def parse_where(items: Sequence[str]) -> dict:
    where = {}
    for item in items:
        key, separator, value = item.partition("=")
        if not separator or not key:
            raise WorkbenchError(f"collect --where must be KEY=VALUE, got {item!r}")
        where[key] = value
    return where


def main(argv: Sequence[str]) -> int:
    """``workbench collect SWEEP_DIR [SWEEP_DIR ...] [--out DIR] [--metric M] [--where K=V] ...``."""
    parser = argparse.ArgumentParser(
        prog="workbench collect",
        description="Gather run records (folders with a 'done' marker) of one or many sweeps into runs.csv/"
                    ".parquet, summary.csv/.parquet (mean and 95%% t-interval over seeds) and alpha_table.md/.tex.")
    parser.add_argument("paths", nargs="+", type=Path, help="sweep folders, run folders or folders above them")
    parser.add_argument("--out", type=Path, help="output folder (default: <the one path>/collected)")
    parser.add_argument("--metric", default="alpha_abs_mean", help="metric of the alpha table")
    parser.add_argument("--where", action="append", default=[], metavar="KEY=VALUE",
                        help="keep only rows with this value, e.g. solver=lstsq (repeatable)")
    parser.add_argument("--columns", default="basis", help="key whose values become the table's columns")
    parser.add_argument("--extra", default="m", help="comma-separated metrics shown beside the row keys")
    parser.add_argument("--over", help="comma-separated replicate columns (default: the overrides naming a seed)")
    args = parser.parse_args(list(argv))
    if args.out is None and len(args.paths) != 1:
        raise WorkbenchError("collect: give --out when collecting more than one path")
    out = args.out or args.paths[0] / "collected"
    written = collect_and_write(
        args.paths, out, metric=args.metric, where=parse_where(args.where), columns=args.columns,
        extra=[name for name in args.extra.split(",") if name],
        over=None if args.over is None else [name for name in args.over.split(",") if name])
    print(written["markdown"], end="")
    note = f"; {written['n_incomplete']} incomplete run folders left out" if written["n_incomplete"] else ""
    print(f"collected {written['n_runs']} runs into {out}{note}")
    return 0
