"""The paper's two claims as ratios: ``H/QE`` and ``QE/PCA`` of one run's alphas, each with its interval, and how
each compares with the ratio Kim & Ko report.

Within a run the ratio of two rows' alphas on the same frames gets the batch-means interval over time of
:func:`workbench.stats.statistics.batch_means_interval` on the log ratio (delta method: the log of the ratio of two
means, or of two pooled alphas, linearised at the means), taken back, so that the bounds are positive as the ratio
is; an interval resting on too few degrees of freedom, or on a persistence at its cap, is not estimable
(:attr:`workbench.stats.statistics.Interval.not_estimable`) and decides nothing. Across replicates (folds, seeds) the ratios get the paired t-interval on log
ratios (:func:`workbench.stats.statistics.paired_ratio_interval`). A ratio's null value is 1; no p-value is
computed, because the claims are read against the paper's ratios, not against 1 alone
(``workbench.reporting.findings.claims``).
"""

from __future__ import annotations

import math
from dataclasses import replace
from typing import Sequence

import numpy as np

from workbench.core.errors import WorkbenchError
from workbench.stats.statistics import CONFIDENCE, TAIL_WIDENING, Interval, batch_means_interval


def _ratio(log_interval: Interval) -> Interval:
    """The interval of a log ratio taken back to the ratio (positive bounds, as a ratio of alphas is)."""
    return replace(
        log_interval,
        estimate=math.exp(log_interval.estimate),
        low=math.exp(log_interval.low),
        high=math.exp(log_interval.high),
        null=1.0,
        p_value=math.nan,
        scale=math.nan,
    )


def _without_interval(sizes: np.ndarray, n: int, confidence: float) -> Interval:
    """A ratio with a zero (or negative) side: its value, and no interval (the log ratio is not defined)."""
    estimate = float(sizes[0] / sizes[1]) if sizes[1] > 0 else math.inf
    return Interval(estimate, math.nan, math.nan, n=n, confidence=confidence, null=1.0)


def ratio_of_means(
    a: np.ndarray,
    b: np.ndarray,
    *,
    takes: Sequence | None = None,
    seconds: Sequence | None = None,
    confidence: float = CONFIDENCE,
) -> Interval:
    """``mean(a) / mean(b)`` of two rows' per-frame alphas on the same frames, with its batch-means interval.

    Parameters
    ----------
    a, b : ndarray of shape (n_frames,)
        Frames where either is NaN are left out of both means.
    takes, seconds, confidence
        As :func:`workbench.stats.statistics.batch_means_interval`.

    Returns
    -------
    Interval
        Null 1, no p-value.
    """
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    if a.ndim != 1 or a.shape != b.shape:
        raise WorkbenchError(f"a ratio of means needs two 1-D arrays of one length, got {a.shape} and {b.shape}")
    valid = np.isfinite(a) & np.isfinite(b)
    if not valid.any() or not np.any(b[valid]):
        raise WorkbenchError("a ratio of means needs frames where both values are defined and the second is not 0")
    series = np.vstack([np.where(valid, a, 0.0), np.where(valid, b, 0.0)])
    if not np.all(series.sum(axis=1) > 0):
        return _without_interval(series.sum(axis=1), len(a), confidence)
    return _ratio(
        batch_means_interval(
            series, lambda m: math.log(m[0] / m[1]), takes=takes, seconds=seconds, confidence=confidence
        )
    )


def ratio_of_pooled(
    error_a: np.ndarray,
    error_b: np.ndarray,
    *,
    takes: Sequence | None = None,
    seconds: Sequence | None = None,
    confidence: float = CONFIDENCE,
) -> Interval:
    """The ratio of two pooled alphas of the same frames, ``sqrt(sum |err_a|^2 / sum |err_b|^2)`` (the reference
    of eq. 6 cancels), with its batch-means interval, its standard error widened by
    :data:`workbench.stats.statistics.TAIL_WIDENING` (means of squared errors have long tails).

    Parameters
    ----------
    error_a, error_b : ndarray of shape (n_frames,)
        Per-frame squared errors of the two reconstructions.
    takes, seconds, confidence
        As :func:`workbench.stats.statistics.batch_means_interval`.

    Returns
    -------
    Interval
        Null 1, no p-value.
    """
    error_a, error_b = np.asarray(error_a, dtype=float), np.asarray(error_b, dtype=float)
    if error_a.ndim != 1 or error_a.shape != error_b.shape or not np.any(error_b):
        raise WorkbenchError(
            f"a ratio of pooled alphas needs two 1-D arrays of squared errors of one length, the second not all 0, "
            f"got shapes {error_a.shape} and {error_b.shape}"
        )
    if not (error_a.sum() > 0 and error_b.sum() > 0):
        return _without_interval(np.sqrt([error_a.sum(), error_b.sum()]), error_a.size, confidence)
    return _ratio(
        batch_means_interval(
            np.vstack([error_a, error_b]),
            lambda m: 0.5 * math.log(m[0] / m[1]),
            takes=takes,
            seconds=seconds,
            confidence=confidence,
            widening=TAIL_WIDENING,
        )
    )
