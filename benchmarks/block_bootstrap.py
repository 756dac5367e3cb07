"""The circular block bootstrap over time that the within-run intervals used before the batch means
(:func:`workbench.stats.statistics.batch_means_interval`) replaced it: kept to measure against
(``benchmarks/run.py coverage --with-bootstrap``; docs/statistics.md), where it covered 0.82 at AR(1) phi 0.96 and
800 frames for a nominal 0.95.

Blocks never cross from one take into another; the block length is chosen from the data (Politis & White 2004,
corrected by Patton, Politis & White 2009).
"""

from __future__ import annotations

import math
from typing import Callable, Sequence

import numpy as np

from workbench.core.errors import WorkbenchError
from workbench.stats.statistics import BLOCK_BOOTSTRAP, CONFIDENCE, Interval, autocovariances, take_spans

RESAMPLES = 2000
SEED = 0


def optimal_block_length(series: np.ndarray, takes: Sequence | None = None) -> float:
    """Block length of the circular block bootstrap for the mean of ``series`` (Politis & White 2004, with the
    correction of Patton, Politis & White 2009).

    The flat-top lag window's bandwidth is twice the smallest lag after which ``K_n`` autocorrelations in a row
    are insignificant (``|rho| < 2 sqrt(log10(n) / n)``, ``K_n = max(5, sqrt(log10(n)))``); then
    ``b = (2 G^2 / D)^(1/3) n^(1/3)`` with ``G = sum lambda(k/M) |k| R(k)`` and ``D = 4/3 (sum lambda(k/M)
    R(k))^2``, at most ``min(3 sqrt(n), n / 3)``.

    Parameters
    ----------
    series : ndarray of shape (n,)
        Finite values (a per-frame difference).
    takes : sequence of shape (n,), optional
        The take of each frame; lagged products never pair frames of two takes.

    Returns
    -------
    float
        In frames, at least 1.
    """
    series = np.asarray(series, dtype=float)
    n = series.size
    if n < 4:
        return 1.0
    spans = take_spans(takes, n)
    k_n = max(5, int(math.ceil(math.sqrt(math.log10(n)))))
    max_lag = min(int(math.ceil(math.sqrt(n))) + k_n, n - 1)
    acv = autocovariances(series, spans, max_lag)
    if acv[0] <= 0.0:
        return 1.0
    rho = np.abs(acv / acv[0])
    threshold = 2.0 * math.sqrt(math.log10(n) / n)
    bandwidth = max_lag
    for lag in range(1, max_lag - k_n + 2):
        if np.all(rho[lag : lag + k_n] < threshold):
            bandwidth = lag - 1
            break
    window = min(2 * max(bandwidth, 1), max_lag)
    lags = np.arange(1, window + 1)
    flat_top = np.where(lags / window <= 0.5, 1.0, 2.0 * (1.0 - lags / window))
    g = 2.0 * np.sum(flat_top * lags * acv[1 : window + 1])
    long_run = acv[0] + 2.0 * np.sum(flat_top * acv[1 : window + 1])
    if long_run <= 0.0:
        return 1.0
    block = (2.0 * g**2 / (4.0 / 3.0 * long_run**2)) ** (1.0 / 3.0) * n ** (1.0 / 3.0)
    return float(min(max(block, 1.0), 3.0 * math.sqrt(n), n / 3.0))


NORMAL_FROM_BLOCKS = 2000
"""From this many blocks per resample on, a resample's totals are drawn from the normal distribution with the
bootstrap's exact mean and covariance (a sum of that many independent blocks is normal to plotting accuracy)
instead of by drawing every block: the cost stays independent of the number of frames."""


