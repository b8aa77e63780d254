"""The whole Kang, Zhang & Park (2009) pipeline on synthetic depth scenes with known motion."""

import math

import cv2
import numpy as np
import pytest

import stabilizer
from stabilizer.motion import Motion, apply_motion, compensate
from stabilizer.t2fuzzy import (
    NO_ROTATION,
    NO_TRANSLATION,
    ROTATION_UNCONVERGED,
    TRANSLATION_DISAGREEMENT,
    FeatureParams,
    SegmentationParams,
    T2FuzzyEstimator,
    FrameAnalysis,
    ThresholdParams,
    TranslationParams,
    match_objects,
)
from stabilizer.t2fuzzy_refinements import Refinements, RotationSearch
from stabilizer.testing import make_depth_scene, random_motion

N_CASES = 100
#: The paper's stages compared on a common disc, without the rotation search.
DISC_ONLY = Refinements(rotation_search=False, common_disc_passes=1)


def _scene(seed):
    return stabilizer.depth_to_disparity(make_depth_scene(seed))


def _simple_scene():
    image = np.full((144, 176), 40, np.uint8)
    cv2.ellipse(image, (80, 70), (30, 14), 20, 0, 360, 150, -1)
    cv2.rectangle(image, (100, 95), (140, 112), 100, -1)
    return image


def _recovery(**params):
    """Absolute errors (angle, dx, dy) on N_CASES synthetic scenes under random motions."""
    rng = np.random.default_rng(2009)
    errors = []
    for seed in range(N_CASES):
        reference = _scene(seed)
        truth = random_motion(rng)  # +-15 deg, +-40 px
        estimate = T2FuzzyEstimator(reference, **params).estimate(apply_motion(reference, truth))
        errors.append(np.subtract(estimate.as_tuple(), truth.as_tuple()))
    errors = np.abs(np.array(errors))
    within = np.mean((errors[:, 0] <= 0.5) & (errors[:, 1] <= 0.5) & (errors[:, 2] <= 0.5))
    medians = np.nanmedian(errors, axis=0)
    print(f"\nt2fuzzy {params or 'defaults'} on {N_CASES} scenes: {within:.0%} within 0.5 deg / "
          f"0.5 px; median |error| angle {medians[0]:.3f} deg, dx {medians[1]:.3f} px, "
          f"dy {medians[2]:.3f} px")
    return errors, within


def test_random_motions_of_synthetic_scenes_are_recovered():
    """Issue 2: >= 90% of cases within 0.5 deg and 0.5 px, none crashes; medians reported."""
    errors, within = _recovery()
    assert np.all(np.isfinite(errors))
    assert within >= 0.9


def _objects(centres, areas):
    """A FrameAnalysis of one object per cluster, of these centres (gray levels) and areas."""
    n = len(centres)
    return FrameAnalysis(np.array(centres, float), np.zeros((4, 4), np.uint8),
                         np.arange(1, n + 1), np.array(areas, float), None, 1, True, None)


def test_objects_pair_by_nearest_cluster_centre_then_by_area():
    """docs/method.md, section 4: ranked by the gap of the cluster centres, ties by the log
    ratio of the areas; one-to-one."""
    reference = _objects([100.0, 60.0], [100.0, 100.0])
    # The nearer centre wins over the equal area; at equal gaps, the nearer area wins.
    assert match_objects(reference, _objects([104.0, 101.0], [100.0, 900.0]), 10.0) == [(0, 1)]
    assert match_objects(reference, _objects([98.0, 102.0, 61.0], [900.0, 120.0, 50.0]),
                         10.0) == [(1, 2), (0, 1)]
    # The ratio of the areas, not their size: a tenth of the area is farther than half again.
    assert match_objects(_objects([100.0], [100.0]), _objects([98.0, 102.0], [10.0, 150.0]),
                         10.0) == [(0, 1)]


def test_objects_whose_centres_differ_by_more_than_the_limit_stay_unmatched():
    reference = _objects([100.0, 200.0], [100.0, 100.0])
    assert match_objects(reference, _objects([103.0, 150.0], [100.0, 100.0]), 10.0) == [(0, 0)]


