"""The findings of a run, stated in sentences generated from its numbers (never written by hand).

:func:`run_findings` reads an alpha table (the columns of :data:`workbench.report.TABLE_COLUMNS`) and the per-shape
intuitiveness of the run, and says per data variant: the ordering of H, QE and PCA under each solver, the ratios
H/QE and QE/PCA beside the paper's, m beside the paper's, what the constrained solvers do to QE against H, and
which hand shapes the projection changes most. Absolute alpha depends on the coordinate origin, so the
comparison with the paper is by ratios.
"""

from __future__ import annotations

import math
from typing import Mapping, Sequence

import pandas as pd

from workbench.reporting.statistics import Interval, interval_text, reciprocal_interval
from workbench.tables import cell_text

PAPER_BASES = ("H", "QE", "PCA")
CONSTRAINED = ("nnls", "box")
RATIO_FORMAT = "{:.4g}"
"""Ratios in findings as in the comparisons table's cells (:func:`workbench.tables.cell_text`)."""
SOLVER_NAMES = {"lstsq": "least squares", "nnls": "non-negative weights", "box": "box [0, 1] weights"}


def _alpha(part: pd.DataFrame, basis: str, solver: str, column: str) -> float:
    """The alpha of a basis under a solver in one data variant's rows (PCA: its projection row), NaN if absent."""
    rows = part[(part["basis"] == basis) & ((part["solver"] == solver) | (part["solver"] == "projection"))]
    return float(rows[column].iloc[0]) if len(rows) else math.nan


def _fmt(value: float) -> str:
    return f"{value:.4g}"


def ordering_text(part: pd.DataFrame, solver: str, column: str, bases: Sequence[str] = PAPER_BASES) -> str:
    """``QE 0.147 < PCA 0.156 < H 0.303``: the bases of one data variant from best to worst under a solver.

    Parameters
    ----------
    part : pandas.DataFrame
        The alpha-table rows of one data variant.
    solver : str
    column : str
        Alpha column.
    bases : sequence of str
    """
    values = {basis: _alpha(part, basis, solver, column) for basis in bases}
    ranked = sorted(((value, basis) for basis, value in values.items() if not math.isnan(value)))
    return " < ".join(f"{basis} {_fmt(value)}" for value, basis in ranked)


def ratio_text(part: pd.DataFrame, column: str, paper_alpha: Mapping[str, float], solver: str = "lstsq") -> str:
    """H/QE and QE/PCA of one data variant beside the paper's (from its reported alpha)."""
    h, qe, pca = (_alpha(part, basis, solver, column) for basis in PAPER_BASES)
    paper = [paper_alpha.get(basis, math.nan) for basis in PAPER_BASES]
    return (f"H/QE = {h / qe:.2f} (paper {paper[0] / paper[1]:.2f}), QE/PCA = {qe / pca:.2f} "
            f"(paper {paper[1] / paper[2]:.2f})")


def constraint_text(part: pd.DataFrame, column: str, solver: str,
                    negative_share: Mapping[str, float] | None = None) -> str:
    """What a constrained solver does to QE against H, relative to least squares."""
    h0, h1 = _alpha(part, "H", "lstsq", column), _alpha(part, "H", solver, column)
    q0, q1 = _alpha(part, "QE", "lstsq", column), _alpha(part, "QE", solver, column)
    verdict = ("QE becomes worse than H" if q1 > h1 else "QE stays better than H")
    text = (f"with {SOLVER_NAMES.get(solver, solver)} QE's alpha goes from {_fmt(q0)} to {_fmt(q1)} "
            f"(x{q1 / q0:.2f}) and H's from {_fmt(h0)} to {_fmt(h1)} (x{h1 / h0:.2f}): {verdict} "
            f"({_fmt(q1)} against {_fmt(h1)})")
    if negative_share and "QE" in negative_share:
        text += (f"; under least squares {100 * negative_share['QE']:.0f} % of the frames give QE a negative weight "
                 f"(H: {100 * negative_share.get('H', math.nan):.0f} %), which the constraint must undo")
    return text


