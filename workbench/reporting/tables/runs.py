"""The tidy runs table of many run records, and its summary over replicates (seeds).

``workbench collect`` and ``workbench report`` both build their tables here, from records read through
:class:`workbench.record.record.RunRecord`, so the two never disagree about the same sweep.
"""

from __future__ import annotations

import math
import re
from pathlib import Path
from typing import Iterable, Mapping, Sequence

import numpy as np
import pandas as pd

from workbench.core.errors import WorkbenchError
from workbench.record.record import DONE, RunRecord, find_records, load_record
from workbench.reporting.tables.cells import is_missing
from workbench.stats.identities import run_identities
from workbench.stats.replicates import PSEUDO_REPLICATES, pseudo_replicate_reason
from workbench.stats.statistics import GEOMETRIC, geometric_interval, paired_ratio_interval, reversed_interval
from workbench.study.table import ALPHA_COLUMNS, CLEAN_COLUMNS

ROW_KEYS = ("data", "train_on", "eval_on", "basis", "projection", "solver")
"""Columns that name one row of a run's alpha table."""
SUMMARY_METRICS = (*ALPHA_COLUMNS, *CLEAN_COLUMNS, "m", "coverage", "n", "n_points", "time_total")
"""Columns of the runs table summarised over replicates (those present)."""
IGNORED_KEYS = ("paths.", "save_inputs", "hydra", "study")
"""Config keys that differ between runs without being a studied setting."""
REPLICATE_SUFFIX = "seed"
"""Settings whose runs are replicates of one another: every seed (of the data, of a random draw of shapes)."""
STATISTICS = ("n", "mean", "std", "min", "max", "geomean", "ci95_low", "ci95_high", "ci_method")
"""Columns of a long summary: replicates, arithmetic mean, sample standard deviation, range, and the geometric
mean with its 95 % interval (:func:`workbench.stats.statistics.geometric_interval`) and the interval's
method."""
PCA_SOLVER = "projection"


def flatten(config: Mapping, prefix: str = "") -> dict:
    """Nested config -> ``{"dotted.key": value}``; lists become their text (``[markers, mesh]``)."""
    flat = {}
    for key, value in config.items():
        name = f"{prefix}{key}"
        if isinstance(value, Mapping):
            flat.update(flatten(value, f"{name}."))
        elif isinstance(value, list):
            flat[name] = "[" + ", ".join(str(item) for item in value) + "]"
        else:
            flat[name] = value
    return flat


def is_replicate_key(key: str) -> bool:
    """Whether runs differing in this setting are replicates (``dataset.seed``, ``basis.subset_seed``, ...)."""
    return key.rsplit(".", 1)[-1].endswith(REPLICATE_SUFFIX)


def varying_keys(configs: Sequence[Mapping]) -> list[str]:
    """Config keys whose value differs between runs, in config order, leaving out paths and the like."""
    flat = [flatten(config) for config in configs]
    keys = list(dict.fromkeys(key for config in flat for key in config))
    return [
        key for key in keys if not key.startswith(IGNORED_KEYS) and len({repr(config.get(key)) for config in flat}) > 1
    ]


def natural_key(value) -> tuple:
    """Sort key: numbers by value, text with embedded numbers naturally (``random3`` before ``random12``),
    missing values last."""
    if is_missing(value):
        return (2, ())
    if isinstance(value, (bool, np.bool_, int, float, np.integer, np.floating)):
        return (0, (float(value),))
    return (
        1,
        tuple((0, int(part), "") if part.isdigit() else (1, 0, part) for part in re.findall(r"\d+|\D+", str(value))),
    )


def config_columns(runs: pd.DataFrame) -> list[str]:
    """The columns holding config values: their keys have dots (``basis.coverage``); no other column has one."""
    return [column for column in runs.columns if "." in column]


def replicate_columns(columns: Iterable[str]) -> list[str]:
    """Config columns that are replicates (averaged over): those whose last key part names a seed."""
    return [column for column in columns if is_replicate_key(column)]