def test_objects_pair_one_to_one_and_at_the_limit_still_pair():
    # Both reference objects are nearest the first current one: the nearer takes it, and the
    # other the next current object within the limit, not the taken one again.
    reference = _objects([100.0, 103.0], [100.0, 100.0])
    assert match_objects(reference, _objects([101.0, 110.0], [100.0, 100.0]), 10.0) == \
        [(0, 0), (1, 1)]
    # Only a gap of more than the limit leaves a pair out.
    assert match_objects(_objects([100.0], [100.0]), _objects([110.0], [100.0]), 10.0) == \
        [(0, 0)]


@pytest.mark.parametrize("refinements", [DISC_ONLY, Refinements.off()])
def test_paper_pipeline_without_refinement_runs_and_is_reported(refinements):
    """The paper's stages (no rotation search; with and without the common disc): coarser,
    see docs/method.md, section 10."""
    errors, _ = _recovery(refinements=refinements)
    assert np.mean(np.isfinite(errors[:, 0])) >= 0.95
    assert np.nanmedian(errors[:, 0]) < 3.0


def test_comparing_a_common_disc_helps_the_paper_stages():
    """Objects cut by the image border in one frame only: the overlap pass compares alike."""
    with_disc, _ = _recovery(refinements=DISC_ONLY)
    as_written, _ = _recovery(refinements=Refinements.off())
    assert np.nanmedian(with_disc[:, 0]) < np.nanmedian(as_written[:, 0])


def _corridor():
    """Walls, floor and ceiling in one band of gray levels (one object), their far end out of
    range (invalid) and a few isolated phase-wrapped pixels (a second cluster cleaned away)."""
    rows, columns = np.mgrid[:144, :176]
    to_border = np.minimum.reduce([columns, 175 - columns, rows, 143 - rows])
    image = np.clip(60 - to_border * 0.25, 41, 60).astype(np.uint8)
    image[:70, 60:116] = 0
    image[75:140:13, 30:150:17] = 200
    return image


@pytest.mark.parametrize("truth", [Motion(4.0, 6.0, -3.0), Motion(-8.0, -15.0, 5.0)])
def test_one_object_beside_a_far_region_gives_an_estimate(truth):
    reference = _corridor()
    current = apply_motion(reference, truth)
    refined = stabilizer.estimate(reference, current)
    assert refined.diagnostics["n_clusters"] == 2 and refined.ok
    assert np.unique(refined.diagnostics["labels"]).tolist() == [0, 1]
    np.testing.assert_allclose(refined.as_tuple(), truth.as_tuple(), atol=0.5)
    assert stabilizer.estimate(reference, current, refinements=DISC_ONLY).ok


def _without_outline():
    image = np.full((144, 176), 60, np.uint8)
    image[70, 80] = 200  # a second level whose cluster the clean-up removes
    image[::37, 3:] = 0  # dropouts: long thin lines, no far region
    return image


def test_an_object_without_scene_outline_has_no_structure():
    """Its only edges are the measurement's: its shape is the frame's, not the scene's."""
    image = _without_outline()
    motion = stabilizer.estimate(image, apply_motion(image, Motion(5.0, 3.0, 2.0)))
    assert motion.status == "no_structure" and motion.diagnostics["frame"] == "reference"


SIGN_CASES = [Motion(6.0, 10.0, -7.0), Motion(-9.5, -20.3, 4.6), Motion(0.0, 0.0, 0.0)]


@pytest.mark.parametrize("params", [{}, {"refinements": Refinements.off()}])
@pytest.mark.parametrize("truth", SIGN_CASES)
def test_signs_follow_the_motion_convention(truth, params):
    reference = _simple_scene()
    estimate = stabilizer.estimate(reference, apply_motion(reference, truth), **params)
    assert estimate.ok
    np.testing.assert_allclose(estimate.as_tuple(), truth.as_tuple(), atol=0.5)


@pytest.mark.parametrize("truth", SIGN_CASES)
def test_signs_of_the_paper_stages_on_a_common_disc(truth):
    """The paper's stages compared on a common disc, which cuts the rectangle of this scene:
    its subband angles spread over about 3 deg, so the angle is good to 1 deg here, the shift
    to 0.5 px."""
    reference = _simple_scene()
    estimate = stabilizer.estimate(reference, apply_motion(reference, truth),
                                   refinements=DISC_ONLY)
    assert estimate.ok and estimate.diagnostics["refine_passes"] == 1
    error = np.abs(np.subtract(estimate.as_tuple(), truth.as_tuple()))
    assert error[0] <= 1.0 and error[1] <= 0.5 and error[2] <= 0.5


