"""The findings of a sweep or of the other bases, stated in sentences generated from its numbers.

:func:`sweep_statements` says, per swept condition and data variant, the bases from best to worst by their
geometric means over the replicates, each neighbouring pair "A < B" only where the paired per-replicate ratio's
verdict allows it and "A ~ B" otherwise, and the primary contrasts (QE against H and against PCA) with their
intervals; every other ratio, interval and p-value is a row of the sweep's comparisons table. :func:`holm_verdicts`
decides the verdicts by Holm's adjustment within two families: the primary contrasts of every condition together,
every other tested comparison of the table together; orderings that hold by construction are a third kind, not
tested. :func:`bases_findings` adds the other bases' sizes, closeness and locality.
The findings of one run are in :mod:`workbench.reporting.findings.run`.
"""

from __future__ import annotations

import math
from typing import Mapping, Sequence

import pandas as pd

from workbench.reporting.findings.run import Detail
from workbench.reporting.tables.cells import cell_text
from workbench.reporting.tables.runs import NOT_DISTINGUISHABLE
from workbench.stats.replicates import PSEUDO_REPLICATES
from workbench.stats.statistics import (
    CONFIDENCE,
    Interval,
    holm,
    reversed_interval,
    short_interval_text,
)
from workbench.stats.statistics import ordering_text as stated_ordering
from workbench.stats.stored import comparison_lookup

PRIMARY_PAIRS = (("QE", "H"), ("QE", "PCA"))
"""The paper's claims: QE against H and against PCA (least squares, the headline alpha, the lead data variant) at
every swept condition, one pre-declared Holm family; every other comparison is a second family."""
HOLM_COLUMN = "p_holm"
"""The comparisons table's column with the p-value Holm-adjusted within its family (NaN for an identity)."""
FAMILY_COLUMN = "family"
"""The comparisons table's column naming each row's family: :data:`PRIMARY`, :data:`SECONDARY` or :data:`IDENTITY`."""
PRIMARY, SECONDARY, IDENTITY = "primary", "secondary", "identity"
"""The families: the primary contrasts (Holm over the conditions together), every other test (Holm within the
report), and the orderings that hold by construction (no test, no p-value)."""
INTERVAL_NOTE = "95 % interval, unadjusted; verdict by Holm"
"""What the comparisons' intervals are, said beside them: their verdicts use the Holm-adjusted p-value."""


def is_primary(row: Mapping, column: str, lead: str | None, solver: str = "lstsq") -> bool:
    """Whether a row of a sweep's comparisons table is a primary contrast (:data:`PRIMARY_PAIRS`)."""
    pair = {row.get("first"), row.get("second")}
    return (
        row.get("metric") == column
        and row.get("solver", solver) == solver
        and row.get("data") == lead
        and any(pair == set(primary) for primary in PRIMARY_PAIRS)
    )


def comparison_families(comparisons: pd.DataFrame, column: str, solver: str = "lstsq") -> list[str]:
    """Each row's family: :data:`IDENTITY` where it holds by construction (its ``by_construction`` reason),
    :data:`PRIMARY` for a primary contrast (:func:`is_primary`, on the table's first data variant), else
    :data:`SECONDARY`."""
    lead = next(iter(comparisons["data"].dropna()), None) if "data" in comparisons.columns else None
    return [
        IDENTITY
        if isinstance(row.get("by_construction"), str) and row["by_construction"] not in ("", "-")
        else PRIMARY
        if is_primary(row, column, lead, solver)
        else SECONDARY
        for row in comparisons.to_dict("records")
    ]


