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
of the alpha table gets a batch-means interval (:func:`batch_means_interval`): the frames are cut into 3 to 30
contiguous batches within takes (fewer when the series' persistence is long), the variance of the mean is taken from
the batch means, inflated by what an AR(1) series of the measured persistence would leave out (neighbouring batches
are still correlated), and the interval uses Student-t quantiles with (batches - 1) degrees of freedom. Its coverage
is measured on AR(1) series by ``benchmarks/run.py coverage`` (docs/statistics.md): at nominal 95 %, at least 93 %
for phi up to 0.99 at 800 and 4,000 frames, where the circular block bootstrap with the Politis-White block length
(:mod:`workbench.block_bootstrap`, kept for comparison) covered 82 % (phi 0.96, 800 frames). Each interval carries the p-value of its
t statistic, for :func:`holm`.

Differences within ``TOL.tie_rel`` of the values compared are ties, never "A < B" (:func:`is_tie`).

Arrays in, an :class:`Interval` out; no pandas. Randomness comes only from a seeded ``numpy.random.Generator``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Callable, Mapping, Sequence

import numpy as np

from workbench.core.errors import WorkbenchError
from workbench.core.tolerances import TOL

CONFIDENCE = 0.95
GEOMETRIC = "geometric mean, t-interval on log values"
PAIRED_T = "paired t"
PAIRED_LOG_RATIO = "paired t on log ratios"
BLOCK_BOOTSTRAP = "circular block bootstrap over time"
BATCH_MEANS = "batch means over time, t-quantiles"
IDENTICAL = "identical on every frame"
SIGNED = "{:+.3g}"
"""The number format of a difference (its sign always shown)."""
RATIO_FORMAT = "{:.4g}"
"""The number format of a ratio (as the comparisons table's cells, :func:`workbench.reporting.tables.cell_text`)."""


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
        if self.tied:
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
        return {
            "estimate": self.estimate,
            "low": self.low,
            "high": self.high,
            "n": self.n,
            "method": self.method,
            "confidence": self.confidence,
            "null": self.null,
            "block_frames": self.block_frames,
            "block_seconds": self.block_seconds,
            "p_value": self.p_value,
            "scale": self.scale,
            "p_adjusted": self.p_adjusted,
        }

    @classmethod
    def from_dict(cls, values: Mapping) -> "Interval":
        """The interval of :meth:`as_dict`'s fields. A stored comparison without ``null`` is a difference (null 0),
        and ``level`` is read as ``confidence`` (records written before the two were one type)."""
        fields = {
            key: values[key]
            for key in (
                "estimate",
                "low",
                "high",
                "n",
                "method",
                "confidence",
                "block_frames",
                "block_seconds",
                "p_value",
                "scale",
                "p_adjusted",
            )
            if key in values
        }
        if "confidence" not in fields and "level" in values:
            fields["confidence"] = values["level"]
        return cls(**fields, null=values.get("null", 0.0))


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
    how = [interval.method] if interval.method else []
    if interval.block_frames:
        unit = "batches" if interval.method == BATCH_MEANS else "blocks"
        how.append(
            f"{unit} of {interval.block_frames} frame{'s' if interval.block_frames > 1 else ''}"
            + (f" = {interval.block_seconds:.2g} s" if math.isfinite(interval.block_seconds) else "")
        )
    adjusted = f", Holm-adjusted p {interval.p_adjusted:.2g}" if math.isfinite(interval.p_adjusted) else ""
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
    adjusted = f", Holm p {interval.p_adjusted:.2g}" if math.isfinite(interval.p_adjusted) else ""
    return f"{name} {estimate} [{number_format.format(interval.low)}, {number_format.format(interval.high)}]{adjusted}"


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
        return replace(interval, estimate=-interval.estimate, low=-interval.high, high=-interval.low)
    if interval.null == 1.0:
        return replace(interval, estimate=1.0 / interval.estimate, low=1.0 / interval.high, high=1.0 / interval.low)
    raise ValueError(f"only a difference (null 0) or a ratio (null 1) can be reversed, got null {interval.null}")


# ---------------------------------------------------------------------------------------------------------------
# Across replicates (the runs of a sweep)
# ---------------------------------------------------------------------------------------------------------------


def _finite(values) -> np.ndarray:
    values = np.asarray(values, dtype=np.float64).ravel()
    return values[np.isfinite(values)]


def _t_quantile(confidence: float, degrees: int) -> float:
    from scipy import stats

    return float(stats.t.ppf(0.5 + confidence / 2.0, degrees))


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
    return Interval(mean, mean - half, mean + half, n, method, confidence, null, p_value=p_value)


def _t_p_value(statistic: float, degrees: float) -> float:
    """Two-sided p-value of a Student-t statistic."""
    from scipy import stats

    return float(2.0 * stats.t.sf(abs(statistic), degrees))


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
    )