def test_a_common_disc_pass_fits_an_uncut_object_as_the_whole_frame_does():
    """An object inside the common disc, with a hole of unmeasured pixels in it, gets the same
    ellipses from a pass on the disc as from the whole frame: the pass too leaves out the
    detail points at the unmeasured pixels (the hole's edge is the measurement's, not the
    scene's)."""
    reference = _simple_scene()
    current = apply_motion(reference, Motion(2.0, 3.0, -2.0))
    current[60:75, 70:78] = 0
    rows, cols = np.nonzero(current == 150)  # the ellipse, well inside the disc
    disc, whole = (stabilizer.estimate(reference, current, verification=None,
                                       refinements=Refinements(rotation_search=False,
                                                               common_disc_passes=passes))
                   for passes in (1, 0))
    assert disc.diagnostics["refine_passes"] == 1 and whole.diagnostics["refine_passes"] == 0
    fits = [fit for fit in whole.diagnostics["ellipses"]
            if math.hypot(fit[0] - cols.mean(), fit[1] - rows.mean()) < 3.0]
    assert len(fits) == 3  # its approximation and detail subbands
    for fit in fits:
        assert any(np.allclose(fit, other) for other in disc.diagnostics["ellipses"])


@pytest.mark.parametrize("passes, extra, steps, agree_from, fail_at, expected", [
    (3, 0, [10.0, 20.0, 30.0, 40.0], None, None, [1, 2, 3]),  # every pass, no more
    (5, 0, [10.0, 20.0, 20.0 + 1e-3, 50.0], None, None, [1, 2, 3]),  # the angle settled
    (4, 0, [10.0, 20.0, 30.0, 40.0], None, 2, [1, 2]),  # a failed pass ends them
    (1, 2, [10.0, 20.0, 30.0, 40.0], None, None, [1, 2, 3]),  # extra passes: angles disagree
    (1, 2, [10.0, 20.0, 30.0, 40.0], 2, None, [1, 2]),  # until the two rotations agree
    (2, 2, [10.0, 20.0, 30.0, 40.0], 1, None, [1, 2]),  # the asked passes whatever they say
])
def test_common_disc_passes_run_as_many_times_as_asked_and_stop_early(
        monkeypatch, passes, extra, steps, agree_from, fail_at, expected):
    """``common_disc_passes`` passes run in turn, each from the last estimate, until the angle
    changes by less than the threshold's resolution or a pass fails (its predecessor is kept);
    then up to ``extra_disc_passes`` more while the searched rotation and the thresholds'
    disagree by more than ``extra_pass_trigger_deg``. Each pass here returns the next angle of
    ``steps``, its thresholds' rotation 100 degrees away, or (from the pass ``agree_from`` on)
    the same."""
    calls = []

    def fake_pass(self, motion, reference, frame, current, image, diagnostics):
        calls.append(diagnostics["refine_passes"])
        if len(calls) == fail_at:
            return Motion.failed(NO_TRANSLATION, **diagnostics)
        angle = steps[len(calls) - 1]
        agree = agree_from is not None and len(calls) >= agree_from
        return Motion(angle, 0.0, 0.0, diagnostics=dict(
            diagnostics, rotation_by_thresholds=angle if agree else angle + 100.0))

    monkeypatch.setattr(T2FuzzyEstimator, "_common_disc_pass", fake_pass)
    reference = _scene(3)
    estimator = T2FuzzyEstimator(reference, refinements=Refinements(
        common_disc_passes=passes, extra_disc_passes=extra))
    estimate = estimator.estimate(apply_motion(reference, Motion(2.0, 6.0, -4.0)))
    assert calls == expected
    kept = len(calls) - 1 if fail_at == len(calls) else len(calls)
    assert estimate.ok and estimate.angle_deg == steps[kept - 1]
    assert estimate.diagnostics["refine_passes"] == kept


def test_compensation_lines_the_frame_up_with_the_reference():
    reference = _scene(7)
    current = apply_motion(reference, Motion(8.0, 12.0, -9.0))
    estimate = stabilizer.estimate(reference, current)
    stabilized = compensate(current, estimate)
    both = (stabilized > 0) & (reference > 0)
    assert np.mean(stabilized[both] == reference[both]) > 0.95