def block_bootstrap_totals(
    series: np.ndarray,
    block: int,
    rng: np.random.Generator,
    *,
    takes: Sequence | None = None,
    n_resamples: int = RESAMPLES,
) -> np.ndarray:
    """Totals of several paired per-frame series over circular-block-bootstrap resamples of the frames.

    Each take is resampled on its own (stratified by take): it is cut into ``ceil(n_take / b)`` blocks of ``b =
    min(block, n_take)`` consecutive frames starting anywhere in the take and wrapping round its end, the last
    block shortened so the resample has the take's length. Every series is resampled with the same blocks (the
    pairing is kept); a block never joins the end of one take to another. With :data:`NORMAL_FROM_BLOCKS` blocks
    or more per resample, the totals are drawn from the normal distribution with the scheme's exact mean and
    covariance.

    Parameters
    ----------
    series : ndarray of shape (k, n)
        ``k`` per-frame series of the same ``n`` frames.
    block : int
        Block length in frames.
    rng : numpy.random.Generator
    takes : sequence of shape (n,), optional
    n_resamples : int

    Returns
    -------
    ndarray of shape (n_resamples, k)
        Each resample's sum of each series.
    """
    series = np.atleast_2d(np.asarray(series, dtype=float))
    n = series.shape[1]
    if isinstance(block, bool) or int(block) != block or block < 1:
        raise WorkbenchError(f"the bootstrap's block length must be a positive whole number of frames, got {block!r}")
    if isinstance(n_resamples, bool) or int(n_resamples) != n_resamples or n_resamples < 1:
        raise WorkbenchError(f"the number of bootstrap resamples must be a positive integer, got {n_resamples!r}")
    takes_blocks = []
    for start, stop in take_spans(takes, n):
        length = stop - start
        size = min(int(block), length)
        wrapped = np.concatenate([series[:, start:stop], series[:, start : start + size - 1]], axis=1)
        cumulative = np.concatenate([np.zeros((series.shape[0], 1)), np.cumsum(wrapped, axis=1)], axis=1)
        n_blocks = -(-length // size)
        lengths = np.full(n_blocks, size)
        lengths[-1] = length - (n_blocks - 1) * size
        takes_blocks.append((length, cumulative, lengths))
    if sum(len(lengths) for _, _, lengths in takes_blocks) >= NORMAL_FROM_BLOCKS:
        mean, covariance = _block_moments(takes_blocks)
        return rng.multivariate_normal(mean, covariance, size=int(n_resamples), method="eigh")
    totals = np.zeros((int(n_resamples), series.shape[0]))
    for length, cumulative, lengths in takes_blocks:
        starts = rng.integers(0, length, size=(int(n_resamples), len(lengths)))
        totals += (cumulative[:, starts + lengths] - cumulative[:, starts]).sum(axis=2).T
    return totals


def _block_moments(takes_blocks) -> tuple[np.ndarray, np.ndarray]:
    """Exact mean and covariance of the circular block bootstrap's totals (blocks start anywhere in their take,
    independently; the takes independently)."""
    mean, covariance = 0.0, 0.0
    for length, cumulative, lengths in takes_blocks:
        starts = np.arange(length)
        for size, count in zip(*np.unique(lengths, return_counts=True)):
            sums = cumulative[:, starts + size] - cumulative[:, starts]  # (k, length): every block of this size
            mean = mean + count * sums.mean(axis=1)
            covariance = covariance + count * np.atleast_2d(np.cov(sums, bias=True))
    return np.asarray(mean), np.asarray(covariance)


def bootstrap_interval(
    series: np.ndarray,
    statistic: Callable[[np.ndarray], np.ndarray],
    *,
    block_series: np.ndarray,
    takes: Sequence | None = None,
    seconds: Sequence | None = None,
    confidence: float = CONFIDENCE,
    n_resamples: int = RESAMPLES,
    seed: int = SEED,
) -> Interval:
    """The percentile interval of a statistic of per-frame totals under the circular block bootstrap; null 0 (the
    statistic is a difference).

    Parameters
    ----------
    series : ndarray of shape (k, n)
        The paired per-frame series whose totals the statistic needs.
    statistic : callable
        Totals of shape (..., k) -> the statistic, shape (...).
    block_series : ndarray of shape (n,)
        The series whose autocorrelation sets the block length (:func:`optimal_block_length`).
    takes, seconds : sequence of shape (n,), optional
        Take and time of each frame (blocks stay within takes; the block length is also given in seconds).
    confidence : float
    n_resamples : int
    seed : int
        Seed of the ``numpy.random.Generator`` (the same seed gives the same interval).

    Returns
    -------
    Interval
        Method :data:`BLOCK_BOOTSTRAP`, ``n`` the frames, with the block length in frames and seconds.
    """
    if not 0.0 < confidence < 1.0:
        raise WorkbenchError(f"the confidence level must be in (0, 1), got {confidence!r}")
    series = np.atleast_2d(np.asarray(series, dtype=float))
    n = series.shape[1]
    block = max(1, int(round(optimal_block_length(block_series, takes))))
    estimate = float(statistic(series.sum(axis=1)))
    with np.errstate(divide="ignore", invalid="ignore"):  # a resample of undefined frames only has no value
        resampled = statistic(
            block_bootstrap_totals(series, block, np.random.default_rng(seed), takes=takes, n_resamples=n_resamples)
        )
    low, high = np.nanquantile(resampled, [(1.0 - confidence) / 2.0, (1.0 + confidence) / 2.0])
    step = float(np.median(np.diff(np.asarray(seconds, dtype=float)))) if seconds is not None and n > 1 else math.nan
    return Interval(
        estimate=estimate,
        low=float(min(low, estimate)),
        high=float(max(high, estimate)),
        n=n,
        method=BLOCK_BOOTSTRAP,
        confidence=confidence,
        null=0.0,
        block_frames=block,
        block_seconds=block * step,
    )
