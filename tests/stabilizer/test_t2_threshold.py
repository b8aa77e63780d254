"""Stage 5: type-2 fuzzy (ultrafuzziness) thresholds around the main group of angles."""

import numpy as np
import pytest

from stabilizer.t2_threshold import MEDIAN_FALLBACK, Type2FuzzyThreshold


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


@pytest.mark.parametrize("values", [[3.0, 1.0], [0.1, 0.7, -0.2, 2.5], [5.0], [1e-9, 1.0 / 3.0]])
def test_fallback_median_is_numpys_bit_for_bit(values):
    robust = Type2FuzzyThreshold(min_values=10)(np.array(values))
    assert robust.fallback == MEDIAN_FALLBACK
    assert robust.value == np.median(values)
