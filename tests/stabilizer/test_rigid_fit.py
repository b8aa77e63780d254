"""The 2-D rigid least-squares fit (stabilizer.rigid_fit) against known motions."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from stabilizer.motion import Motion, motion_matrix, transform_points
from stabilizer.rigid_fit import fit_rigid
from stabilizer.testing import SR4000_SHAPE


def _moved(points: np.ndarray, motion: Motion) -> np.ndarray:
    matrix = motion_matrix(motion, SR4000_SHAPE)
    return points @ matrix[:, :2].T + matrix[:, 2]


def test_recovers_a_motion_about_the_image_centre():
    truth = Motion(-7.5, 12.0, -3.25)
    points = np.random.default_rng(0).uniform(0, 170, (30, 2))
    fit = fit_rigid(points, _moved(points, truth), SR4000_SHAPE)
    np.testing.assert_allclose(fit.motion.as_tuple(), truth.as_tuple(), atol=1e-9)
    assert fit.residual_rms_px < 1e-9


@settings(max_examples=40, deadline=None)
@given(angle=st.floats(-170, 170), dx=st.floats(-50, 50), dy=st.floats(-50, 50))
def test_recovers_any_rigid_motion(angle, dx, dy):
    points = np.random.default_rng(1).uniform(0, [176, 144], size=(200, 2))
    fit = fit_rigid(points, _moved(points, Motion(angle, dx, dy)), SR4000_SHAPE)
    assert fit.motion.angle_deg == pytest.approx(angle, abs=1e-7)
    assert fit.motion.dx == pytest.approx(dx, abs=1e-6)
    assert fit.motion.dy == pytest.approx(dy, abs=1e-6)


def test_residual_is_the_rms_distance_left_by_the_fit():
    rng = np.random.default_rng(2)
    points = rng.uniform(0, 170, (500, 2))
    current = _moved(points, Motion(3.0, -4.0, 6.0)) + rng.normal(0.0, 0.5, points.shape)
    fit = fit_rigid(points, current, SR4000_SHAPE)
    distances = np.linalg.norm(transform_points(fit.motion, points, SR4000_SHAPE) - current,
                               axis=1)
    assert fit.residual_rms_px == pytest.approx(np.sqrt(np.mean(distances ** 2)), rel=1e-9)
    assert fit.residual_rms_px == pytest.approx(0.5 * np.sqrt(2.0), rel=0.1)


def test_same_input_gives_bit_identical_output():
    points = np.random.default_rng(3).uniform(0, 170, (50, 2))
    current = _moved(points, Motion(1.0, 2.0, 3.0))
    first, second = (fit_rigid(points, current, SR4000_SHAPE) for _ in range(2))
    assert first.motion.as_tuple() == second.motion.as_tuple()
    assert first.residual_rms_px == second.residual_rms_px



@pytest.mark.parametrize("n_points", [2, 7, 500, 6113])
def test_centring_column_by_column_keeps_numpys_values(n_points):
    # The fit centres the points column by column for speed; the ground truth of every
    # recorded sequence depends on it giving numpy's values, for C- and Fortran-ordered input.
    rng = np.random.default_rng(n_points)
    points = rng.uniform(-20.0, 190.0, (n_points, 2))
    current = _moved(points, Motion(4.0, -7.0, 2.5)) + rng.normal(0.0, 1.5, points.shape)
    p, q = points - points.mean(axis=0), current - current.mean(axis=0)
    angle = np.arctan2(np.sum(q[:, 0] * p[:, 1] - q[:, 1] * p[:, 0]), np.sum(p * q))
    for layout in (np.ascontiguousarray, np.asfortranarray):
        fit = fit_rigid(layout(points), layout(current), SR4000_SHAPE)
        np.testing.assert_array_equal(fit.reference_centred, p)
        np.testing.assert_array_equal(fit.current_centred, q)
        assert np.radians(fit.motion.angle_deg) == pytest.approx(angle, abs=1e-15)
        residual = fit.residual
        assert fit.residual_rms_px == float(np.sqrt(np.mean(np.sum(residual * residual, axis=1))))
        np.testing.assert_array_equal(fit.squared_residual,
                                      np.einsum("ij,ij->i", residual, residual))

@pytest.mark.parametrize("reference, current, message", [
    (np.zeros((5, 2)), np.zeros((4, 2)), "N x 2"),
    (np.zeros((5, 3)), np.zeros((5, 3)), "N x 2"),
    (np.zeros(10), np.zeros(10), "N x 2"),
    (np.zeros((1, 2)), np.zeros((1, 2)), "at least 2 points"),
])
def test_bad_point_sets_are_rejected(reference, current, message):
    with pytest.raises(ValueError, match=message):
        fit_rigid(reference, current, SR4000_SHAPE)
