"""The summary a sweep's report opens with (at most 200 words): the paper's two claims on one condition, as each
run stored them (``metrics.json`` ``claims``, :mod:`workbench.study.claims`: counted, not decided again), the
coverage m = n reaches, how well H and QE determine their weights, and what the design rests on.

The condition is the paper's regime m = n where the sweep has it (a data variant fitted at m = n, or a condition
whose every run kept m = n), else the sweep's lead condition; the summary says which.
"""

from __future__ import annotations

import math
from typing import Mapping, Sequence

import numpy as np
import pandas as pd

from workbench.record.record import RunRecord
from workbench.reporting.findings.claims import PAPER_RATIOS, counted_claims_text
from workbench.reporting.findings.sweep import comparison_interval
from workbench.reporting.tables.runs import flatten
from workbench.study.claims import base_variant
from workbench.study.regime import is_paper_regime

SUMMARY_WORDS = 200


def _text(value) -> str:
    return f"{value:g}" if isinstance(value, (float, np.floating)) else str(value)


def _range(values: Sequence[float], number: str = "{:.3g}") -> str:
    """``0.7-0.84`` over the runs, or one value where they agree."""
    values = [float(value) for value in values if value is not None and math.isfinite(float(value))]
    if not values:
        return "-"
    low, high = number.format(min(values)), number.format(max(values))
    return low if low == high else f"{low}-{high}"


def summary_condition(per_run: pd.DataFrame, swept: Sequence[str], lead: str, values: bool = True) -> tuple[dict, str]:
    """The condition the summary speaks of, and where it stands to the paper's regime.

    Parameters
    ----------
    per_run : pandas.DataFrame
        The runs table (``data``, ``basis``, ``n``, ``m`` and the swept keys).
    swept : sequence of str
    lead : str
        The lead data variant (that of the primary contrasts).
    values : bool
        Whether the text names the condition by its settings' values (else by its place: the first row of the
        tables, or the condition where every run kept m = n), to keep the summary short with many swept settings.

    Returns
    -------
    condition : dict
        Swept key -> its value (empty when nothing but the seed is swept).
    where : str
        ``at the paper's regime m = n (the variant markers m=n)``, ``at basis.coverage = 0.999, where every run
        kept m = n = 18 (the paper's regime)``, or ``at the lead condition basis.coverage = 0.9, not the paper's
        regime m = n (m = 5-16, n = 18)``.
    """
    rows = per_run[per_run["data"] == lead]
    groups = list(rows.groupby(list(swept), sort=False, dropna=False)) if swept else [((), rows)]
    named = []
    for found, part in groups:
        condition = dict(zip(swept, found if isinstance(found, tuple) else (found,)))
        hand = set(part.loc[part["basis"] == "H", "n"].dropna().astype(int))
        label = ", ".join(f"{key} = {value}" for key, value in condition.items()) if values else ""  # as the findings
        named.append((condition, label, part, hand))
    if is_paper_regime(lead):
        condition, label, _, _ = named[0]
        return condition, f"at the paper's regime m = n (the variant {lead}{', ' + label if label else ''})"
    for condition, label, part, hand in named:
        kept = set(part["m"].dropna().astype(int))
        if len(hand) == 1 and kept == hand:
            place = label if label else "the condition" if swept else "the one condition"
            return condition, f"at {place}, where every run kept m = n = {hand.pop()} (the paper's regime)"
    condition, label, part, hand = named[0]
    place = (
        f"the lead condition {label}"
        if label
        else "the lead condition (the first row of the tables)"
        if swept
        else "the one condition"
    )
    return condition, (
        f"at {place}, not the paper's regime m = n "
        f"(m = {_range(part['m'], '{:.0f}')}, n = {_range(sorted(hand), '{:.0f}')})"
    )


