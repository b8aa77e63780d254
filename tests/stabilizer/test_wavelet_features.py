"""Stage 3: wavelet point sets of object masks, in image coordinates."""

import numpy as np
import pytest
import pywt

from stabilizer.wavelet_features import (
    MAX_EDGE_MARGIN,
    MAX_LEVEL,
    WaveletFeatures,
    _block_centre,
    haar_detail_energy,
    haar_sums,
)


def _square_labels():
    labels = np.ones((64, 64), np.int32)
    labels[16:32, 24:48] = 2  # rows 16..31, columns 24..47: edges on multiples of 8
    return labels


def _points(sets, object_index, name, features):
    chosen = sets.set_id == object_index * sets.n_subbands + features.subband_names.index(name)
    return sets.x[chosen], sets.y[chosen], sets.weight[chosen]


def test_subband_names_and_counts():
    assert WaveletFeatures(level=2).subband_names == ["cA2", "D2", "D1"]
    separate = WaveletFeatures(level=2, merge_details=False)
    assert separate.subband_names == ["cA2", "cH2", "cV2", "cD2", "cH1", "cV1", "cD1"]
    assert separate.n_subbands == 7


@pytest.mark.parametrize("shape", [(3, 144, 176), (2, 17, 23)])
def test_haar_sums_are_twice_pywavelets(shape):
    stack = np.random.default_rng(0).random(shape).astype(np.float32)
    ours = haar_sums(stack)
    theirs = pywt.dwt2(stack, "haar", axes=(-2, -1))
    np.testing.assert_allclose(ours[0], 2 * theirs[0], atol=1e-5)
    for mine, reference in zip(ours[1], theirs[1]):
        np.testing.assert_allclose(mine, 2 * reference, atol=1e-5)


@pytest.mark.parametrize("shape", [(3, 144, 176), (2, 17, 23)])
def test_detail_energy_equals_the_squared_bands_bit_for_bit_on_masks(shape):
    masks = (np.random.default_rng(2).random(shape) > 0.6).astype(np.int16)
    level_input = masks
    for _ in range(2):  # level 1 on the masks, level 2 on their block sums
        approximation, details = haar_sums(level_input)
        squares = [np.square(band, dtype=np.float32) for band in details]
        ours_approximation, energy = haar_detail_energy(level_input)
        np.testing.assert_array_equal(ours_approximation, approximation)
        assert energy.dtype == np.float32
        np.testing.assert_array_equal(energy, np.sqrt(squares[0] + squares[1] + squares[2]))
        if level_input is masks:  # 0/1 values: the shortcut for masks gives the same
            np.testing.assert_array_equal(haar_detail_energy(masks, binary=True)[1], energy)
        level_input = approximation


@pytest.mark.parametrize("wavelet", ["haar", "db2"])  # evenly spaced block centres or not
def test_every_detail_point_lies_on_a_pixel_clear_of_the_measurement_edge(wavelet):
    margin = 2
    features = WaveletFeatures(wavelet=wavelet, edge_margin=margin)
    labels = np.ones((64, 64), np.int32)
    labels[17:35, 21:45] = 2  # edges off the block grid: detail points at both levels
    valid = np.ones(labels.shape, bool)
    valid[:, 40:] = False
    labels[~valid] = 0
    sets = features(labels, np.array([1, 2]), valid)
    detail = np.array([not name.startswith("cA") for name in features.subband_names])
    chosen = detail[sets.set_id % sets.n_subbands]
    assert chosen.any()
    columns = np.clip(np.rint(sets.x[chosen]), 0, 63)
    rows = np.clip(np.rint(sets.y[chosen]), 0, 63)
    # Clear of the border and of the invalid columns 40.. by more than the margin.
    assert columns.min() >= margin and rows.min() >= margin and rows.max() <= 63 - margin
    assert columns.max() <= 39 - margin


def test_a_detail_point_is_judged_by_the_pixel_nearest_its_block_centre():
    # The level-1 block of columns 38-39 has its centre at 38.5; its nearest pixel (38, by
    # round-half-to-even) is 2 columns from the invalid column 40: clear of a 1-pixel margin.
    features = WaveletFeatures(edge_margin=1)
    labels = np.ones((64, 64), np.int32)
    labels[17:35, 21:45] = 2
    valid = np.ones(labels.shape, bool)
    valid[:, 40:] = False
    labels[~valid] = 0
    x, _, _ = _points(features(labels, np.array([1, 2]), valid), 1, "D1", features)
    assert x.max() == 38.5


def test_decomposition_equals_wavedec2_magnitudes():
    masks = (np.random.default_rng(1).random((2, 32, 48)) > 0.5).astype(np.float32)
    features = WaveletFeatures(level=2, merge_details=False)
    ours = {name: band for band, _, name in features.decompose(masks)}
    reference = pywt.wavedec2(masks, "haar", level=2, axes=(-2, -1))
    # Unnormalised Haar: level-L magnitudes are 2^L times PyWavelets'.
    np.testing.assert_allclose(ours["cA2"], 4 * np.abs(reference[0]), atol=1e-5)
    for level, details in ((2, reference[1]), (1, reference[2])):
        for name, band in zip(("cH", "cV", "cD"), details):
            np.testing.assert_allclose(ours[f"{name}{level}"], 2 ** level * np.abs(band),
                                       atol=1e-5)
    general = WaveletFeatures(wavelet="db2", level=2, merge_details=False).decompose(masks)
    assert [name for _, _, name in general] == [name for _, _, name in features.decompose(masks)]


