"""The variance of a mean over autocorrelated frames, for the within-run intervals of
:func:`workbench.stats.statistics.batch_means_interval`: overlapping batch means within takes (Meketon & Schmeiser
1984), made unbiased for an AR(1) of a deliberately high persistence, with their degrees of freedom.

A series of frames comes in takes (contiguous runs of frames of one capture); no batch, autocovariance or
correction ever pairs frames of two takes, and takes are taken as independent of each other. Arrays in, floats out;
nothing is drawn at random.
"""

from __future__ import annotations

import math
from typing import Sequence

import numpy as np

from workbench.core.errors import WorkbenchError

MIN_BATCHES, MAX_BATCHES = 3, 30
"""A batch spans between ``n / MAX_BATCHES`` and ``n / MIN_BATCHES`` frames."""
BATCH_TAUS = 6.0
"""A batch spans at least this many integrated autocorrelation times ``(1 + phi) / (1 - phi)``."""
PERSISTENCE_SE = 2.0
"""The lag-1 estimate of :func:`persistence` is raised by this many standard errors."""
PERSISTENCE_MAX = 0.999
"""The persistence used for the batches and their correction is at most this (a unit root has no mean)."""
OVERLAP_DEGREES = 1.5
"""Degrees of freedom per batch length of overlapping batch means (Meketon & Schmeiser 1984: ``1.5 (n / b - 1)``)."""
MIN_DEGREES = 6.0
"""An interval resting on fewer degrees of freedom than this is not estimable (:func:`not_estimable_reason`): its
t quantile exceeds 2.45, and on series like the workbench's (rows sharing the frame's difficulty, persistence 0.96
and more; ``benchmarks/run.py coverage``, docs/statistics.md) such intervals no longer hold their 95 %."""
THIN_DESIGN = 60.0
"""The standard error of an interval over time is multiplied by ``1 + THIN_DESIGN / d^2`` (:func:`thin_design_widening`,
``d`` its degrees of freedom): 1.03 at 43 degrees (30 batches of one take), 1.15 at 20, 1.6 at 10, 2.67 at the
threshold 6. Where few batches fit, the persistence that sized them is itself uncertain, and the series that pass
:data:`MIN_DEGREES` are those whose persistence happened to look short: their batches are too short and their spread
too small, together. On series like the workbench's (``benchmarks/run.py coverage``, docs/statistics.md) the intervals
that were estimable covered only 0.57-0.93 in the designs whose memory is as long as the run (persistence 0.96-0.99
with 800 or 4,000 frames, or the three takes of 398, 375 and 226); a sharper threshold on the same estimate (more
degrees of freedom, or an effective sample size ``n (1 - phi) / (1 + phi)`` of 40-120) selected those series even
more strictly and covered less (0.59-0.91). With this widening the estimable intervals cover 0.946 or more in every
cell where 30 or more are estimable; at 50 the lowest was 0.941 and at 40 0.914 (seed 0, 2,000 series per cell)."""


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


