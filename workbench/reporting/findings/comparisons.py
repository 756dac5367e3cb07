"""The paired comparisons within a run as its report states them: the primary contrasts (the paper's two claims, at
their own 95 %), Holm's adjustment of the rest, the sentence that says how the orderings are read, and the table
'Paired comparisons within the run' with its method."""

from __future__ import annotations

import math
from typing import Mapping

import pandas as pd

from workbench.reporting.findings.claims import NOT_ESTIMABLE, NOT_TESTED, claim_cell
from workbench.stats.identities import identity_lookup, run_identities
from workbench.stats.statistics import (
    Interval,
)
from workbench.stats.stored import holm_adjusted


def finite_value(value) -> bool:
    """Whether a stored number is there and finite (records keep None or NaN where a value is missing)."""
    return value is not None and math.isfinite(value)


PRIMARY_CONTRASTS = (frozenset({("H", "lstsq"), ("QE", "lstsq")}), frozenset({("QE", "lstsq"), ("PCA", "projection")}))
"""The paper's two claims, with least squares: H against QE and QE against PCA (on the record's first data variant)."""


def primary_data(metrics: Mapping) -> str | None:
    """The data variant a record leads with (its first): where the primary contrasts are stated."""
    return next(iter(metrics.get("data") or {}), None)


def claim_comparison(stored: Mapping, pair: tuple, column: str) -> dict:
    """A stored claim (:mod:`workbench.study.claims`) as the comparison of its two rows: the ratio with its
    interval (null 1; no bounds where it is not estimable or not tested), marked ``claim``."""
    informs = stored["verdict"] not in (NOT_ESTIMABLE, NOT_TESTED)
    interval = Interval(
        stored["estimate"],
        stored["low"] if informs else math.nan,
        stored["high"] if informs else math.nan,
        n=stored["n"],
        method=stored["method"],
        confidence=stored["confidence"],
        null=1.0,
        block_frames=stored["block_frames"],
        block_seconds=stored["block_seconds"],
        degrees=stored["degrees"],
    )
    return {"a": list(pair[0]), "b": list(pair[1]), "column": column, **interval.as_dict(), "claim": dict(stored)}


def with_claims(metrics: Mapping) -> dict:
    """Data variant -> its stored comparisons, the primary contrasts of a variant with stored claims replaced by
    the claims themselves (:func:`claim_comparison`): a primary contrast is tested once, by its claim's ratio."""
    data_facts = metrics.get("data") or {}
    stored = {data: list(facts.get("comparisons") or []) for data, facts in data_facts.items()}
    claims = metrics.get("claims") or {}
    for entry in claims.get("entries") or []:
        if entry["data"] not in stored:
            continue
        kept = [c for c in stored[entry["data"]] if frozenset({tuple(c["a"]), tuple(c["b"])}) not in PRIMARY_CONTRASTS]
        pairs = {"H/QE": (("H", "lstsq"), ("QE", "lstsq")), "QE/PCA": (("QE", "lstsq"), ("PCA", "projection"))}
        stored[entry["data"]] = [
            claim_comparison(dict(entry[name], ratio=name), pair, claims["column"]) for name, pair in pairs.items()
        ] + kept
    return stored


def adjusted_comparisons(metrics: Mapping, solvers: Mapping | None = None) -> dict:
    """Data variant -> its stored comparisons (:func:`with_claims`), every one but the primary contrasts (the
    stored claims; on a record without them :data:`PRIMARY_CONTRASTS` on :func:`primary_data`) with its
    Holm-adjusted p-value (:func:`workbench.stats.stored.holm_adjusted`) over the run's family; comparisons of
    records without p-values keep their unadjusted interval. ``solvers``: the run's ``solver`` settings (its
    config), whose bounds decide which solvers nest (an identity, not tested)."""
    lead = primary_data(metrics)
    data_facts = metrics.get("data") or {}
    stored = with_claims(metrics)
    identities = {
        data: run_identities(
            [row for row in metrics.get("rows") or [] if row.get("data") == data], data_facts.get(data) or {}, solvers
        )
        for data in stored
    }

    def untested(data: str, entry: Mapping) -> bool:
        """A primary contrast (its own 95 %), an identity or a tie (no test at all): outside Holm's family."""
        a, b = tuple(entry["a"]), tuple(entry["b"])
        lookup = identity_lookup(identities[data], entry.get("column", ""))
        return (
            "claim" in entry
            or (not metrics.get("claims") and data == lead and frozenset({a, b}) in PRIMARY_CONTRASTS)
            or lookup(a, b) is not None
            or lookup(b, a) is not None
            or Interval.from_dict(entry).tied
        )

    return holm_adjusted(stored, untested) if any(stored.values()) else {}


