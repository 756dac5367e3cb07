"""Paired comparisons within a run: the block length, the circular block bootstrap within takes, the intervals and
the orderings stated from them, on series whose answer is known."""

import math

import numpy as np
import pytest

from workbench.errors import WorkbenchError
from workbench.reporting import statistics
from workbench.reporting.statistics import (Interval, block_bootstrap_totals, comparison_lookup, format_interval,
                                            optimal_block_length, ordering_text, paired_mean_difference,
                                            paired_pooled_difference)


def ar1(n: int, phi: float, rng: np.random.Generator) -> np.ndarray:
    """A stationary AR(1) series with unit innovations."""
    noise = rng.standard_normal(n)
    series = np.empty(n)
    series[0] = noise[0] / math.sqrt(1.0 - phi ** 2)
    for t in range(1, n):
        series[t] = phi * series[t - 1] + noise[t]
    return series


def test_block_length_follows_the_theory_on_autoregressive_series():
    # Politis & White's circular-block length for AR(1): (3/2 (2 phi / (1 - phi^2))^2)^(1/3) n^(1/3)
    rng = np.random.default_rng(1)
    n = 20000
    for phi in (0.5, 0.9):
        theory = (1.5 * (2 * phi / (1 - phi ** 2)) ** 2) ** (1 / 3) * n ** (1 / 3)
        assert optimal_block_length(ar1(n, phi, rng)) == pytest.approx(theory, rel=0.2)
    assert optimal_block_length(rng.standard_normal(n)) < 4  # no memory: blocks of about one frame


def test_block_length_never_pairs_frames_of_two_takes():
    # two takes, each a constant: within each there is no variation around its own level... but around the common
    # mean each take is one flat step; pairing across the boundary would add a lag product of opposite signs
    rng = np.random.default_rng(2)
    series = np.concatenate([ar1(3000, 0.8, rng), ar1(3000, 0.8, rng)])
    takes = np.repeat(["a", "b"], 3000)
    values = statistics.autocovariances(series, statistics.take_spans(takes, 6000), 3)
    centred = series - series.mean()
    expected = (centred[:2999] @ centred[1:3000] + centred[3000:5999] @ centred[3001:]) / 6000
    assert values[1] == pytest.approx(expected, rel=1e-12)


def test_resamples_keep_each_take_whole():
    # +1 in take a, -1 in take b: a block crossing the boundary would change the totals, stratified resampling
    # within takes keeps every resample's total at 50 - 70 exactly
    series = np.concatenate([np.ones(50), -np.ones(70)])[None, :]
    takes = np.repeat(["a", "b"], [50, 70])
    totals = block_bootstrap_totals(series, 9, np.random.default_rng(0), takes=takes, n_resamples=300)
    np.testing.assert_array_equal(totals, -20.0)
    # without the takes the blocks wrap round the whole series and the totals vary
    assert np.ptp(block_bootstrap_totals(series, 9, np.random.default_rng(0), n_resamples=300)) > 0


def test_the_normal_route_has_the_bootstrap_s_exact_mean_and_covariance(monkeypatch):
    rng = np.random.default_rng(3)
    series = rng.standard_normal((2, 400))
    takes = np.repeat(["a", "b"], [150, 250])
    drawn = block_bootstrap_totals(series, 7, np.random.default_rng(4), takes=takes, n_resamples=40000)
    monkeypatch.setattr(statistics, "NORMAL_FROM_BLOCKS", 1)
    normal = block_bootstrap_totals(series, 7, np.random.default_rng(4), takes=takes, n_resamples=40000)
    # the circular scheme draws every frame equally often: the mean total is the series' own total
    np.testing.assert_allclose(normal.mean(axis=0), series.sum(axis=1), atol=4 * np.sqrt(np.diag(np.cov(drawn.T))
                                                                                        / 40000).max())
    # covariances agree to the Monte Carlo error of 40,000 draws (about 1 % of the variances)
    np.testing.assert_allclose(np.cov(normal.T), np.cov(drawn.T), atol=0.04 * np.diag(np.cov(drawn.T)).max())


