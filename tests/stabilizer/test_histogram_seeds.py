"""Stage 1: cluster count and seeds from histogram peaks (Kang et al. 2009, section II-B)."""

import numpy as np
import pytest

from stabilizer.histogram_seeds import HistogramSeeds, valid_level_histogram


def _image_of_levels(levels_and_counts, invalid=0):
    pixels = np.concatenate([np.full(n, g, np.uint8) for g, n in levels_and_counts]
                            + [np.zeros(invalid, np.uint8)])
    return np.random.default_rng(0).permutation(pixels).reshape(1, -1)


def test_three_separated_levels_give_three_seeds_at_them():
    image = _image_of_levels([(50, 400), (120, 300), (200, 300)])
    seeds = HistogramSeeds()(image)
    assert seeds.n_clusters == 3
    np.testing.assert_allclose(seeds.seeds, [50, 120, 200])


def test_invalid_pixels_never_count():
    # 90% invalid pixels: level 0 must not be a peak nor lower the others below 2%.
    image = _image_of_levels([(60, 50), (180, 50)], invalid=900)
    seeds = HistogramSeeds()(image)
    np.testing.assert_allclose(seeds.seeds, [60, 180])
    assert valid_level_histogram(image)[0] == 0


def test_peak_below_the_ratio_is_not_a_seed():
    image = _image_of_levels([(30, 600), (110, 385), (230, 15)])  # 1.5% at 230
    seeds = HistogramSeeds(min_ratio=0.02)(image)
    np.testing.assert_allclose(seeds.seeds, [30, 110])
    assert HistogramSeeds(min_ratio=0.01)(image).n_clusters == 3


def test_a_bin_of_exactly_the_ratio_is_not_a_peak():
    # The paper's peaks hold more than 2% of the pixels: 20 of 1000 is not more.
    image = _image_of_levels([(30, 600), (110, 380), (230, 20)])
    np.testing.assert_allclose(HistogramSeeds(min_ratio=0.02)(image).seeds, [30, 110])
    image = _image_of_levels([(30, 600), (110, 379), (230, 21)])
    np.testing.assert_allclose(HistogramSeeds(min_ratio=0.02)(image).seeds, [30, 110, 230])


def test_the_first_and_the_last_bin_can_be_peaks():
    # Levels 1-20 (the farthest depths) and 241-255: the histogram's ends are peaks as well.
    image = _image_of_levels([(5, 500), (120, 200), (250, 300)])
    np.testing.assert_allclose(HistogramSeeds()(image).seeds, [5, 120, 250])


def test_the_second_seed_is_the_level_farthest_from_the_first():
    # One peak (level 200); of the levels too rare to peak, 20 is farther from it than 240.
    image = _image_of_levels([(20, 5), (200, 990), (240, 5)])
    np.testing.assert_allclose(HistogramSeeds()(image).seeds, [20, 200])


def test_neighbouring_smaller_bin_is_not_a_peak_and_seed_is_bin_centre_of_mass():
    # Bins 41-60 (levels 45, 55) and 61-80 (level 70, fewer): one peak, centre of mass 50.
    image = _image_of_levels([(45, 300), (55, 300), (70, 200), (200, 300)])
    seeds = HistogramSeeds()(image)
    np.testing.assert_allclose(seeds.seeds, [50, 200])


def test_plateau_of_equal_bins_counts_once():
    image = _image_of_levels([(30, 200), (50, 200), (150, 100)])  # bins 21-40 and 41-60 equal
    seeds = HistogramSeeds()(image)
    assert seeds.n_clusters == 2
    np.testing.assert_allclose(seeds.seeds, [40, 150])


def test_one_peak_but_two_levels_still_gives_two_seeds():
    image = _image_of_levels([(100, 990), (103, 10)])
    # 103 is alone in bin 101-120 with 1%: no peak, yet it is the second seed.
    np.testing.assert_allclose(HistogramSeeds()(image).seeds, [100, 103])


def test_flat_and_empty_images():
    assert HistogramSeeds()(np.full((8, 8), 77, np.uint8)).n_clusters == 1
    assert HistogramSeeds()(np.zeros((8, 8), np.uint8)).n_clusters == 0


@pytest.mark.parametrize("kwargs", [{"bin_width": 0}, {"bin_width": 300}, {"min_ratio": 1.0},
                                    {"min_ratio": -0.1}])
def test_bad_parameters_raise(kwargs):
    with pytest.raises(ValueError):
        HistogramSeeds(**kwargs)


def test_with_no_bin_above_the_ratio_the_densest_bins_centre_of_mass_is_a_seed():
    # min_ratio 0.9: neither bin holds 90% of the pixels. The densest (levels 150 and 152,
    # 600 pixels) gives the seed at its centre of mass; the level farthest from it the other.
    image = _image_of_levels([(50, 400), (150, 300), (152, 300)])
    np.testing.assert_allclose(HistogramSeeds(min_ratio=0.9)(image).seeds, [50, 151])


@pytest.mark.parametrize("kwargs", [{"bin_width": 1}, {"bin_width": 255}, {"min_ratio": 0.0}])
def test_parameters_at_their_limits_are_accepted(kwargs):
    assert HistogramSeeds(**kwargs)(_image_of_levels([(60, 50), (180, 50)])).n_clusters == 2