def typed_columns(runs: pd.DataFrame, columns: Iterable[str]) -> pd.DataFrame:
    """Give config columns one type each (numbers, booleans or text) so the table writes to Parquet."""
    runs = runs.copy()
    for column in columns:
        values = [value for value in runs[column] if not is_missing(value)]
        if values and all(isinstance(value, (bool, np.bool_)) for value in values):
            runs[column] = runs[column].astype("boolean")
        elif values and all(
            isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, (bool, np.bool_))
            for value in values
        ):
            runs[column] = pd.to_numeric(runs[column])
        else:
            runs[column] = [None if is_missing(value) else str(value) for value in runs[column]]
    return runs


def record_rows(record: RunRecord, keys: Sequence[str], root: Path | None = None) -> list[dict]:
    """One run's rows of the runs table: the run's identity, its values of ``keys``, then per alpha-table row
    that row's values, the data variant's sizes and the stage timings."""
    flat = flatten(record.config)
    run = {
        "study": record.study,
        "sweep": str(record.folder.parent),
        "run": str(record.folder.relative_to(root)) if root is not None else record.folder.name,
        "job_num": record.job_num,
        "config_hash": record.config_hash,
        "git_commit": record.git.get("commit"),
        "git_dirty": record.git.get("dirty"),
    }
    run.update({key: flat.get(key) for key in keys})
    rows = []
    never_worse = never_worse_than(record)
    for row in record.rows():
        data = record.metrics["data"].get(row["data"], {})
        entry = {**run, **{key: value for key, value in row.items() if not isinstance(value, (dict, list))}}
        entry[NEVER_WORSE_COLUMN] = never_worse.get((row["data"], row["basis"], row["solver"]), "-")
        entry.setdefault("train_on", row["data"])
        entry.setdefault("eval_on", row["data"])
        entry.update(
            n_points=data.get("n_points"),
            n_train_frames=data.get("n_train_frames"),
            n_eval_frames=data.get("n_eval_frames"),
        )
        entry.update({f"time_{stage}": seconds for stage, seconds in record.timings.items()})
        rows.append(entry)
    return rows


NEVER_WORSE_COLUMN = "never_worse_than"
"""The runs table's column listing, per row, the rows of its data variant it can never be worse than by
construction (:func:`never_worse_than`)."""
POOLED_ONLY = " (pooled)"


def never_worse_than(record: RunRecord) -> dict:
    """Per row of a run, the rows of the same data variant it can never be worse than by construction
    (:func:`workbench.stats.identities.run_identities`), as text: ``basis/solver`` items joined by ``;``, an item
    followed by :data:`POOLED_ONLY` where the ordering holds for the pooled alphas only.

    Returns
    -------
    dict
        ``(data, basis, solver)`` -> the text (rows with none are left out; the runs table writes ``-``, which a
        CSV file keeps, where an empty text would come back as a missing value).
    """
    rows = record.rows()
    solvers = record.config.get("solver")  # each solver's kind and bounds: they decide the solvers' nesting
    found: dict = {}
    for data, facts in (record.metrics.get("data") or {}).items():
        for identity in run_identities([row for row in rows if row.get("data") == data], facts, solvers):
            key = (data, *identity.smaller)
            item = "/".join(identity.larger) + (POOLED_ONLY if identity.pooled_only else "")
            found[key] = f"{found[key]};{item}" if key in found else item
    return found


def holds_by_construction(group: pd.DataFrame, first: str, second: str, metric: str, between: str = "basis") -> bool:
    """Whether ``first <= second`` holds by construction in every replicate of a comparison's group (the rows of
    one condition, data variant and solver): the runs table's :data:`NEVER_WORSE_COLUMN` of ``first``'s row lists
    ``second``'s row in each run. Scores against other frames than those reconstructed (``clean_*``) hold none.
    """
    if between != "basis" or metric.startswith("clean_") or NEVER_WORSE_COLUMN not in group.columns:
        return False
    pooled = "pooled" in metric
    replicates = group.groupby(["sweep", "run"], sort=False)
    for _, runs_rows in replicates:
        mine, other = runs_rows[runs_rows["basis"] == first], runs_rows[runs_rows["basis"] == second]
        if len(mine) != 1 or len(other) != 1:
            return False
        text = mine[NEVER_WORSE_COLUMN].iloc[0]
        listed = [item for item in text.split(";") if item] if isinstance(text, str) else []
        allowed = {item.removesuffix(POOLED_ONLY) for item in listed if pooled or not item.endswith(POOLED_ONLY)}
        larger = other.iloc[0]
        if f"{second}/{larger['solver']}" not in allowed and f"{second}/{PCA_SOLVER}" not in allowed:
            return False
    return len(replicates) > 0