def holm_verdicts(comparisons: pd.DataFrame, column: str, solver: str = "lstsq") -> pd.DataFrame:
    """A sweep's comparisons table with its families (:func:`comparison_families`) and Holm's adjustment within
    each: the primary contrasts of every condition are one family, every other tested row the other; each row's
    Holm-adjusted p-value goes into :data:`HOLM_COLUMN` (:func:`workbench.stats.statistics.holm`) and its
    ``verdict`` is ``<`` only where that is below 0.05. An identity keeps its verdict, and has no p-value.

    Parameters
    ----------
    comparisons : pandas.DataFrame
        :func:`workbench.reporting.tables.runs.sweep_comparisons`: ``first``, ``second``, ``metric``, ``ratio``,
        ``ratio_low``, ``ratio_high``, ``verdict``, ``p`` and, per row, its condition, ``data`` and ``solver``.
    column : str
        The headline alpha column (that of the primary contrasts).
    solver : str

    Returns
    -------
    pandas.DataFrame
        A copy with :data:`HOLM_COLUMN` and :data:`FAMILY_COLUMN` after ``p``.
    """
    table = comparisons.copy()
    if table.empty or "p" not in table.columns:
        return table.assign(**{HOLM_COLUMN: pd.Series(dtype=float), FAMILY_COLUMN: pd.Series(dtype=str)})
    families = comparison_families(table, column, solver)
    adjusted = pd.Series(math.nan, index=table.index)
    for name in (PRIMARY, SECONDARY):
        family = [k for k, found in enumerate(families) if found == name]
        adjusted.iloc[family] = holm(table["p"].iloc[family].to_numpy(float))
        for k in family:
            if table["verdict"].iloc[k] == PSEUDO_REPLICATES:  # no test over pseudo-replicates
                continue
            interval = Interval(
                float(table["ratio"].iloc[k]),
                float(table["ratio_low"].iloc[k]),
                float(table["ratio_high"].iloc[k]),
                null=1.0,
                p_adjusted=float(adjusted.iloc[k]),
            )
            table.iloc[k, table.columns.get_loc("verdict")] = "<" if interval.excludes_null else NOT_DISTINGUISHABLE
    at = table.columns.get_loc("p") + 1
    table.insert(at, HOLM_COLUMN, adjusted)
    table.insert(at + 1, FAMILY_COLUMN, families)
    return table


def family_sizes(comparisons: pd.DataFrame) -> dict:
    """Rows per family of a comparisons table (:data:`FAMILY_COLUMN`): ``{"primary": k, "secondary": k,
    "identity": k}``, zero for a family without rows."""
    found = comparisons[FAMILY_COLUMN].value_counts() if FAMILY_COLUMN in comparisons.columns else {}
    return {name: int(found.get(name, 0)) for name in (PRIMARY, SECONDARY, IDENTITY)}


def rows_text(count: int) -> str:
    """``1 row``, ``3 rows``."""
    return f"{count} row{'' if count == 1 else 's'}"


def holm_text(comparisons: pd.DataFrame, column: str, solver: str = "lstsq") -> str:
    """The sentence that says, once, how a sweep's orderings are decided: the method of the intervals, the two
    Holm families and their sizes, and the identities (:func:`holm_verdicts`)."""
    method = comparisons["method"].iloc[0] if len(comparisons) else "-"
    n = int(comparisons["n"].max()) if len(comparisons) else 0
    sizes = family_sizes(comparisons)
    lead = next(iter(comparisons["data"].dropna()), "-") if "data" in comparisons.columns else "-"
    return (
        f"**how to read**: levels: geometric means over the replicates; 'A < B': A/B per replicate ({method}, "
        f"n = {n}) below 1 by its {HOLM_COLUMN} < {1 - CONFIDENCE:.2g}, Holm within its family: the primary QE/H "
        f"and QE/PCA (`{column}`, {solver}, {lead}, each condition; {rows_text(sizes[PRIMARY])}) or the others "
        f"({rows_text(sizes[SECONDARY])}); intervals: {INTERVAL_NOTE}; '~': not distinguishable; '=': a tie; "
        f"'A <= B by construction' ({rows_text(sizes[IDENTITY])}): holds in every replicate, not tested; each "
        "number is a row of comparisons.csv."
    )


def comparison_interval(comparisons: pd.DataFrame, first: str, second: str) -> Interval:
    """The paired ratio ``first / second`` from a comparisons table (either orientation), as an interval."""
    for a, b, flip in ((first, second, False), (second, first, True)):
        found = comparisons[(comparisons["first"] == a) & (comparisons["second"] == b)]
        if len(found):
            row = found.iloc[0]
            adjusted = float(row[HOLM_COLUMN]) if HOLM_COLUMN in row.index else math.nan
            pseudo = row.get("pseudo_replicates")
            interval = Interval(
                float(row["ratio"]),
                float(row["ratio_low"]),
                float(row["ratio_high"]),
                int(row["n"]),
                str(row["method"]),
                null=1.0,
                p_adjusted=adjusted,
                not_estimable=f"not replicates: {pseudo}" if isinstance(pseudo, str) and pseudo else "",
            )
            return reversed_interval(interval) if flip else interval
    return Interval(math.nan, math.nan, math.nan, 0, "no paired values", null=1.0)


