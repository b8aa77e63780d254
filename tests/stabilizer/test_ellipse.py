"""Stage 4: direct least-squares ellipse fits (Halir & Flusser) and their orientation."""

import cv2
import numpy as np
import pytest

from stabilizer.ellipse import MIN_POINTS, axis_angle_difference, fit_ellipses
from stabilizer.motion import Motion, apply_motion


def _ellipse_points(cx, cy, a, b, angle_deg, n, noise, rng):
    t = rng.uniform(0, 2 * np.pi, n)
    th = np.radians(angle_deg)
    x = cx + a * np.cos(t) * np.cos(th) - b * np.sin(t) * np.sin(th)
    y = cy + a * np.cos(t) * np.sin(th) + b * np.sin(t) * np.cos(th)
    return x + rng.normal(0, noise, n), y + rng.normal(0, noise, n)


@pytest.mark.parametrize("angle", [0.0, 12.5, 45.0, 89.0, 133.0, 179.5])
def test_known_orientation_with_noise(angle):
    rng = np.random.default_rng(int(angle * 10))
    x, y = _ellipse_points(70, 60, 30, 12, angle, 300, 0.3, rng)
    fit = fit_ellipses(x, y, np.zeros(x.size, int), 1)
    assert fit.valid[0] and fit.oriented[0]
    assert abs(axis_angle_difference(fit.angle_deg[0], angle)) < 0.5
    assert fit.centre_x[0] == pytest.approx(70, abs=0.2)
    assert fit.half_major[0] == pytest.approx(30, abs=0.3)
    assert fit.half_minor[0] == pytest.approx(12, abs=0.3)


def test_many_sets_at_once_equal_separate_fits():
    rng = np.random.default_rng(1)
    sets = [_ellipse_points(50 + 10 * k, 40, 20 + k, 8, 17 * k, 80, 0.5, rng) for k in range(5)]
    x = np.concatenate([s[0] for s in sets])
    y = np.concatenate([s[1] for s in sets])
    ids = np.repeat(np.arange(5), 80)
    together = fit_ellipses(x, y, ids, 5)
    for k, (xs, ys) in enumerate(sets):
        alone = fit_ellipses(xs, ys, np.zeros(xs.size, int), 1)
        assert together.angle_deg[k] == pytest.approx(alone.angle_deg[0], abs=1e-8)


def test_matches_opencv_fit_ellipse_direct():
    rng = np.random.default_rng(2)
    for k in range(20):
        x, y = _ellipse_points(*rng.uniform(30, 120, 2), *sorted(rng.uniform(5, 40, 2))[::-1],
                               rng.uniform(0, 180), 60, 1.0, rng)
        ours = fit_ellipses(x, y, np.zeros(x.size, int), 1)
        (cx, cy), (w, h), cv_angle = cv2.fitEllipseDirect(np.column_stack((x, y)).astype(
            np.float32))
        major_angle = cv_angle if w >= h else cv_angle + 90.0  # cv2: angle of the width axis
        assert ours.centre_x[0] == pytest.approx(cx, abs=1e-2)
        assert ours.centre_y[0] == pytest.approx(cy, abs=1e-2)
        assert ours.half_major[0] == pytest.approx(max(w, h) / 2, rel=1e-3)
        assert ours.half_minor[0] == pytest.approx(min(w, h) / 2, rel=1e-3)
        assert abs(axis_angle_difference(ours.angle_deg[0], major_angle)) < 0.05


def test_matches_scikit_image_ellipse_model():
    measure = pytest.importorskip("skimage.measure")
    rng = np.random.default_rng(5)
    x, y = _ellipse_points(80, 70, 35, 15, 28.0, 200, 0.2, rng)
    model = measure.EllipseModel.from_estimate(np.column_stack((x, y)))
    assert model
    (xc, yc), (a, b), theta = model.center, model.axis_lengths, model.theta
    sk_major = np.degrees(theta) if a >= b else np.degrees(theta) + 90.0
    ours = fit_ellipses(x, y, np.zeros(x.size, int), 1)
    assert ours.centre_x[0] == pytest.approx(xc, abs=0.1)
    assert ours.centre_y[0] == pytest.approx(yc, abs=0.1)
    assert abs(axis_angle_difference(ours.angle_deg[0], sk_major)) < 0.2


