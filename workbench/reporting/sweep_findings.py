"""The findings of a sweep or of the other bases, stated in sentences generated from its numbers.

:func:`sweep_statements` says, per swept condition and data variant, the bases from best to worst by their
geometric means over the replicates, each neighbouring pair "A < B" only where the interval of the per-replicate
ratio excludes 1 and "not distinguishable" otherwise, with the interval, its method and n (a cell of the sweep's
comparisons table); :func:`bases_findings` adds the other bases' sizes, closeness and locality. The findings of
one run are in :mod:`workbench.reporting.findings`.
"""

from __future__ import annotations

import math
from typing import Mapping, Sequence

import pandas as pd

from workbench.statistics import RATIO_FORMAT, Interval, comparison_lookup, interval_text, reversed_interval
from workbench.statistics import ordering_text as stated_ordering
from workbench.tables import cell_text

def _comparison(comparisons: pd.DataFrame, first: str, second: str) -> Interval:
    """The paired ratio ``first / second`` from a comparisons table (either orientation), as an interval."""
    for a, b, flip in ((first, second, False), (second, first, True)):
        found = comparisons[(comparisons["first"] == a) & (comparisons["second"] == b)]
        if len(found):
            row = found.iloc[0]
            interval = Interval(float(row["ratio"]), float(row["ratio_low"]), float(row["ratio_high"]),
                                int(row["n"]), str(row["method"]), null=1.0)
            return reversed_interval(interval) if flip else interval
    return Interval(math.nan, math.nan, math.nan, 0, "no paired values", null=1.0)


def pair_text(comparisons: pd.DataFrame, first: str, second: str) -> str:
    """``QE < H (QE/H 0.5212, 95 % interval [0.4601, 0.5804] (paired t on log ratios, n = 5))``, or ``QE and H
    not distinguishable (...)`` when the interval of the paired ratio includes 1: the row of the comparisons
    table, in its orientation (the smaller first)."""
    interval = _comparison(comparisons, first, second)
    if interval.estimate > 1.0:
        first, second, interval = second, first, reversed_interval(interval)
    detail = interval_text(interval, f"{first}/{second}", RATIO_FORMAT)
    if not interval.excludes_null:
        return f"{first} and {second} not distinguishable ({detail})"
    return f"{first} {'<' if interval.sign < 0 else '>'} {second} ({detail})"


def _has(table: pd.DataFrame, column: str) -> bool:
    """Whether a summary has a column's value or its range over the runs."""
    return column in table.columns or f"{column}_min" in table.columns


def _range_text(row, column: str) -> str:
    low, high = row.get(f"{column}_min", row.get(column)), row.get(f"{column}_max", row.get(column))
    return f"{low:g}" if low == high else f"{low:g}-{high:g}"


def ordering_with_intervals(part: pd.DataFrame, comparisons: pd.DataFrame, column: str, key: str = "basis") -> str:
    """The bases of one condition from best to worst by their geometric mean, then each neighbouring pair's paired
    verdict: ``QE 0.162, PCA 0.169, H 0.312; QE and PCA not distinguishable (...); PCA < H (...)``.

    Parameters
    ----------
    part : pandas.DataFrame
        A wide summary's rows of one condition, data variant and solver: ``basis``, ``column`` (geometric mean
        over the replicates) and optionally ``n_min``/``n_max`` (basis sizes; a basis whose size differs from
        the hand basis's is marked with it).
    comparisons : pandas.DataFrame
        The paired comparisons of the same condition (:func:`workbench.reporting.runs.paired_comparisons`).
    column : str
    key : str
        What is ordered: ``basis``, or ``train_on`` (one basis fitted on each data variant).
    """
    ranked = part.dropna(subset=[column]).sort_values(column, kind="stable")
    hand = ranked[ranked["basis"] == "H"] if key == "basis" else ranked.iloc[:0]
    sized = _has(ranked, "n")
    usual = _range_text(hand.iloc[0], "n") if len(hand) and sized else None
    names = []
    for row in ranked.to_dict("records"):
        size = _range_text(row, "n") if sized else None
        names.append(f"{row[key]}{f' (n = {size})' if usual is not None and size != usual else ''} "
                     f"{cell_text(column, row[column])}")
    bases = list(ranked[key])
    pairs = [pair_text(comparisons, first, second) for first, second in zip(bases, bases[1:])]
    return "; ".join([", ".join(names), *pairs])


def _of_solver(summary: pd.DataFrame, comparisons: pd.DataFrame, column: str,
               solver: str) -> tuple[pd.DataFrame, pd.DataFrame]:
    """The summary's rows of a solver (PCA's projection beside it) and the comparisons of ``column`` under it."""
    rows = summary[(summary["solver"] == solver) | (summary["solver"] == "projection")]
    if len(comparisons):
        comparisons = comparisons[(comparisons["solver"] == solver) & (comparisons["metric"] == column)]
    return rows, comparisons


