"""Stage 2: IT2-FCM on the weighted histogram, KM type reduction, labels, clean-up."""

import cv2
import numpy as np
import pytest

from stabilizer.histogram_seeds import HistogramSeeds, valid_level_histogram
from stabilizer.inputs import MAX_ITERATIONS, MAX_KERNEL_SIDE, depth_to_disparity
from stabilizer.it2fcm import (
    IT2FCM,
    MASKS_PER_CALL,
    LabelCleaner,
    interval_memberships,
    karnik_mendel,
    type1_memberships,
)
from stabilizer.testing import make_depth_scene


def _iterative_km(x, lower, upper, right):
    """Textbook Karnik-Mendel iteration for one cluster (x ascending)."""
    weights = (lower + upper) / 2.0
    centre = np.sum(weights * x) / np.sum(weights)
    switch = None
    while True:
        k = np.searchsorted(x, centre, side="right")  # x[:k] <= centre < x[k:]
        if k == switch:
            return centre
        switch = k
        first, rest = (lower, upper) if right else (upper, lower)
        weights = np.concatenate((first[:k], rest[k:]))
        centre = np.sum(weights * x) / np.sum(weights)


def _per_pixel_it2fcm(pixels, seeds, m1, m2, tol, max_iter):
    """IT2-FCM on every valid pixel, the reference form of the histogram implementation."""
    x = np.sort(pixels.astype(np.float64))
    m = (m1 + m2) / 2.0
    centres = np.sort(np.asarray(seeds, np.float64))
    for _ in range(max_iter):
        upper, lower = interval_memberships(x, centres, m1, m2)
        new = np.array([(_iterative_km(x, lower[j] ** m, upper[j] ** m, False)
                         + _iterative_km(x, lower[j] ** m, upper[j] ** m, True)) / 2
                        for j in range(centres.size)])
        done = np.max(np.abs(new - centres)) < tol
        centres = new
        if done:
            break
    return centres


def test_vectorised_km_equals_iterative_km():
    rng = np.random.default_rng(3)
    for _ in range(20):
        x = np.sort(rng.uniform(0, 255, 40))
        lower = rng.uniform(0.0, 0.5, (3, 40))
        upper = lower + rng.uniform(0.0, 0.5, (3, 40))
        v_left, v_right = karnik_mendel(x, lower, upper)
        for j in range(3):
            assert v_left[j] == pytest.approx(_iterative_km(x, lower[j], upper[j], False),
                                              abs=1e-10)
            assert v_right[j] == pytest.approx(_iterative_km(x, lower[j], upper[j], True),
                                               abs=1e-10)
        assert np.all(v_left <= v_right + 1e-12)


def test_km_of_equal_bounds_is_the_weighted_mean():
    x = np.array([1.0, 2.0, 4.0, 8.0])
    w = np.array([[1.0, 2.0, 3.0, 4.0]])
    v_left, v_right = karnik_mendel(x, w, w)
    expected = np.sum(w[0] * x) / w.sum()
    assert v_left[0] == pytest.approx(expected) and v_right[0] == pytest.approx(expected)


def test_memberships_sum_to_one_and_a_point_on_a_centre_belongs_to_it():
    x = np.array([10.0, 20.0, 35.0, 50.0])
    u = type1_memberships(x, np.array([20.0, 50.0]), m=2.0)
    np.testing.assert_allclose(u.sum(axis=0), 1.0)
    np.testing.assert_allclose(u[:, 1], [1.0, 0.0])
    np.testing.assert_allclose(u[:, 3], [0.0, 1.0])
    upper, lower = interval_memberships(x, np.array([20.0, 50.0]), 2.0, 5.0)
    assert np.all(upper >= lower)


def test_histogram_form_equals_per_pixel_form_on_a_real_image():
    image = depth_to_disparity(make_depth_scene(1, floor=True))
    seeds = HistogramSeeds()(image)
    fcm = IT2FCM(m1=2.0, m2=5.0, tol=1e-6, max_iter=30)
    fast = fcm.fit(seeds.level_counts, seeds.seeds)
    slow = _per_pixel_it2fcm(image[image > 0], seeds.seeds, 2.0, 5.0, 1e-6, 30)
    np.testing.assert_allclose(fast.centres, slow, rtol=0, atol=1e-8)


def test_known_clusters_are_found_and_labelled():
    rng = np.random.default_rng(0)
    levels = np.concatenate([rng.normal(40, 3, 3000), rng.normal(120, 4, 2000),
                             rng.normal(210, 3, 1000)])
    image = np.clip(np.rint(levels), 1, 255).astype(np.uint8).reshape(60, 100)
    fcm = IT2FCM()
    result = fcm.fit(valid_level_histogram(image), np.array([30.0, 100.0, 200.0]))
    assert result.converged
    np.testing.assert_allclose(result.centres, [40, 120, 210], atol=1.5)
    assert np.all(result.intervals[:, 0] <= result.intervals[:, 1])
    assert result.level_labels[0] == 0
    assert list(result.level_labels[[40, 120, 210]]) == [1, 2, 3]