def _matching_records(records: Sequence[RunRecord], condition: Mapping, data: str) -> list[RunRecord]:
    """The records that scored the data variant ``data`` and whose config holds the condition's values (compared
    as text, as a sweep's settings are); a sweep over ``dataset.train_on`` has runs without the variant."""
    found = []
    for record in records:
        flat = flatten(record.config)
        scored = any(row.get("data") == data for row in record.metrics.get("rows") or [])
        if scored and all(_text(flat.get(key)) == _text(value) for key, value in condition.items()):
            found.append(record)
    return found


def _lstsq_row(record: RunRecord, data: str, basis: str) -> Mapping:
    return next(
        (
            row
            for row in record.metrics.get("rows") or []
            if (row["data"], row["basis"], row["solver"]) == (data, basis, "lstsq")
        ),
        {},
    )


def conditioning_text(records: Sequence[RunRecord], data: str) -> str:
    """``H condition number 34.9, largest |w| 0.7-0.84; QE rank 6-7 of 18 (singular), largest |w| 1-2.6``: how
    well least squares determines H's and QE's weights, as ranges over the runs; empty when not recorded."""
    parts = []
    for basis in ("H", "QE"):
        rows = [_lstsq_row(record, data, basis) for record in records]
        found = [row.get("basis_conditioning") for row in rows if row.get("basis_conditioning")]
        if not found:
            continue
        full = [entry["condition_number"] for entry in found if entry["rank"] >= entry["n_shapes"]]
        short = [entry for entry in found if entry["rank"] < entry["n_shapes"]]
        said = []
        if full:
            said.append(f"condition number {_range(full)}" + (f" in {len(full)} runs" if short else ""))
        if short:
            ranks = _range([entry["rank"] for entry in short], "{:.0f}")
            said.append(
                f"rank {ranks} of {short[0]['n_shapes']} (singular)" + (f" in {len(short)} runs" if full else "")
            )
        largest = _range([row.get("w_max_abs", math.nan) for row in rows])
        parts.append(f"{basis} {', '.join(said)}, largest |w| {largest}")
    return "; ".join(parts)


def coverage_text(records: Sequence[RunRecord], data: str, n: int) -> str:
    """``m = n = 18 eigenfaces cover 99.2-99.6 % of the training variance``: the coverage the paper's m reaches
    in each run (its PCA's explained variance ratios), empty when not recorded."""
    reached = []
    for record in records:
        ratios = (((record.metrics.get("data") or {}).get(data) or {}).get("pca") or {}).get("explained_variance_ratio")
        if ratios is not None and len(ratios) >= n:
            reached.append(100.0 * float(np.sum(ratios[:n])))
    return f"m = n = {n} eigenfaces cover {_range(reached, '{:.2f}')} % of the training variance" if reached else ""


def stored_claims_text(runs: Sequence[RunRecord], lead: str) -> str:
    """The claims each run stored, counted over the runs per protocol
    (:func:`workbench.reporting.findings.claims.counted_claims_text`, as the sweep's findings state them): ``The
    paper's claims at m = n, as each run stored them (...): training frames: QE better than H reproduced in 4, not
    decided in 1 (H/QE 1.55-1.97); ...``."""
    text = counted_claims_text([record.claims for record in runs], base_variant(lead))
    return f"{text[0].upper()}{text[1:]}."


def design_text(records: Sequence[RunRecord], data: str, over: Sequence[str], column: str, interval) -> str:
    """``5 runs (dataset.seed), 1000 training and 1000 evaluated frames each; intervals over the runs, 4 degrees of
    freedom; one metric, `alpha_abs_mean`, at a time`` (``interval``: one of the summary's, for its n)."""
    facts = [(record.metrics.get("data") or {}).get(data) or {} for record in records]
    training = _range([fact.get("n_train_frames", math.nan) for fact in facts], "{:.0f}")
    evaluated = _range([fact.get("n_eval_frames", math.nan) for fact in facts], "{:.0f}")
    runs = len(records)
    degrees = f", {interval.n - 1} degrees of freedom" if interval.n >= 2 else ""
    return (
        f"{runs} run{'s' if runs != 1 else ''} ({', '.join(over) or 'no replicate setting'}), {training} training "
        f"and {evaluated} evaluated frames each; intervals over the runs{degrees}; one metric, `{column}`, at a time"
    )