def pair_text(comparisons: pd.DataFrame, first: str, second: str) -> str:
    """``QE < H (QE/H 0.521 [0.46, 0.58])``, or ``QE and H not distinguishable (...)`` when the comparison's verdict
    (its interval, or its Holm-adjusted p-value where there is one) does not exclude 1: the row of the comparisons
    table, in its orientation (the smaller first); its method is said once, above the findings."""
    interval = comparison_interval(comparisons, first, second)
    if interval.estimate > 1.0:
        first, second, interval = second, first, reversed_interval(interval)
    detail = short_interval_text(interval, f"{first}/{second}", "{:.3g}")
    reason = construction(comparisons, first, second)
    if reason:
        return f"{first} <= {second} by construction ({reason}; {detail})"
    if not interval.excludes_null:
        return f"{first} and {second} not distinguishable ({detail})"
    return f"{first} {'<' if interval.sign < 0 else '>'} {second} ({detail})"


def _has(table: pd.DataFrame, column: str) -> bool:
    """Whether a summary has a column's value or its range over the runs."""
    return column in table.columns or f"{column}_min" in table.columns


def _range_text(row, column: str) -> str:
    low, high = row.get(f"{column}_min", row.get(column)), row.get(f"{column}_max", row.get(column))
    return f"{low:g}" if low == high else f"{low:g}-{high:g}"


def ordering_with_intervals(
    part: pd.DataFrame, comparisons: pd.DataFrame, column: str, key: str = "basis", primary: bool = False
) -> str:
    """The bases of one condition from best to worst by their geometric mean, each neighbouring pair joined by its
    verdict in the comparisons table (``<``, ``~`` not distinguishable, ``=`` a tie, ``,`` no comparison), then
    (with ``primary``) the primary contrasts with their intervals: ``QE 0.162 ~ PCA (n = 9-11) 0.169 < H 0.312;
    QE/H 0.52 [0.46, 0.58], QE/PCA 0.959 [0.9, 1.02]``.

    Parameters
    ----------
    part : pandas.DataFrame
        A wide summary's rows of one condition, data variant and solver: ``basis``, ``column`` (geometric mean
        over the replicates) and optionally ``n_min``/``n_max`` (basis sizes; a basis whose size differs from
        the hand basis's is marked with it).
    comparisons : pandas.DataFrame
        The paired comparisons of the same condition (:func:`workbench.reporting.tables.runs.paired_comparisons`, with
        :func:`holm_verdicts`' adjusted p-values where it was applied).
    column : str
    key : str
        What is ordered: ``basis``, or ``train_on`` (one basis fitted on each data variant).
    primary : bool
        Whether this condition holds the primary contrasts (:data:`PRIMARY_PAIRS`), stated with their intervals.
    """
    ranked = part.dropna(subset=[column]).sort_values(column, kind="stable")
    hand = ranked[ranked["basis"] == "H"] if key == "basis" else ranked.iloc[:0]
    sized = _has(ranked, "n")
    usual = _range_text(hand.iloc[0], "n") if len(hand) and sized else None
    names = {}
    for row in ranked.to_dict("records"):
        size = _range_text(row, "n") if sized else None
        names[row[key]] = f"{row[key]}{f' (n = {size})' if usual is not None and size != usual else ''}"

    def compare(first, second):
        interval = comparison_interval(comparisons, first, second)
        return None if interval.n == 0 and math.isnan(interval.estimate) else interval

    values = {name: float(value) for name, value in zip(ranked[key], ranked[column])}
    text = stated_ordering(
        values,
        compare,
        name=lambda item: names[item],
        digits=3,
        detail=lambda *args: "",
        identity=lambda first, second: construction(comparisons, first, second),
    )
    if primary:
        stated = [
            short_interval_text(found, f"{a}/{b}", "{:.3g}")
            + (
                " (by construction: its size, not its sign)"
                if construction(comparisons, a, b) or construction(comparisons, b, a)
                else ""
            )
            for a, b in PRIMARY_PAIRS
            if a in values and b in values and (found := compare(a, b)) is not None
        ]
        text += "; " + ", ".join(stated) if stated else ""
    return text