def test_round_fits_carry_no_angle_and_small_sets_are_invalid():
    rng = np.random.default_rng(4)
    x, y = _ellipse_points(50, 50, 20, 19.9, 30, 200, 0.05, rng)
    fit = fit_ellipses(np.r_[x, x[:4]], np.r_[y, y[:4]], np.r_[np.zeros(200, int), [1] * 4], 3,
                       min_axis_ratio=1.05)
    assert fit.valid[0] and not fit.oriented[0]
    assert not fit.valid[1] and not fit.valid[2]  # 4 points; no points at all
    assert np.isnan(fit.angle_deg[1])


def test_a_set_of_min_points_is_fitted_and_one_fewer_is_not():
    # Five points determine a conic exactly, so a fit of five checks nothing: too few.
    # MIN_POINTS (6) points of one ellipse give it back exactly.
    angles = np.linspace(0.0, 2.0 * np.pi, MIN_POINTS, endpoint=False)
    x, y = 30.0 + 10.0 * np.cos(angles), 20.0 + 4.0 * np.sin(angles)
    fit = fit_ellipses(np.r_[x, x[:-1]], np.r_[y, y[:-1]],
                       np.r_[np.zeros(MIN_POINTS, int), np.ones(MIN_POINTS - 1, int)], 2)
    assert fit.valid[0] and not fit.valid[1]
    np.testing.assert_allclose([fit.centre_x[0], fit.centre_y[0], fit.half_major[0],
                                fit.half_minor[0]], [30.0, 20.0, 10.0, 4.0], atol=1e-9)


@pytest.mark.parametrize("slope", [0.0, 0.5, None])  # a row of pixels, a slanted line, a column
def test_points_on_a_straight_line_have_no_ellipse(slope):
    """A straight edge seen alone (one side of a box) fixes no ellipse: the set is invalid
    and carries no angle, rather than an ellipse of arbitrary size."""
    t = np.arange(40.0)
    x, y = (np.full(40, 60.0), 10.0 + t) if slope is None else (10.0 + t, 50.0 + slope * t)
    fit = fit_ellipses(np.r_[x, x + 100.0], np.r_[y, y], np.r_[np.zeros(40, int),
                                                             np.ones(40, int)], 2)
    assert not fit.valid.any() and not fit.oriented.any()
    assert np.isnan(fit.angle_deg).all()


def test_a_point_of_weight_zero_counts_for_nothing_and_a_ratio_of_one_orients_every_fit():
    # Weights may be 0 (a point left out) and min_axis_ratio 1 (no fit is too round).
    rng = np.random.default_rng(8)
    x, y = _ellipse_points(60, 60, 25, 10, 70, 50, 1.0, rng)
    outlier_x, outlier_y = np.r_[x, 150.0], np.r_[y, 5.0]
    without = fit_ellipses(x, y, np.zeros(x.size, int), 1)
    ignored = fit_ellipses(outlier_x, outlier_y, np.zeros(x.size + 1, int), 1,
                           weight=np.r_[np.ones(x.size), 0.0])
    np.testing.assert_allclose(ignored.as_tuples(), without.as_tuples(), rtol=1e-9)
    circle_x, circle_y = _ellipse_points(60, 60, 20, 20, 0, 40, 0.0, rng)
    assert fit_ellipses(circle_x, circle_y, np.zeros(40, int), 1, min_axis_ratio=1.0).oriented[0]