def runs_table(records: Sequence[RunRecord], root: Path | None = None) -> pd.DataFrame:
    """Every alpha-table row of every run, one row each: the tidy runs table.

    Parameters
    ----------
    records : sequence of RunRecord
    root : pathlib.Path, optional
        Run names are paths relative to it (default: the run folders' names).

    Returns
    -------
    pandas.DataFrame
        ``study``, ``sweep``, ``run``, ``job_num``, ``config_hash``, ``git_commit``, ``git_dirty``, the config
        keys that differ between the runs (dotted names, typed), :data:`ROW_KEYS`, the alpha-table columns, the
        solver diagnostics, ``n_points``, ``n_train_frames``, ``n_eval_frames`` and ``time_<stage>``; sorted by
        sweep, then the sweep's job order, then the config values in natural order.
    """
    if not records:
        raise WorkbenchError("no run records to tabulate")
    keys = varying_keys([record.config for record in records])
    runs = pd.DataFrame.from_records([row for record in records for row in record_rows(record, keys, root)])
    sweeps = {sweep: i for i, sweep in enumerate(dict.fromkeys(runs["sweep"]))}
    order_keys = ["study", "sweep", "job_num", *keys]
    order = sorted(
        range(len(runs)),
        key=lambda i: tuple(
            (0, (sweeps[runs["sweep"].iloc[i]],)) if key == "sweep" else natural_key(runs[key].iloc[i])
            for key in order_keys
        ),
    )
    runs = runs.iloc[order].reset_index(drop=True)
    return typed_columns(runs, keys)


def collect_runs(paths: Iterable[Path]) -> tuple[pd.DataFrame, list[Path]]:
    """The runs table of every complete record under ``paths``.

    Returns
    -------
    runs : pandas.DataFrame
    incomplete : list of pathlib.Path
        Run folders without a completion marker (left out).
    """
    runs, incomplete, _ = collect_records(paths)
    return runs, incomplete


def collect_records(paths: Iterable[Path]) -> tuple[pd.DataFrame, list[Path], list[RunRecord]]:
    """:func:`collect_runs` with the records it read (their stored claims, for the findings)."""
    from workbench.core.progress import progress

    paths = [Path(path) for path in paths]
    complete, incomplete = find_records(paths)
    if not complete:
        raise WorkbenchError(f"no complete run record (a folder with '{DONE}') under {', '.join(map(str, paths))}")
    records = [load_record(folder) for folder in progress(complete, desc="records")]
    root = paths[0] if len(paths) == 1 and paths[0] not in complete else None
    return runs_table(records, root), incomplete, records


def interval_label(table: pd.DataFrame, replicates: str = "seeds") -> str:
    """``95 % interval: geometric mean, t-interval on log values; n = 5 seeds``: the method and replicate count
    of a summary's intervals (its ``ci_method`` and ``n_seeds``), named beside every interval shown or drawn."""
    method = (
        str(table["ci_method"].dropna().iloc[0])
        if "ci_method" in table.columns and table["ci_method"].notna().any()
        else GEOMETRIC
    )
    counts = table["n_seeds"].dropna().astype(int) if "n_seeds" in table.columns else pd.Series([], dtype=int)
    n_text = (
        ""
        if counts.empty
        else "; n = "
        + (f"{counts.min()}" if counts.min() == counts.max() else f"{counts.min()}-{counts.max()}")
        + f" {replicates}"
    )
    return f"95 % interval: {method}{n_text}"