def multiplicity_text(metrics: Mapping, solvers: Mapping | None = None) -> str:
    """The sentence that says how the run's orderings are decided, once, above them (``solvers``: the run's
    ``solver`` settings, :func:`adjusted_comparisons`)."""
    adjusted = adjusted_comparisons(metrics, solvers)
    family = sum(1 for entries in adjusted.values() for entry in entries if "holm_family" in entry)
    without = sum(
        1
        for entries in adjusted.values()
        for entry in entries
        if "holm_family" in entry and not finite_value(entry.get("p_value"))
    )
    text = (
        f"**how to read**: '<': the paired 95 % interval (batch means over time, docs/statistics.md) excludes "
        f"0; primary contrasts (H vs QE, QE vs PCA, lstsq, on {primary_data(metrics)}) at their own 95 %, the "
        f"other {family} Holm-adjusted; '=': a tie within tolerance; '<= by construction': an identity, not tested"
    )
    if without:
        text += f" ({without} comparisons of this record carry no p-value and keep their unadjusted interval)"
    return text + "."


def comparison_table(metrics: Mapping, column: str | None = None, solvers: Mapping | None = None) -> pd.DataFrame:
    """The run's paired comparisons as the report's table 'Paired comparisons within the run', with what decides
    each verdict: an identity (``a <= b by construction``, no test), a tie (``a = b``), or the interval, at its
    own 95 % for a primary contrast and Holm-adjusted otherwise (``p (Holm)``).

    Parameters
    ----------
    metrics : mapping
        The run's ``metrics.json``.
    column : str, optional
        The alpha column compared (the comparisons' own ``column`` when not given).
    solvers : mapping, optional
        The run's ``solver`` settings (its config): their bounds decide which solvers nest.

    Returns
    -------
    pandas.DataFrame
        One row per comparison: ``data``, ``a``, ``b``, ``a - b``, ``low``, ``high``, ``confidence`` (:func:`shown_interval`), ``p``,
        ``p (Holm)`` (NaN for a primary contrast; both NaN for an identity or a tie, which are not tested), ``frames``, ``batch (frames)``, ``batch (s)``, ``verdict``.
    """
    records = []
    for data, entries in adjusted_comparisons(metrics, solvers).items():
        facts = (metrics.get("data") or {}).get(data) or {}
        rows = [row for row in metrics.get("rows") or [] if row.get("data") == data]
        identities = run_identities(rows, facts, solvers)
        for entry in entries:
            interval = Interval.from_dict(entry)
            a, b = tuple(entry["a"]), tuple(entry["b"])
            lookup = identity_lookup(identities, column or entry.get("column", ""))
            found = lookup(a, b) or lookup(b, a)
            tested = found is None and not interval.tied
            if "claim" in entry:  # the paper's claim: its stored ratio test, no difference test beside it
                records.append(claim_row(data, a, b, entry["claim"]))
                continue
            if found is not None:
                verdict = f"{'a <= b' if lookup(a, b) else 'b <= a'} by construction ({found.reason})"
            elif interval.tied:  # round-off: '=', no interval beside it
                verdict = "a = b (within the tie tolerance)"
                records.append(tie_row(data, a, b, interval, verdict))
                continue
            else:
                verdict = {-1: "a < b", 1: "a > b", 0: "not distinguishable"}[interval.sign]
            records.append(
                {
                    "data": data,
                    "a": " ".join(a),
                    "b": " ".join(b),
                    "a - b": interval.estimate,
                    **shown_interval(interval, tested),
                    "p": interval.p_value if tested else math.nan,
                    "p (Holm)": interval.p_adjusted if tested else math.nan,
                    "frames": interval.n,
                    "batch (frames)": interval.block_frames,
                    "batch (s)": interval.block_seconds,
                    "verdict": verdict,
                }
            )
    return pd.DataFrame.from_records(records)


