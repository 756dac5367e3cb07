"""The findings of a sweep or of the other bases, stated in sentences generated from its numbers.

:func:`sweep_statements` says, per swept condition and data variant, the bases from best to worst by their
geometric means over the replicates, each neighbouring pair "A < B" only where the paired per-replicate ratio's
verdict allows it and "A ~ B" otherwise, and per sweep cell the paper's two claims as its runs stored them at
m = n (counted, never decided again: :mod:`workbench.study.claims` judges each once); QE/H and QE/PCA over the
replicates at a cell's own m (not m = n) are stated as secondary comparisons at that m, and every other ratio,
interval and p-value is a row of the sweep's comparisons table. :func:`holm_verdicts` decides the verdicts by
Holm's adjustment over every tested row together; orderings that hold by construction are not tested.
:func:`bases_findings` adds the other bases' sizes, closeness and locality.
The findings of one run are in :mod:`workbench.reporting.findings.run`.
"""

from __future__ import annotations

import math
from typing import Mapping, Sequence

import pandas as pd

from workbench.reporting.findings.claims import counted_claims_text
from workbench.reporting.findings.run import Detail
from workbench.reporting.tables.cells import cell_text
from workbench.reporting.tables.runs import NOT_DISTINGUISHABLE, flatten
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
from workbench.study.claims import base_variant
from workbench.study.regime import is_paper_regime

PRIMARY_PAIRS = (("QE", "H"), ("QE", "PCA"))
"""The pairs of the paper's claims. Their verdicts are the runs' own, stored at m = n
(:mod:`workbench.study.claims`) and stated per sweep cell (:func:`workbench.reporting.findings.claims.counted_claims_text`);
the sweep's paired ratios of these pairs at another m are secondary comparisons, tested with every other row."""
HOLM_COLUMN = "p_holm"
"""The comparisons table's column with the p-value Holm-adjusted within its family (NaN for an identity)."""
FAMILY_COLUMN = "family"
"""The comparisons table's column naming each row's family: :data:`SECONDARY` or :data:`IDENTITY`."""
SECONDARY, IDENTITY = "secondary", "identity"
"""The families: every tested comparison (one Holm family: the paper's claims are not among them, each run judged
those once), and the orderings that hold by construction (no test, no p-value)."""
INTERVAL_NOTE = "95 % interval, unadjusted; verdict by Holm"
"""What the comparisons' intervals are, said beside them: their verdicts use the Holm-adjusted p-value."""
SECONDARY_NOTE = "secondary comparisons at {m} (not the paper's claims)"
"""How a sweep's QE/H and QE/PCA over the replicates at a condition's m (not m = n) are labelled."""


def comparison_families(comparisons: pd.DataFrame) -> list[str]:
    """Each row's family: :data:`IDENTITY` where it holds by construction (its ``by_construction`` reason), else
    :data:`SECONDARY` (QE/H and QE/PCA included: the paper's claims are the runs' stored ones)."""
    return [
        IDENTITY
        if isinstance(row.get("by_construction"), str) and row["by_construction"] not in ("", "-")
        else SECONDARY
        for row in comparisons.to_dict("records")
    ]


def holm_verdicts(comparisons: pd.DataFrame) -> pd.DataFrame:
    """A sweep's comparisons table with its families (:func:`comparison_families`) and Holm's adjustment over every
    tested row together; each row's Holm-adjusted p-value goes into :data:`HOLM_COLUMN`
    (:func:`workbench.stats.statistics.holm`) and its ``verdict`` is ``<`` only where that is below 0.05. An
    identity keeps its verdict, and has no p-value. The paper's two claims are no row's verdict: each run stored
    them at m = n, and the findings state those.

    Parameters
    ----------
    comparisons : pandas.DataFrame
        :func:`workbench.reporting.tables.runs.sweep_comparisons`: ``first``, ``second``, ``metric``, ``ratio``,
        ``ratio_low``, ``ratio_high``, ``verdict``, ``p`` and, per row, its condition, ``data`` and ``solver``.

    Returns
    -------
    pandas.DataFrame
        A copy with :data:`HOLM_COLUMN` and :data:`FAMILY_COLUMN` after ``p``.
    """
    table = comparisons.copy()
    if table.empty or "p" not in table.columns:
        return table.assign(**{HOLM_COLUMN: pd.Series(dtype=float), FAMILY_COLUMN: pd.Series(dtype=str)})
    families = comparison_families(table)
    adjusted = pd.Series(math.nan, index=table.index)
    family = [k for k, found in enumerate(families) if found == SECONDARY]
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
    """Rows per family of a comparisons table (:data:`FAMILY_COLUMN`): ``{"secondary": k, "identity": k}``, zero
    for a family without rows."""
    found = comparisons[FAMILY_COLUMN].value_counts() if FAMILY_COLUMN in comparisons.columns else {}
    return {name: int(found.get(name, 0)) for name in (SECONDARY, IDENTITY)}


def rows_text(count: int) -> str:
    """``1 row``, ``3 rows``."""
    return f"{count} row{'' if count == 1 else 's'}"


