"""Coverage and width of the reports' intervals on series whose answer is known (``python benchmarks/run.py
coverage``).

Within a run, for each frame count n and persistence phi, ``--replications`` stationary AR(1) series (unit
stationary variance, one ``numpy.random.Generator`` seeded by ``--seed``) are given to the interval of one run's
comparisons; printed are the share of intervals holding the true value, their mean width, that width over the
known-variance width ``2 z_0.975 sd`` (``sd`` the true standard deviation of the statistic, exact from the AR(1)'s
autocovariances) and the mean degrees of freedom of the t quantiles:

- ``mean``: :func:`workbench.stats.statistics.paired_mean_difference` of a series against zeros (true value 0);
- ``pooled, sigma s``: :func:`workbench.stats.statistics.paired_pooled_difference` of squared errors ``exp(s x_t)`` and
  ``exp(s y_t) / 4`` of two independent series over a constant reference of 100, log-normal of sigma ``s`` (0.5,
  and 1 as AnimFace's errors, whose p95/median is about 5); true value ``100 (sqrt(E e_a) - sqrt(E e_b)) / 10 =
  5 exp(s^2 / 4)``; its ``sd`` is that of the delta method's linearisation, exact for the lognormal's
  autocovariances ``exp(s^2) (exp(s^2 phi^h) - 1)``;
- ``ratio, sigma s``: :func:`workbench.stats.ratios.ratio_of_means` of per-frame alphas ``exp(s x_t)`` and
  ``exp(s y_t) / 4`` of two independent series (the interval of the paper's two claims, H/QE and QE/PCA); true
  value 4; its width is taken on the log ratio, where the interval is made, against the delta method's ``sd`` of
  ``log(mean_a / mean_b)``;
- ``bootstrap`` (``--with-bootstrap``): the circular block bootstrap with the Politis-White block length that the
  batch means replaced (:func:`workbench.block_bootstrap.bootstrap_interval`), for the mean.

Across replicates, ``seeds``: the paired t-interval on log ratios over 5 replicates
(:func:`workbench.stats.statistics.paired_ratio_interval`) when the log ratios are normal, and when they are
skewed (an exponential, shifted to mean 0, and a lognormal of sigma 1, shifted to mean 0), 5,000 families each.

Series like the workbench's own data (:mod:`workbench_designs`): two rows sharing the frame's difficulty (log errors
correlated 0.88), a reference that varies with it, log-normal tails of sigma 1 (AnimFace) and 1.5 (heavier),
persistence 0.5 to 0.99, one take of 800 or 4,000 frames or three takes of 398, 375 and 226 (AnimFace's headline).
``--design-replications`` series per cell (2,000 by default) are given to ``ratio of means`` (:func:`ratio_of_means`
of the per-frame alphas, the paper's claims), ``ratio of pooled`` (:func:`workbench.stats.ratios.ratio_of_pooled`),
``pooled difference`` (:func:`workbench.stats.statistics.paired_pooled_difference`) and ``mean difference``
(:func:`workbench.stats.statistics.paired_mean_difference` of the alphas). Printed per cell: the share of intervals
that are estimable (:attr:`workbench.stats.statistics.Interval.estimable`), the coverage of the statements made (an
interval that is "not estimable" states nothing and counts as holding the truth) and its binomial standard error,
the coverage of the estimable intervals alone and its binomial standard error (over the estimable intervals only),
and the coverage of every interval's bounds whether estimable or not.

A binomial standard error of a coverage near 0.95 over R replications is ``sqrt(0.95 * 0.05 / R)`` (0.0069 at
R = 1,000, 0.0049 at 2,000).
"""

from __future__ import annotations

import math

import block_bootstrap  # beside this file (benchmarks/ is on the path when run.py runs)
import numpy as np
import workbench_designs
from scipy import stats
from scipy.signal import lfilter

