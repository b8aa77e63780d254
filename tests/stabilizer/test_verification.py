"""The trust check (stabilizer.verification) and the promise it backs: every "ok" is trustworthy.

Properties, for every method of ``stabilizer.available_methods()`` (hypothesis, derandomized):

- frames with no relation to each other (independent random noise, two different synthetic
  scenes) never give "ok";
- identical frames give "ok" with (near) zero motion, or a failure; never an invented motion,
  that is more than :data:`INVENTED` degrees or pixels;
- a frame moved by a known motion gives that motion within :data:`ROTATION_TOLERANCE_DEG` and
  :data:`SHIFT_TOLERANCE_PX`, or a failure; never an "ok" that is wrong.

The tolerances are what the check can tell apart (docs/method.md, section 11): it rejects
estimates that misalign the frames' depth edges, so a wrong rotation about the image centre of
a scene whose structure sits near the centre passes up to several degrees.

Beside them: image sizes are checked up front for every method, in the user's terms.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import stabilizer
from stabilizer import Motion, Stabilizer, apply_motion, available_methods, estimate
from stabilizer.api import MAX_SIDE, _estimator_class
from stabilizer.motion import wrap_angle_deg
from stabilizer.t2fuzzy import TranslationParams
from stabilizer.testing import SR4000_SHAPE, make_depth_scene, random_motion
from stabilizer.verification import UNVERIFIED, VerificationParams, Verifier

METHODS = available_methods()
#: An estimate on identical frames larger than this (degrees or pixels) is an invented motion.
#: t2fuzzy's rotation search climbs the correlation peak in 1.5-degree steps and interpolates
#: between the last three; on identical frames it can end about a degree off, which the check
#: cannot see (the frames still line up within a pixel or so).
INVENTED = 1.5
#: An "ok" estimate of a known motion off by more than these is wrong.
ROTATION_TOLERANCE_DEG = 10.0
SHIFT_TOLERANCE_PX = 10.0

PROPERTY = settings(derandomize=True, deadline=None, database=None, max_examples=25,
                    suppress_health_check=[HealthCheck.too_slow])


def min_side(method: str) -> int:
    return _estimator_class(method).min_side()


def scene(seed: int, shape) -> np.ndarray:
    return stabilizer.depth_to_disparity(make_depth_scene(seed, shape))


def shapes(method: str, smallest: int = 0):
    """Frame shapes from the method's smallest side (or ``smallest``) to a little over the
    SR4000's."""
    side = st.integers(max(min_side(method), smallest), 200)
    return st.tuples(side, side)


#: Two different synthetic scenes are a wall with four boxes, cylinders or slanted planes each;
#: in frames much smaller than the SR4000's, one object of each can coincide after a rotation
#: (say two tilted squares of the same size), and lining those up is a true match of what the
#: frames show. From this side on, the scenes hold enough structure to differ.
DIFFERENT_SCENES_MIN_SIDE = 128


# ----------------------------------------------------------------------------- properties
@pytest.mark.parametrize("method", METHODS)
@settings(PROPERTY)
@given(data=st.data(), seed=st.integers(0, 2**31 - 1), kind=st.sampled_from(("noise", "scenes")))
def test_unrelated_frames_never_give_ok(method, data, seed, kind):
    shape = data.draw(shapes(method, DIFFERENT_SCENES_MIN_SIDE if kind == "scenes" else 0))
    rng = np.random.default_rng(seed)
    if kind == "noise":
        reference, current = (rng.integers(0, 256, shape, dtype=np.uint8) for _ in range(2))
    else:
        reference, current = scene(seed, shape), scene(seed + 1, shape)
    motion = estimate(reference, current, method)
    assert not motion.ok, f"{method} {kind} {shape}: ok {motion.as_tuple()}"


@pytest.mark.parametrize("method", METHODS)
@settings(PROPERTY)
@given(data=st.data(), seed=st.integers(0, 2**31 - 1), kind=st.sampled_from(("noise", "scene")))
def test_identical_frames_give_no_invented_motion(method, data, seed, kind):
    shape = data.draw(shapes(method))
    rng = np.random.default_rng(seed)
    frame = rng.integers(0, 256, shape, dtype=np.uint8) if kind == "noise" else scene(seed, shape)
    motion = estimate(frame, frame.copy(), method)
    if motion.ok:
        assert max(abs(value) for value in motion.as_tuple()) <= INVENTED, (
            f"{method} {kind} {shape}: invented {motion.as_tuple()}")


@pytest.mark.parametrize("method", METHODS)
@settings(PROPERTY)
@given(data=st.data(), seed=st.integers(0, 2**31 - 1))
def test_known_motion_is_found_or_fails(method, data, seed):
    shape = data.draw(shapes(method))
    rng = np.random.default_rng(seed)
    reference = scene(seed, shape)
    truth = random_motion(rng, max_angle_deg=15.0, max_shift_px=0.2 * min(shape))
    motion = estimate(reference, apply_motion(reference, truth), method)
    if motion.ok:
        angle_error = abs(float(wrap_angle_deg(motion.angle_deg - truth.angle_deg)))
        shift_error = math.hypot(motion.dx - truth.dx, motion.dy - truth.dy)
        assert angle_error <= ROTATION_TOLERANCE_DEG and shift_error <= SHIFT_TOLERANCE_PX, (
            f"{method} {shape}: ok {motion.as_tuple()} for {truth.as_tuple()}")