def level_statistics(values) -> dict:
    """The summary of one metric over replicates: ``n``, ``mean``, ``std`` (ddof 1), ``min``, ``max``, and the
    geometric mean with its 95 % interval (``geomean``, ``ci95_low``, ``ci95_high``, ``ci_method``; see
    :func:`workbench.stats.statistics.geometric_interval`).

    Parameters
    ----------
    values : array_like of shape (n,)
        One value per replicate; NaNs left out.
    """
    values = np.asarray(values, dtype=np.float64)
    values = values[np.isfinite(values)]
    interval = geometric_interval(values)
    return {
        "n": int(values.size),
        "mean": float(values.mean()) if values.size else np.nan,
        "std": float(values.std(ddof=1)) if values.size > 1 else np.nan,
        "min": float(values.min()) if values.size else np.nan,
        "max": float(values.max()) if values.size else np.nan,
        "geomean": interval.estimate,
        "ci95_low": interval.low,
        "ci95_high": interval.high,
        "ci_method": interval.method,
    }


def condition_keys(runs: pd.DataFrame, over: Sequence[str] | None) -> tuple[list[str], list[str]]:
    """The config columns that make a condition, and the replicate columns (``over``, default those naming a
    seed), checked against the runs table."""
    conditions = config_columns(runs)
    over = replicate_columns(conditions) if over is None else list(over)
    unknown = [column for column in over if column not in runs.columns]
    if unknown:
        raise WorkbenchError(f"--over: {unknown} are not config columns of these runs ({conditions})")
    return [column for column in conditions if column not in over], over


def not_replicates_reason(runs: pd.DataFrame, over: Sequence[str] | None = None) -> str:
    """Why the runs of a table are not replicates, "" when they are: per condition, the replicate columns that vary
    within it (:func:`workbench.stats.replicates.pseudo_replicate_reason`), each distinct reason once. A figure
    of these runs says it beside its bands and bars, as the comparisons table does in ``pseudo_replicates``."""
    conditions, over = condition_keys(runs, over)
    groups = runs.groupby(conditions, sort=False, dropna=False) if conditions else [((), runs)]
    reasons = []
    for _, group in groups:
        varying = [column for column in over if group[column].nunique(dropna=False) > 1]
        reasons.append(pseudo_replicate_reason(varying, group.iloc[0].to_dict()))
    return "; ".join(dict.fromkeys(reason for reason in reasons if reason))


def summarise(
    runs: pd.DataFrame,
    over: Sequence[str] | None = None,
    metrics: Sequence[str] = SUMMARY_METRICS,
    row_keys: Sequence[str] = ROW_KEYS,
) -> pd.DataFrame:
    """Every metric over the replicate settings, per condition and table row: mean, range, and the geometric mean
    with its 95 % interval, which stays positive (:func:`level_statistics`).

    Parameters
    ----------
    runs : pandas.DataFrame
        From :func:`runs_table`.
    over : sequence of str, optional
        Replicate columns; default the config columns naming a seed (:func:`replicate_columns`).
    metrics : sequence of str
        Columns to summarise (those present).
    row_keys : sequence of str
        Columns naming a row within a condition.

    Returns
    -------
    pandas.DataFrame
        Long form: ``study``, the condition columns, ``row_keys``, ``metric``, then :data:`STATISTICS`.
    """
    conditions, over = condition_keys(runs, over)
    keys = ["study", *conditions, *row_keys]
    present = [column for column in metrics if column in runs.columns]
    records = []
    for group_values, group in runs.groupby(keys, sort=False, dropna=False):
        for metric in present:
            records.append(
                dict(
                    zip(keys, group_values),
                    metric=metric,
                    **level_statistics(pd.to_numeric(group[metric], errors="coerce").to_numpy(float)),
                )
            )
    return pd.DataFrame.from_records(records)