def _matching(comparisons: pd.DataFrame, keys: Sequence[str], values: Sequence) -> pd.DataFrame:
    """The comparisons whose ``keys`` hold ``values`` (compared as text, as a sweep's settings are)."""
    for key, value in zip(keys, values):
        comparisons = comparisons[comparisons[key].astype(str) == str(value)]
    return comparisons


def sweep_findings(summary: pd.DataFrame, comparisons: pd.DataFrame, swept: Sequence[str], column: str,
                   solver: str) -> list[str]:
    """Findings of a sweep, one per swept condition and data variant: m over the runs, the bases from best to
    worst by their geometric mean over the replicates, and for each neighbouring pair "A < B" only where the 95 %
    interval of the per-replicate ratio excludes 1, else "not distinguishable", with the interval, its method and
    n. Every number is a cell of the summary or of the comparisons table.

    Parameters
    ----------
    summary : pandas.DataFrame
        Wide summary (:func:`workbench.reporting.runs.wide`): the swept keys, ``data``, ``basis``, ``solver``,
        ``n_seeds``, ``column``, and ``m_min``/``m_max``, ``n_min``/``n_max`` where present.
    comparisons : pandas.DataFrame
        :func:`workbench.reporting.runs.paired_comparisons` of ``column`` (PCA beside every solver).
    swept : sequence of str
        The condition keys (none: one finding per data variant).
    column : str
    solver : str
        The solver of the findings (PCA is compared beside it).

    Returns
    -------
    list of str
    """
    rows, comparisons = _of_solver(summary, comparisons, column, solver)
    keys = [*swept, "data"]
    lines = []
    for values, part in rows.groupby(keys, sort=False, dropna=False):
        values = values if isinstance(values, tuple) else (values,)
        mine = _matching(comparisons, keys, values)
        setting = ", ".join(f"{key} = {value}" for key, value in zip(swept, values[:-1]))
        first = part.iloc[0]
        m = f"m = {_range_text(first, 'm')}; " if _has(part, "m") else ""
        lines.append(f"{setting + ', ' if setting else ''}**{values[-1]}** ({m}{int(part['n_seeds'].max())} seeds, "
                     f"{solver}): `{column}` geometric means, best first: "
                     + ordering_with_intervals(part, mine, column) + ".")
    return lines


def training_findings(summary: pd.DataFrame, comparisons: pd.DataFrame, swept: Sequence[str], column: str,
                      solver: str) -> list[str]:
    """Findings of a sweep that fitted the bases on several data variants and scored each on common evaluation sets
    (``dataset.eval_on``): per condition, evaluation set and basis, the variants fitted on from best to worst, and
    for each neighbouring pair "A < B" only where the paired interval excludes 1.

    Parameters
    ----------
    summary : pandas.DataFrame
        Wide summary with ``train_on``, ``eval_on``, ``basis``, ``solver``, ``n_seeds`` and ``column``.
    comparisons : pandas.DataFrame
        :func:`workbench.reporting.runs.paired_comparisons` with ``between="train_on"``.
    swept : sequence of str
        The condition keys other than the data variant fitted on.
    column : str
    solver : str

    Returns
    -------
    list of str
    """
    rows, comparisons = _of_solver(summary, comparisons, column, solver)
    keys = [*swept, "eval_on", "basis"]
    lines = []
    for values, part in rows.groupby(keys, sort=False, dropna=False):
        if part["train_on"].nunique() < 2 or values[-1] == "H":  # the hand shapes are not fitted
            continue
        mine = _matching(comparisons, keys, values)
        setting = ", ".join(f"{key} = {value}" for key, value in zip(swept, values[:-2]))
        lines.append(f"{setting + ', ' if setting else ''}scored on **{values[-2]}**, {values[-1]} "
                     f"({int(part['n_seeds'].max())} seeds, {solver}): `{column}` geometric means by the data "
                     "fitted on, best first: " + ordering_with_intervals(part, mine, column, key="train_on") + ".")
    return lines