def test_a_constant_difference_is_stated_and_a_sign_change_is_not():
    frames = np.arange(1000)
    a = 1.0 + 0.1 * np.sin(frames / 50.0)
    interval = paired_mean_difference(a, a - 0.25)
    assert (interval.estimate, interval.low, interval.high) == pytest.approx((0.25, 0.25, 0.25))
    assert interval.excludes_zero
    # the second half reverses the first: the mean difference is small against its block-bootstrap spread
    b = a + np.where(frames < 500, 0.3, -0.28) + 0.05 * np.random.default_rng(0).standard_normal(1000)
    interval = paired_mean_difference(a, b, seconds=frames / 120.0)
    assert interval.estimate == pytest.approx(np.mean(a - b))
    assert interval.low < 0 < interval.high and not interval.excludes_zero
    assert interval.block_frames > 1 and interval.block_seconds == pytest.approx(interval.block_frames / 120.0)
    assert "circular block bootstrap over 1000 frames" in interval.method and "seed 0" in interval.method


def test_identical_rows_are_not_distinguishable_and_undefined_frames_are_left_out():
    a = np.array([1.0, 2.0, np.nan, 3.0])
    interval = paired_mean_difference(a, a.copy())
    assert (interval.estimate, interval.low, interval.high, interval.excludes_zero) == (0.0, 0.0, 0.0, False)
    found = paired_mean_difference(a, np.array([0.5, 1.5, 7.0, 2.5]))
    assert found.estimate == pytest.approx(0.5) and found.n == 4
    with pytest.raises(WorkbenchError, match="one length"):
        paired_mean_difference(a, a[:3])


def test_the_same_seed_gives_the_same_interval():
    rng = np.random.default_rng(5)
    a, b = ar1(2000, 0.9, rng), ar1(2000, 0.9, rng)

    def bounds(seed):
        found = paired_mean_difference(a, b, seed=seed)
        return found.low, found.high

    assert bounds(3) == bounds(3)
    assert bounds(3) != bounds(4)


def test_the_interval_covers_the_true_difference_about_as_often_as_it_says():
    # 200 AR(1) series (phi 0.5, mean 0) of 1,000 frames: the 95 % interval of the mean holds 0 in about 95 %
    rng = np.random.default_rng(6)
    held = [paired_mean_difference(ar1(1000, 0.5, rng), np.zeros(1000), n_resamples=500, seed=k)
            for k in range(200)]
    coverage = np.mean([interval.low <= 0.0 <= interval.high for interval in held])
    assert 0.88 <= coverage <= 0.99


def test_pooled_difference_is_the_difference_of_the_pooled_alphas():
    rng = np.random.default_rng(7)
    reference = 100.0 + rng.random(500)
    error_a, error_b = 0.04 * reference * (1 + rng.random(500)), 0.01 * reference * (1 + rng.random(500))
    interval = paired_pooled_difference(error_a, error_b, reference)
    expected = 100 * (np.sqrt(error_a.sum() / reference.sum()) - np.sqrt(error_b.sum() / reference.sum()))
    assert interval.estimate == pytest.approx(expected, rel=1e-12)
    assert interval.low <= expected <= interval.high and interval.excludes_zero


def test_ordering_states_less_than_only_with_an_interval_that_excludes_zero():
    values = {"H": 1.08, "QE": 1.21, "QE-linear": 1.04, "PCA": 0.19}
    stored = [{"a": ["PCA"], "b": ["QE-linear"], "estimate": -0.85, "low": -0.9, "high": -0.8},
              {"a": ["H"], "b": ["QE-linear"], "estimate": 0.04, "low": -0.01, "high": 0.09},
              {"a": ["H"], "b": ["QE"], "estimate": -0.13, "low": -0.2, "high": -0.06}]
    lookup = comparison_lookup(stored)
    compare = lambda a, b: lookup((a,), (b,))  # noqa: E731
    assert ordering_text(values, compare) == ("PCA 0.19 < QE-linear 1.04 ~ H 1.08 (QE-linear - H -0.04 [-0.09, "
                                              "+0.01]: not distinguishable) < QE 1.21")
    # without comparisons nothing is claimed
    assert ordering_text(values, lambda a, b: None) == "PCA 0.19, QE-linear 1.04, H 1.08, QE 1.21"


def test_interval_text_and_round_trip():
    interval = Interval(estimate=0.0231, low=0.0104, high=0.0358, method="m", n=10, block_frames=3,
                        block_seconds=0.025)
    assert format_interval(interval) == "+0.0231 [+0.0104, +0.0358]"
    assert Interval.from_dict(interval.as_dict()) == interval