def holm_text(comparisons: pd.DataFrame) -> str:
    """The sentence that says, once, how a sweep's orderings are decided: the method of the intervals, the one Holm
    family and its size, the identities (:func:`holm_verdicts`), and that the paper's claims are the runs' own."""
    method = comparisons["method"].iloc[0] if len(comparisons) else "-"
    n = int(comparisons["n"].max()) if len(comparisons) else 0
    sizes = family_sizes(comparisons)
    return (
        f"**how to read**: the paper's claims are those each run stored at m = n (its own interval), counted per "
        f"condition; levels: geometric means over the replicates; 'A < B': A/B per replicate ({method}, n = {n}) "
        f"below 1 by its {HOLM_COLUMN} < {1 - CONFIDENCE:.2g}, Holm over every tested row "
        f"({rows_text(sizes[SECONDARY])}, QE/H and QE/PCA at each cell's m among them: secondary, not the paper's "
        "claims); "
        f"intervals: {INTERVAL_NOTE}; '~': not distinguishable; '=': a tie; 'A <= B by construction' "
        f"({rows_text(sizes[IDENTITY])}): holds in every replicate, not tested; each number is a row of "
        "comparisons.csv."
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
    part: pd.DataFrame,
    comparisons: pd.DataFrame,
    column: str,
    key: str = "basis",
    primary: str = "",
    judged: Sequence[tuple] = (),
) -> str:
    """The bases of one condition from best to worst by their geometric mean, each neighbouring pair joined by its
    verdict in the comparisons table (``<``, ``~`` not distinguishable, ``=`` a tie, ``,`` no comparison), then
    (with ``primary``, their label) QE/H and QE/PCA with their intervals: ``QE 0.162 ~ PCA (n = 9-11) 0.169 < H
    0.312; secondary comparisons at this m, not the paper's claims: QE/H 0.52 [0.46, 0.58], QE/PCA 0.959 [0.9,
    1.02]``.

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
    primary : str
        The label of :data:`PRIMARY_PAIRS`' intervals at this condition (empty: not stated).
    judged : sequence of tuple
        Pairs judged elsewhere (the runs' stored claims at m = n): joined by ``,``, no verdict of the sweep's own.
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
        if {first, second} in [set(pair) for pair in judged]:
            return None
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
    stated = claim_pairs_text(comparisons, set(values)) if primary else ""
    return text + (f"; {primary}: {stated}" if stated else "")


def claim_pairs_text(comparisons: pd.DataFrame, bases: set) -> str:
    """QE/H and QE/PCA (:data:`PRIMARY_PAIRS`) of one condition with their intervals from its comparisons:
    ``QE/H 0.52 [0.46, 0.58], Holm p 0.01, QE/PCA 0.959 [0.9, 1.02]``; empty without them."""
    stated = []
    for a, b in PRIMARY_PAIRS:
        found = comparison_interval(comparisons, a, b)
        if a not in bases or b not in bases or (found.n == 0 and math.isnan(found.estimate)):
            continue
        built = construction(comparisons, a, b) or construction(comparisons, b, a)
        stated.append(
            short_interval_text(found, f"{a}/{b}", "{:.3g}")
            + (" (by construction: its size, not its sign)" if built else "")
        )
    return ", ".join(stated)


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


SECONDARY_RANK = 1.5
"""QE/H and QE/PCA at a cell's m are left out of findings over their words after other solvers' and columns'
orderings (rank 2), before the lead orderings (rank 1): the paper's claims are the stored ones."""


def at_m_equals_n(part: pd.DataFrame) -> bool:
    """Whether every run of a condition's rows kept m = n (the hand basis's n): the paper's regime, where the runs'
    stored claims test QE/H and QE/PCA and the sweep's own ratios of them would judge them a second time."""
    hand = part[part["basis"] == "H"]
    if not (_has(part, "m") and _has(hand, "n") and len(hand)):
        return False
    return _range_text(part.iloc[0], "m") == _range_text(hand.iloc[0], "n") and "-" not in _range_text(
        hand.iloc[0], "n"
    )


def condition_key(values: Sequence) -> tuple:
    """A sweep cell's swept values as text (``0.99`` and ``"0.99"`` alike), to look its claims up."""
    return tuple(str(value) for value in values)


def cell_claims(records: Sequence, swept: Sequence[str], lead: str) -> dict:
    """Each sweep cell's claims per data variant: ``(condition_key, base)`` -> the claims its runs stored at m = n
    for that base variant, counted (:func:`workbench.reporting.findings.claims.counted_claims_text`): for the lead
    variant's base always (saying "not tested at m = n" and why where no run has them), for another base only where
    some run stored claims for it.

    Parameters
    ----------
    records : sequence of workbench.record.record.RunRecord
    swept : sequence of str
        The condition keys (dotted config names).
    lead : str
        The lead data variant (that of the sweep's summary).
    """
    cells: dict = {}
    for record in records:
        flat = flatten(record.config)
        cells.setdefault(condition_key([flat.get(key) for key in swept]), []).append(record.claims)
    bases = {base_variant(lead)} | {
        entry["base"] for record in records for entry in (record.claims or {}).get("entries") or []
    }
    return {(key, base): counted_claims_text(claims, base) for key, claims in cells.items() for base in bases}