def bases_findings(summary: pd.DataFrame, comparisons: pd.DataFrame, column: str, ordering: bool = True,
                   run_comparisons: Mapping[str, Sequence[Mapping]] | None = None, solver: str = "lstsq") -> list[str]:
    """Findings of a run or sweep that scored other bases, per data variant: the bases from most to least
    accurate with the paired verdict of each neighbouring pair and the sizes that differ, and which bases are
    closest to the hand shapes and most local, each stated only where the paired interval allows it.

    Parameters
    ----------
    summary : pandas.DataFrame
        One row per data variant and basis: ``data``, ``basis``, ``n_min``, ``n_max``, ``n_seeds``, ``column``,
        ``matched_abs_cosine`` and ``locality`` (geometric means over the runs).
    comparisons : pandas.DataFrame
        Paired comparisons over the runs with ``data``, ``metric`` (``column``, ``matched_abs_cosine``,
        ``locality``) and :data:`workbench.reporting.runs.COMPARISON_COLUMNS`.
    column : str
    ordering : bool
        Whether to state the ordering by ``column`` (a sweep's findings state it already).
    run_comparisons : mapping, optional
        Data variant -> the paired per-frame comparisons of one run (``metrics.json``): the ordering by ``column``
        then comes from them (a block bootstrap over the run's frames), as one run has no replicates to pair.
    solver : str
        The solver of ``column``'s values (PCA: its projection), to find them in ``run_comparisons``.
    """
    lines = []
    for data, part in summary.groupby("data", sort=False):
        mine = comparisons[comparisons["data"] == data]
        if ordering and run_comparisons is not None:
            values = {(basis, "projection" if basis == "PCA" else solver): float(value)
                      for basis, value in zip(part["basis"], part[column])}
            lines.append(f"**{data}** (one run): `{column}` from best to worst: "
                         + stated_ordering(values, comparison_lookup(run_comparisons.get(data, [])),
                                           name=lambda key: key[0]) + ".")
        elif ordering:
            lines.append(f"**{data}** ({int(part['n_seeds'].max())} runs): `{column}` geometric means, best first: "
                         + ordering_with_intervals(part, mine[mine["metric"] == column], column) + ".")
        hand = part[part["basis"] == "H"]
        sizes = {row["basis"]: _range_text(row, "n") for row in part.to_dict("records")}
        other = {basis: size for basis, size in sizes.items() if len(hand) and size != sizes["H"]}
        if other:
            lines.append(f"**{data}**: bases of other sizes than the hand basis's n = {sizes['H']}: "
                         + ", ".join(f"{basis} n = {size}" for basis, size in other.items())
                         + "; their alpha is not that of a basis of the same size.")
        others = part[part["basis"] != "H"]
        for measure, ascending, what in (("matched_abs_cosine", False, "closest to the hand shapes "
                                                                      "(mean matched |cosine|)"),
                                         ("locality", True, "most local (share of the face holding an element's "
                                                            "displacement)")):
            ranked = others.dropna(subset=[measure]).sort_values(measure, ascending=ascending, kind="stable")
            if len(ranked) < 2:
                continue
            best, runner = ranked.iloc[0], ranked.iloc[1]
            verdict = pair_text(mine[mine["metric"] == measure], best["basis"], runner["basis"])
            lead = (f"{best['basis']} {cell_text(measure, best[measure])}, then {runner['basis']} "
                    f"{cell_text(measure, runner[measure])}"
                    + (f" (the hand shapes' {cell_text(measure, hand[measure].iloc[0])})" if len(hand) else ""))
            lines.append(f"**{data}**: {what}: {lead}; {verdict}.")
    return lines


def replicate_caveat(replicates: Sequence[str]) -> list[str]:
    """A finding saying what the intervals cannot cover when no replicate key varies the data (only, say, the
    random starts of a fit): then no statement generalises beyond the one take. Empty otherwise.

    Parameters
    ----------
    replicates : sequence of str
        The replicate (seed) settings of the sweep.
    """
    if any(key.startswith("dataset.") for key in replicates):
        return []
    varied = ", ".join(replicates) or "nothing"
    return [f"The replicates vary {varied} only, not the data: the intervals below cover that, not other takes, "
            "and no finding here generalises beyond this one capture."]


def sweep_statements(summary: pd.DataFrame, comparisons: pd.DataFrame, swept: Sequence[str],
                     columns: Sequence[str], solver: str) -> list[str]:
    """Every finding of a sweep for each of ``columns``: the bases compared (:func:`sweep_findings`), then the
    data variants fitted on where the comparisons hold those (:func:`training_findings`).

    Parameters
    ----------
    summary : pandas.DataFrame
    comparisons : pandas.DataFrame
        :func:`workbench.reporting.runs.sweep_comparisons`.
    swept : sequence of str
    columns : sequence of str
    solver : str
    """
    by_basis = comparisons[comparisons["first"].isin(summary["basis"])] if len(comparisons) else comparisons
    by_variant = comparisons[~comparisons["first"].isin(summary["basis"])] if len(comparisons) else comparisons
    lines = [line for column in columns for line in sweep_findings(summary, by_basis, swept, column, solver)]
    if len(by_variant):
        lines += [line for column in columns for line in training_findings(summary, by_variant, swept, column,
                                                                           solver)]
    return lines