# ---------------------------------------------------------------------------------------------------------------
# Within a run (the frames)
# ---------------------------------------------------------------------------------------------------------------


def take_spans(takes: Sequence | None, n: int) -> list[tuple[int, int]]:
    """(start, stop) of each run of consecutive frames of one take; one span when ``takes`` is None."""
    if takes is None:
        return [(0, n)]
    takes = np.asarray(takes)
    if takes.shape != (n,):
        raise WorkbenchError(f"takes must name the take of each of the {n} frames, got shape {takes.shape}")
    edges = [0, *(np.flatnonzero(takes[1:] != takes[:-1]) + 1).tolist(), n]
    return list(zip(edges[:-1], edges[1:]))


def autocovariances(series: np.ndarray, spans: Sequence[tuple[int, int]], max_lag: int) -> np.ndarray:
    """Autocovariances at lags ``0..max_lag`` of a series made of several takes, never pairing frames of two takes.

    Parameters
    ----------
    series : ndarray of shape (n,)
    spans : sequence of (start, stop)
        The takes (:func:`take_spans`).
    max_lag : int

    Returns
    -------
    ndarray of shape (max_lag + 1,)
        ``sum over takes and t of (x_t - mean)(x_{t+k} - mean) / n`` (the usual biased estimate).
    """
    centred = series - series.mean()
    values = np.zeros(max_lag + 1)
    for start, stop in spans:
        part = centred[start:stop]
        size = 1 << int(2 * len(part) - 1).bit_length()  # zero padding: the circular products become linear ones
        spectrum = np.fft.rfft(part, size)
        lags = min(max_lag, len(part) - 1) + 1
        values[:lags] += np.fft.irfft(spectrum * spectrum.conj(), size)[:lags]
    return values / len(series)


MIN_BATCHES, MAX_BATCHES = 3, 30
"""The batch count's range: 30 batches when the frames forget quickly, down to 3 when they remember long."""
BATCH_TAUS = 6.0
"""A batch spans at least this many integrated autocorrelation times ``(1 + phi) / (1 - phi)``."""
PERSISTENCE_SE = 2.0
"""The lag-1 estimate of :func:`persistence` is raised by this many standard errors."""
PERSISTENCE_MAX = 0.999
"""The persistence used for the batches and their correction is at most this (a unit root has no mean)."""