def construction(comparisons: pd.DataFrame, first: str, second: str) -> str | None:
    """Why ``first <= second`` holds by construction in a comparisons table (its ``by_construction`` column), or
    None."""
    if "by_construction" not in comparisons.columns:
        return None
    found = comparisons[(comparisons["first"] == first) & (comparisons["second"] == second)]
    reasons = [str(reason) for reason in found["by_construction"] if isinstance(reason, str) and reason]
    return reasons[0] if reasons else None


def _of_solver(
    summary: pd.DataFrame, comparisons: pd.DataFrame, column: str, solver: str
) -> tuple[pd.DataFrame, pd.DataFrame]:
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


def sweep_findings(
    summary: pd.DataFrame,
    comparisons: pd.DataFrame,
    swept: Sequence[str],
    column: str,
    solver: str,
    headline: bool = True,
) -> list[str]:
    """Findings of a sweep, one per swept condition and data variant: m over the runs and the bases from best to
    worst by their geometric mean over the replicates, each neighbouring pair joined by its verdict in the
    comparisons table (:func:`ordering_with_intervals`), and on the lead (first) data variant, with least squares
    and the headline column, the primary contrasts with their intervals. Every number is a cell of the summary or
    of the comparisons table; each line a :class:`workbench.reporting.findings.run.Detail` (those of another solver or
    column go first when the findings run over their words).

    Parameters
    ----------
    summary : pandas.DataFrame
        Wide summary (:func:`workbench.reporting.tables.runs.wide`): the swept keys, ``data``, ``basis``, ``solver``,
        ``n_seeds``, ``column``, and ``m_min``/``m_max``, ``n_min``/``n_max`` where present.
    comparisons : pandas.DataFrame
        :func:`workbench.reporting.tables.runs.paired_comparisons` of ``column`` (PCA beside every solver).
    swept : sequence of str
        The condition keys (none: one finding per data variant).
    column : str
    solver : str
        The solver of the findings (PCA is compared beside it).
    headline : bool
        Whether ``column`` is the headline alpha (that of the primary contrasts).

    Returns
    -------
    list of str
    """
    rows, comparisons = _of_solver(summary, comparisons, column, solver)
    keys = [*swept, "data"]
    lead = next(iter(summary["data"]), None)
    primary = headline and solver == "lstsq"
    lines = []
    for values, part in rows.groupby(keys, sort=False, dropna=False):
        values = values if isinstance(values, tuple) else (values,)
        mine = _matching(comparisons, keys, values)
        setting = ", ".join(f"{key} = {value}" for key, value in zip(swept, values[:-1]))
        first = part.iloc[0]
        m = f"m = {_range_text(first, 'm')}; " if _has(part, "m") else ""
        ordering = ordering_with_intervals(part, mine, column, primary=primary and values[-1] == lead)
        lines.append(
            Detail(
                f"{setting + ', ' if setting else ''}**{values[-1]}** ({m}{int(part['n_seeds'].max())} "
                f"seeds, {solver}) `{column}`: {ordering}.",
                1 if primary else 2,
                f"the tables 'Paired comparisons' and '{column} over seeds'",
            )
        )
    return lines


