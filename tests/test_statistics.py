"""The statistics of the reports: intervals that stay positive, paired comparisons, and their text; known answers
computed by hand and the coverage of the geometric interval on log-normal samples."""

import math

import numpy as np
import pytest

from workbench.reporting.statistics import (GEOMETRIC, PAIRED_LOG_RATIO, PAIRED_T, Interval, geometric_interval,
                                            interval_text, paired_difference_interval, paired_ratio_interval,
                                            reciprocal_interval, t_interval)

T_975_2 = 4.302652729749462  # Student t, 97.5 % quantile, 2 degrees of freedom (tables: 4.3027)
T_975_4 = 2.7764451051977934  # 4 degrees of freedom (tables: 2.7764)


def test_geometric_interval_of_1_2_4_by_hand():
    # logs 0, ln 2, 2 ln 2: mean ln 2, sample sd ln 2; bounds 2 exp(-+ t ln 2 / sqrt 3)
    interval = geometric_interval([1.0, 2.0, 4.0])
    half = T_975_2 * math.log(2.0) / math.sqrt(3.0)
    assert interval.estimate == pytest.approx(2.0, rel=1e-12)
    assert interval.low == pytest.approx(2.0 * math.exp(-half), rel=1e-9)
    assert interval.high == pytest.approx(2.0 * math.exp(half), rel=1e-9)
    assert (interval.n, interval.method, interval.null) == (3, GEOMETRIC, None)
    assert interval.low > 0  # the Student-t interval of the mean, 7/3 -+ 3.79, reaches -1.46
    assert t_interval([1.0, 2.0, 4.0]).low == pytest.approx(7 / 3 - T_975_2 * math.sqrt(7 / 3) / math.sqrt(3))


def test_geometric_interval_covers_the_geometric_mean_of_log_normal_samples_95_percent_of_the_time():
    rng = np.random.default_rng(20261124)
    mu, sigma, n, repeats = -1.2, 0.6, 5, 4000
    samples = rng.lognormal(mu, sigma, size=(repeats, n))
    intervals = [geometric_interval(sample) for sample in samples]
    covered = np.mean([interval.low <= math.exp(mu) <= interval.high for interval in intervals])
    # binomial standard error sqrt(0.95 * 0.05 / 4000) = 0.0034: 0.95 within four of them
    assert abs(covered - 0.95) < 0.014, covered
    assert min(interval.low for interval in intervals) > 0


def test_geometric_interval_needs_two_positive_values():
    single = geometric_interval([0.3, float("nan")])
    assert single.n == 1 and single.estimate == pytest.approx(0.3) and math.isnan(single.low)
    assert not single.defined
    zero = geometric_interval([0.0, 1.0])
    assert math.isnan(zero.estimate) and "needs positive values" in zero.method
    same = geometric_interval([1.5, 1.5, 1.5])  # replicates that do not vary: no spread to show, no interval
    assert same.estimate == pytest.approx(1.5) and same.n == 3 and not same.defined


def test_paired_ratio_interval_by_hand():
    # ratios 1/2, 1/2.2, 1/1.8: logs l_k = -ln 2, -ln 2.2, -ln 1.8
    first, second = [1.0, 1.0, 1.0], [2.0, 2.2, 1.8]
    logs = [-math.log(2.0), -math.log(2.2), -math.log(1.8)]
    mean = sum(logs) / 3
    sd = math.sqrt(sum((value - mean) ** 2 for value in logs) / 2)
    half = T_975_2 * sd / math.sqrt(3)
    interval = paired_ratio_interval(first, second)
    assert interval.estimate == pytest.approx(math.exp(mean), rel=1e-12)
    assert (interval.low, interval.high) == pytest.approx((math.exp(mean - half), math.exp(mean + half)), rel=1e-9)
    assert (interval.n, interval.method, interval.null) == (3, PAIRED_LOG_RATIO, 1.0)
    assert interval.distinguishes and interval.sign == -1  # the first is smaller on every seed, by 10 % or more
    back = reciprocal_interval(interval)
    assert (back.estimate, back.low, back.high) == pytest.approx(
        (1 / interval.estimate, 1 / interval.high, 1 / interval.low))
    assert back.sign == 1


def test_two_seeds_that_disagree_do_not_distinguish():
    # the coverage preset's seeds at threshold 0.95: QE 0.42 > H 0.31 on seed 0, QE 0.17 < H 0.33 on seed 1
    interval = paired_ratio_interval([0.42, 0.17], [0.31, 0.33])
    assert interval.n == 2 and not interval.distinguishes and interval.sign == 0
    assert interval.low < 1 < interval.high and interval.low > 0


def test_paired_difference_interval_by_hand():
    # differences 1, 2, 3: mean 2, sd 1, half t / sqrt 3
    interval = paired_difference_interval([1.0, 2.0, 3.0])
    half = T_975_2 / math.sqrt(3)
    assert (interval.estimate, interval.low, interval.high) == pytest.approx((2.0, 2.0 - half, 2.0 + half))
    assert interval.method == PAIRED_T and interval.null == 0.0 and not interval.distinguishes
    apart = paired_difference_interval([1.0, 1.1, 0.9, 1.2, 0.8])
    half = T_975_4 * math.sqrt(0.025) / math.sqrt(5)
    assert (apart.low, apart.high) == pytest.approx((1.0 - half, 1.0 + half))
    assert apart.distinguishes and apart.sign == 1


def test_interval_text_names_the_method_and_n():
    interval = Interval(0.012, 0.004, 0.02, 5, PAIRED_T, null=0.0)
    assert interval_text(interval) == "difference 0.012, 95 % interval [0.004, 0.02] (paired t, n = 5)"
    assert interval_text(interval, "QE/H", "{:.3f}") == \
        "QE/H 0.012, 95 % interval [0.004, 0.020] (paired t, n = 5)"
    lone = paired_ratio_interval([0.2], [0.3])
    assert interval_text(lone, "QE/H") == "QE/H 0.667 (no interval: paired t on log ratios, n = 1)"
    constant = paired_ratio_interval([0.98, 0.98], [1.0, 1.0])  # a fixed ratio on replicates that did not vary
    assert not constant.distinguishes and interval_text(constant, "A/B") == \
        "A/B 0.98 (no interval: the same on every replicate)"
    with pytest.raises(ValueError, match="no null"):
        geometric_interval([1.0, 2.0]).distinguishes
    with pytest.raises(ValueError, match="one of each"):
        paired_ratio_interval([1.0, 2.0], [1.0])