def test_iteration_cap_is_reported():
    image = depth_to_disparity(make_depth_scene(0))
    seeds = HistogramSeeds()(image)
    result = IT2FCM(max_iter=1).fit(seeds.level_counts, seeds.seeds)
    assert result.iterations == 1 and not result.converged


def test_cleaner_removes_specks_fills_holes_and_keeps_invalid_pixels_out():
    labels = np.ones((40, 40), np.int32)
    labels[10:30, 10:30] = 2
    labels[20, 20] = 1        # hole in object 2
    labels[5, 5] = 2          # speck in object 1
    labels[:, 35:] = 0        # invalid stripe
    cleaned = LabelCleaner(morph_size=3, min_area=0)(labels, 2)
    assert cleaned[20, 20] == 2 and cleaned[5, 5] == 1
    assert np.all(cleaned[:, 35:] == 0)
    dropped = LabelCleaner(morph_size=3, min_area=500)(labels, 2)
    assert np.all(dropped[labels == 2] != 2)


def _clean_label_by_label(labels, n_labels, morph_size, min_area):
    """The clean-up rule written plainly, one label mask at a time."""
    kernel = np.ones((morph_size, morph_size), np.uint8)
    cleaned = np.zeros(labels.shape, np.int64)
    covered = np.zeros(labels.shape, np.int64)
    for label in range(1, n_labels + 1):
        mask = (labels == label).astype(np.uint8)
        mask = cv2.morphologyEx(cv2.morphologyEx(mask, cv2.MORPH_OPEN, kernel),
                                cv2.MORPH_CLOSE, kernel).astype(bool)
        cleaned[mask & (labels == label)] = label
        covered[mask & (covered == 0)] = label
    lost = (labels > 0) & (cleaned == 0)
    cleaned[lost] = covered[lost]
    for label in range(1, n_labels + 1):
        if np.count_nonzero(cleaned == label) < min_area:
            cleaned[cleaned == label] = 0
    return cleaned


@pytest.mark.parametrize("seed", range(6))
def test_cleaner_equals_the_label_by_label_rule_and_counts_its_areas(seed):
    rng = np.random.default_rng(seed)
    n_labels = int(rng.integers(1, 10))
    labels = rng.integers(0, n_labels + 1, (48, 56)).astype(np.uint8)
    labels[rng.random(labels.shape) < 0.6] = labels[0, 0]  # large regions with noise
    for morph_size, min_area in ((3, 30), (5, 200), (1, 0)):
        cleaner = LabelCleaner(morph_size, min_area)
        cleaned, areas = cleaner.with_areas(labels, n_labels)
        expected = _clean_label_by_label(labels, n_labels, morph_size, min_area)
        np.testing.assert_array_equal(cleaned, expected)
        np.testing.assert_array_equal(cleaner(labels, n_labels), cleaned)
        np.testing.assert_array_equal(areas, np.bincount(expected.ravel(),
                                                         minlength=n_labels + 1)[1:])


@pytest.mark.parametrize("kwargs", [{"m1": 1.0}, {"m1": 3.0, "m2": 2.0}, {"tol": 0},
                                    {"max_iter": 0},
                                    # with a tiny tolerance, it ran for minutes
                                    {"max_iter": 10**9, "tol": 1e-300}])
def test_bad_fcm_parameters_raise(kwargs):
    with pytest.raises(ValueError):
        IT2FCM(**kwargs)


def test_bad_cleaner_parameters_raise():
    with pytest.raises(ValueError):
        LabelCleaner(morph_size=4)
    with pytest.raises(ValueError):
        LabelCleaner(min_area=-1)
    with pytest.raises(ValueError, match="morph_size"):  # a kernel of a terabyte
        LabelCleaner(morph_size=10**6 + 1)


def _textbook_fit(level_counts, seeds, m1, m2, tol, max_iter):
    """IT2-FCM on the histogram written as the formulas read: interval_memberships, then
    karnik_mendel on [lower^m, upper^m] times the counts, the crisp centres, the stopping rule."""
    x = np.flatnonzero(level_counts[1:] > 0) + 1.0
    counts = level_counts[x.astype(int)]
    m = (m1 + m2) / 2.0
    centres = np.sort(np.asarray(seeds, np.float64))
    for iteration in range(1, max_iter + 1):
        upper, lower = interval_memberships(x, centres, m1, m2)
        with np.errstate(invalid="ignore", divide="ignore"):
            v_left, v_right = karnik_mendel(x, lower ** m * counts, upper ** m * counts)
        new = (v_left + v_right) / 2.0
        done = np.max(np.abs(new - centres)) < tol
        centres = new
        if done:
            break
    return centres, iteration