@pytest.mark.parametrize("wavelet", ["haar", "db2"])
def test_merged_details_are_the_root_sum_of_squares_of_the_three_bands(wavelet):
    # merge_details: one point set per level, sqrt(cH^2 + cV^2 + cD^2) of that level's bands
    # (Haar's fast path and the general one alike), up to one factor per subband.
    masks = np.random.default_rng(2).random((2, 32, 48)) > 0.5
    merged = WaveletFeatures(wavelet=wavelet, level=2).decompose(masks)
    separate = {name: band for band, _, name in
                WaveletFeatures(wavelet=wavelet, level=2, merge_details=False).decompose(masks)}
    assert [name for _, _, name in merged] == ["D1", "D2", "cA2"]
    for band, level, name in merged[:2]:
        expected = np.sqrt(sum(np.square(separate[f"{kind}{level}"].astype(np.float64))
                               for kind in ("cH", "cV", "cD")))
        np.testing.assert_allclose(band, expected, rtol=1e-5, atol=1e-5)


def test_approximation_points_cover_the_object_at_block_centres():
    features = WaveletFeatures()
    labels = _square_labels()
    sets = features(labels, np.array([2]), np.ones(labels.shape, bool))
    for name, scale in (("cA2", 4),):
        x, y, weight = _points(sets, 0, name, features)
        expected_x = np.arange(24, 48, scale) + (scale - 1) / 2
        expected_y = np.arange(16, 32, scale) + (scale - 1) / 2
        np.testing.assert_allclose(np.unique(x), expected_x)
        np.testing.assert_allclose(np.unique(y), expected_y)
        np.testing.assert_allclose(weight, 1.0)  # fully covered blocks


def test_detail_points_lie_on_the_object_outline():
    features = WaveletFeatures()
    labels = np.ones((64, 64), np.int32)
    labels[17:35, 21:45] = 2  # odd edges: level-1 details see them
    sets = features(labels, np.array([2]), np.ones(labels.shape, bool))
    x, y, _ = _points(sets, 0, "D1", features)
    assert x.size > 0
    near_vertical_edge = (np.abs(x - 21) <= 1.5) | (np.abs(x - 44.5) <= 1.5)
    near_horizontal_edge = (np.abs(y - 17) <= 1.5) | (np.abs(y - 34.5) <= 1.5)
    assert np.all(near_vertical_edge | near_horizontal_edge)


def test_detail_points_next_to_invalid_pixels_or_the_border_are_dropped():
    features = WaveletFeatures(edge_margin=2)
    labels = np.ones((64, 64), np.int32)
    labels[17:35, 21:45] = 2
    valid = np.ones(labels.shape, bool)
    valid[:, 43:] = False  # the object's right side ends at invalid pixels
    labels[~valid] = 0
    sets = features(labels, np.array([1, 2]), valid)
    x, _, _ = _points(sets, 1, "D1", features)
    assert x.max() < 43 - 2
    wall_x, wall_y, _ = _points(sets, 0, "D1", features)  # the frame border is no edge either
    assert wall_x.min() > 1 and wall_y.min() > 1


def test_significance_drops_weak_coefficients():
    labels = _square_labels()
    labels[40:41, 10:11] = 2  # a single pixel: weak level-2 approximation coefficient
    valid = np.ones(labels.shape, bool)
    loose = WaveletFeatures(significance=0.0)(labels, np.array([2]), valid)
    strict = WaveletFeatures(significance=0.5)(labels, np.array([2]), valid)
    assert strict.x.size < loose.x.size


@pytest.mark.parametrize("kwargs", [{"wavelet": "nope"}, {"level": 0}, {"significance": 1.0},
                                    {"edge_margin": -1},
                                    # Unbounded, these ran for minutes or asked for terabytes.
                                    {"level": 10**6}, {"edge_margin": 10**6},
                                    {"level": MAX_LEVEL + 1},
                                    {"edge_margin": MAX_EDGE_MARGIN + 1}])
def test_bad_parameters_raise(kwargs):
    with pytest.raises(ValueError):
        WaveletFeatures(**kwargs)


@pytest.mark.parametrize("kwargs", [{"level": 1}, {"level": MAX_LEVEL}, {"edge_margin": 0},
                                    {"edge_margin": MAX_EDGE_MARGIN}])
def test_parameters_at_their_limits_are_accepted(kwargs):
    features = WaveletFeatures(**kwargs)
    assert all(getattr(features, name) == value for name, value in kwargs.items())


@pytest.mark.parametrize("name", ["haar", "db2", "db3"])
@pytest.mark.parametrize("level", [1, 2])
def test_a_coefficients_position_is_the_centre_of_the_samples_it_depends_on(name, level):
    # PyWavelets itself says which samples a coefficient depends on: those whose impulse
    # moves it. The centre of their span is the coefficient's point (away from the signal's
    # ends, where the signal extension adds samples).
    wavelet = pywt.Wavelet(name)
    size = 64
    responses = np.array([pywt.wavedec(np.eye(size)[sample], wavelet, level=level)[1]
                          for sample in range(size)])
    coefficients = np.arange(3, responses.shape[1] - 3)
    spans = [np.flatnonzero(np.abs(responses[:, k]) > 1e-12) for k in coefficients]
    np.testing.assert_array_equal(_block_centre(coefficients, level, wavelet.dec_len),
                                  [(span.min() + span.max()) / 2.0 for span in spans])