def _ar1_persistence(series: np.ndarray, spans: Sequence[tuple[int, int]]) -> float:
    """The larger of the raised lag-1 estimate and Geyer's ``tau`` as an AR(1)'s ``phi`` (:func:`persistence`)."""
    n = series.size
    acv = autocovariances(series, spans, n - 1)
    if acv[0] <= 0.0:
        return 0.0
    rho = acv / acv[0]
    lag1 = float(rho[1]) + (1.0 + 3.0 * float(rho[1])) / n
    lag1 += PERSISTENCE_SE * math.sqrt(max(1.0 - lag1**2, 0.0) / n)
    pairs = rho[1 : (n - 1) // 2 * 2 + 1].reshape(-1, 2).sum(axis=1)
    positive = pairs[: int(np.argmax(pairs <= 0.0))] if np.any(pairs <= 0.0) else pairs
    tau = 1.0 + 2.0 * float(positive.sum())
    return max(lag1, (tau - 1.0) / (tau + 1.0), 0.0)


def normal_scores(series: np.ndarray) -> np.ndarray:
    """The series' ranks taken to standard normal quantiles, ``Phi^-1((rank - 1/2) / n)`` (ties share their mean
    rank): the same order, without the long tail."""
    from scipy.special import ndtri

    return ndtri((mean_ranks(series) - 0.5) / series.size)


def mean_ranks(series: np.ndarray) -> np.ndarray:
    """Ranks 1..n of a 1-D series, ties sharing their mean rank (``scipy.stats.rankdata``'s default, without
    importing ``scipy.stats``: 0.4 s at every start of a run that prints an interval).

    Parameters
    ----------
    series : ndarray of shape (n,)

    Returns
    -------
    ndarray of shape (n,) of float
    """
    order = np.argsort(series, kind="stable")
    ordered = series[order]
    new_value = np.concatenate(([True], ordered[1:] != ordered[:-1]))
    starts = np.flatnonzero(new_value)  # the first sorted position of each distinct value
    ends = np.append(starts[1:], series.size)  # one past its last
    mean_rank = (starts + ends + 1) / 2.0  # positions starts..ends-1 are ranks starts+1..ends
    ranks = np.empty(series.size)
    ranks[order] = np.repeat(mean_rank, ends - starts)
    return ranks


def persistence(series: np.ndarray, takes: Sequence | None = None) -> float:
    """A deliberately high estimate of the series' persistence, as the lag-1 coefficient ``phi`` of an AR(1).

    The larger of (a) the lag-1 autocorrelation within takes, corrected for its bias (Kendall 1954,
    ``+ (1 + 3 phi) / n``) and raised by :data:`PERSISTENCE_SE` standard errors ``sqrt((1 - phi^2) / n)``, and (b)
    the ``phi`` of an AR(1) with the integrated autocorrelation time ``tau`` of Geyer's initial positive sequence
    (1992), ``(tau - 1) / (tau + 1)``, which catches memory longer than lag 1 says; each computed on the series and
    on its :func:`normal_scores`. A long right tail (errors that share the frame's difficulty, log-normal) hides
    memory from the autocorrelations of the values, which a few large ones dominate; the ranks keep it. Erring high
    costs width; erring low costs coverage.

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
    if n < 4 or not np.ptp(series) > 0.0:
        return 0.0
    spans = take_spans(takes, n)
    found = max(_ar1_persistence(series, spans), _ar1_persistence(normal_scores(series), spans))
    return float(min(found, PERSISTENCE_MAX))


def batch_length(n: int, phi: float) -> int:
    """Frames per batch: ``BATCH_TAUS`` integrated autocorrelation times ``(1 + phi) / (1 - phi)``, between
    ``n / MAX_BATCHES`` and ``n / MIN_BATCHES`` (at least 1)."""
    tau = (1.0 + phi) / (1.0 - phi)
    return max(1, int(round(min(max(BATCH_TAUS * tau, n / MAX_BATCHES), n / MIN_BATCHES))))


def ar1_sum_variance(m, phi: float) -> np.ndarray:
    """Variance of the sum of ``m`` consecutive values of a unit-innovation AR(1) with coefficient ``phi`` (0 for
    ``m <= 0``).

    Parameters
    ----------
    m : array_like of int, any shape
    phi : float
        In ``[0, 1)``.

    Returns
    -------
    ndarray of the shape of ``m``
    """
    m = np.maximum(np.asarray(m, dtype=float), 0.0)
    return (m * (1 + phi) / (1 - phi) - 2 * phi * (1 - phi**m) / (1 - phi) ** 2) / (1 - phi**2)


def _take_batches(start: int, stop: int, length: int) -> tuple[np.ndarray, int]:
    """Starts of the overlapping batches of one take and their length (the whole take when it is shorter)."""
    size = min(length, stop - start)
    return np.arange(start, stop - size + 1), size


def _batch_deviations(
    influence: np.ndarray, spans: Sequence[tuple[int, int]], length: int
) -> list[tuple[np.ndarray, int]]:
    """Per take, ``S_j - L z_bar`` of every batch of ``L`` consecutive frames in it (``S_j`` its sum, ``z_bar`` the
    mean of all frames) and ``L``; a take shorter than ``length`` is one batch of its own length."""
    mean, deviations = float(influence.mean()), []
    for start, stop in spans:
        starts, size = _take_batches(start, stop, length)
        cumulative = np.concatenate([[0.0], np.cumsum(influence[start:stop] - mean)])
        deviations.append((cumulative[starts - start + size] - cumulative[starts - start], size))
    return deviations


def overlapping_batch_sum(influence: np.ndarray, spans: Sequence[tuple[int, int]], length: int) -> float:
    """``sum_j (S_j - L z_bar)^2 / L`` over every batch of ``L`` consecutive frames within a take.

    Parameters
    ----------
    influence : ndarray of shape (n,)
    spans : sequence of (start, stop)
    length : int

    Returns
    -------
    float
    """
    return float(sum(np.sum(sums**2) / size for sums, size in _batch_deviations(influence, spans, length)))


def ar1_overlapping_bias(spans: Sequence[tuple[int, int]], length: int, phi: float) -> float:
    """The true variance of the mean over the expected :func:`overlapping_batch_sum`, for a unit-innovation AR(1)
    of coefficient ``phi`` within each take and independent takes: the factor that makes the batch sum an unbiased
    estimate of the variance of the mean for that AR(1) (white noise at ``phi = 0``).

    Parameters
    ----------
    spans : sequence of (start, stop)
    length : int
    phi : float
        In ``[0, 1)``.

    Returns
    -------
    float
        NaN when the batch sum has no spread to expect (a single frame).
    """
    sizes = np.array([stop - start for start, stop in spans], dtype=float)
    n = float(sizes.sum())
    variance_of_total = float(ar1_sum_variance(sizes, phi).sum())  # n^2 times the variance of the mean
    expected = 0.0
    for take_size in sizes.astype(int):
        starts, size = _take_batches(0, take_size, length)
        before, after = starts, take_size - size - starts
        # covariance of a batch sum with its take's sum (the other takes are independent of it)
        with_take = 0.5 * (
            ar1_sum_variance(before + size, phi)
            + ar1_sum_variance(after + size, phi)
            - ar1_sum_variance(before, phi)
            - ar1_sum_variance(after, phi)
        )
        terms = ar1_sum_variance(size, phi) - 2.0 * size / n * with_take + size**2 * variance_of_total / n**2
        expected += float(np.sum(terms)) / size
    return variance_of_total / n**2 / expected if expected > 0.0 else math.nan  # NaN: one frame, no spread


def overlapping_degrees(spans: Sequence[tuple[int, int]], length: int) -> float:
    """Degrees of freedom of the overlapping batch means: ``f n_k / L - (f - 1)`` per take of ``n_k >= L`` frames (1
    for a take that is one batch), less 1 for the mean, with ``f = 1.5 - 0.5 / L``: ``1.5 (n / L - 1)`` for one take
    and long batches (Meketon & Schmeiser 1984), ``n - 1`` for batches of one frame (the sample variance), and
    ``batches - 1`` when every take is one batch."""
    factor = OVERLAP_DEGREES - (OVERLAP_DEGREES - 1.0) / length
    per_take = [factor * max(stop - start, length) / length - (factor - 1.0) for start, stop in spans]
    return float(sum(per_take) - 1.0)


def mean_variance(influence: np.ndarray, spans: Sequence[tuple[int, int]], phi: float) -> tuple[float, float, int]:
    """The variance of the mean of a series by overlapping batch means within takes, unbiased for an AR(1) of
    persistence ``phi``, with its degrees of freedom and the batch length.

    Parameters
    ----------
    influence : ndarray of shape (n,)
    spans : sequence of (start, stop)
        The takes.
    phi : float
        The persistence (:func:`persistence`).

    Returns
    -------
    variance : float
    degrees : float
        Student-t degrees of freedom (:func:`overlapping_degrees`).
    length : int
        Frames per batch (:func:`batch_length`).
    """
    length = batch_length(len(influence), phi)
    raw = overlapping_batch_sum(influence, spans, length)
    variance = raw * ar1_overlapping_bias(spans, length, phi)
    return variance, overlapping_degrees(spans, length), length


def thin_design_widening(degrees: float) -> float:
    """The factor ``1 + THIN_DESIGN / d^2`` by which an interval over time on ``degrees`` degrees of freedom is
    widened (:data:`THIN_DESIGN`), ``d`` the degrees but at least :data:`MIN_DEGREES`: below it the interval is not
    estimable and its kept bounds are those of the threshold's widening (2.67); 1 without degrees (NaN)."""
    if not degrees >= 0.0:
        return 1.0
    return 1.0 + THIN_DESIGN / max(degrees, MIN_DEGREES) ** 2


def not_estimable_reason(degrees: float, phi: float) -> str:
    """Why an interval over time cannot inform ("" when it can): fewer than :data:`MIN_DEGREES` degrees of
    freedom, or the persistence at its cap :data:`PERSISTENCE_MAX` (memory as long as the takes: the frames hold
    too few independent values to estimate the spread from).

    Parameters
    ----------
    degrees : float
        The interval's degrees of freedom (:func:`mean_variance`).
    phi : float
        The persistence it was made with (:func:`persistence`).

    Returns
    -------
    str
    """
    if phi >= PERSISTENCE_MAX:
        return f"persistence at its cap {PERSISTENCE_MAX:g}"
    if not degrees >= MIN_DEGREES:
        return f"{degrees:.2g} degrees of freedom, below {MIN_DEGREES:g}"
    return ""
