"""Intervals and paired comparisons for the numbers a study reports.

Alpha and point errors are positive, and a sweep has few replicates (seeds). A Student-t interval of the mean
over 2 to 5 values reaches below zero whenever the values spread, so levels get the geometric mean and a
t-interval on the log values, taken back: a multiplicative interval that stays positive
(:func:`geometric_interval`). Two bases measured on the same replicates are compared by the per-replicate
difference (:func:`paired_difference_interval`) or log ratio (:func:`paired_ratio_interval`): one is better
than the other only when the 95 % interval excludes "no difference" (:attr:`Interval.distinguishes`). Every
interval carries its method and number of replicates, and :func:`interval_text` writes them beside it.

Pure NumPy/SciPy: arrays in, :class:`Interval` out.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

CONFIDENCE = 0.95
GEOMETRIC = "geometric mean, t-interval on log values"
PAIRED_T = "paired t"
PAIRED_LOG_RATIO = "paired t on log ratios"


@dataclass(frozen=True)
class Interval:
    """An estimate and its two-sided confidence interval.

    Attributes
    ----------
    estimate : float
        The point estimate (a mean, a geometric mean, a mean difference or a geometric mean ratio).
    low, high : float
        The interval's bounds; NaN when it cannot be computed (fewer than two values).
    n : int
        Replicates behind it (finite values used).
    method : str
        How it was computed, as printed beside it (:data:`GEOMETRIC`, :data:`PAIRED_T`, ...).
    confidence : float
    null : float or None
        The value meaning "no difference" (0 for a difference, 1 for a ratio); None for a level.
    """

    estimate: float
    low: float
    high: float
    n: int
    method: str
    confidence: float = CONFIDENCE
    null: float | None = None

    @property
    def defined(self) -> bool:
        """Whether the interval has finite bounds."""
        return math.isfinite(self.low) and math.isfinite(self.high)

    @property
    def distinguishes(self) -> bool:
        """Whether the interval excludes its null value (a difference that is not zero, a ratio that is not 1)."""
        if self.null is None:
            raise ValueError("a level has no null value; only a difference or a ratio distinguishes")
        return self.defined and not self.low <= self.null <= self.high

    @property
    def sign(self) -> int:
        """-1 when the interval lies below its null value, +1 above, 0 when it does not distinguish."""
        if not self.distinguishes:
            return 0
        return -1 if self.high < self.null else 1


def _finite(values) -> np.ndarray:
    values = np.asarray(values, dtype=np.float64).ravel()
    return values[np.isfinite(values)]


def _t_quantile(confidence: float, degrees: int) -> float:
    from scipy import stats

    return float(stats.t.ppf(0.5 + confidence / 2.0, degrees))


def t_interval(values, confidence: float = CONFIDENCE, *, method: str = "Student t",
               null: float | None = None) -> Interval:
    """Mean and two-sided Student-t interval of the mean, ``mean +- t_{(1+c)/2, n-1} s / sqrt(n)``.

    For values that may take either sign (differences). Non-finite values are left out.

    Parameters
    ----------
    values : array_like of shape (n,)
    confidence : float
    method : str
        Named in the result.
    null : float, optional

    Returns
    -------
    Interval
        Bounds NaN with fewer than two values, or when every value is the same: replicates that do not vary
        say nothing about the spread (a zero-width interval would claim a precision no replicate showed).
    """
    values = _finite(values)
    n = int(values.size)
    mean = float(values.mean()) if n else math.nan
    if n < 2 or np.ptp(values) == 0.0:
        return Interval(mean, math.nan, math.nan, n, method, confidence, null)
    half = _t_quantile(confidence, n - 1) * float(values.std(ddof=1)) / math.sqrt(n)
    return Interval(mean, mean - half, mean + half, n, method, confidence, null)


def geometric_interval(values, confidence: float = CONFIDENCE) -> Interval:
    """Geometric mean of positive values and its interval: the t-interval of the mean of ``log(values)``, taken
    back with ``exp`` (exact when the values are log-normal; the bounds are positive by construction).

    Parameters
    ----------
    values : array_like of shape (n,)
        Positive values (alpha, errors in mm, m, seconds); non-finite ones are left out.
    confidence : float

    Returns
    -------
    Interval
        ``estimate = exp(mean(log v))``, ``low``/``high`` = ``exp(mean +- t s / sqrt(n))``; bounds NaN with fewer
        than two values or identical ones (:func:`t_interval`), and every field NaN when a value is zero or
        negative (no geometric mean exists).
    """
    values = _finite(values)
    if np.any(values <= 0.0):
        return Interval(math.nan, math.nan, math.nan, int(values.size), f"{GEOMETRIC} (needs positive values)",
                        confidence)
    logs = t_interval(np.log(values), confidence)
    return Interval(math.exp(logs.estimate) if logs.n else math.nan, math.exp(logs.low), math.exp(logs.high),
                    logs.n, GEOMETRIC, confidence)


def paired_difference_interval(differences, confidence: float = CONFIDENCE) -> Interval:
    """Mean of paired differences ``a_k - b_k`` (one per replicate) and its Student-t interval; null 0.

    Parameters
    ----------
    differences : array_like of shape (n,)
        One difference per replicate (seed), both values measured on that replicate.
    confidence : float

    Returns
    -------
    Interval
    """
    return t_interval(differences, confidence, method=PAIRED_T, null=0.0)


def paired_ratio_interval(first, second, confidence: float = CONFIDENCE) -> Interval:
    """Geometric mean of the paired ratios ``a_k / b_k`` and its interval: the t-interval of the mean log ratio,
    taken back with ``exp``; null 1.

    Parameters
    ----------
    first, second : array_like of shape (n,)
        Positive values of the two alternatives on the same replicates, in the same order; pairs with a
        non-finite or non-positive value are left out.
    confidence : float

    Returns
    -------
    Interval
        Of ``first / second``: below 1 where the first is smaller.
    """
    first, second = np.asarray(first, dtype=np.float64).ravel(), np.asarray(second, dtype=np.float64).ravel()
    if first.shape != second.shape:
        raise ValueError(f"paired values need one of each per replicate, got {first.size} and {second.size}")
    usable = np.isfinite(first) & np.isfinite(second) & (first > 0) & (second > 0)
    logs = t_interval(np.log(first[usable] / second[usable]), confidence)
    estimate = math.exp(logs.estimate) if logs.n else math.nan
    return Interval(estimate, math.exp(logs.low), math.exp(logs.high), logs.n, PAIRED_LOG_RATIO, confidence, 1.0)


def reciprocal_interval(interval: Interval) -> Interval:
    """The interval of ``1 / ratio`` from that of a ratio (``b / a`` from ``a / b``): bounds swapped and inverted.

    Parameters
    ----------
    interval : Interval
        Of a positive ratio (null 1).

    Returns
    -------
    Interval
    """
    if interval.null != 1.0:
        raise ValueError(f"only the interval of a ratio (null 1) has a reciprocal, got null {interval.null}")
    return Interval(1.0 / interval.estimate, 1.0 / interval.high, 1.0 / interval.low, interval.n, interval.method,
                    interval.confidence, 1.0)


def interval_text(interval: Interval, name: str = "difference", number_format: str = "{:.3g}") -> str:
    """``difference 0.012, 95 % interval [0.004, 0.020] (paired t, n = 5)``: an estimate with its interval,
    method and replicates.

    Parameters
    ----------
    interval : Interval
    name : str
        What the estimate is (``difference``, ``QE/H``, ...).
    number_format : str

    Returns
    -------
    str
    """
    estimate = "-" if math.isnan(interval.estimate) else number_format.format(interval.estimate)
    if not interval.defined:
        why = "the same on every replicate" if interval.n >= 2 else f"{interval.method}, n = {interval.n}"
        return f"{name} {estimate} (no interval: {why})"
    return (f"{name} {estimate}, {100 * interval.confidence:g} % interval [{number_format.format(interval.low)}, "
            f"{number_format.format(interval.high)}] ({interval.method}, n = {interval.n})")