@pytest.mark.parametrize("m1, m2", [(2.0, 5.0), (1.5, 3.0)])
@pytest.mark.parametrize("on_levels", [False, True])
def test_fit_equals_the_formulas_to_the_last_bit(on_levels, m1, m2):
    """The stacked, buffer-reusing update changes no bit of the centres or the iteration
    count, also when a seed sits exactly on a gray level (a membership of 1 there), for the
    default fuzzifiers and others (m1 = 2 makes 2 / (m1 - 1) and 2 (m1 - 1) alike)."""
    rng = np.random.default_rng(11)
    fcm = IT2FCM(m1=m1, m2=m2, tol=1e-2, max_iter=100)
    for _ in range(25):
        counts = np.zeros(256)
        levels = rng.choice(np.arange(1, 256), rng.integers(3, 200), replace=False)
        counts[levels] = rng.integers(1, 400, levels.size)
        n_seeds = int(rng.integers(1, 5))
        seeds = (rng.choice(levels, n_seeds, replace=False).astype(float) if on_levels
                 else rng.uniform(1, 255, n_seeds))
        fitted = fcm.fit(counts, seeds)
        centres, iterations = _textbook_fit(counts, seeds, m1, m2, 1e-2, 100)
        assert fitted.iterations == iterations
        np.testing.assert_array_equal(fitted.centres, centres)


def test_a_histogram_without_valid_pixels_is_refused():
    counts = np.zeros(256)
    counts[0] = 500  # invalid pixels only
    with pytest.raises(ValueError, match="level_counts has no valid pixel"):
        IT2FCM().fit(counts, np.array([10.0, 100.0]))


def test_a_label_of_exactly_min_area_pixels_is_kept_and_one_of_fewer_dropped():
    # A 5 x 6 block (30 pixels, whole under the 3 x 3 opening) of label 2 in label 1.
    labels = np.ones((20, 24), np.uint8)
    labels[5:10, 6:12] = 2
    cleaned, areas = LabelCleaner(min_area=30).with_areas(labels, 2)
    assert areas.tolist() == [450, 30] and np.count_nonzero(cleaned == 2) == 30
    cleaned, areas = LabelCleaner(min_area=31).with_areas(labels, 2)
    assert areas.tolist() == [450, 0] and not np.any(cleaned == 2)
    assert np.count_nonzero(cleaned == 0) == 30  # dropped, not given to another label


def test_each_level_takes_the_cluster_of_its_largest_mean_membership_the_nearest_centre():
    # Every membership, upper, lower or their mean, ranks the clusters by distance: each level
    # takes the nearest centre's label; level 0 (invalid) none.
    counts = np.zeros(256)
    counts[[20, 21, 22, 90, 91, 180, 181, 182]] = [50, 80, 40, 30, 60, 70, 20, 10]
    clusters = IT2FCM().fit(counts, np.array([20.0, 90.0, 180.0]))
    levels = np.arange(1, 256)
    nearest = 1 + np.argmin(np.abs(levels[:, None] - clusters.centres[None, :]), axis=1)
    np.testing.assert_array_equal(clusters.level_labels[1:], nearest)
    assert clusters.level_labels[0] == 0


def test_a_pixel_its_own_label_loses_takes_the_label_whose_closing_covers_it():
    # A one-pixel speck of label 1 inside label 2: the opening removes it from label 1, and
    # label 2's closing covers it, so it becomes 2 (not unlabelled).
    labels = np.full((20, 20), 2, np.uint8)
    labels[:, :5] = 1
    labels[10, 12] = 1
    cleaned = LabelCleaner(min_area=0)(labels, 2)
    assert cleaned[10, 12] == 2 and np.all(cleaned[:, :5] == 1)


@pytest.mark.parametrize("kwargs", [{"m1": 1.0001, "m2": 1.0002}, {"max_iter": 1},
                                    {"max_iter": MAX_ITERATIONS}])
def test_fcm_parameters_at_their_limits_are_accepted(kwargs):
    IT2FCM(**kwargs)


def test_cleaner_parameters_at_their_limits_are_accepted():
    LabelCleaner(morph_size=1, min_area=0)
    LabelCleaner(morph_size=MAX_KERNEL_SIDE)


def test_more_labels_than_an_opencv_image_has_channels_are_cleaned_alike():
    # 255 labels, the most a uint8 label image holds, in blocks with specks of other labels:
    # more than OpenCV filters in one image (MASKS_PER_CALL), and the same rule as one by one.
    rng = np.random.default_rng(3)
    labels = np.repeat(np.repeat(np.arange(1, 256, dtype=np.uint8).reshape(15, 17), 6, axis=0),
                       6, axis=1)
    specks = rng.random(labels.shape) < 0.05
    labels[specks] = rng.integers(0, 256, np.count_nonzero(specks))
    assert 255 > MASKS_PER_CALL
    cleaned, areas = LabelCleaner(3, 20).with_areas(labels, 255)
    np.testing.assert_array_equal(cleaned, _clean_label_by_label(labels, 255, 3, 20))
    np.testing.assert_array_equal(areas, np.bincount(cleaned.ravel(), minlength=256)[1:])
