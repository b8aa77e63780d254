"""Bootstrap intervals over sequences: means, paired differences, degenerate samples."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sim.harness.suite.statistics import (BCA, PERCENTILE, Interval, mean_interval,
                                          paired_difference)


def test_the_interval_of_a_known_sample_contains_its_mean():
    samples = np.random.default_rng(1).gamma(4.0, 0.25, size=24)
    interval = mean_interval(samples)
    assert interval.method == BCA and interval.n == 24
    assert interval.mean == pytest.approx(samples.mean())
    assert interval.low < interval.mean < interval.high
    assert interval.high - interval.low < samples.max() - samples.min()


def test_the_interval_is_a_95_percent_one():
    # Many normal samples: the bootstrap interval of the mean approaches the normal one,
    # mean +- 1.96 s / sqrt(n); a 90% interval would be 1.645 / 1.96 = 0.84 times as wide.
    samples = np.random.default_rng(5).normal(0.0, 1.0, size=400)
    interval = mean_interval(samples)
    normal_width = 2 * 1.96 * samples.std(ddof=1) / math.sqrt(samples.size)
    assert interval.high - interval.low == pytest.approx(normal_width, rel=0.05)


def test_the_same_samples_give_the_same_interval_bit_for_bit():
    samples = np.random.default_rng(2).normal(1.0, 0.3, size=20)
    assert mean_interval(samples) == mean_interval(samples.copy())


def test_a_paired_difference_with_a_clear_sign_excludes_zero():
    rng = np.random.default_rng(3)
    base = rng.gamma(4.0, 0.25, size=24)  # sequences differ a lot; the gap between methods not
    better, worse = base, base + 0.2 + rng.normal(0.0, 0.02, size=24)
    difference = paired_difference(better, worse)
    assert difference.high < 0 and difference.excludes_zero()
    assert difference.mean == pytest.approx(-0.2, abs=0.02)
    # Unpaired, the spread between sequences would hide the gap: the intervals overlap.
    assert mean_interval(worse).low < mean_interval(better).high


def test_identical_methods_give_a_difference_interval_containing_zero():
    rng = np.random.default_rng(4)
    base = rng.gamma(4.0, 0.25, size=24)
    first, second = base + rng.normal(0, 0.05, 24), base + rng.normal(0, 0.05, 24)
    difference = paired_difference(first, second)
    assert difference.low < 0 < difference.high and not difference.excludes_zero()


@pytest.mark.parametrize("value", [0.25, 0.025, 1 / 3])
def test_all_equal_samples_fall_back_to_the_percentile_interval(value):
    # 0.025 and 1/3: the float mean of equal samples need not equal them.
    interval = mean_interval([value] * 12)
    assert interval.method == PERCENTILE
    assert (interval.mean, interval.low, interval.high, interval.n) == (value, value, value, 12)
    same = paired_difference([1.0, 2.0, 3.0], [1.0, 2.0, 3.0])
    assert (same.low, same.high, same.excludes_zero()) == (0.0, 0.0, False)


@pytest.mark.parametrize("samples, n, mean", [
    ([], 0, math.nan), ([math.nan, math.nan], 0, math.nan), ([0.7], 1, 0.7),
    ([0.7, math.nan], 1, 0.7)])
def test_fewer_than_two_samples_give_no_interval(samples, n, mean):
    interval = mean_interval(samples)
    assert interval.n == n and interval.method == ""
    assert math.isnan(interval.low) and math.isnan(interval.high)
    assert (math.isnan(interval.mean) if math.isnan(mean) else interval.mean == mean)
    assert not interval.excludes_zero()


def test_non_finite_samples_are_left_out_and_pairs_need_both_sides():
    interval = mean_interval([1.0, math.nan, 3.0, math.inf, 2.0, -math.inf])
    assert interval.n == 3 and interval.mean == 2.0
    difference = paired_difference([1.0, math.nan, 3.0], [0.5, 1.0, math.nan])
    assert difference.n == 1 and difference.mean == 0.5


def test_paired_samples_of_different_lengths_are_refused():
    with pytest.raises(ValueError, match="same length"):
        paired_difference([1.0, 2.0], [1.0])


def test_two_samples_are_enough_for_an_interval():
    # A suite of two scene seeds, as CI runs, has intervals.
    interval = mean_interval([1.0, 2.0])
    assert (interval.mean, interval.n) == (1.5, 2)
    assert 1.0 <= interval.low < 1.5 < interval.high <= 2.0 and interval.method == BCA


@pytest.mark.parametrize("low, high, excludes", [(0.2, 0.8, True), (1e-9, 3.0, True),
                                                 (-0.8, -0.2, True), (-0.1, 0.1, False),
                                                 (0.0, 0.5, False), (math.nan, math.nan, False)])
def test_an_interval_excludes_zero_only_when_wholly_on_one_side(low, high, excludes):
    assert Interval((low + high) / 2, low, high, 10, BCA).excludes_zero() is excludes
