"""The paper's two claims and the verdicts a report states on them, from the intervals of its two ratios.

Kim & Ko report, with least squares at m = n = 18, H 5.2, QE 0.72 and PCA 0.62 % (alpha): QE far better than the
hand basis H (H/QE 7.2) and nearly as accurate as PCA (QE/PCA 1.16). A report opens with what its data say on each:

- claim 1, "QE better than H": reproduced when the interval of H/QE lies wholly above 1, not reproduced when wholly
  below 1, else not decided; and where the paper's 7.2 lies relative to that interval;
- claim 2, "QE nearly as accurate as PCA (QE/PCA <= 1.16)": reproduced when the interval of QE/PCA lies wholly at or
  below 1.16, not reproduced when wholly above it, else not decided; when QE <= PCA holds by construction (QE spans
  PCA's reconstruction, :mod:`workbench.stats.identities`) it is said so and not tested.

:func:`claim_verdicts` is the one place that decides them; a run's summary and a sweep's summary both call it.
"""

from __future__ import annotations

import math
from dataclasses import replace
from typing import NamedTuple

from workbench.stats.statistics import Interval

PAPER_ALPHA = {"H": 5.2, "QE": 0.72, "PCA": 0.62}
"""The paper's alpha (%) of the hand basis, the quasi-eigen faces and PCA, with least squares at m = n = 18."""
PAPER_RATIOS = {"H/QE": PAPER_ALPHA["H"] / PAPER_ALPHA["QE"], "QE/PCA": PAPER_ALPHA["QE"] / PAPER_ALPHA["PCA"]}
"""The paper's ratios, from its absolute alpha: H/QE 7.2, QE/PCA 1.16."""
REPRODUCED = "reproduced"
NOT_REPRODUCED = "not reproduced"
NOT_DECIDED = "not decided"
BY_CONSTRUCTION = "holds by construction"
CLAIM_1 = "QE better than H"
CLAIM_2 = f"QE nearly as accurate as PCA (QE/PCA <= {PAPER_RATIOS['QE/PCA']:.3g})"


class ClaimVerdicts(NamedTuple):
    """The two verdict texts (each begins with the claim and its decision), and the decisions alone."""

    h_over_qe: str
    qe_over_pca: str
    h_over_qe_decision: str
    qe_over_pca_decision: str


def ratio_interval_text(interval: Interval, name: str, brief: bool = False) -> str:
    """``H/QE 2.1 [1.7, 2.6] (95 % interval, paired t on log ratios, n = 5)``, with ``Holm p`` where the interval
    carries a Holm-adjusted p-value, and ``no interval`` where its bounds are not finite; ``brief``: without the
    parenthesis (for a text that says once how its intervals are made)."""
    estimate = "-" if math.isnan(interval.estimate) else f"{interval.estimate:.3g}"
    how = ", ".join(part for part in (interval.method, f"n = {interval.n}") if part)
    if not interval.defined:
        return f"{name} {estimate} (no interval" + ("" if brief else f": {how}") + ")"
    adjusted = f", Holm p {interval.p_adjusted:.2g}" if math.isfinite(interval.p_adjusted) else ""
    bounds = f"{name} {estimate} [{interval.low:.3g}, {interval.high:.3g}]"
    return bounds if brief else f"{bounds} ({100 * interval.confidence:g} % interval, {how}{adjusted})"


def where_paper_lies(interval: Interval, paper: float) -> str:
    """``the paper's 7.2 lies above it``: the paper's value against the interval (against the estimate when the
    interval has no finite bounds)."""
    if not interval.defined:
        side = "above" if paper > interval.estimate else "below"
        return f"the paper's {paper:.2g} lies {side} the estimate"
    if paper > interval.high:
        return f"the paper's {paper:.2g} lies above it"
    if paper < interval.low:
        return f"the paper's {paper:.2g} lies below it"
    return f"the paper's {paper:.2g} lies within it"


def first_claim(h_over_qe: Interval) -> str:
    """Claim 1's decision from the interval of H/QE (null 1): above 1 reproduced, below 1 not; where the interval
    carries a Holm-adjusted p-value, it decides whether 1 is excluded (:attr:`Interval.excludes_null`)."""
    interval = replace(h_over_qe, null=1.0)
    if math.isnan(interval.estimate) or not interval.excludes_null:
        return NOT_DECIDED
    return REPRODUCED if interval.estimate > 1.0 else NOT_REPRODUCED


def second_claim(qe_over_pca: Interval, bound: float = PAPER_RATIOS["QE/PCA"]) -> str:
    """Claim 2's decision from the interval of QE/PCA against the paper's ``bound``: wholly at or below it
    reproduced, wholly above it not, else (or without finite bounds) not decided."""
    if not qe_over_pca.defined:
        return NOT_DECIDED
    if qe_over_pca.high <= bound:
        return REPRODUCED
    return NOT_REPRODUCED if qe_over_pca.low > bound else NOT_DECIDED


def claim_verdicts(
    h_over_qe: Interval, qe_over_pca: Interval, qe_below_pca_by_construction: bool, brief: bool = False
) -> ClaimVerdicts:
    """The verdicts on the paper's two claims, each as text with its interval.

    Parameters
    ----------
    h_over_qe : Interval
        H/QE (a ratio of alphas, least squares) with its 95 % interval; its ``p_adjusted``, where finite, decides
        whether 1 is excluded (a Holm family), else its bounds do.
    qe_over_pca : Interval
        QE/PCA with its 95 % interval.
    qe_below_pca_by_construction : bool
        Whether QE <= PCA holds by construction in every run the interval rests on: then claim 2 holds whatever
        the data, is not tested, and only the size of QE/PCA is stated.
    brief : bool
        Intervals without their method and n (:func:`ratio_interval_text`).

    Returns
    -------
    ClaimVerdicts
        ``h_over_qe``: ``QE better than H: reproduced, H/QE 2.1 [1.7, 2.6] (95 % interval, paired t on log
        ratios, n = 5); the paper's 7.2 lies above it``; ``qe_over_pca`` likewise against 1.16; and the two
        decisions (:data:`REPRODUCED`, :data:`NOT_REPRODUCED`, :data:`NOT_DECIDED`, :data:`BY_CONSTRUCTION`).
    """
    first = first_claim(h_over_qe)
    one = (
        f"{CLAIM_1}: {first}, {ratio_interval_text(h_over_qe, 'H/QE', brief)}; "
        f"{where_paper_lies(h_over_qe, PAPER_RATIOS['H/QE'])}"
    )
    # claim 2 is decided against 1.16 by the interval alone: a Holm p-value (a test against 1) is not its evidence
    size = ratio_interval_text(replace(qe_over_pca, p_adjusted=math.nan), "QE/PCA", brief)
    if qe_below_pca_by_construction:
        second = BY_CONSTRUCTION
        two = f"{CLAIM_2}: {second} (QE <= PCA in every run whatever the data), not tested; its size {size}"
    else:
        second = second_claim(qe_over_pca)
        two = f"{CLAIM_2}: {second}, {size}"
    return ClaimVerdicts(one, two, first, second)