# ----------------------------------------------------------------------------- the check itself
REFERENCE = scene(0, SR4000_SHAPE)
TRUTH = Motion(6.0, 12.0, -8.0)
CURRENT = apply_motion(REFERENCE, TRUTH)


def test_the_true_motion_passes_with_its_measurements():
    checked = Verifier(REFERENCE)(CURRENT, TRUTH)
    assert checked.ok and checked.as_tuple() == TRUTH.as_tuple()
    assert checked.diagnostics["verify_correlation"] > 0.8
    assert 0.5 < checked.diagnostics["verify_overlap"] <= 1.0
    assert checked.diagnostics["verify_null_correlation"] < checked.diagnostics[
        "verify_correlation"]


@pytest.mark.parametrize("wrong, failed", [
    (Motion(6.0, 32.0, -8.0), "correlation"),       # 20 px off
    (Motion(-20.0, 12.0, -8.0), "correlation"),      # 26 degrees off
    (Motion(0.0, 170.0, 0.0), "overlap"),            # almost out of view
])
def test_a_wrong_motion_fails_with_the_measured_values(wrong, failed):
    checked = Verifier(REFERENCE)(CURRENT, wrong)
    assert checked.status == UNVERIFIED and not checked.ok
    assert checked.diagnostics["verify_failed"] == failed
    assert checked.diagnostics["unverified_motion"] == wrong.as_tuple()
    assert all(math.isnan(value) for value in checked.as_tuple())


def test_a_motion_invented_on_frames_that_did_not_move_fails():
    checked = Verifier(REFERENCE)(REFERENCE.copy(), Motion(1.5, 1.0, -1.0))
    assert checked.status == UNVERIFIED and checked.diagnostics["verify_failed"] == "no_motion"


def test_failures_and_method_diagnostics_pass_through():
    failure = Motion.failed("no_structure", frame="current")
    assert Verifier(REFERENCE)(CURRENT, failure) is failure
    estimate_ = Motion(*TRUTH.as_tuple(), diagnostics={"ncc_peak": 0.9})
    assert Verifier(REFERENCE)(CURRENT, estimate_).diagnostics["ncc_peak"] == 0.9


def test_thresholds_are_parameters():
    strict = Stabilizer(REFERENCE, "ecc", verification=VerificationParams(min_correlation=1.0))
    assert strict.estimate(CURRENT).status == UNVERIFIED
    unchecked = Stabilizer(REFERENCE, "ecc", verification=None).estimate(CURRENT)
    assert unchecked.ok and "verify_correlation" not in unchecked.diagnostics


@pytest.mark.parametrize("bad", [dict(min_correlation=1.5), dict(min_overlap=-0.1),
                                 dict(null_margin=-1.0), dict(sigma_px=0.0),
                                 dict(clip_factor=0.0)])
def test_bad_thresholds_are_rejected(bad):
    with pytest.raises(ValueError, match=next(iter(bad))):
        VerificationParams(**bad)


@pytest.mark.parametrize("method", METHODS)
def test_every_method_reports_the_check(method):
    motion = estimate(REFERENCE, CURRENT, method)
    assert "verify_correlation" in motion.diagnostics or motion.status != "ok"


# ----------------------------------------------------------------------------- image sizes
@pytest.mark.parametrize("method", METHODS)
def test_frames_below_the_smallest_side_are_rejected_up_front(method):
    side = min_side(method)
    small = np.zeros((side - 1, side + 10), np.uint8)
    with pytest.raises(ValueError) as info:
        estimate(small, small, method)
    message = str(info.value)
    assert f"at least {side} x {side} pixels" in message, message
    assert f"{side + 10} x {side - 1}" in message and method in message, message


@pytest.mark.parametrize("method", METHODS)
def test_frames_above_the_largest_side_are_rejected_up_front(method):
    # A broadcast view: no memory, and any conversion before the check would take seconds.
    huge = np.broadcast_to(np.float32(2.0), (64 * 2, MAX_SIDE + 1))
    with pytest.raises(ValueError) as info:
        Stabilizer(huge, method)
    assert f"at most {MAX_SIDE} x {MAX_SIDE}" in str(info.value)
    assert f"{MAX_SIDE + 1} x 128" in str(info.value)


@pytest.mark.parametrize("method", METHODS)
def test_a_current_frame_of_another_size_is_named(method):
    side = min_side(method)
    tracker = Stabilizer(scene(1, (side, side)), method)
    with pytest.raises(ValueError, match=rf"same shape; got \({side}, {side}\) and \(20, 20\)"):
        tracker.estimate(np.zeros((20, 20), np.uint8))


@pytest.mark.parametrize("method", METHODS)
def test_frames_of_the_smallest_side_are_accepted(method):
    side = min_side(method)
    frame = scene(2, (side, side))
    motion = estimate(frame, apply_motion(frame, Motion(2.0, 3.0, -2.0)), method)
    assert isinstance(motion, Motion)


def test_t2fuzzy_smallest_side_follows_its_search_range():
    assert min_side("t2fuzzy") == 96 == 2 * TranslationParams().max_shift_px + 8
    frame = scene(3, (48, 60))
    with pytest.raises(ValueError, match="at least 96 x 96"):
        estimate(frame, frame)
    motion = estimate(frame, frame, translation=TranslationParams(max_shift_px=20))
    assert isinstance(motion, Motion)
