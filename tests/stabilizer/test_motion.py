"""The Motion convention's conversions (stabilizer.motion): matrices, points and rotations."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest

from stabilizer.motion import (
    Motion,
    apply_motion,
    compensate,
    image_centre,
    motion_from_matrix,
    motion_from_rotation,
    motion_matrix,
    rotation_matrix,
    transform_points,
    wrap_angle_deg,
)
from stabilizer.testing import SR4000_SHAPE


def test_rotation_matrix_is_the_2x2_part_of_opencvs_rotation():
    for angle in (-30.0, 0.0, 7.5, 90.0):
        opencv = cv2.getRotationMatrix2D((0.0, 0.0), angle, 1.0)[:, :2]
        np.testing.assert_allclose(rotation_matrix(math.radians(angle)), opencv, atol=1e-12)


def test_rotations_turn_about_the_centre_of_the_pixel_grid():
    # Pixel centres are integers: the centre of a W x H grid is ((W - 1) / 2, (H - 1) / 2), so
    # a half turn maps pixel (x, y) onto (W - 1 - x, H - 1 - y) exactly.
    assert image_centre(SR4000_SHAPE) == (87.5, 71.5)
    image = np.random.default_rng(0).integers(1, 256, SR4000_SHAPE, dtype=np.uint8)
    np.testing.assert_array_equal(apply_motion(image, Motion(180.0, 0.0, 0.0)),
                                  image[::-1, ::-1])


def test_positive_angles_turn_counter_clockwise_as_displayed():
    # +x (right) turns toward -y (up on screen) for a small positive angle.
    turned = rotation_matrix(math.radians(10.0)) @ np.array([1.0, 0.0])
    assert turned[0] > 0 and turned[1] < 0


def test_matrix_about_the_origin_converts_to_the_centre_convention():
    """A rotation about (0, 0), as ECC reports it, re-expressed about the image centre."""
    about_origin = cv2.getRotationMatrix2D((0.0, 0.0), 6.0, 1.0)
    about_origin[:, 2] += (4.0, -2.0)
    motion = motion_from_matrix(about_origin, SR4000_SHAPE)
    np.testing.assert_allclose(motion_matrix(motion, SR4000_SHAPE), about_origin, atol=1e-9)
    assert motion.angle_deg == pytest.approx(6.0)


def test_motion_from_matrix_inverts_motion_matrix():
    truth = Motion(-12.0, 30.0, -7.5)
    found = motion_from_matrix(motion_matrix(truth, SR4000_SHAPE), SR4000_SHAPE)
    np.testing.assert_allclose(found.as_tuple(), truth.as_tuple(), atol=1e-9)


def test_motion_from_matrix_rejects_other_shapes():
    with pytest.raises(ValueError, match="2 x 3"):
        motion_from_matrix(np.eye(3), SR4000_SHAPE)


def test_motion_from_rotation_carries_the_point_onto_its_target():
    reference_point, current_point = np.array([20.0, 100.0]), np.array([35.5, 90.25])
    motion = motion_from_rotation(math.radians(8.0), reference_point, current_point,
                                  SR4000_SHAPE)
    assert motion.angle_deg == pytest.approx(8.0)
    moved = transform_points(motion, reference_point[None, :], SR4000_SHAPE)[0]
    np.testing.assert_allclose(moved, current_point, atol=1e-9)


def test_the_image_centre_only_moves_by_the_translation():
    motion = Motion(25.0, 3.0, -4.0)
    centre = np.array([image_centre(SR4000_SHAPE)])
    np.testing.assert_allclose(transform_points(motion, centre, SR4000_SHAPE),
                               centre + (3.0, -4.0), atol=1e-9)


def test_transform_points_inverse_undoes_the_motion():
    motion = Motion(-9.0, 14.0, 6.0)
    points = np.random.default_rng(0).uniform(0, 170, (20, 2))
    moved = transform_points(motion, points, SR4000_SHAPE)
    np.testing.assert_allclose(transform_points(motion, moved, SR4000_SHAPE, inverse=True),
                               points, atol=1e-9)


@pytest.mark.parametrize("image, motion, interpolation, error, named", [
    (np.zeros((8, 8), np.uint8), [1.0, 2.0, 3.0], cv2.INTER_NEAREST, TypeError, "Motion"),
    (np.zeros((8, 8), np.uint8), Motion(math.nan, 0.0, 0.0, "ok"), cv2.INTER_NEAREST,
     ValueError, "finite"),
    (np.zeros(8, np.uint8), Motion(1.0, 0.0, 0.0), cv2.INTER_NEAREST, ValueError, "2-D"),
    (np.zeros((0, 0), np.uint8), Motion(1.0, 0.0, 0.0), cv2.INTER_NEAREST, ValueError,
     "non-empty"),
    (np.zeros((8, 8), np.int64), Motion(1.0, 0.0, 0.0), cv2.INTER_NEAREST, ValueError, "int64"),
    (np.zeros((8, 8), bool), Motion(1.0, 0.0, 0.0), cv2.INTER_NEAREST, ValueError, "bool"),
    (np.zeros((8, 8), np.uint8), Motion(1.0, 0.0, 0.0), 99, ValueError, "interpolation"),
    (np.zeros((8, 8, 129), np.uint8), Motion(1.0, 0.0, 0.0), cv2.INTER_NEAREST, ValueError,
     "at most 128 channels"),  # was OpenCV's own error
])
def test_warping_names_what_it_cannot_take(image, motion, interpolation, error, named):
    for warp in (apply_motion, compensate):
        with pytest.raises(error, match=named):
            warp(image, motion, interpolation)


@pytest.mark.parametrize("channels", [1, 3, 128])
def test_a_warped_image_keeps_its_shape(channels):
    image = np.arange(8 * 8 * channels, dtype=np.float32).reshape(8, 8, channels)
    for warp in (apply_motion, compensate):
        assert warp(image, Motion(3.0, 1.0, -1.0)).shape == (8, 8, channels)


@pytest.mark.parametrize("angle, period, wrapped", [
    (0.0, 360.0, 0.0), (180.0, 360.0, 180.0), (-180.0, 360.0, 180.0), (190.0, 360.0, -170.0),
    (-190.0, 360.0, 170.0), (725.0, 360.0, 5.0), (90.0, 180.0, 90.0), (-90.0, 180.0, 90.0),
    (100.0, 180.0, -80.0), (-170.0, 180.0, 10.0)])
def test_angles_wrap_into_the_half_open_period_about_zero(angle, period, wrapped):
    # (-period / 2, period / 2]: the upper end is in, the lower one is not.
    assert wrap_angle_deg(angle, period) == pytest.approx(wrapped, abs=1e-12)
    np.testing.assert_allclose(wrap_angle_deg(np.array([angle, angle + period]), period),
                               [wrapped, wrapped], atol=1e-12)


def test_a_failed_motion_needs_a_failure_status():
    assert Motion.failed("no_overlap").status == "no_overlap"
    with pytest.raises(ValueError, match="other than 'ok'"):
        Motion.failed("ok")