def tie_row(data: str, a: tuple, b: tuple, interval: Interval, verdict: str) -> dict:
    """A row of :func:`comparison_table` whose difference is round-off: '=' with no difference and no interval."""
    return {
        "data": data,
        "a": " ".join(a),
        "b": " ".join(b),
        "a - b": math.nan,
        "low": math.nan,
        "high": math.nan,
        "confidence": math.nan,
        "p": math.nan,
        "p (Holm)": math.nan,
        "frames": interval.n,
        "batch (frames)": interval.block_frames,
        "batch (s)": interval.block_seconds,
        "verdict": verdict,
    }


def claim_row(data: str, a: tuple, b: tuple, stored: Mapping) -> dict:
    """A primary contrast's row of :func:`comparison_table`: no difference, its stored claim as the verdict."""
    return {
        "data": data,
        "a": " ".join(a),
        "b": " ".join(b),
        "a - b": math.nan,
        "low": math.nan,
        "high": math.nan,
        "confidence": 100 * stored["confidence"],
        "p": math.nan,
        "p (Holm)": math.nan,
        "frames": stored["frames"],
        "batch (frames)": stored["batch_frames"],
        "batch (s)": stored["block_seconds"],
        "verdict": f"the paper's claim, {claim_cell(stored)} ({stored['rests_on']})",
    }


def shown_interval(interval: Interval, tested: bool) -> dict:
    """The interval a comparison row shows, the one its verdict rests on: at its Holm step's confidence for a member
    of the Holm family (it excludes 0 exactly when the adjusted p-value is below 0.05), else at 95 % (a primary
    contrast; an identity's or a tie's size).

    Returns
    -------
    dict
        ``low``, ``high`` and ``confidence`` (in %).
    """
    if tested and math.isfinite(interval.adjusted_low) and math.isfinite(interval.adjusted_high):
        return {
            "low": interval.adjusted_low,
            "high": interval.adjusted_high,
            "confidence": 100 * interval.adjusted_confidence,
        }
    return {"low": interval.low, "high": interval.high, "confidence": 100 * interval.confidence}


def comparison_method_text(metrics: Mapping) -> str:
    """The paragraph above :func:`comparison_table`: how its intervals, identities, ties and adjustment are made."""
    lead = primary_data(metrics)
    return (
        "Every '<' of the findings and of the printed headline is a row here. The difference is that of the "
        "headline alpha between two rows of the alpha table on the same evaluated frames; its 95 % interval "
        "comes from overlapping batch means over time: every run of six autocorrelation times of frames within a "
        "take is a batch, the variance made unbiased for an AR(1) of the series' persistence, Student-t quantiles "
        "with 1.5 (n / L - 1) degrees of freedom (coverage and width measured on AR(1) series in "
        "docs/statistics.md). H vs QE and QE vs PCA with lstsq "
        f"on {lead} are the primary contrasts: where the run stored the paper's claims, each of their rows is "
        "that claim's ratio test (its ratio, interval and verdict; no difference beside it); every other row's "
        "verdict uses its "
        "Holm-adjusted p-value over the run (p (Holm) < 0.05), and its interval (low, high) is shown at its "
        "Holm step's confidence, so that it excludes 0 exactly when the verdict says '<'. Orderings that hold by "
        "construction are marked so and not tested (no p-value; the interval is their size, at 95 %); "
        "differences within the tie tolerance are equal."
    )