def sweep_findings(
    summary: pd.DataFrame,
    comparisons: pd.DataFrame,
    swept: Sequence[str],
    column: str,
    solver: str,
    headline: bool = True,
    claims: Mapping[tuple, str] | None = None,
) -> list[str]:
    """Findings of a sweep, one per swept condition and data variant: m over the runs and the bases from best to
    worst by their geometric mean over the replicates, each neighbouring pair joined by its verdict in the
    comparisons table (:func:`ordering_with_intervals`); with least squares and the headline column, the paper's
    claims as the cell's runs stored them (``claims``, a line never left out, before the first line of each base
    variant that has them), no verdict of the sweep's own on QE against H and PCA in a variant at m = n (the claims
    judge those), and on the lead (first) variant, where the cell is not at m = n, QE/H and QE/PCA over the
    replicates labelled :data:`SECONDARY_NOTE`. Every number is a cell of the summary, of the
    comparisons table or of a run's stored claims; each ordering a :class:`workbench.reporting.findings.run.Detail`
    (those of another solver or column go first when the findings run over their words).

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
        Whether ``column`` is the headline alpha (that of the paper's claims).
    claims : mapping, optional
        :func:`cell_claims`: each cell's stored claims per base variant as text (none: not stated, and the
        orderings at m = n judge QE against H and PCA themselves, as before the runs stored claims).

    Returns
    -------
    list of str
    """
    rows, comparisons = _of_solver(summary, comparisons, column, solver)
    keys = [*swept, "data"]
    lead = next(iter(summary["data"]), None)
    primary = headline and solver == "lstsq"
    rank = 1 if primary else 2
    lines, told = [], set()
    for values, part in rows.groupby(keys, sort=False, dropna=False):
        values = values if isinstance(values, tuple) else (values,)
        mine = _matching(comparisons, keys, values)
        setting = ", ".join(f"{key} = {value}" for key, value in zip(swept, values[:-1]))
        first = part.iloc[0]
        m = f"m = {_range_text(first, 'm')}; " if _has(part, "m") else ""
        on_lead = primary and values[-1] == lead
        head = f"{setting + ', ' if setting else ''}**{values[-1]}**"
        said = (condition_key(values[:-1]), base_variant(values[-1]))
        stated = (claims or {}).get(said) if primary and said not in told else None
        if stated:  # the cell's stored claims of this variant's base, once, before its first line
            lines.append(f"{head}: {stated}.")
            told.add(said)
        # at m = n the runs' stored claims judge QE against H and PCA: the sweep's own ratios do not a second time
        at_n = primary and claims is not None and (is_paper_regime(values[-1]) or at_m_equals_n(part))
        ordering = ordering_with_intervals(part, mine, column, judged=PRIMARY_PAIRS if at_n else ())
        where = f"the tables 'Paired comparisons' and '{column} over seeds'"
        lines.append(
            Detail(
                f"{head} ({m}{int(part['n_seeds'].max())} seeds, {solver}) `{column}`: {ordering}"
                + (" (QE against H and PCA: the runs' stored claims)" if at_n else "")
                + ".",
                rank,
                where,
            )
        )
        pairs = claim_pairs_text(mine, set(part["basis"])) if on_lead else ""
        if pairs and not is_paper_regime(values[-1]) and not at_m_equals_n(part):
            label = SECONDARY_NOTE.format(m=m.removesuffix("; ") or "the runs' own m")
            lines.append(Detail(f"{head}, {solver}, `{column}`: {label}: {pairs}.", SECONDARY_RANK, where))
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
                    part,
                    mine[mine["metric"] == column],
                    column,
                    primary=SECONDARY_NOTE.format(m="the runs' m")
                    if data == lead and solver == "lstsq" and not is_paper_regime(data)
                    else "",
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
    summary: pd.DataFrame,
    comparisons: pd.DataFrame,
    swept: Sequence[str],
    columns: Sequence[str],
    solver: str,
    claims: Mapping[tuple, str] | None = None,
) -> list[str]:
    """Every finding of a sweep for each of ``columns``: the bases compared (:func:`sweep_findings`, with each
    cell's stored claims), then the data variants fitted on where the comparisons hold those
    (:func:`training_findings`).

    Parameters
    ----------
    summary : pandas.DataFrame
    comparisons : pandas.DataFrame
        :func:`workbench.reporting.tables.runs.sweep_comparisons`.
    swept : sequence of str
    columns : sequence of str
    solver : str
    claims : mapping, optional
        :func:`cell_claims`.
    """
    by_basis = comparisons[comparisons["first"].isin(summary["basis"])] if len(comparisons) else comparisons
    by_variant = comparisons[~comparisons["first"].isin(summary["basis"])] if len(comparisons) else comparisons
    lines = [
        line
        for column in columns
        for line in sweep_findings(
            summary, by_basis, swept, column, solver, headline=column == columns[0], claims=claims
        )
    ]
    if len(by_variant):
        lines += [line for column in columns for line in training_findings(summary, by_variant, swept, column, solver)]
    return lines