def training_findings(
    summary: pd.DataFrame, comparisons: pd.DataFrame, swept: Sequence[str], column: str, solver: str
) -> list[str]:
    """Findings of a sweep that fitted the bases on several data variants and scored each on common evaluation sets
    (``dataset.eval_on``): per condition, evaluation set and basis, the variants fitted on from best to worst, and
    for each neighbouring pair "A < B" only where the paired interval excludes 1.

    Parameters
    ----------
    summary : pandas.DataFrame
        Wide summary with ``train_on``, ``eval_on``, ``basis``, ``solver``, ``n_seeds`` and ``column``.
    comparisons : pandas.DataFrame
        :func:`workbench.reporting.tables.runs.paired_comparisons` with ``between="train_on"``.
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
        lines.append(
            Detail(
                f"{setting + ', ' if setting else ''}scored on **{values[-2]}**, {values[-1]} "
                f"({int(part['n_seeds'].max())} seeds, {solver}) `{column}` by the data fitted on: "
                + ordering_with_intervals(part, mine, column, key="train_on")
                + ".",
                2,
                "the table 'Paired comparisons'",
            )
        )
    return lines


def bases_findings(
    summary: pd.DataFrame,
    comparisons: pd.DataFrame,
    column: str,
    ordering: bool = True,
    run_comparisons: Mapping[str, Sequence[Mapping]] | None = None,
    solver: str = "lstsq",
) -> list[str]:
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
        ``locality``) and :data:`workbench.reporting.tables.runs.COMPARISON_COLUMNS`.
    column : str
    ordering : bool
        Whether to state the ordering by ``column`` (a sweep's findings state it already).
    run_comparisons : mapping, optional
        Data variant -> the paired per-frame comparisons of one run (``metrics.json``): the ordering by ``column``
        then comes from them (a block bootstrap over the run's frames), as one run has no replicates to pair.
    solver : str
        The solver of ``column``'s values (PCA: its projection), to find them in ``run_comparisons``.
    """
    lines, lead = [], next(iter(summary["data"]), None)
    for data, part in summary.groupby("data", sort=False):
        mine = comparisons[comparisons["data"] == data]
        if ordering and run_comparisons is not None:
            values = {
                (basis, "projection" if basis == "PCA" else solver): float(value)
                for basis, value in zip(part["basis"], part[column])
            }
            lines.append(
                f"**{data}** (one run): `{column}` from best to worst: "
                + stated_ordering(values, comparison_lookup(run_comparisons.get(data, [])), name=lambda key: key[0])
                + "."
            )
        elif ordering:
            lines.append(
                f"**{data}** ({int(part['n_seeds'].max())} runs) `{column}`: "
                + ordering_with_intervals(
                    part, mine[mine["metric"] == column], column, primary=data == lead and solver == "lstsq"
                )
                + "."
            )
        hand = part[part["basis"] == "H"]
        sizes = {row["basis"]: _range_text(row, "n") for row in part.to_dict("records")}
        other = {basis: size for basis, size in sizes.items() if len(hand) and size != sizes["H"]}
        if other:
            lines.append(
                Detail(
                    f"**{data}**: bases of other sizes than the hand basis's n = {sizes['H']}: "
                    + ", ".join(f"{basis} n = {size}" for basis, size in other.items())
                    + "; their alpha is not that of a basis of the same size.",
                    3,
                    "the table 'Other bases: alpha against intuitiveness'",
                )
            )
        others = part[part["basis"] != "H"]
        for measure, ascending, what in (
            ("matched_abs_cosine", False, "closest to the hand shapes (mean matched |cosine|)"),
            ("locality", True, "most local (share of the face holding an element's displacement)"),
        ):
            ranked = others.dropna(subset=[measure]).sort_values(measure, ascending=ascending, kind="stable")
            if len(ranked) < 2:
                continue
            best, runner = ranked.iloc[0], ranked.iloc[1]
            verdict = pair_text(mine[mine["metric"] == measure], best["basis"], runner["basis"])
            lead = (
                f"{best['basis']} {cell_text(measure, best[measure])}, then {runner['basis']} "
                f"{cell_text(measure, runner[measure])}"
                + (f" (the hand shapes' {cell_text(measure, hand[measure].iloc[0])})" if len(hand) else "")
            )
            lines.append(
                Detail(
                    f"**{data}**: {what}: {lead}; {verdict}.", 2, "the table 'Other bases: alpha against intuitiveness'"
                )
            )
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
    return [
        f"The replicates vary {varied} only, not the data: the intervals below cover that, not other takes, "
        "and no finding here generalises beyond this one capture."
    ]


def sweep_statements(
    summary: pd.DataFrame, comparisons: pd.DataFrame, swept: Sequence[str], columns: Sequence[str], solver: str
) -> list[str]:
    """Every finding of a sweep for each of ``columns``: the bases compared (:func:`sweep_findings`), then the
    data variants fitted on where the comparisons hold those (:func:`training_findings`).

    Parameters
    ----------
    summary : pandas.DataFrame
    comparisons : pandas.DataFrame
        :func:`workbench.reporting.tables.runs.sweep_comparisons`.
    swept : sequence of str
    columns : sequence of str
    solver : str
    """
    by_basis = comparisons[comparisons["first"].isin(summary["basis"])] if len(comparisons) else comparisons
    by_variant = comparisons[~comparisons["first"].isin(summary["basis"])] if len(comparisons) else comparisons
    lines = [
        line
        for column in columns
        for line in sweep_findings(summary, by_basis, swept, column, solver, headline=column == columns[0])
    ]
    if len(by_variant):
        lines += [line for column in columns for line in training_findings(summary, by_variant, swept, column, solver)]
    return lines