def summary_lead(per_run: pd.DataFrame, comparisons: pd.DataFrame) -> str:
    """The data variant a sweep's summary and findings state the paper's claims on: the comparisons table's first,
    else the runs table's first."""
    lead = next(iter(comparisons["data"].dropna()), None) if "data" in comparisons.columns else None
    return lead if lead is not None else str(per_run["data"].iloc[0])


def sweep_summary(
    records: Sequence[RunRecord],
    per_run: pd.DataFrame,
    comparisons: pd.DataFrame,
    swept: Sequence[str],
    over: Sequence[str],
    column: str,
) -> str:
    """The summary of a sweep's report (at most :data:`SUMMARY_WORDS` words).

    Parameters
    ----------
    records : sequence of RunRecord
    per_run : pandas.DataFrame
        The runs table.
    comparisons : pandas.DataFrame
        The sweep's one comparisons table, with its families
        (:func:`workbench.reporting.findings.sweep.holm_verdicts`).
    swept, over : sequence of str
        The condition keys and the replicate keys.
    column : str
        The headline alpha column.

    Returns
    -------
    str
    """
    lead = summary_lead(per_run, comparisons)
    condition, where = summary_condition(per_run, swept, lead)
    text = _summary_text(records, per_run, comparisons, condition, where, lead, over, column)
    if len(text.split()) > SUMMARY_WORDS and condition:  # many swept settings: the condition named by its place
        condition, where = summary_condition(per_run, swept, lead, values=False)
        text = _summary_text(records, per_run, comparisons, condition, where, lead, over, column)
    return text


def _summary_text(
    records: Sequence[RunRecord],
    per_run: pd.DataFrame,
    comparisons: pd.DataFrame,
    condition: Mapping,
    where: str,
    lead: str,
    over: Sequence[str],
    column: str,
) -> str:
    """The summary's text at one condition (:func:`sweep_summary`)."""
    chosen = comparisons[(comparisons["data"] == lead) & (comparisons["metric"] == column)]
    chosen = chosen[chosen["solver"] == "lstsq"] if "solver" in chosen.columns else chosen
    for key, value in condition.items():
        chosen = chosen[chosen[key].map(_text) == _text(value)]
    h_qe, qe_pca = comparison_interval(chosen, "H", "QE"), comparison_interval(chosen, "QE", "PCA")
    runs = _matching_records(records, condition, lead)
    opening = (
        f"The paper (least squares, m = n = 18): H/QE {PAPER_RATIOS['H/QE']:.2g}, QE/PCA "
        f"{PAPER_RATIOS['QE/PCA']:.3g}. Here `{column}`, least squares, on {lead}, {where}. "
    )
    if math.isnan(h_qe.estimate) or math.isnan(qe_pca.estimate):
        claims = "These runs lack H or QE with least squares, or PCA, there: the claims are not assessed."
    else:
        claims = stored_claims_text(runs, lead)
    n = sorted({int(row["n"]) for row in (_lstsq_row(record, lead, "H") for record in runs) if row.get("n")})
    facts = [
        text
        for text in (
            coverage_text(runs, lead, n[0]) if len(n) == 1 else "",
            conditioning_text(runs, lead),
        )
        if text
    ]
    return (
        opening
        + claims
        + (f" Over the runs: {'; least squares: '.join(facts)}." if len(facts) == 2 else "")
        + (f" Over the runs: {facts[0]}." if len(facts) == 1 else "")
        + f" Design: {design_text(runs, lead, over, column, h_qe)}."
    )