def test_weights_equal_to_repetition():
    rng = np.random.default_rng(6)
    x, y = _ellipse_points(60, 60, 25, 10, 70, 50, 1.0, rng)
    weights = rng.integers(1, 4, x.size)
    weighted = fit_ellipses(x, y, np.zeros(x.size, int), 1, weight=weights.astype(float))
    repeated = fit_ellipses(np.repeat(x, weights), np.repeat(y, weights),
                            np.zeros(weights.sum(), int), 1)
    assert weighted.angle_deg[0] == pytest.approx(repeated.angle_deg[0], abs=1e-8)


def test_angle_difference_is_wrapped_and_axis_symmetric():
    np.testing.assert_allclose(axis_angle_difference([179.0, 10.0, 100.0], [1.0, 0.0, 100.0]),
                               [-2.0, 10.0, 0.0])
    assert axis_angle_difference(0.0, 90.0) == 90.0  # (-90, 90]


def test_rotation_sign_follows_the_motion_convention():
    image = np.zeros((144, 176), np.uint8)
    cv2.ellipse(image, (88, 72), (40, 15), 25.0, 0, 360, 200, -1)
    rotated = apply_motion(image, Motion(8.0, 0.0, 0.0))
    fits = []
    for frame in (image, rotated):
        ys, xs = np.nonzero(cv2.Canny(frame, 50, 150))
        fits.append(fit_ellipses(xs.astype(float), ys.astype(float), np.zeros(xs.size, int),
                                 1).angle_deg[0])
    assert fits[0] == pytest.approx(25.0, abs=0.5)
    assert axis_angle_difference(fits[0], fits[1]) == pytest.approx(8.0, abs=0.5)


def _points(n: int = 20):
    angles = np.linspace(0.0, 2.0 * np.pi, n, endpoint=False)
    return 30.0 + 10.0 * np.cos(angles), 40.0 + 4.0 * np.sin(angles), np.zeros(n, np.intp)


@pytest.mark.parametrize("change, message", [
    ({"y": np.zeros(5)}, "1-D arrays of one length"),
    ({"x": np.zeros((20, 1))}, "1-D arrays of one length"),
    ({"set_id": np.zeros(19, np.intp)}, "1-D arrays of one length"),
    ({"x": np.zeros(20, complex)}, "real-valued"),
    ({"x": np.full(20, np.nan)}, "finite"),
    ({"n_sets": -1}, "n_sets must be an integer >= 0"),
    ({"n_sets": 1.0}, "n_sets must be an integer >= 0"),
    ({"set_id": np.zeros(20)}, "set_id must be an integer array"),
    ({"set_id": np.full(20, 1, np.intp)}, r"set_id must lie in \[0, n_sets\)"),
    ({"set_id": np.full(20, -1, np.intp)}, r"set_id must lie in \[0, n_sets\)"),
    ({"min_axis_ratio": 0.5}, "min_axis_ratio must be >= 1"),
    ({"min_axis_ratio": np.nan}, "min_axis_ratio must be >= 1"),
    ({"weight": np.ones(3)}, "weight must have the shape of x"),
    ({"weight": -np.ones(20)}, "finite and non-negative"),
    ({"weight": np.full(20, np.inf)}, "finite and non-negative"),
])
def test_bad_inputs_are_rejected_with_what_is_accepted(change, message):
    x, y, set_id = _points()
    arguments = {"x": x, "y": y, "set_id": set_id, "n_sets": 1, **change}
    with pytest.raises(ValueError, match=message):
        fit_ellipses(**arguments)


def test_no_points_and_no_sets_are_accepted():
    empty = np.zeros(0)
    assert fit_ellipses(empty, empty, np.zeros(0, np.intp), 0).valid.size == 0
    assert not fit_ellipses(empty, empty, np.zeros(0, np.intp), 2).valid.any()


def test_integer_coordinates_fit_as_floats():
    x, y, set_id = _points()
    ints = fit_ellipses(np.rint(x).astype(int), np.rint(y).astype(int), set_id, 1)
    floats = fit_ellipses(np.rint(x), np.rint(y), set_id, 1)
    assert ints.as_tuples() == floats.as_tuples()