def test_diagnostics_describe_what_the_estimator_saw():
    reference = _scene(3)
    estimate = stabilizer.estimate(reference, apply_motion(reference, Motion(5.0, 3.0, 2.0)))
    d = estimate.diagnostics
    assert d["n_clusters"] == len(d["centres"]) >= 2
    assert d["labels"].shape == reference.shape and d["labels"].dtype == np.int32
    assert set(np.unique(d["labels"])) <= set(range(d["n_clusters"] + 1))
    assert np.all(d["labels"][apply_motion(reference, Motion(5.0, 3.0, 2.0)) == 0] == 0)
    assert d["object_angles"].shape == d["inliers"].shape
    assert d["angle_sources"].shape == (d["object_angles"].size, 3)
    lower, upper = d["thresholds"]
    assert np.all(d["object_angles"][d["inliers"]] >= lower)
    assert np.all(d["object_angles"][d["inliers"]] <= upper)
    assert d["threshold_fallback"] in (None, "median")
    assert -1.0 <= d["ncc_peak"] <= 1.0 and d["ncc_at_border"] in (True, False)
    assert d["refine_passes"] in (0, 1, 2) and np.isfinite(d["rotation_by_thresholds"])
    assert all(len(e) == 5 and e[2] >= e[3] > 0 and 0 <= e[4] < 180 for e in d["ellipses"])


def test_ellipses_are_in_image_coordinates():
    reference = _simple_scene()
    d = stabilizer.estimate(reference, reference).diagnostics
    # The drawn ellipse: centre (80, 70), half-axes 30 x 14, major axis at 20 deg.
    closest = min(d["ellipses"], key=lambda e: np.hypot(e[0] - 80, e[1] - 70))
    assert closest[0] == pytest.approx(80, abs=1.5) and closest[1] == pytest.approx(70, abs=1.5)
    assert closest[4] == pytest.approx(20, abs=2)


def test_reference_is_analysed_once():
    calls = []

    class Counting(T2FuzzyEstimator):
        def analyse(self, image, start=None, **options):
            calls.append(start)
            return super().analyse(image, start, **options)

    reference = _scene(2)
    estimator = Counting(reference)
    for angle in (2.0, 4.0, 6.0):
        estimator.estimate(apply_motion(reference, Motion(angle, 1.0, 1.0)))
    assert len(calls) == 4  # the reference once, then each current frame


def test_same_input_gives_identical_results():
    reference = _scene(11)
    current = apply_motion(reference, Motion(-7.0, 15.0, 5.0))
    first = stabilizer.estimate(reference, current)
    second = stabilizer.estimate(reference.copy(), current.copy())
    assert first.as_tuple() == second.as_tuple()
    assert np.array_equal(first.diagnostics["labels"], second.diagnostics["labels"])


def test_round_objects_only_give_no_rotation_estimate():
    """No ellipse orients a disc: the paper's stages have no rotation estimate; ``t2fuzzy``
    searches from rotation 0 (``search_without_estimates``), where the frames line up. Nor does
    anything else fix the rotation of a lone disc: turned about its own centre it looks the
    same, so the trust check finds a turn of about 13 degrees (with the matching shift) that
    lines the frames up as well, and reports the estimate as ambiguous."""
    image = np.full((144, 144), 40, np.uint8)
    cv2.circle(image, (72, 72), 30, 160, -1)
    current = apply_motion(image, Motion(0.0, 3.0, 2.0))
    paper = stabilizer.estimate(image, current, method="t2fuzzy_paper")
    assert paper.status == NO_ROTATION and np.isnan(paper.dx)
    searched = stabilizer.estimate(image, current, verification=None)
    assert searched.ok and searched.diagnostics["object_angles"].size == 0
    np.testing.assert_allclose(searched.as_tuple(), (0.0, 3.0, 2.0), atol=0.5)
    checked = stabilizer.estimate(image, current)
    assert checked.status == "unverified" and checked.diagnostics["verify_failed"] == "ambiguous"
    assert abs(checked.diagnostics["verify_candidate"][0]) > 5.0
    unsearched = stabilizer.estimate(image, current,
                                     refinements=Refinements(search_without_estimates=False))
    assert unsearched.status == NO_ROTATION