def wide(summary: pd.DataFrame) -> pd.DataFrame:
    """A long summary as one row per condition and table row: per metric its geometric mean, ``<metric>_ci_low``,
    ``<metric>_ci_high``, ``<metric>_min`` and ``<metric>_max``; ``n_seeds`` (the replicate count of the first
    metric) and ``ci_method``."""
    keys = [column for column in summary.columns if column not in (*STATISTICS, "metric")]
    records = []
    for values, group in summary.groupby(keys, sort=False, dropna=False):
        row = dict(zip(keys, values), n_seeds=int(group["n"].iloc[0]), ci_method=GEOMETRIC)
        for entry in group.itertuples(index=False):
            row.update(
                {
                    entry.metric: entry.geomean,
                    f"{entry.metric}_ci_low": entry.ci95_low,
                    f"{entry.metric}_ci_high": entry.ci95_high,
                    f"{entry.metric}_min": entry.min,
                    f"{entry.metric}_max": entry.max,
                }
            )
        records.append(row)
    return pd.DataFrame.from_records(records)


COMPARISON_COLUMNS = (
    "metric",
    "first",
    "second",
    "n",
    "ratio",
    "ratio_low",
    "ratio_high",
    "method",
    "verdict",
    "p",
    "by_construction",
    "pseudo_replicates",
)
"""Columns of :func:`paired_comparisons` after the condition and row keys."""
NOT_DISTINGUISHABLE = "not distinguishable"
BY_CONSTRUCTION = "<= by construction"


def construction_reason(smaller: str, larger: str = "PCA") -> str:
    """Why a basis comparison holds by construction in every replicate (:func:`holds_by_construction`): QE spans
    PCA's affine subspace, or QE-linear's shapes (which lie in PCA's eigenface span), or PCA is the Eckart-Young
    optimum."""
    if smaller == "PCA":
        return "Eckart-Young on the training frames, n <= m in every run"
    if larger == "QE-linear":
        return "QE's affine shapes span mu + span(eigenfaces), which holds QE-linear's shapes, rank m + 1 in every run"
    return "QE spans PCA's affine subspace, rank m + 1 in every run"


def with_pca_beside_every_solver(runs: pd.DataFrame) -> pd.DataFrame:
    """The rows with PCA's (solver ``projection``: it has no solver) repeated under every solver present, so that
    PCA is compared and shown beside each solver's bases."""
    if "solver" not in runs.columns:
        return runs
    solvers = [solver for solver in dict.fromkeys(runs["solver"]) if solver != PCA_SOLVER]
    pca = runs[runs["solver"] == PCA_SOLVER]
    if not solvers or pca.empty:
        return runs
    parts = [runs[runs["solver"] != PCA_SOLVER]] + [pca.assign(solver=solver) for solver in solvers]
    return pd.concat(parts, ignore_index=True)


IMPLIED_KEYS = {"basis": ("projection",), "train_on": ("data", "dataset.train_on")}
"""Columns a compared key determines (the projection goes with the basis label; the data variant and the
setting with the variant the bases were fitted on)."""