from workbench.stats import statistics
from workbench.stats.ratios import ratio_of_means, ratio_of_pooled
from workbench.stats.time_series import ar1_sum_variance

FRAMES = (800, 4000)
PERSISTENCES = (0.0, 0.5, 0.9, 0.96, 0.99)
SIGMAS = {"pooled, sigma 0.5": 0.5, "pooled, sigma 1": 1.0, "ratio, sigma 0.5": 0.5, "ratio, sigma 1": 1.0}
SEED_REPLICATES, SEED_FAMILIES = 5, 5000
Z = float(stats.norm.ppf(0.975))


def ar1_series(rng: np.random.Generator, n: int, phi: float, count: int) -> np.ndarray:
    """``count`` stationary AR(1) series of ``n`` values with coefficient ``phi`` and unit stationary variance.

    Returns
    -------
    ndarray of shape (count, n)
    """
    noise = rng.standard_normal((count, n)) * math.sqrt(1.0 - phi**2)
    noise[:, 0] /= math.sqrt(1.0 - phi**2)
    return lfilter([1.0], [1.0, -phi], noise, axis=1)


def mean_variance_of(covariance: np.ndarray) -> float:
    """Variance of the mean of ``n`` values of a stationary series with autocovariances ``covariance[0..n-1]``."""
    n = covariance.size
    weights = n - np.arange(n, dtype=float)
    weights[1:] *= 2.0
    return float(weights @ covariance) / n**2


def true_sd(kind: str, n: int, phi: float) -> float:
    """The standard deviation of the statistic a cell's interval is about (the mean's exactly; the pooled
    difference's by the delta method with the exact variance of the two means)."""
    if kind in ("mean", "bootstrap"):
        return math.sqrt((1.0 - phi**2) * float(ar1_sum_variance(n, phi))) / n
    s = SIGMAS[kind]
    lags = np.arange(n, dtype=float)
    variance = mean_variance_of(math.exp(s**2) * (np.exp(s**2 * phi**lags) - 1.0))
    mean = math.exp(s**2 / 2.0)
    if kind.startswith("ratio"):  # log(mean_a / mean_b) of two independent copies: each log mean's variance
        return math.sqrt(2.0 * variance / mean**2)
    # 10 (sqrt(m_a) - sqrt(m_b)) with m_b a quarter of an independent copy: gradients 5 / sqrt(mean_k)
    return math.sqrt(25.0 * variance / mean + 25.0 * (variance / 16.0) / (mean / 4.0))


def one_interval(kind: str, n: int, first: np.ndarray, second: np.ndarray | None, k: int):
    """The interval of one replication and the true value it should hold."""
    if kind == "mean":
        return statistics.paired_mean_difference(first, np.zeros(n)), 0.0
    if kind == "bootstrap":
        found = block_bootstrap.bootstrap_interval(
            first[None, :], lambda t: t[..., 0] / n, block_series=first, n_resamples=500, seed=k
        )
        return found, 0.0
    s = SIGMAS[kind]
    if kind.startswith("ratio"):
        return ratio_of_means(np.exp(s * first), np.exp(s * second) / 4.0), 4.0
    found = statistics.paired_pooled_difference(np.exp(s * first), np.exp(s * second) / 4.0, np.full(n, 100.0))
    return found, 5.0 * math.exp(s**2 / 4.0)


def coverage_row(kind: str, n: int, phi: float, replications: int, rng: np.random.Generator) -> dict:
    """Coverage, mean width, width over the known-variance width and mean degrees of freedom of one cell."""
    hits, widths, degrees = 0, [], []
    series = ar1_series(rng, n, phi, replications)
    others = ar1_series(rng, n, phi, replications) if kind.startswith(("pooled", "ratio")) else [None] * replications
    for k in range(replications):
        interval, truth = one_interval(kind, n, series[k], others[k], k)
        hits += interval.low <= truth <= interval.high
        # a ratio's interval is made on the log ratio: its width there
        widths.append(
            math.log(interval.high / interval.low) if kind.startswith("ratio") else interval.high - interval.low
        )
        degrees.append(getattr(interval, "degrees", math.nan))
    width = float(np.mean(widths))
    return {
        "interval": kind,
        "n": n,
        "phi": phi,
        "nominal": statistics.CONFIDENCE,
        "coverage": hits / replications,
        "mean width": width,
        "width ratio": width / (2.0 * Z * true_sd(kind, n, phi)),
        "degrees": float(np.nanmean(degrees)) if np.isfinite(degrees).any() else math.nan,
        "replications": replications,
    }