def test_unmatched_correlation_gives_no_translation_estimate():
    reference = _simple_scene()
    motion = stabilizer.estimate(reference, reference,
                                 translation=TranslationParams(min_ncc=1.01))
    assert motion.status == NO_TRANSLATION
    assert motion.diagnostics["ncc_peak"] == pytest.approx(1.0, abs=1e-3)


def test_a_flat_central_template_gives_no_translation_estimate():
    # Objects only near the corners: the paper's central template (44 px in from every side)
    # is flat, its correlation undefined (NaN) at every shift: a failure, not an "ok" NaN.
    reference = np.full((144, 176), 60, np.uint8)
    for centre in ((20, 20), (150, 25), (25, 120), (150, 118)):
        cv2.ellipse(reference, centre, (14, 8), 30, 0, 360, 180, -1)
    current = apply_motion(reference, Motion(2.0, 1.0, 1.0))
    motion = stabilizer.estimate(reference, current, method="t2fuzzy_paper", verification=None)
    assert motion.status == NO_TRANSLATION and math.isnan(motion.diagnostics["ncc_peak"])


def _odd_frames():
    rng = np.random.default_rng(5)
    noise = rng.integers(0, 256, (144, 176)).astype(np.uint8)
    stripes = np.tile(np.repeat(np.array([30, 200], np.uint8), 8), (144, 11))
    speck = np.full((144, 176), 60, np.uint8)
    speck[70, 80] = 200
    half_invalid = _scene(4)
    half_invalid[:, :90] = 0
    tiny = np.zeros((16, 16), np.uint8)
    tiny[4:12, 5:10] = 120
    return [noise, stripes, speck, half_invalid, tiny]