def paired_comparisons(
    runs: pd.DataFrame,
    metric: str,
    over: Sequence[str] | None = None,
    row_keys: Sequence[str] = ROW_KEYS,
    between: str = "basis",
) -> pd.DataFrame:
    """Every pair of bases (or of the variants they were fitted on) compared on the same replicates, per condition:
    the geometric mean of the per-replicate ratio ``first / second`` and its 95 % interval
    (:func:`workbench.stats.statistics.paired_ratio_interval`), and the verdict it allows. Each pair is
    written with the smaller geometric mean first (ratio at most 1), as the findings state it.

    Parameters
    ----------
    runs : pandas.DataFrame
        From :func:`runs_table`.
    metric : str
        The (positive) metric compared, e.g. ``alpha_abs_mean``.
    over : sequence of str, optional
        Replicate columns (default: the config columns naming a seed); values are paired by them.
    row_keys : sequence of str
        Columns naming a row within a condition; every one but ``between`` and what it implies is held fixed.
    between : {"basis", "train_on"}
        What is compared: the bases of one data variant, or one basis fitted on each data variant and scored on
        the same evaluated one (``eval_on``, held fixed).

    Returns
    -------
    pandas.DataFrame
        ``study``, the condition columns, the row keys held fixed, then :data:`COMPARISON_COLUMNS`: ``first`` and
        ``second`` the smaller and the larger by their geometric mean ratio (values of ``between``), ``n`` the
        replicates both have, ``verdict`` ``<`` (the interval lies below 1), :data:`NOT_DISTINGUISHABLE` or
        :data:`BY_CONSTRUCTION` (the ordering holds in every replicate whatever the data,
        :func:`holds_by_construction`: its reason in ``by_construction``, no test and no p-value), or
        :data:`workbench.stats.replicates.PSEUDO_REPLICATES` when the runs differ only in seeds that leave the data
        the same (an optimiser's start: its reason in ``pseudo_replicates``, no test and no p-value), ``p`` the
        two-sided p-value of the same paired t on the log ratios (for :func:`workbench.stats.statistics.holm`).
    """
    if metric not in runs.columns:
        raise WorkbenchError(f"no column {metric!r} to compare")
    if between not in IMPLIED_KEYS:
        raise WorkbenchError(f"comparisons are between one of {list(IMPLIED_KEYS)}, got {between!r}")
    conditions, over = condition_keys(runs, over)
    implied = (between, *IMPLIED_KEYS[between])
    fixed = [key for key in row_keys if key not in implied and key in runs.columns]
    keys = ["study", *[key for key in conditions if key not in implied], *fixed]
    records = []
    for group_values, group in with_pca_beside_every_solver(runs).groupby(keys, sort=False, dropna=False):
        replicate = group[over].astype(str).agg(" ".join, axis=1) if over else ""
        table = group.assign(_replicate=replicate).pivot_table(
            index="_replicate", columns=between, values=metric, aggfunc="first", sort=False, dropna=False
        )
        bases = list(dict.fromkeys(group[between]))
        varying = [column for column in over if group[column].nunique(dropna=False) > 1]
        pseudo = pseudo_replicate_reason(varying, group.iloc[0].to_dict())
        for i, first in enumerate(bases):
            for second in bases[i + 1 :]:
                interval = paired_ratio_interval(table[first].to_numpy(float), table[second].to_numpy(float))
                lower, higher = (first, second) if not interval.estimate > 1.0 else (second, first)
                if lower != first:
                    interval = reversed_interval(interval)
                verdict = "<" if interval.excludes_null else NOT_DISTINGUISHABLE
                reason, p_value = None, interval.p_value
                if pseudo:  # the spread is an optimiser's jitter on one data set: no "<", no test
                    verdict, p_value = PSEUDO_REPLICATES, math.nan
                if holds_by_construction(group, higher, lower, metric, between):  # equal within rounding
                    lower, higher, interval = higher, lower, reversed_interval(interval)
                if holds_by_construction(group, lower, higher, metric, between):
                    verdict, reason, p_value = BY_CONSTRUCTION, construction_reason(lower, higher), math.nan
                records.append(
                    dict(
                        zip(keys, group_values),
                        metric=metric,
                        first=lower,
                        second=higher,
                        n=interval.n,
                        ratio=interval.estimate,
                        ratio_low=interval.low,
                        ratio_high=interval.high,
                        method=interval.method,
                        verdict=verdict,
                        p=p_value,
                        by_construction=reason,
                        pseudo_replicates=pseudo or None,
                    )
                )
    return pd.DataFrame.from_records(records, columns=[*keys, *COMPARISON_COLUMNS])


def fitted_on_several(runs: pd.DataFrame) -> bool:
    """Whether the runs scored bases fitted on several data variants on the same evaluated one (eval_on)."""
    return bool(
        {"train_on", "eval_on"} <= set(runs.columns) and (runs.groupby("eval_on")["train_on"].nunique() > 1).any()
    )


def sweep_comparisons(runs: pd.DataFrame, metrics: Sequence[str], over: Sequence[str] | None = None) -> pd.DataFrame:
    """The paired comparisons of a sweep for each metric (those present): between the bases, and where the bases
    were fitted on several data variants and scored on common ones, between those variants
    (:func:`paired_comparisons`); the rows of one kind leave the other's key columns empty."""
    present = [metric for metric in metrics if metric in runs.columns]
    kinds = ["basis", "train_on"] if fitted_on_several(runs) else ["basis"]
    parts = [paired_comparisons(runs, metric, over, between=kind) for kind in kinds for metric in present]
    return pd.concat(parts, ignore_index=True) if parts else pd.DataFrame(columns=list(COMPARISON_COLUMNS))
