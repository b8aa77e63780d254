"""Stage 5: type-2 fuzzy (ultrafuzziness) thresholds around the main group of angles."""

import numpy as np
import pytest

from stabilizer.t2_threshold import (MAX_BANDWIDTH_DEG, MEDIAN_FALLBACK,
                                     MIN_RESOLUTION_DEG, Type2FuzzyThreshold)


def test_planted_outliers_are_cut_on_both_sides():
    rng = np.random.default_rng(0)
    good = rng.normal(5.0, 0.1, 30)
    outliers = np.array([-40.0, -12.0, 1.5, 9.0, 33.0])
    values = rng.permutation(np.concatenate((good, outliers)))
    result = Type2FuzzyThreshold()(values)
    assert result.fallback is None
    assert result.lower < 5.0 < result.upper
    assert result.value == pytest.approx(5.0, abs=0.05)
    # The paper's Fig. 7: the rotation is the mean of the estimates between the thresholds.
    assert result.value == values[result.inliers].mean()
    assert not result.inliers[np.isin(values, outliers)].any()
    assert result.inliers[np.isin(values, good)].mean() > 0.9


def test_ultrafuzziness_has_one_peak_each_side_of_a_tight_group():
    threshold = Type2FuzzyThreshold(bandwidth_deg=1.0)
    positions, gamma = threshold.ultrafuzziness(np.full(10, 3.0))
    inner = (gamma[1:-1] > gamma[:-2]) & (gamma[1:-1] >= gamma[2:])
    peaks = positions[1:-1][inner]
    assert peaks.size == 2
    np.testing.assert_allclose(peaks, [2.4, 3.6], atol=0.11)  # mu ~ 0.4 about 0.6 bw out


def test_too_few_values_fall_back_to_the_median():
    result = Type2FuzzyThreshold(min_values=3)(np.array([1.0, 2.0]))
    assert result.fallback == MEDIAN_FALLBACK and result.value == 1.5
    assert np.isnan(result.lower) and not result.inliers.any()


def test_no_finite_values_gives_nan():
    result = Type2FuzzyThreshold()(np.array([np.nan]))
    assert np.isnan(result.value) and result.fallback == MEDIAN_FALLBACK


def test_nan_values_are_ignored():
    values = np.array([2.0, 2.1, np.nan, 1.9, 2.0])
    result = Type2FuzzyThreshold()(values)
    assert result.value == pytest.approx(2.0) and not result.inliers[2]


@pytest.mark.parametrize("kwargs", [{"alpha": 1.0}, {"alpha": 2.5},
                                    {"bandwidth_deg": 0.05, "resolution_deg": 0.1},
                                    {"min_values": 0},
                                    # a minutes-long histogram and convolution
                                    {"bandwidth_deg": 1e5}, {"resolution_deg": 1e-7}])
def test_bad_parameters_raise(kwargs):
    with pytest.raises(ValueError):
        Type2FuzzyThreshold(**kwargs)


@pytest.mark.parametrize("kwargs", [{"min_values": 1}, {"alpha": 2.0},
                                    {"bandwidth_deg": MAX_BANDWIDTH_DEG},
                                    {"resolution_deg": MIN_RESOLUTION_DEG}])
def test_parameters_at_their_limits_are_accepted(kwargs):
    assert Type2FuzzyThreshold(**kwargs)(np.array([1.0, 1.1, 0.9])).value == pytest.approx(1.0)


def test_a_resolution_as_wide_as_the_bandwidth_is_refused():
    with pytest.raises(ValueError, match="bandwidth_deg > resolution_deg"):
        Type2FuzzyThreshold(bandwidth_deg=0.5, resolution_deg=0.5)


@pytest.mark.parametrize("values", [[3.0, 1.0], [0.1, 0.7, -0.2, 2.5], [5.0], [1e-9, 1.0 / 3.0]])
def test_fallback_median_is_numpys_bit_for_bit(values):
    robust = Type2FuzzyThreshold(min_values=10)(np.array(values))
    assert robust.fallback == MEDIAN_FALLBACK
    assert robust.value == np.median(values)


def _eq6_by_definition(values, alpha, bandwidth, resolution):
    """Eq. (6) written out: at every position T of the histogram (every step from one
    bandwidth below the least quantised value to one above the largest), gamma(T) = (1 / N)
    sum over the values of mu_U - mu_L = mu^(1/alpha) - mu^alpha, mu the triangle of half-width
    ``bandwidth`` centred at T; distances counted in histogram steps."""
    bins = np.rint(np.asarray(values) / resolution).astype(int)
    reach = int(np.ceil(bandwidth / resolution))
    steps = np.arange(bins.min() - reach, bins.max() + reach + 1)
    gamma = []
    for step in steps:
        mu = np.clip(1.0 - np.abs(bins - step) * resolution / bandwidth, 0.0, 1.0)
        gamma.append(np.sum(mu ** (1.0 / alpha) - mu ** alpha) / bins.size)
    return steps * resolution, np.array(gamma)


def _threshold_candidates(values, alpha, bandwidth, resolution):
    """The documented rule: the highest gamma at or below the median is the lower threshold,
    the highest at or above it the upper one. Peaks equal in exact arithmetic (a symmetric set)
    differ in the last bits of either sum, so each comes as the positions within 1e-12 of the
    highest (the code takes the lowest position of exactly equal peaks)."""
    positions, gamma = _eq6_by_definition(values, alpha, bandwidth, resolution)
    median = np.median(values)
    sides = (positions <= median, positions >= median)
    return [positions[side][gamma[side] >= gamma[side].max() - 1e-12] for side in sides]


@pytest.mark.parametrize("alpha, bandwidth, resolution", [(2.0, 1.0, 0.1), (1.5, 2.0, 0.25),
                                                        (1.2, 1.0, 0.3)])
def test_ultrafuzziness_and_thresholds_follow_eq6_and_the_documented_rule(alpha, bandwidth,
                                                                           resolution):
    # Random sets, some on the histogram's grid (where a value can sit on a threshold and the
    # median on a position), some off it; eq. (6) and the threshold rule written out decide.
    threshold = Type2FuzzyThreshold(alpha=alpha, bandwidth_deg=bandwidth,
                                    resolution_deg=resolution)
    rng = np.random.default_rng(7)
    for trial in range(300):
        size = int(rng.integers(3, 12))
        values = (rng.integers(-30, 30, size) * resolution if trial % 2 else
                  rng.normal(0.0, 2.0, size))
        positions, gamma = threshold.ultrafuzziness(values)
        expected_positions, expected_gamma = _eq6_by_definition(values, alpha, bandwidth,
                                                                resolution)
        np.testing.assert_allclose(positions, expected_positions, rtol=0, atol=1e-12)
        np.testing.assert_allclose(gamma, expected_gamma, rtol=1e-12, atol=1e-15)
        lowers, uppers = _threshold_candidates(values, alpha, bandwidth, resolution)
        result = threshold(values)
        if result.fallback is None:
            assert np.isclose(lowers, result.lower, rtol=0, atol=1e-12).any()
            assert np.isclose(uppers, result.upper, rtol=0, atol=1e-12).any()
            # The mean of the estimates between the thresholds, both included.
            between = (values >= result.lower) & (values <= result.upper)
            assert between.any() and (result.inliers == between).all()
            assert result.value == values[between].mean()
        else:  # no estimate between the thresholds (of one choice among equal peaks)
            assert result.fallback == MEDIAN_FALLBACK and result.value == np.median(values)
            assert any(not ((values >= lower) & (values <= upper)).any()
                       for lower in lowers for upper in uppers)
