"""Intervals a reviewer accepts, and the paired comparisons that decide whether one basis beats another.

One :class:`Interval` for every number a run, a sweep, a report, a finding or a plot states with its uncertainty:
the estimate, its bounds, the confidence, how it was made and on how many units (``n``), and for a comparison the
value meaning "no difference" (``null``: 0 for a difference, 1 for a ratio). A comparison says "A < B" only where
its interval excludes that value (:attr:`Interval.excludes_null`), and :func:`interval_text` writes every interval
the same way, with its method and n beside it.

Across the replicates of a sweep (seeds, takes) the units are the runs. Alpha and point errors are positive and a
sweep has few replicates: a Student-t interval of the mean over 2 to 5 values reaches below zero whenever the values
spread, so levels get the geometric mean and a t-interval on the log values, taken back (:func:`geometric_interval`,
positive by construction). Two bases measured on the same replicates are compared by the per-replicate difference
(:func:`paired_difference_interval`) or log ratio (:func:`paired_ratio_interval`).

Within one run the units are the frames, and frames are autocorrelated: the per-frame paired difference of two rows
of the alpha table gets an overlapping-batch-means interval (:func:`batch_means_interval`, Meketon & Schmeiser
1984; the variance in :mod:`workbench.stats.time_series`): every run of ``L`` consecutive frames within a take is a
batch, ``L`` six integrated autocorrelation times of a deliberately high estimate of the series' persistence (between
n/30 and n/3 frames), the variance of the mean comes from the batch means' spread, made unbiased for an AR(1) of that
persistence, and the interval uses Student-t quantiles with about ``1.5 (n / L - 1)`` degrees of freedom (half as many
again as non-overlapping batches of the same length; :attr:`Interval.degrees`), the standard error widened by
``1 + 60 / d^2`` on ``d`` degrees (:data:`workbench.stats.time_series.THIN_DESIGN`: where few batches fit). Its coverage and its width over the
width a known variance would give are measured on AR(1) series by ``benchmarks/run.py coverage``
(docs/statistics.md). Each interval carries the p-value of its t statistic, for :func:`holm`; :func:`holm_intervals`
gives each member of a family the interval at the confidence of its Holm step, which excludes the null value exactly
where Holm rejects it.

Differences within ``TOL.tie_rel`` of the values compared are ties, never "A < B" (:func:`is_tie`).

Arrays in, an :class:`Interval` out; no pandas. Randomness comes only from a seeded ``numpy.random.Generator``.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, fields, replace
from typing import Callable, Mapping, Sequence

import numpy as np

from workbench.core.errors import WorkbenchError
from workbench.core.tolerances import TOL
from workbench.stats.multiplicity import holm, holm_levels  # noqa: F401  (holm_levels: re-exported)
from workbench.stats.time_series import (  # noqa: F401  (autocovariances: re-exported for callers)
    autocovariances,
    mean_variance,
    not_estimable_reason,
    persistence,
    take_spans,
    thin_design_widening,
)

CONFIDENCE = 0.95
GEOMETRIC = "geometric mean, t-interval on log values"
PAIRED_T = "paired t"
PAIRED_LOG_RATIO = "paired t on log ratios"
BLOCK_BOOTSTRAP = "circular block bootstrap over time"
BATCH_MEANS = "overlapping batch means over time, t-quantiles"
IDENTICAL = "identical on every frame"
TAIL_WIDENING = 1.2
"""The standard error of a difference of mean alphas over time (:func:`paired_mean_difference`) and of a ratio of
pooled alphas (:func:`workbench.stats.ratios.ratio_of_pooled`) is widened by this factor. A difference of alphas is
a difference of long-tailed levels that share the frame's difficulty, and pooled alphas are means of squared errors
(twice the log-normal sigma of the alphas): their estimate and estimated spread fall together when a run misses an
excursion, so misses fall on one side. Unwidened, on series like the workbench's (``benchmarks/run.py coverage``,
docs/statistics.md), the pooled difference covered 0.88-0.92 and the ratio of pooled alphas 0.92 at persistence
0.9-0.96; the ratio of mean alphas (:func:`workbench.stats.ratios.ratio_of_means`, the paper's claims) covered 0.935
or more where it was estimable with many batches and is not widened by it (every interval over time is widened where
few batches fit: :data:`workbench.stats.time_series.THIN_DESIGN`)."""
POOLED_DIFFERENCE_WIDENING = 1.35
"""The same for a difference of pooled alphas (:func:`paired_pooled_difference`): means of squared errors, whose
shared difficulty no log ratio cancels; at 1.2 it still covered 0.915-0.925 with squared errors of log-normal sigma
1.5 at persistence 0.9 and 0.99, at 1.35 0.934 or more (docs/statistics.md)."""
SIGNED = "{:+.3g}"
"""The number format of a difference (its sign always shown)."""
RATIO_FORMAT = "{:.4g}"
"""The number format of a ratio (as the comparisons table's cells, :func:`workbench.reporting.tables.cells.cell_text`)."""


@dataclass(frozen=True)
class Interval:
    """A point estimate and its two-sided confidence interval, with how it was made.

    Attributes
    ----------
    estimate : float
        A mean, a geometric mean, a mean difference or a geometric mean ratio.
    low, high : float
        The bounds; NaN when they cannot be computed (fewer than two replicates, or replicates that do not vary).
    n : int
        The units it rests on: replicates (runs) across a sweep, frames within a run.
    method : str
        How it was made (:data:`GEOMETRIC`, :data:`PAIRED_T`, :data:`PAIRED_LOG_RATIO`, :data:`BLOCK_BOOTSTRAP`,
        ...), named beside it wherever it is shown.
    confidence : float
        Coverage of ``[low, high]`` (0.95).
    null : float or None
        The value meaning "no difference": 0 for a difference, 1 for a ratio; None for a level.
    block_frames : int
        Block length of a block bootstrap (0: not one).
    block_seconds : float
        The block length in seconds of capture (NaN: not known or not a block bootstrap).
    p_value : float
        Two-sided p-value of the test of the null value by the same method (NaN: not computed); Holm's adjustment
        (:func:`holm`) works on these.
    scale : float
        The size of the values compared (the larger mean); a difference within ``TOL.tie_rel`` of it is a tie
        (:attr:`tied`). NaN: not known.
    p_adjusted : float
        The p-value after Holm's adjustment over a family of comparisons (:func:`holm`); when finite, the null is
        excluded only where it is below ``1 - confidence``. NaN: a primary contrast, or not adjusted.
    degrees : float
        The degrees of freedom of the Student-t quantiles the bounds rest on (``n - 1`` across replicates, those of
        the overlapping batch means within a run). NaN: not a t interval (or a record written before it was kept).
    adjusted_low, adjusted_high, adjusted_confidence : float
        The interval at the confidence of its Holm step (:func:`holm_intervals`): it excludes the null value exactly
        where the Holm-adjusted p-value is below ``1 - confidence``; ``low``/``high`` stay the unadjusted interval.
        NaN: not adjusted (or not a t interval).
    persistence : float
        The persistence the batches were sized and corrected with (:func:`workbench.stats.time_series.persistence`;
        NaN: not an interval over time, or a record written before it was kept).
    not_estimable : str
        Why the interval cannot inform, "" when it can (:attr:`estimable`): an interval over time whose degrees of
        freedom are below :data:`workbench.stats.time_series.MIN_DEGREES` or whose persistence is at its cap
        :data:`workbench.stats.time_series.PERSISTENCE_MAX` (:func:`workbench.stats.time_series.not_estimable_reason`).
        Its bounds are kept (in the record) but it decides nothing: :attr:`excludes_null` is False and
        :func:`interval_text` writes "not estimable: <why>" instead of them.
    """

    estimate: float
    low: float
    high: float
    n: int = 0
    method: str = ""
    confidence: float = CONFIDENCE
    null: float | None = None
    block_frames: int = 0
    block_seconds: float = math.nan
    p_value: float = math.nan
    scale: float = math.nan
    p_adjusted: float = math.nan
    degrees: float = math.nan
    adjusted_low: float = math.nan
    adjusted_high: float = math.nan
    adjusted_confidence: float = math.nan
    persistence: float = math.nan
    not_estimable: str = ""

    @property
    def estimable(self) -> bool:
        """Whether the interval can inform (:attr:`not_estimable` is empty)."""
        return not self.not_estimable

    @property
    def batches(self) -> float:
        """Frames over the batch length, ``n / block_frames``, of an interval over time (NaN otherwise)."""
        return self.n / self.block_frames if self.block_frames else math.nan

    @property
    def defined(self) -> bool:
        """Whether the interval has finite bounds."""
        return math.isfinite(self.low) and math.isfinite(self.high)

    @property
    def excludes_null(self) -> bool:
        """Whether the interval lies wholly on one side of its null value (a difference that is not zero, a ratio
        that is not 1): only then is "A < B" stated."""
        if self.null is None:
            raise ValueError("a level has no null value; only a difference or a ratio excludes one")
        if self.tied or not self.estimable:
            return False
        if math.isfinite(self.p_adjusted):
            return self.defined and self.p_adjusted < 1.0 - self.confidence
        return self.defined and not self.low <= self.null <= self.high

    @property
    def tied(self) -> bool:
        """Whether the estimate is within ``TOL.tie_rel`` of its null value, relative to :attr:`scale` for a
        difference and to 1 for a ratio: rounding, never a finding."""
        if self.null is None or math.isnan(self.estimate):
            return False
        scale = 1.0 if self.null == 1.0 else self.scale
        return math.isfinite(scale) and abs(self.estimate - self.null) <= TOL.tie_rel * abs(scale)

    @property
    def sign(self) -> int:
        """-1 when the interval lies below its null value, +1 above, 0 when it does not exclude it."""
        if not self.excludes_null:
            return 0
        return -1 if self.estimate < self.null else 1

    def as_dict(self) -> dict:
        """The fields by name (JSON-ready: a record's ``metrics.json`` stores its comparisons so)."""
        return asdict(self)

    @classmethod
    def from_dict(cls, values: Mapping) -> "Interval":
        """The interval of :meth:`as_dict`'s fields. A stored comparison without ``null`` is a difference (null 0),
        ``level`` is read as ``confidence`` (records written before the two were one type), and fields a record
        predates keep their defaults (NaN ``degrees``: not known)."""
        names = {field.name for field in fields(cls)} - {"null"}
        found = {key: values[key] for key in names if key in values}
        if "confidence" not in found and "level" in values:
            found["confidence"] = values["level"]
        return cls(**found, null=values.get("null", 0.0))


def interval_text(interval: Interval, name: str = "difference", number_format: str = "{:.3g}") -> str:
    """``difference 0.012, 95 % interval [0.004, 0.020] (paired t, n = 5)``: an estimate with its interval, its
    method and n (and a block bootstrap's block length).

    Parameters
    ----------
    interval : Interval
    name : str
        What the estimate is (``difference``, ``QE/H``, ``QE - H``, ...).
    number_format : str
        Of the estimate and the bounds (:data:`SIGNED` for a difference).

    Returns
    -------
    str
    """
    estimate = "-" if math.isnan(interval.estimate) else number_format.format(interval.estimate)
    if not interval.defined:
        why = "the same on every replicate" if interval.n >= 2 else f"{interval.method}, n = {interval.n}"
        return f"{name} {estimate} (no interval: {why})"
    if not interval.estimable:
        return f"{name} {estimate} (not estimable: {interval.not_estimable}; {interval.method}, n = {interval.n})"
    how = [interval.method] if interval.method else []
    if interval.block_frames:
        unit = "batches" if "batch means" in interval.method else "blocks"  # also a record of the earlier method
        how.append(
            f"{unit} of {interval.block_frames} frame{'s' if interval.block_frames > 1 else ''}"
            + (f" = {interval.block_seconds:.2g} s" if math.isfinite(interval.block_seconds) else "")
        )
    adjusted = f", Holm-adjusted p {interval.p_adjusted:.2g}" if math.isfinite(interval.p_adjusted) else ""
    adjusted += _holm_bounds_text(interval, number_format)
    return (
        f"{name} {estimate}, {100 * interval.confidence:g} % interval [{number_format.format(interval.low)}, "
        f"{number_format.format(interval.high)}] ({', '.join([*how, f'n = {interval.n}'])}){adjusted}"
    )


def short_interval_text(interval: Interval, name: str = "difference", number_format: str = "{:.3g}") -> str:
    """``QE - H +0.4 [+0.2, +0.6]``: an estimate and its bounds only, for text that names the interval's
    confidence and method once (with a Holm-adjusted p-value where there is one)."""
    estimate = "-" if math.isnan(interval.estimate) else number_format.format(interval.estimate)
    if not interval.defined:
        return f"{name} {estimate} (no interval)"
    if not interval.estimable:
        return f"{name} {estimate} (not estimable: {interval.not_estimable})"
    adjusted = f", Holm p {interval.p_adjusted:.2g}" if math.isfinite(interval.p_adjusted) else ""
    adjusted += _holm_bounds_text(interval, number_format)
    return f"{name} {estimate} [{number_format.format(interval.low)}, {number_format.format(interval.high)}]{adjusted}"


def _holm_bounds_text(interval: Interval, number_format: str) -> str:
    """``, Holm 99.6 % interval [a, b]``: the interval at its Holm step's confidence, when there is one."""
    if not (math.isfinite(interval.adjusted_low) and math.isfinite(interval.adjusted_high)):
        return ""
    return (
        f", Holm {100 * interval.adjusted_confidence:.3g} % interval [{number_format.format(interval.adjusted_low)}, "
        f"{number_format.format(interval.adjusted_high)}]"
    )


def comparison_name(first: str, second: str, interval: Interval) -> str:
    """``A - B`` for a difference, ``A/B`` for a ratio."""
    return f"{first}/{second}" if interval.null == 1.0 else f"{first} - {second}"


def reversed_interval(interval: Interval) -> Interval:
    """The comparison the other way round: ``b - a`` from ``a - b`` (negated), ``b / a`` from ``a / b`` (inverted),
    the bounds swapped.

    Parameters
    ----------
    interval : Interval
        Of a difference (null 0) or a positive ratio (null 1).

    Returns
    -------
    Interval
    """
    if interval.null == 0.0:
        return replace(
            interval,
            estimate=-interval.estimate,
            low=-interval.high,
            high=-interval.low,
            adjusted_low=-interval.adjusted_high,
            adjusted_high=-interval.adjusted_low,
        )
    if interval.null == 1.0:
        return replace(
            interval,
            estimate=1.0 / interval.estimate,
            low=1.0 / interval.high,
            high=1.0 / interval.low,
            adjusted_low=1.0 / interval.adjusted_high,
            adjusted_high=1.0 / interval.adjusted_low,
        )
    raise ValueError(f"only a difference (null 0) or a ratio (null 1) can be reversed, got null {interval.null}")


# ---------------------------------------------------------------------------------------------------------------
# Across replicates (the runs of a sweep)
# ---------------------------------------------------------------------------------------------------------------


def _finite(values) -> np.ndarray:
    values = np.asarray(values, dtype=np.float64).ravel()
    return values[np.isfinite(values)]


def _t_quantile(confidence: float, degrees: float) -> float:
    # scipy.stats.t.ppf is this function (t_gen._ppf), without importing scipy.stats (0.4 s at every start-up)
    from scipy.special import stdtrit

    return float(stdtrit(degrees, 0.5 + confidence / 2.0))


def t_interval(
    values, confidence: float = CONFIDENCE, *, method: str = "Student t", null: float | None = None
) -> Interval:
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
    error = float(values.std(ddof=1)) / math.sqrt(n)
    half = _t_quantile(confidence, n - 1) * error
    p_value = math.nan if null is None else _t_p_value((mean - null) / error, n - 1)
    return Interval(mean, mean - half, mean + half, n, method, confidence, null, p_value=p_value, degrees=n - 1.0)


def _t_p_value(statistic: float, degrees: float) -> float:
    """Two-sided p-value of a Student-t statistic."""
    from scipy.special import stdtr  # scipy.stats.t.sf(x, df) is stdtr(df, -x) (t_gen._sf)

    return float(2.0 * stdtr(degrees, -abs(statistic)))


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
        return Interval(
            math.nan, math.nan, math.nan, int(values.size), f"{GEOMETRIC} (needs positive values)", confidence
        )
    logs = t_interval(np.log(values), confidence)
    return Interval(
        math.exp(logs.estimate) if logs.n else math.nan,
        math.exp(logs.low),
        math.exp(logs.high),
        logs.n,
        GEOMETRIC,
        confidence,
        degrees=logs.degrees,
    )


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
    logs = t_interval(np.log(first[usable] / second[usable]), confidence, null=0.0)
    estimate = math.exp(logs.estimate) if logs.n else math.nan
    return Interval(
        estimate,
        math.exp(logs.low),
        math.exp(logs.high),
        logs.n,
        PAIRED_LOG_RATIO,
        confidence,
        1.0,
        p_value=logs.p_value,
        degrees=logs.degrees,
    )


# ---------------------------------------------------------------------------------------------------------------
# Within a run (the frames)
# ---------------------------------------------------------------------------------------------------------------


def batch_means_interval(
    series: np.ndarray,
    statistic: Callable[[np.ndarray], np.ndarray],
    *,
    takes: Sequence | None = None,
    seconds: Sequence | None = None,
    confidence: float = CONFIDENCE,
    scale: float = math.nan,
    widening: float = 1.0,
) -> Interval:
    """A statistic of per-frame means with its overlapping-batch-means interval over time; null 0 (a difference).

    The statistic is linearised at the means (delta method, central differences): the variance of the mean of each
    frame's influence ``grad . (x_t - mean)`` is that of overlapping batch means within takes
    (:func:`workbench.stats.time_series.mean_variance`: every run of ``L`` consecutive frames of a take is a batch,
    ``L`` six integrated autocorrelation times of the series' :func:`persistence`, the sum of squares made
    unbiased for an AR(1) of that persistence), and the interval is ``estimate +- t_{(1+c)/2, d} w sqrt(variance)``
    with ``d`` the overlapping batch means' degrees of freedom (about ``1.5 (n / L - 1)`` for one take) and
    ``w = widening (1 + THIN_DESIGN / d^2)`` (``time_series.THIN_DESIGN``: wider where few batches fit); the p-value
    is that of the t statistic.

    Parameters
    ----------
    series : ndarray of shape (k, n)
        The paired per-frame series whose means the statistic needs.
    statistic : callable
        Means of shape (k,) -> the statistic (a float).
    takes, seconds : sequence of shape (n,), optional
        Take and time of each frame (batches stay within takes; their length is also given in seconds).
    confidence : float
    scale : float
        The size of the values compared (:attr:`Interval.scale`).
    widening : float
        The standard error is multiplied by this (and the p-value is that of the widened t statistic):
        :data:`TAIL_WIDENING` for a difference of mean alphas or a ratio of pooled alphas,
        :data:`POOLED_DIFFERENCE_WIDENING` for a difference of pooled alphas, 1 for a ratio of mean alphas; and,
        for every statistic, by :func:`workbench.stats.time_series.thin_design_widening` of its degrees of freedom
        (``1 + 60 / d^2``: about 1 where many batches fit, 2.67 at the not-estimable threshold of 6).

    Returns
    -------
    Interval
        Method :data:`BATCH_MEANS`, ``n`` the frames, ``block_frames`` the batch length, ``degrees`` the t
        quantiles' degrees of freedom, ``persistence`` the one the batches were made with, ``not_estimable`` why
        it cannot inform (:func:`workbench.stats.time_series.not_estimable_reason`: fewer than ``MIN_DEGREES``
        degrees of freedom or the persistence at its cap); bounds NaN with less than one degree of freedom.
    """
    if not 0.0 < confidence < 1.0:
        raise WorkbenchError(f"the confidence level must be in (0, 1), got {confidence!r}")
    series = np.atleast_2d(np.asarray(series, dtype=float))
    n = series.shape[1]
    means = series.mean(axis=1)
    estimate = float(statistic(means))
    steps = 1e-6 * np.maximum(np.abs(means), 1e-300)
    gradient = np.array(
        [
            (statistic(means + step * unit) - statistic(means - step * unit)) / (2 * step)
            for step, unit in zip(steps, np.eye(len(means)))
        ]
    )
    influence = gradient @ (series - means[:, None])
    spans = take_spans(takes, n)
    phi = persistence(influence, takes)
    variance, degrees, length = mean_variance(influence, spans, phi)
    step = float(np.median(np.diff(np.asarray(seconds, dtype=float)))) if seconds is not None and n > 1 else math.nan
    found = Interval(
        estimate,
        math.nan,
        math.nan,
        n,
        BATCH_MEANS,
        confidence,
        0.0,
        length,
        length * step,
        scale=scale,
        persistence=phi,
        not_estimable=not_estimable_reason(degrees, phi),
    )
    if not degrees >= 1.0:
        return found
    found = replace(found, degrees=degrees)
    if variance <= 0.0:  # the same in every batch: the estimate is exact
        return replace(found, low=estimate, high=estimate, p_value=0.0 if estimate else 1.0)
    error = widening * thin_design_widening(degrees) * math.sqrt(variance)
    half = _t_quantile(confidence, degrees) * error
    return replace(found, low=estimate - half, high=estimate + half, p_value=_t_p_value(estimate / error, degrees))


def paired_mean_difference(
    a: np.ndarray,
    b: np.ndarray,
    *,
    takes: Sequence | None = None,
    seconds: Sequence | None = None,
    confidence: float = CONFIDENCE,
) -> Interval:
    """Mean over frames of ``a - b`` (two rows' per-frame alpha on the same frames), with its batch-means
    interval (:func:`batch_means_interval`). Frames where either value is NaN (alpha undefined) are left out of
    both means.

    Parameters
    ----------
    a, b : ndarray of shape (n_frames,)
    takes, seconds, confidence
        As :func:`batch_means_interval`.

    Returns
    -------
    Interval
        ``estimate`` = mean(a) - mean(b) over the frames both define; ``scale`` the larger of the two means.
    """
    a, b = _paired(a, b)
    valid = np.isfinite(a) & np.isfinite(b)
    if not valid.any():
        raise WorkbenchError("a paired difference needs at least one frame where both values are defined")
    difference = np.where(valid, a - b, 0.0)
    if not np.any(difference):
        return _identical(int(valid.sum()), confidence)
    scale = float(max(np.abs(a[valid]).mean(), np.abs(b[valid]).mean()))
    return batch_means_interval(
        np.vstack([difference, valid.astype(float)]),
        lambda m: m[0] / m[1],
        takes=takes,
        seconds=seconds,
        confidence=confidence,
        scale=scale,
        widening=TAIL_WIDENING,
    )


def paired_pooled_difference(
    error_a: np.ndarray,
    error_b: np.ndarray,
    reference: np.ndarray,
    *,
    takes: Sequence | None = None,
    seconds: Sequence | None = None,
    confidence: float = CONFIDENCE,
) -> Interval:
    """Difference of two pooled alphas (eq. 6 over all frames, ``100 sqrt(sum |err|^2 / sum |ref|^2)``) of the same
    frames, with its batch-means interval (:func:`batch_means_interval`, delta method).

    Parameters
    ----------
    error_a, error_b : ndarray of shape (n_frames,)
        Per-frame squared errors of the two reconstructions.
    reference : ndarray of shape (n_frames,)
        Per-frame squared reference norms (the denominator of eq. 6).
    takes, seconds, confidence
        As :func:`batch_means_interval`.

    Returns
    -------
    Interval
        ``scale`` the larger of the two pooled alphas.
    """
    error_a, error_b = _paired(error_a, error_b)
    reference = np.asarray(reference, dtype=float)
    if reference.shape != error_a.shape:
        raise WorkbenchError(f"reference must have one value per frame ({error_a.shape}), got {reference.shape}")
    if not np.any(error_a - error_b):
        return _identical(error_a.size, confidence)
    total = reference.sum()
    scale = 100.0 * math.sqrt(max(error_a.sum(), error_b.sum()) / total) if total > 0 else math.nan
    return batch_means_interval(
        np.vstack([error_a, error_b, reference]),
        lambda m: 100.0 * (np.sqrt(m[0] / m[2]) - np.sqrt(m[1] / m[2])),
        takes=takes,
        seconds=seconds,
        confidence=confidence,
        scale=scale,
        widening=POOLED_DIFFERENCE_WIDENING,
    )


def _paired(a, b) -> tuple[np.ndarray, np.ndarray]:
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    if a.ndim != 1 or a.shape != b.shape or a.size == 0:
        raise WorkbenchError(
            f"paired per-frame values must be two non-empty 1-D arrays of one length, got shapes "
            f"{a.shape} and {b.shape}"
        )
    return a, b


def _identical(n: int, confidence: float) -> Interval:
    """Two rows equal on every frame: the difference is exactly 0, not an estimate (no resampling can move it)."""
    return Interval(estimate=0.0, low=0.0, high=0.0, n=n, method=IDENTICAL, confidence=confidence, null=0.0)


# ---------------------------------------------------------------------------------------------------------------
# Stating an ordering
# ---------------------------------------------------------------------------------------------------------------

BETTER = " < "
TIED = " ~ "
EQUAL = " = "
"""Between two values within ``TOL.tie_rel`` of each other (:func:`values_tie`): equal, no interval spent."""


def values_tie(first: float, second: float, tolerance: float | None = None) -> bool:
    """Whether two values differ by no more than ``TOL.tie_rel`` (or ``tolerance``) times the larger of them."""
    tolerance = TOL.tie_rel if tolerance is None else tolerance
    return abs(first - second) <= tolerance * max(abs(first), abs(second))


def holm_intervals(intervals: Sequence[Interval], confidence: float = CONFIDENCE) -> list[Interval]:
    """A family's intervals with Holm's adjustment: each with its Holm-adjusted p-value (:func:`holm`) and its
    interval at the confidence of its Holm step (:func:`holm_levels`) in ``adjusted_low``/``adjusted_high``, which
    excludes the null value exactly where Holm rejects it; the unadjusted bounds are kept.

    The bounds are those of the same t statistic at the new quantile: ``estimate +- t_{(1+c')/2, d} error`` with
    ``error`` from the unadjusted bounds (on the log scale for a ratio), so an interval needs ``degrees`` (a t
    interval) and defined bounds to get adjusted ones.

    Parameters
    ----------
    intervals : sequence of Interval
        Of differences (null 0) or ratios (null 1), with their ``p_value`` (NaN: left out of the family).
    confidence : float
        The family-wise confidence.

    Returns
    -------
    list of Interval
        In the input order.
    """
    adjusted = holm([interval.p_value for interval in intervals])
    levels = holm_levels([interval.p_value for interval in intervals], confidence)
    found = []
    for interval, p_adjusted, level in zip(intervals, adjusted, levels):
        interval = replace(interval, p_adjusted=float(p_adjusted))
        if math.isfinite(level) and interval.defined and math.isfinite(interval.degrees):
            interval = _at_confidence(interval, float(level))
        found.append(interval)
    return found


def _at_confidence(interval: Interval, level: float) -> Interval:
    """``interval`` with ``adjusted_low``/``adjusted_high`` its t interval at confidence ``level``."""
    if level == interval.confidence:
        return replace(interval, adjusted_low=interval.low, adjusted_high=interval.high, adjusted_confidence=level)
    ratio = interval.null == 1.0
    forward, back = (np.log, np.exp) if ratio else (float, float)
    centre, low, high = (float(forward(value)) for value in (interval.estimate, interval.low, interval.high))
    scale = (high - low) / (2.0 * _t_quantile(interval.confidence, interval.degrees))
    half = _t_quantile(level, interval.degrees) * scale
    return replace(
        interval,
        adjusted_low=float(back(centre - half)),
        adjusted_high=float(back(centre + half)),
        adjusted_confidence=level,
    )


def ordering_text(
    values: Mapping,
    compare: Callable[[object, object], Interval | None],
    name: Callable[[object], str] = str,
    digits: int = 4,
    identity: Callable[[object, object], str | None] | None = None,
    detail: Callable[..., str] | None = None,
) -> str:
    """Items from smallest to largest value, each neighbouring pair joined by what its paired comparison allows.

    ``A 0.17 = B 0.17`` when the two values tie (:func:`values_tie`, or the interval is :attr:`Interval.tied`);
    ``A 0.17 < B 0.19`` when the interval of ``A - B`` (or ``A/B``) excludes its null value; ``A 1.04 ~ B 1.08 (A -
    B -0.04, 95 % interval [-0.09, +0.01] (method, n = k): not distinguishable)`` when it does not; ``A 0.17, B
    0.19`` when there is no comparison (no claim).

    Parameters
    ----------
    values : mapping
        Item -> its value (NaN items left out).
    compare : callable
        ``compare(a, b)`` -> the :class:`Interval` of ``a - b`` or ``a / b``, or None.
    name : callable
        Item -> its name in the text.
    digits : int
        Significant digits of the values.
    identity : callable, optional
        ``identity(a, b)`` -> why ``a <= b`` holds by construction, or None: such a pair is written ``A 0.15 <= B
        0.16 by construction (why)`` and its interval is not used.
    detail : callable, optional
        ``detail(interval, name, number_format)`` -> the text of a tie's interval (:func:`interval_text`, or
        :func:`short_interval_text` where the method is said once elsewhere).

    Returns
    -------
    str
    """
    ranked = sorted(
        (value, index, item)
        for index, (item, value) in enumerate(values.items())
        if value is not None and math.isfinite(value)
    )
    if not ranked:
        return ""
    text = f"{name(ranked[0][2])} {ranked[0][0]:.{digits}g}"
    for (previous, _, before), (value, _, item) in zip(ranked, ranked[1:]):
        interval = compare(before, item)
        shown = f"{name(item)} {value:.{digits}g}"
        reason = identity(before, item) if identity is not None else None
        if values_tie(previous, value) or (interval is not None and interval.tied):
            text += EQUAL + shown
        elif reason:
            text += f" <= {shown} by construction ({reason})"
        elif interval is None:
            text += ", " + shown
        elif interval.excludes_null:
            text += BETTER + shown
        else:
            label = comparison_name(name(before), name(item), interval)
            number = SIGNED if interval.null == 0.0 else RATIO_FORMAT
            said = (detail or interval_text)(interval, label, number)
            text += f"{TIED}{shown}" + (f" ({said}: not distinguishable)" if said else "")
    return text
