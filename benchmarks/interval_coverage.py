"""Coverage of the within-run intervals on AR(1) series whose answer is known (``python benchmarks/run.py coverage``).

For each frame count n and persistence phi, ``--replications`` stationary AR(1) series (unit stationary variance,
one ``numpy.random.Generator`` seeded by ``--seed``) are given to the interval of one run's comparisons, and the
share of intervals holding the true value is printed with the intervals' mean width:

- ``mean``: :func:`workbench.stats.statistics.paired_mean_difference` of a series against zeros (true value 0);
- ``pooled``: :func:`workbench.stats.statistics.paired_pooled_difference` of squared errors ``exp(x_t / 2)``
  and ``exp(y_t / 2) / 4`` of two independent series over a constant reference of 100 (true value
  ``100 (sqrt(E e_a) - sqrt(E e_b)) / 10 = 5 exp(1/16)`` with ``E exp(x / 2) = exp(1/8)``);
- ``bootstrap`` (``--with-bootstrap``): the circular block bootstrap with the Politis-White block length that the
  batch means replaced (:func:`workbench.block_bootstrap.bootstrap_interval`), for the mean.

A binomial standard error of a coverage near 0.95 over R replications is ``sqrt(0.95 * 0.05 / R)`` (0.0069 at
R = 1,000).
"""

from __future__ import annotations

import math

import block_bootstrap  # beside this file (benchmarks/ is on the path when run.py runs)
import numpy as np
from scipy.signal import lfilter

from workbench.stats import statistics

FRAMES = (800, 4000)
PERSISTENCES = (0.0, 0.5, 0.9, 0.96, 0.99)
POOLED_TRUTH = 5.0 * math.exp(1.0 / 16.0)


def ar1_series(rng: np.random.Generator, n: int, phi: float, count: int) -> np.ndarray:
    """``count`` stationary AR(1) series of ``n`` values with coefficient ``phi`` and unit stationary variance.

    Returns
    -------
    ndarray of shape (count, n)
    """
    noise = rng.standard_normal((count, n)) * math.sqrt(1.0 - phi**2)
    noise[:, 0] /= math.sqrt(1.0 - phi**2)
    return lfilter([1.0], [1.0, -phi], noise, axis=1)


def coverage_row(kind: str, n: int, phi: float, replications: int, rng: np.random.Generator) -> dict:
    """Coverage and mean width of one interval on one (n, phi) cell."""
    hits, widths = 0, []
    series = ar1_series(rng, n, phi, replications)
    others = ar1_series(rng, n, phi, replications) if kind == "pooled" else None
    for k in range(replications):
        if kind == "mean":
            interval, truth = statistics.paired_mean_difference(series[k], np.zeros(n)), 0.0
        elif kind == "pooled":
            interval = statistics.paired_pooled_difference(
                np.exp(series[k] / 2.0), np.exp(others[k] / 2.0) / 4.0, np.full(n, 100.0)
            )
            truth = POOLED_TRUTH
        else:
            interval = block_bootstrap.bootstrap_interval(
                series[k][None, :], lambda t: t[..., 0] / n, block_series=series[k], n_resamples=500, seed=k
            )
            truth = 0.0
        hits += interval.low <= truth <= interval.high
        widths.append(interval.high - interval.low)
    return {
        "interval": kind,
        "n": n,
        "phi": phi,
        "nominal": statistics.CONFIDENCE,
        "coverage": hits / replications,
        "mean width": float(np.mean(widths)),
        "replications": replications,
    }


def bench_coverage(args) -> None:
    """Print the coverage table of the within-run intervals."""
    rng = np.random.default_rng(args.seed)
    kinds = ["mean", "pooled"] + (["bootstrap"] if args.with_bootstrap else [])
    print(
        f"coverage of the within-run intervals on AR(1) series, seed {args.seed} "
        f"(binomial standard error at 0.95: {math.sqrt(0.95 * 0.05 / args.replications):.4f})"
    )
    print("| interval | n | phi | nominal | coverage | mean width | replications |")
    print("|---|---:|---:|---:|---:|---:|---:|")
    for kind in kinds:
        for n in FRAMES:
            for phi in PERSISTENCES:
                row = coverage_row(kind, n, phi, args.replications, rng)
                print(
                    f"| {row['interval']} | {n} | {phi:g} | {row['nominal']:.2f} | {row['coverage']:.3f} | "
                    f"{row['mean width']:.3g} | {row['replications']} |",
                    flush=True,
                )
