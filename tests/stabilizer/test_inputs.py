"""Input conversion and checks (stabilizer.inputs): metric depth to the 8-bit disparity-like
image of docs/method.md, section 0."""

import re

import numpy as np
import pytest

from stabilizer.inputs import (DEFAULT_FAR_M, DEFAULT_NEAR_M, check_integer, check_number,
                               check_size, depth_to_disparity)


def test_disparity_falls_as_one_over_depth_from_255_at_the_near_limit():
    depth = np.array([[DEFAULT_NEAR_M, 1.0, 2.0, 3.0, DEFAULT_FAR_M]])
    expected = np.rint(255.0 * DEFAULT_NEAR_M / depth[0]).astype(np.uint8)
    np.testing.assert_array_equal(depth_to_disparity(depth)[0], expected)
    assert depth_to_disparity(depth)[0, 0] == 255
    # Rounded to the nearest level: 255 * 0.5 / 1.9 = 67.1, / 1.7 = 75.0, / 1.65 = 77.3.
    np.testing.assert_array_equal(depth_to_disparity(np.array([[1.9, 1.7, 1.65]])),
                                  [[67, 75, 77]])


@pytest.mark.parametrize("value", [0.0, -1.0, np.nan, np.inf, DEFAULT_NEAR_M * 0.99,
                                   DEFAULT_FAR_M * 1.01])
def test_no_measurement_and_depths_outside_the_limits_are_invalid(value):
    depth = np.full((2, 3), 1.0)
    depth[1, 2] = value
    disparity = depth_to_disparity(depth)
    assert disparity[1, 2] == 0 and np.all(disparity.ravel()[:5] == 128)


def test_depths_beyond_255_near_limits_stay_valid_at_level_1():
    # 255 * 0.5 / 400 rounds to 0, which means no measurement: a valid depth keeps level 1.
    disparity = depth_to_disparity(np.array([[400.0, 1000.0]]), far_m=1000.0)
    np.testing.assert_array_equal(disparity, [[1, 1]])


@pytest.mark.parametrize("depth, near_m, far_m, match", [
    (np.ones(3), 0.5, 10.0, "2-D"), (np.ones((2, 2), np.uint16), 0.5, 10.0, "float"),
    (np.ones((2, 2)), 0.0, 10.0, "near_m"), (np.ones((2, 2)), 2.0, 1.0, "near_m"),
    (np.ones((2, 2)), 2.0, 2.0, "near_m")])
def test_bad_depth_or_limits_are_value_errors(depth, near_m, far_m, match):
    with pytest.raises(ValueError, match=match):
        depth_to_disparity(depth, near_m, far_m)


def test_sizes_at_the_limits_are_accepted_and_a_pixel_beyond_is_refused():
    for shape in ((96, 200), (200, 96), (96, 4096), (4096, 96)):
        check_size(shape, "frame", 96, 4096)
    for shape in ((95, 200), (200, 95), (96, 4097), (4097, 96)):
        with pytest.raises(ValueError, match="at least 96 x 96 pixels and at most 4096 x 4096"):
            check_size(shape, "frame", 96, 4096)
    check_size((96, 10**6), "frame", 96)  # no upper limit


def test_integers_at_the_limits_are_accepted_and_one_beyond_is_refused():
    for value in (3, 5, np.int64(4)):
        check_integer("n", value, 3, 5)
    for value in (2, 6, 4.0, True):
        with pytest.raises(ValueError, match="n must be an integer from 3 to 5"):
            check_integer("n", value, 3, 5)
    check_integer("n", 10**9, 3)
    with pytest.raises(ValueError, match="n must be an integer >= 3"):
        check_integer("n", 2, 3)


@pytest.mark.parametrize("open_low, open_high, interval", [
    (False, False, "[0, 1]"), (True, False, "(0, 1]"), (False, True, "[0, 1)"),
    (True, True, "(0, 1)")])
def test_numbers_at_each_end_are_accepted_unless_that_end_is_open(open_low, open_high,
                                                                  interval):
    refused = f"x must be a finite number in {re.escape(interval)}; got"
    check_number("x", 0.5, 0.0, 1.0, open_low=open_low, open_high=open_high)
    for end, is_open in ((0.0, open_low), (1.0, open_high)):
        if is_open:
            with pytest.raises(ValueError, match=refused):
                check_number("x", end, 0.0, 1.0, open_low=open_low, open_high=open_high)
        else:
            check_number("x", end, 0.0, 1.0, open_low=open_low, open_high=open_high)
    for value in (-1e-9, 1.0 + 1e-9, float("nan"), float("inf"), True, "0.5"):
        with pytest.raises(ValueError, match=refused):
            check_number("x", value, 0.0, 1.0, open_low=open_low, open_high=open_high)


def test_an_unbounded_end_is_written_open():
    with pytest.raises(ValueError, match=r"in \(-inf, 2\]"):
        check_number("x", 3.0, high=2.0)
    with pytest.raises(ValueError, match=r"in \[2, inf\)"):
        check_number("x", 1.0, 2.0)
    check_number("x", -1e300)