def seed_rows(rng: np.random.Generator, families: int = SEED_FAMILIES, size: int = SEED_REPLICATES) -> list[dict]:
    """Coverage of the paired t-interval on log ratios over ``size`` replicates, per shape of the log ratios."""
    shapes = {
        "normal": lambda: rng.standard_normal((families, size)),
        "exponential": lambda: rng.exponential(1.0, (families, size)) - 1.0,
        "lognormal sigma 1": lambda: rng.lognormal(0.0, 1.0, (families, size)) - math.exp(0.5),
    }
    rows = []
    for name, draw in shapes.items():
        logs = draw()  # true mean log ratio 0: true ratio 1
        held = [statistics.paired_ratio_interval(np.exp(row), np.ones(size)) for row in logs]
        rows.append(
            {
                "log ratios": name,
                "replicates": size,
                "coverage": float(np.mean([found.low <= 1.0 <= found.high for found in held])),
                "families": families,
            }
        )
    return rows


def bench_coverage(args) -> None:
    """Print the coverage and width table of the within-run intervals, then the seeds' coverage, then the coverage
    on series like the workbench's (:func:`bench_design_coverage`; only that with ``--designs-only``)."""
    if args.designs_only:
        bench_design_coverage(args)
        return
    rng = np.random.default_rng(args.seed)
    kinds = ["mean", *SIGMAS] + (["bootstrap"] if args.with_bootstrap else [])
    print(
        f"coverage of the within-run intervals on AR(1) series, seed {args.seed} "
        f"(binomial standard error at 0.95: {math.sqrt(0.95 * 0.05 / args.replications):.4f}); width ratio: mean "
        f"width / (2 z_0.975 true sd)"
    )
    print("| interval | n | phi | nominal | coverage | mean width | width ratio | t dof | replications |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|---:|")
    for kind in kinds:
        for n in FRAMES:
            for phi in PERSISTENCES:
                row = coverage_row(kind, n, phi, args.replications, rng)
                print(
                    f"| {row['interval']} | {n} | {phi:g} | {row['nominal']:.2f} | {row['coverage']:.3f} | "
                    f"{row['mean width']:.3g} | {row['width ratio']:.2f} | {row['degrees']:.3g} | "
                    f"{row['replications']} |",
                    flush=True,
                )
    print(f"\ncoverage of the paired t-interval on log ratios across replicates, seed {args.seed}")
    print("| log ratios | replicates | nominal | coverage | families |")
    print("|---|---:|---:|---:|---:|")
    for row in seed_rows(rng):
        print(
            f"| {row['log ratios']} | {row['replicates']} | {statistics.CONFIDENCE:.2f} | {row['coverage']:.3f} | "
            f"{row['families']} |"
        )
    bench_design_coverage(args)


DESIGN_PERSISTENCES = (0.5, 0.9, 0.96, 0.99)
DESIGN_KINDS = (
    ("ratio of means", 1.0),
    ("ratio of means", 1.5),
    ("ratio of pooled", 1.0),
    ("pooled difference", 1.0),
    ("pooled difference", 1.5),
    ("mean difference", 1.0),
    ("mean difference", 1.5),
)
"""(interval, log-normal sigma of the squared errors) of the workbench-like table."""