def closeness_text(intuitiveness: Sequence[Mapping], projection: str = "affine", count: int = 3) -> str:
    """Where QE loses a hand shape's look: the shapes the projection changes most, and the median closeness.

    Parameters
    ----------
    intuitiveness : sequence of mapping
        ``metrics.json`` rows: ``shape``, ``projection``, ``relative_distance``, ``cosine``.
    projection : str
    count : int
        Shapes named.
    """
    rows = sorted((row for row in intuitiveness if row["projection"] == projection),
                  key=lambda row: -row["relative_distance"])
    if not rows:
        return ""
    cosines = sorted(row["cosine"] for row in rows)
    median = cosines[len(cosines) // 2] if len(cosines) % 2 else (cosines[len(cosines) // 2 - 1]
                                                                    + cosines[len(cosines) // 2]) / 2
    named = ", ".join(f"{row['shape']} (cosine {row['cosine']:.2f}, relative distance {row['relative_distance']:.2f})"
                      for row in rows[:count])
    return (f"the projection changes most {named}; median cosine of the {len(rows)} shapes to their quasi-eigen "
            f"faces {median:.2f}")


def run_findings(table: pd.DataFrame, column: str, paper: Mapping, intuitiveness: Mapping[str, Sequence[Mapping]],
                 negative_share: Mapping[str, Mapping[str, float]] | None = None) -> list[str]:
    """The findings of a run, one Markdown line per data variant and topic.

    Parameters
    ----------
    table : pandas.DataFrame
        The run's alpha table.
    column : str
        The alpha column the findings use (the run's headline).
    paper : mapping
        ``m`` and ``alpha`` (basis -> the paper's value), as in the study config's ``paper`` node.
    intuitiveness : mapping
        Data variant -> its per-shape intuitiveness rows (``metrics.json``).
    negative_share : mapping, optional
        Data variant -> (basis -> share of frames with a negative least-squares weight).

    Returns
    -------
    list of str
    """
    lines = []
    solvers = [solver for solver in dict.fromkeys(table["solver"]) if solver != "projection"]
    for data, part in table.groupby("data", sort=False):
        m = round(float(part["m"].iloc[0]), 1)
        n = float(part.loc[part["basis"] == "H", "n"].iloc[0]) if (part["basis"] == "H").any() else math.nan
        ordering = "; ".join(f"{solver}: {ordering_text(part, solver, column)}" for solver in solvers)
        lines.append(f"**{data}**: `{column}` from best to worst, {ordering}.")
        if "lstsq" in solvers:
            lines.append(f"**{data}**: {ratio_text(part, column, paper.get('alpha', {}))} with least squares; "
                         "absolute alpha depends on the coordinate origin, the ratios compare across datasets.")
        spans = "can span" if m <= n else "cannot span"
        reach = (f" reach coverage {float(part['coverage'].iloc[0]):.4f}" if "coverage" in part.columns
                 else " (mean over the runs)")
        lines.append(f"**{data}**: m = {m:g} eigenfaces{reach} "
                     f"(paper: m = {paper.get('m')}); the {n:g} hand shapes {spans} them"
                     + (", so QE can match PCA" if m <= n else ", so QE cannot reach PCA") + ".")
        constrained = [s for s in CONSTRAINED if s in solvers and "lstsq" in solvers]
        for k, solver in enumerate(constrained):  # the share of negative weights is said once
            lines.append(f"**{data}**: " + constraint_text(part, column, solver,
                                                          (negative_share or {}).get(data) if k == 0 else None)
                         + ".")
        closeness = closeness_text(intuitiveness.get(data, []))
        if closeness:
            lines.append(f"**{data}**: {closeness}.")
    return lines


def facts_frame(metrics: Mapping) -> pd.DataFrame:
    """The run's facts in one table, a row per data variant: points, frames, m, coverage, empty axes.

    Parameters
    ----------
    metrics : mapping
        ``metrics.json`` of the run.
    """
    rows = []
    for data, values in metrics["data"].items():
        pca = values["pca"]
        rows.append({"data": data, "points": values["n_points"], "training frames": values["n_train_frames"],
                     "evaluated frames": values["n_eval_frames"], "m": pca["m"],
                     "coverage": round(float(pca["coverage_reached"]), 4), "PCA method": pca["method"],
                     "empty PCA axes": "; ".join(f"{projection}: {', '.join(map(str, qe['empty_axes'])) or 'none'}"
                                                 for projection, qe in values["quasi_eigen"].items())})
    return pd.DataFrame.from_records(rows)


def shared_notes(metrics: Mapping) -> tuple[list[str], dict[str, list[str]]]:
    """The run's notes, those every data variant shares once and the rest per variant.

    Returns
    -------
    shared : list of str
    own : dict
        Data variant -> its notes not in ``shared``.
    """
    notes = {data: list(values.get("notes", [])) for data, values in metrics["data"].items()}
    first = next(iter(notes.values()), [])
    shared = [note for note in first if all(note in other for other in notes.values())]
    return shared, {data: [note for note in own if note not in shared] for data, own in notes.items()}


def _comparison(comparisons: pd.DataFrame, first: str, second: str) -> Interval:
    """The paired ratio ``first / second`` from a comparisons table (either orientation), as an interval."""
    for a, b, flip in ((first, second, False), (second, first, True)):
        found = comparisons[(comparisons["first"] == a) & (comparisons["second"] == b)]
        if len(found):
            row = found.iloc[0]
            interval = Interval(float(row["ratio"]), float(row["ratio_low"]), float(row["ratio_high"]),
                                int(row["n"]), str(row["method"]), null=1.0)
            return reciprocal_interval(interval) if flip else interval
    return Interval(math.nan, math.nan, math.nan, 0, "no paired values", null=1.0)


def pair_text(comparisons: pd.DataFrame, first: str, second: str) -> str:
    """``QE < H (QE/H 0.5212, 95 % interval [0.4601, 0.5804] (paired t on log ratios, n = 5))``, or ``QE and H
    not distinguishable (...)`` when the interval of the paired ratio includes 1: the row of the comparisons
    table, in its orientation (the smaller first)."""
    interval = _comparison(comparisons, first, second)
    if interval.estimate > 1.0:
        first, second, interval = second, first, reciprocal_interval(interval)
    detail = interval_text(interval, f"{first}/{second}", RATIO_FORMAT)
    if interval.sign == 0:
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
    rows = summary[(summary["solver"] == solver) | (summary["solver"] == "projection")]
    comparisons = comparisons[(comparisons["solver"] == solver) & (comparisons["metric"] == column)] \
        if len(comparisons) else comparisons
    keys = [*swept, "data"]
    lines = []
    for values, part in rows.groupby(keys, sort=False, dropna=False):
        values = values if isinstance(values, tuple) else (values,)
        mine = comparisons
        for key, value in zip(keys, values):
            mine = mine[mine[key].astype(str) == str(value)]
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
    rows = summary[(summary["solver"] == solver) | (summary["solver"] == "projection")]
    comparisons = comparisons[(comparisons["solver"] == solver) & (comparisons["metric"] == column)] \
        if len(comparisons) else comparisons
    keys = [*swept, "eval_on", "basis"]
    lines = []
    for values, part in rows.groupby(keys, sort=False, dropna=False):
        if part["train_on"].nunique() < 2 or values[-1] == "H":  # the hand shapes are not fitted
            continue
        mine = comparisons
        for key, value in zip(keys, values):
            mine = mine[mine[key].astype(str) == str(value)]
        setting = ", ".join(f"{key} = {value}" for key, value in zip(swept, values[:-2]))
        lines.append(f"{setting + ', ' if setting else ''}scored on **{values[-2]}**, {values[-1]} "
                     f"({int(part['n_seeds'].max())} seeds, {solver}): `{column}` geometric means by the data "
                     "fitted on, best first: " + ordering_with_intervals(part, mine, column, key="train_on") + ".")
    return lines


def bases_findings(summary: pd.DataFrame, comparisons: pd.DataFrame, column: str, ordering: bool = True) -> list[str]:
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
    """
    lines = []
    for data, part in summary.groupby("data", sort=False):
        mine = comparisons[comparisons["data"] == data]
        n_runs = int(part["n_seeds"].max())
        if ordering:
            lines.append(f"**{data}** ({n_runs} runs): `{column}` geometric means, best first: "
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