def persistence(series: np.ndarray, takes: Sequence | None = None) -> float:
    """A deliberately high estimate of the series' persistence, as the lag-1 coefficient ``phi`` of an AR(1).

    The larger of (a) the lag-1 autocorrelation within takes, corrected for its bias (Kendall 1954,
    ``+ (1 + 3 phi) / n``) and raised by :data:`PERSISTENCE_SE` standard errors ``sqrt((1 - phi^2) / n)``, and (b) the ``phi`` of an
    AR(1) with the integrated autocorrelation time ``tau`` of Geyer's initial positive sequence (1992),
    ``(tau - 1) / (tau + 1)``, which catches memory longer than lag 1 says. Erring high costs width; erring low
    costs coverage, which is what the batch means must keep.

    Parameters
    ----------
    series : ndarray of shape (n,)
    takes : sequence of shape (n,), optional

    Returns
    -------
    float
        In ``[0, PERSISTENCE_MAX]``.
    """
    series = np.asarray(series, dtype=float)
    n = series.size
    if n < 4:
        return 0.0
    acv = autocovariances(series, take_spans(takes, n), n - 1)
    if acv[0] <= 0.0:
        return 0.0
    rho = acv / acv[0]
    lag1 = float(rho[1]) + (1.0 + 3.0 * float(rho[1])) / n
    lag1 += PERSISTENCE_SE * math.sqrt(max(1.0 - lag1**2, 0.0) / n)
    pairs = rho[1 : (n - 1) // 2 * 2 + 1].reshape(-1, 2).sum(axis=1)
    positive = pairs[: int(np.argmax(pairs <= 0.0))] if np.any(pairs <= 0.0) else pairs
    tau = 1.0 + 2.0 * float(positive.sum())
    return float(min(max(lag1, (tau - 1.0) / (tau + 1.0), 0.0), PERSISTENCE_MAX))


def batch_edges(spans: Sequence[tuple[int, int]], phi: float) -> list[tuple[int, int]]:
    """Contiguous batches within takes: (start, stop) of each.

    A batch spans ``max(BATCH_TAUS tau, n / MAX_BATCHES)`` frames with ``tau = (1 + phi) / (1 - phi)``, and
    at most ``n / MIN_BATCHES``; each take is cut into as many whole batches of about that length as it holds
    (at least one).
    """
    n = sum(stop - start for start, stop in spans)
    tau = (1.0 + phi) / (1.0 - phi)
    length = min(max(BATCH_TAUS * tau, n / MAX_BATCHES), n / MIN_BATCHES)
    edges = []
    for start, stop in spans:
        count = max(1, int(math.floor((stop - start) / max(length, 1.0) + 1e-9)))
        cuts = np.round(np.linspace(start, stop, count + 1)).astype(int)
        edges += list(zip(cuts[:-1].tolist(), cuts[1:].tolist()))
    return edges


def _ar1_sum_variance(m, phi: float) -> np.ndarray:
    """Variance of the sum of ``m`` consecutive values of a unit-innovation AR(1) with coefficient ``phi``."""
    m = np.maximum(np.asarray(m, dtype=float), 0.0)  # pairs that overlap (the diagonal) are set apart
    return (m * (1 + phi) / (1 - phi) - 2 * phi * (1 - phi**m) / (1 - phi) ** 2) / (1 - phi**2)


def ar1_batch_correction(edges: Sequence[tuple[int, int]], spans: Sequence[tuple[int, int]], phi: float) -> float:
    """How much the batch-means variance of the mean falls short for an AR(1) of coefficient ``phi``: the true
    variance of the mean over the expected batch-means estimate, exact for the batches and takes given (takes
    independent), at least 1.

    Parameters
    ----------
    edges : sequence of (start, stop)
        The batches (:func:`batch_edges`).
    spans : sequence of (start, stop)
        The takes.
    phi : float
    """
    if phi <= 0.0 or len(edges) < 2:
        return 1.0
    starts, stops = np.array(edges).T
    take = np.searchsorted(np.array([start for start, _ in spans]), starts, side="right")
    a, b = np.meshgrid(starts, starts, indexing="ij"), np.meshgrid(stops, stops, indexing="ij")
    first, last = np.minimum(a[0], a[1]), np.maximum(b[0], b[1])
    low_stop, high_start = np.minimum(b[0], b[1]), np.maximum(a[0], a[1])
    # covariance of two batch sums: 1/2 (V(span) + V(gap) - V(first to the later start) - V(earlier stop to end))
    cross = 0.5 * (
        _ar1_sum_variance(last - first, phi)
        + _ar1_sum_variance(high_start - low_stop, phi)
        - _ar1_sum_variance(high_start - first, phi)
        - _ar1_sum_variance(last - low_stop, phi)
    )
    covariance = np.where(take[:, None] == take[None, :], cross, 0.0)
    np.fill_diagonal(covariance, _ar1_sum_variance(stops - starts, phi))
    n, count = float((stops - starts).sum()), len(edges)
    centring = np.eye(count) - np.outer((stops - starts) / n, np.ones(count))
    expected = count / (count - 1) * np.trace(centring @ covariance @ centring.T)
    return float(max(covariance.sum() / expected, 1.0))


def batch_means_interval(
    series: np.ndarray,
    statistic: Callable[[np.ndarray], np.ndarray],
    *,
    takes: Sequence | None = None,
    seconds: Sequence | None = None,
    confidence: float = CONFIDENCE,
    scale: float = math.nan,
) -> Interval:
    """A statistic of per-frame means with its batch-means interval over time; null 0 (a difference).

    The statistic is linearised at the means (delta method, central differences): each frame's influence
    ``grad . (x_t - mean)`` is cut into contiguous batches within takes (:func:`batch_edges`, their length from
    :func:`persistence`), the variance of its mean is ``b / (b - 1) sum_k (S_k - L_k zbar)^2 / n^2`` over the ``b``
    batch sums ``S_k`` of ``L_k`` frames, multiplied by :func:`ar1_batch_correction`, and the interval is
    ``estimate +- t_{(1+c)/2, b-1} sqrt(variance)``; the p-value is that of the t statistic.

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

    Returns
    -------
    Interval
        Method :data:`BATCH_MEANS`, ``n`` the frames, ``block_frames`` the median batch length; bounds NaN with
        fewer than two batches.
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
    spans, phi = take_spans(takes, n), persistence(influence, takes)
    edges = batch_edges(spans, phi)
    lengths = np.array([stop - start for start, stop in edges])
    step = float(np.median(np.diff(np.asarray(seconds, dtype=float)))) if seconds is not None and n > 1 else math.nan
    found = Interval(
        estimate,
        math.nan,
        math.nan,
        n,
        BATCH_MEANS,
        confidence,
        0.0,
        int(np.median(lengths)),
        float(np.median(lengths)) * step,
        scale=scale,
    )
    if len(edges) < 2:
        return found
    sums = np.array([influence[start:stop].sum() for start, stop in edges])
    variance = len(edges) / (len(edges) - 1) * float(np.sum((sums - lengths * influence.mean()) ** 2)) / n**2
    variance *= ar1_batch_correction(edges, spans, phi)
    if variance <= 0.0:  # the same in every batch: the estimate is exact (as a bootstrap would find it)
        return replace(found, low=estimate, high=estimate, p_value=0.0 if estimate else 1.0)
    error = math.sqrt(variance)
    half = _t_quantile(confidence, len(edges) - 1) * error
    return replace(
        found, low=estimate - half, high=estimate + half, p_value=_t_p_value(estimate / error, len(edges) - 1)
    )


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


def holm(p_values) -> np.ndarray:
    """Holm's step-down adjustment of p-values for multiple comparisons (Holm 1979): with the ``m`` finite
    p-values sorted, ``p_(k)`` becomes ``max_{j <= k} min(1, (m - j + 1) p_(j))``; an adjusted p-value below
    ``1 - confidence`` rejects its null with the family-wise error rate held at that level.

    Parameters
    ----------
    p_values : array_like of shape (m,)
        NaN for a comparison without a p-value (left out of ``m``, NaN in the result).

    Returns
    -------
    ndarray of shape (m,)
        In the input order.
    """
    values = np.asarray(p_values, dtype=float).ravel()
    adjusted = np.full(values.shape, math.nan)
    finite = np.flatnonzero(np.isfinite(values))
    order = finite[np.argsort(values[finite], kind="stable")]
    steps = (len(order) - np.arange(len(order))) * values[order]
    adjusted[order] = np.minimum(np.maximum.accumulate(steps), 1.0)
    return adjusted


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


def holm_adjusted(comparisons: Mapping[str, Sequence[Mapping]], primary: Callable[[str, Mapping], bool]) -> dict:
    """Stored comparisons with Holm's adjustment over the family of the non-primary ones.

    Parameters
    ----------
    comparisons : mapping
        Data variant -> its stored comparisons (``a``, ``b`` and :class:`Interval` fields, ``p_value`` among them).
    primary : callable
        ``primary(data, entry)``: whether a comparison is a primary contrast (stated at its own confidence).

    Returns
    -------
    dict
        The same entries (copies), each non-primary one with ``p_adjusted`` (NaN where it had no p-value) and
        ``holm_family`` (the family's size); the family is every non-primary comparison of every data variant.
    """
    adjusted = {data: [dict(entry) for entry in entries] for data, entries in comparisons.items()}
    family = [entry for data, entries in adjusted.items() for entry in entries if not primary(data, entry)]
    for entry, value in zip(family, holm([entry.get("p_value", math.nan) for entry in family])):
        entry["p_adjusted"], entry["holm_family"] = float(value), len(family)
    return adjusted


def comparison_lookup(comparisons: Sequence[Mapping]) -> Callable[[tuple, tuple], Interval | None]:
    """``compare(a, b)`` over stored comparisons (``a``, ``b`` and :class:`Interval` fields each): the interval of
    ``a`` against ``b``, the stored one of ``b`` against ``a`` reversed (:func:`reversed_interval`), or None."""
    stored = {(tuple(entry["a"]), tuple(entry["b"])): Interval.from_dict(entry) for entry in comparisons}

    def compare(a, b) -> Interval | None:
        a, b = tuple(a), tuple(b)
        if (a, b) in stored:
            return stored[a, b]
        if (b, a) in stored:
            return reversed_interval(stored[b, a])
        return None

    return compare