def design_interval(kind: str, error_a, error_b, reference, takes):
    """The interval ``kind`` of one series of :func:`workbench_designs.design_series`, and its true value's key."""
    if kind == "ratio of means":
        alpha_a, alpha_b = workbench_designs.alphas(error_a, reference), workbench_designs.alphas(error_b, reference)
        return ratio_of_means(alpha_a, alpha_b, takes=takes), "ratio"
    if kind == "ratio of pooled":
        return ratio_of_pooled(error_a, error_b, takes=takes), "ratio"
    if kind == "pooled difference":
        return statistics.paired_pooled_difference(error_a, error_b, reference, takes=takes), "pooled"
    alpha_a, alpha_b = workbench_designs.alphas(error_a, reference), workbench_designs.alphas(error_b, reference)
    return statistics.paired_mean_difference(alpha_a, alpha_b, takes=takes), "mean"


def design_row(kind: str, sigma: float, geometry: str, phi: float, replications: int, rng: np.random.Generator) -> dict:
    """One cell of the workbench-like table: estimable share, coverages and mean degrees of freedom."""
    sizes = workbench_designs.GEOMETRIES[geometry]
    takes = workbench_designs.take_labels(sizes) if len(sizes) > 1 else None
    error_a, error_b, reference = workbench_designs.design_series(rng, sizes, phi, sigma, replications)
    held, estimable, degrees = [], [], []
    for k in range(replications):
        interval, key = design_interval(kind, error_a[k], error_b[k], reference[k], takes)
        truth = workbench_designs.true_value(key, sigma)
        held.append(bool(interval.low <= truth <= interval.high))
        estimable.append(interval.estimable and interval.defined)
        degrees.append(interval.degrees)
    held, estimable = np.array(held), np.array(estimable)
    return {
        "interval": kind,
        "sigma": sigma,
        "takes": geometry,
        "phi": phi,
        "estimable": float(estimable.mean()),
        "coverage": float(np.where(estimable, held, True).mean()),
        "estimable coverage": float(held[estimable].mean()) if estimable.any() else math.nan,
        "estimable count": int(estimable.sum()),
        "bounds coverage": float(held.mean()),
        "degrees": float(np.nanmean(np.where(estimable, degrees, np.nan))) if estimable.any() else math.nan,
        "replications": replications,
    }


def bench_design_coverage(args) -> None:
    """Print the coverage table of the within-run intervals on series like the workbench's own data."""
    rng = np.random.default_rng(args.seed)
    replications = args.design_replications
    print(
        f"\ncoverage on series like the workbench's (rows sharing the frame's difficulty, log errors correlated "
        f"{workbench_designs.SHARED:g}, a reference that varies with it), seed {args.seed}, {replications} series "
        f"per cell (binomial standard error at 0.95: {math.sqrt(0.95 * 0.05 / replications):.4f}); coverage: of the "
        f"statements made (not estimable: no statement, counted as holding)"
    )
    print(
        "| interval | sigma | takes | phi | estimable | coverage | s.e. | estimable coverage | s.e. | bounds coverage | "
        "t dof | replications |"
    )
    print("|---|---:|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for kind, sigma in DESIGN_KINDS:
        for geometry in workbench_designs.GEOMETRIES:
            for phi in DESIGN_PERSISTENCES:
                row = design_row(kind, sigma, geometry, phi, replications, rng)
                error = math.sqrt(row["coverage"] * (1.0 - row["coverage"]) / replications)
                held, count = row["estimable coverage"], row["estimable count"]
                estimable_error = math.sqrt(held * (1.0 - held) / count) if count else math.nan
                print(
                    f"| {kind} | {sigma:g} | {geometry} | {phi:g} | {row['estimable']:.2f} | {row['coverage']:.3f} | "
                    f"{error:.4f} | {held:.3f} | {estimable_error:.4f} | {row['bounds coverage']:.3f} | "
                    f"{row['degrees']:.3g} | {replications} |",
                    flush=True,
                )