@pytest.mark.parametrize("frame", _odd_frames())
def test_odd_frames_never_crash(frame):
    for current in (frame, apply_motion(frame, Motion(7.0, 3.0, -2.0)), np.zeros_like(frame)):
        search = TranslationParams(max_shift_px=min(44, frame.shape[0] // 4))
        motion = stabilizer.estimate(frame, current, translation=search)
        assert motion.ok or motion.status in ("no_structure", NO_ROTATION, NO_TRANSLATION,
                                              ROTATION_UNCONVERGED, TRANSLATION_DISAGREEMENT)
        assert motion.ok == np.isfinite(motion.angle_deg)


@pytest.mark.parametrize("group, params", [
    (FeatureParams, {"min_hole_size": 0}), (TranslationParams, {"ncc_sigma": -1.0}),
    # Unchecked, these failed later in OpenCV (out of memory), numpy or the comparisons.
    (SegmentationParams, {"bin_width": float("inf")}), (SegmentationParams, {"min_ratio": "x"}),
    (SegmentationParams, {"fcm_tol": float("nan")}), (SegmentationParams, {"m2": 1.5}),
    (SegmentationParams, {"morph_size": 4}), (SegmentationParams, {"warm_start": 1}),
    (FeatureParams, {"edge_margin": 100_000}), (FeatureParams, {"wavelet_level": 10**9}),
    (FeatureParams, {"max_centre_shift": float("nan")}), (FeatureParams, {"weighted_fit": "yes"}),
    (FeatureParams, {"wavelet": 3}), (FeatureParams, {"significance": 1.0}),
    # Unbounded, these asked for gigabytes or ran for minutes.
    (TranslationParams, {"ncc_sigma": 1e9}), (SegmentationParams, {"morph_size": 100_001}),
    (ThresholdParams, {"bandwidth_deg": 1e5}), (ThresholdParams, {"resolution_deg": 1e-7}),
    (SegmentationParams, {"fcm_max_iter": 10**9}),
])
def test_bad_parameters_are_value_errors(group, params):
    with pytest.raises(ValueError, match=next(iter(params))):
        group(**params)


def test_the_diagnostics_are_the_callers_to_change():
    reference = _scene(3)
    tracker = stabilizer.Stabilizer(reference)
    current = apply_motion(reference, Motion(2.0, 3.0, -1.0))
    first = tracker.estimate(current)
    first.diagnostics["subbands"].clear()  # was the estimator's own list: then a ValueError
    again = tracker.estimate(current)
    assert again.as_tuple() == first.as_tuple() and again.diagnostics["subbands"]


def test_too_small_a_frame_for_the_search_range_is_a_value_error():
    """The template must keep 8 x 8 pixels: 2 * 44 + 8 = 96 pixels per side by default."""
    T2FuzzyEstimator(np.zeros((96, 96), np.uint8))
    with pytest.raises(ValueError, match="max_shift_px"):
        T2FuzzyEstimator(np.zeros((95, 120), np.uint8))


def test_estimates_the_central_template_and_the_whole_overlap_disagree_on_are_failures():
    """The wide search's shift is in the diagnostics; an estimate farther from it than
    ``max_shift_disagreement_px`` is a failure that keeps the estimate for inspection."""
    reference = _scene(7)
    current = apply_motion(reference, Motion(4.0, 9.0, -6.0))
    agreed = stabilizer.estimate(reference, current, verification=None)
    assert agreed.ok
    np.testing.assert_allclose(agreed.diagnostics["wide_shift"], (9.0, -6.0), atol=2.0)
    strict = stabilizer.estimate(reference, current, verification=None,
                                 refinements=Refinements(max_shift_disagreement_px=1e-6))
    assert strict.status == TRANSLATION_DISAGREEMENT
    np.testing.assert_allclose(strict.diagnostics["disagreeing_motion"], agreed.as_tuple())
    paper = stabilizer.estimate(reference, current, method="t2fuzzy_paper", verification=None)
    assert "wide_shift" not in paper.diagnostics and "search_converged" not in paper.diagnostics
    # The disagreement is the distance between the two shifts, not one axis of it.
    gap_x, gap_y = (abs(shift - wide) for shift, wide in
                    zip(agreed.as_tuple()[1:], agreed.diagnostics["wide_shift"]))
    between = (max(gap_x, gap_y) + math.hypot(gap_x, gap_y)) / 2.0
    assert min(gap_x, gap_y) > 0.1 * between
    beyond = stabilizer.estimate(reference, current, verification=None, refinements=Refinements(
        max_shift_disagreement_px=between, resolve_disagreement=False))
    assert beyond.status == TRANSLATION_DISAGREEMENT
    within = stabilizer.estimate(reference, current, verification=None, refinements=Refinements(
        max_shift_disagreement_px=1.1 * math.hypot(gap_x, gap_y), resolve_disagreement=False))
    assert within.as_tuple() == agreed.as_tuple()


def test_an_unconverged_rotation_search_is_a_failure():
    """With no climbing step, the search stops where it starts: here at the thresholded
    rotation of stage 5 (3.5 deg for a 9 deg motion), which is no peak of the correlation."""
    reference = _scene(8)
    current = apply_motion(reference, Motion(9.0, 3.0, 2.0))
    cut_short = Refinements(search_max_steps=0, search_candidates=0)
    motion = stabilizer.estimate(reference, current, verification=None, refinements=cut_short)
    assert motion.status == ROTATION_UNCONVERGED
    assert not motion.diagnostics["search_converged"]
    assert abs(motion.diagnostics["unconverged_motion"][0] - 9.0) > 2.0
    climbed = stabilizer.estimate(reference, current, verification=None)
    assert climbed.ok and climbed.diagnostics["search_converged"]
    assert climbed.angle_deg == pytest.approx(9.0, abs=0.5)


def test_an_unconverged_search_is_settled_on_the_whole_overlap(monkeypatch):
    """A search said to end without a maximum is climbed again on the whole overlap from its
    estimate and from the wide search's motion (``resolve_disagreement``): both climbs reach
    the truth here, so it is the estimate; without the refinement the frame fails."""
    reference = _scene(8)
    truth = Motion(9.0, 3.0, 2.0)
    current = apply_motion(reference, truth)
    search = RotationSearch.__call__

    def unconverged(self, *args, **kwargs):
        angle, match, _ = search(self, *args, **kwargs)
        return angle, match, False

    monkeypatch.setattr(RotationSearch, "__call__", unconverged)
    settled = stabilizer.estimate(reference, current, verification=None)
    assert settled.ok
    np.testing.assert_allclose(settled.as_tuple(), truth.as_tuple(), atol=0.5)
    assert "unconverged_motion" in settled.diagnostics
    failed = stabilizer.estimate(reference, current, verification=None,
                                 refinements=Refinements(resolve_disagreement=False))
    assert failed.status == ROTATION_UNCONVERGED
