"""The refinements of ``t2fuzzy`` over the paper's pipeline, one by one."""

import math

import cv2
import numpy as np
import pytest

import stabilizer
from stabilizer.fncc import RotatedTemplate, TemplateMatch
from stabilizer.motion import Motion, apply_motion
from stabilizer.t2fuzzy import TRANSLATION_DISAGREEMENT, T2FuzzyEstimator
from stabilizer.t2fuzzy_refinements import (
    Refinements,
    RotationSearch,
    WideSearch,
    common_disc,
    half_resolution_template,
    half_resolution_valid,
    translation_guess,
)
from stabilizer.testing import corpus_frames, make_depth_scene
from stabilizer.verification import VerificationParams
from tests.stabilizer.walking_frames import walking_frames


def _scene():
    image = np.full((144, 176), 40, np.uint8)
    cv2.ellipse(image, (80, 70), (30, 14), 20, 0, 360, 150, -1)
    cv2.rectangle(image, (100, 95), (140, 112), 100, -1)
    return image


def _smoothed(image):
    return cv2.GaussianBlur(image.astype(np.float32), (0, 0), 1.0)


@pytest.mark.parametrize("motion", [Motion(6.0, 10.0, -7.0), Motion(-12.0, -30.0, 20.0)])
def test_common_disc_masks_show_the_same_part_of_the_scene(motion):
    in_reference, in_current = common_disc(motion, (144, 176))
    moved = apply_motion(in_reference.view(np.uint8), motion) > 0
    overlap = np.count_nonzero(moved & in_current) / np.count_nonzero(moved | in_current)
    assert overlap > 0.97
    height, width = in_reference.shape
    for mask in (in_reference, in_current):  # whole discs, inside the image
        assert not (mask[0].any() or mask[-1].any() or mask[:, 0].any() or mask[:, -1].any())
    assert np.count_nonzero(in_reference) > 0.3 * height * width


def test_the_common_disc_is_centred_half_way_along_the_shift_and_as_large_as_both_allow():
    # A shift of 100 px along x: the disc sits at x = 37.5 in the reference and 137.5 in the
    # current frame, 38.5 px from each image's side, so its radius is 36.5 px (one pixel in).
    in_reference, in_current = common_disc(Motion(0.0, 100.0, 0.0), (144, 176))
    for mask, centre_x in ((in_reference, 37.5), (in_current, 137.5)):
        rows, cols = np.nonzero(mask)
        assert cols.mean() == pytest.approx(centre_x, abs=0.1)
        assert rows.mean() == pytest.approx(71.5, abs=0.1)
        assert rows.size == pytest.approx(math.pi * 36.5 ** 2, rel=0.03)
        # It reaches the pixels one in from the side, and no farther.
        assert (cols.min(), cols.max()) == (centre_x - 36.5, centre_x + 36.5)


@pytest.mark.parametrize("row, col", [(20, 30), (21, 31), (21, 30)])
def test_a_half_resolution_pixel_is_unmeasured_when_its_kernel_sees_an_unmeasured_one(row, col):
    """cv2.pyrDown's 5 x 5 kernel reaches 2 full-resolution pixels either side of pixel
    (2i, 2j): exactly the half-resolution pixels within that reach of one unmeasured pixel are
    unmeasured, also those that see it with the kernel's least weight (1/256, at a corner)."""
    valid = np.ones((144, 176), bool)
    valid[row, col] = False
    rows, cols = np.indices((72, 88))
    expected = (np.abs(2 * rows - row) <= 2) & (np.abs(2 * cols - col) <= 2)
    np.testing.assert_array_equal(~half_resolution_valid(valid), expected)


def test_translation_guess_finds_the_shift_at_half_resolution():
    reference = _scene()
    coarse = half_resolution_template(_smoothed(reference), 44)
    guess = translation_guess(coarse, _smoothed(apply_motion(reference, Motion(0, 12, -8))), 0.3)
    assert guess.angle_deg == 0.0
    np.testing.assert_allclose((guess.dx, guess.dy), (12, -8), atol=1.0)
    assert translation_guess(coarse, _smoothed(reference), 1.01) is None
    # A flat reference has no correlation at all (NaN): no guess either.
    flat = half_resolution_template(np.full((144, 176), 50.0, np.float32), 44)
    assert translation_guess(flat, _smoothed(reference), 0.3) is None


@pytest.mark.parametrize("start", [0.0, 6.0, 12.0])
def test_rotation_search_climbs_to_the_correlation_peak(start):
    """Whatever the ellipse estimates, the search ends at the rotation that matches best."""
    reference = _scene()
    smoothed = _smoothed(reference)
    search = RotationSearch(RotatedTemplate(smoothed, 44), half_resolution_template(smoothed, 44),
                            Refinements())
    truth = Motion(7.0, 5.0, -3.0)
    angle, match, converged = search(np.array([start]), start,
                                     _smoothed(apply_motion(reference, truth)))
    np.testing.assert_allclose((angle, match.x, match.y), truth.as_tuple(), atol=0.5)
    assert converged


def _wide_search_setup(truth):
    reference = _scene()
    smoothed = _smoothed(reference)
    wide = WideSearch(smoothed, reference > 0, 72, 0.3)
    search = RotationSearch(RotatedTemplate(smoothed, 44), half_resolution_template(smoothed, 44),
                            Refinements(), wide)
    current = apply_motion(reference, truth)
    return search, _smoothed(current), current


@pytest.mark.parametrize("truth", [Motion(5.0, 12.0, -6.0), Motion(-8.0, 58.0, 20.0),
                                   Motion(3.0, -20.0, -52.0)])
def test_wide_search_finds_shifts_beyond_the_central_template(truth):
    """The central template reaches +-44 px; the masked search of the whole overlap finds
    the shift beyond it too (the last two), and a nearby one to start the fine search."""
    search, image, current = _wide_search_setup(truth)
    valid = current > 0
    angle, match, converged = search(np.array([truth.angle_deg]), truth.angle_deg, image,
                                      valid=valid)
    np.testing.assert_allclose((angle, match.x, match.y), truth.as_tuple(), atol=1.0)
    assert converged
    # Without the wide search the central template cannot reach the shift.
    if max(abs(truth.dx), abs(truth.dy)) > 44:
        _, alone, _ = search(np.array([truth.angle_deg]), truth.angle_deg, image)
        assert max(abs(alone.x - truth.dx), abs(alone.y - truth.dy)) > 5.0


def test_wide_search_scores_the_whole_overlap():
    """Structures near the border, outside the central template, fix the shift: a scene whose
    central region is a horizontal edge only (no x information) with two pillars at the sides."""
    reference = np.full((144, 176), 40, np.uint8)
    reference[72:] = 90  # a horizon across the whole frame: the centre fixes y only
    cv2.rectangle(reference, (8, 10), (22, 130), 200, -1)
    cv2.rectangle(reference, (150, 10), (166, 130), 200, -1)
    smoothed = _smoothed(reference)
    truth = Motion(0.0, -9.0, 2.0)
    current = apply_motion(reference, truth)
    wide = WideSearch(smoothed, reference > 0, 72, 0.3)
    spectra = wide.spectra(cv2.pyrDown(_smoothed(current)), half_resolution_valid(current > 0))
    match = wide.match(spectra, 0.0)
    np.testing.assert_allclose((match.x, match.y), (truth.dx, truth.dy), atol=1.0)
    central = RotatedTemplate(smoothed, 44).match(_smoothed(current), 0.0)
    assert abs(central.x - truth.dx) > 3.0  # the central template alone slides along the edge


def test_wide_search_reuses_its_upright_reference_exactly():
    """Rotation 0 is scored on most frames: the reference's spectra at 0 are made once per
    reference, and every later frame gets the very match a fresh search gives."""
    reference = _scene()
    smoothed = _smoothed(reference)
    reused = WideSearch(smoothed, reference > 0, 72, 0.3)
    for truth in (Motion(0.0, 12.0, -6.0), Motion(4.0, -20.0, 9.0), Motion(-2.0, 3.0, 30.0)):
        current = apply_motion(reference, truth)
        half, valid = cv2.pyrDown(_smoothed(current)), half_resolution_valid(current > 0)
        fresh = WideSearch(smoothed, reference > 0, 72, 0.3)
        for angle in (0.0, truth.angle_deg, 0.0):
            assert (reused.match(reused.spectra(half, valid), angle)
                    == fresh.match(fresh.spectra(half, valid), angle))


def test_a_climb_that_finds_no_peak_is_unconverged():
    """A climb cut off by ``search_max_steps`` (here 1 step of 1.5 deg at each resolution, from
    0 towards a 7 deg rotation) reports that it found no local maximum."""
    reference = _scene()
    smoothed = _smoothed(reference)
    search = RotationSearch(RotatedTemplate(smoothed, 44), half_resolution_template(smoothed, 44),
                            Refinements(search_max_steps=1, search_candidates=0))
    truth = Motion(7.0, 5.0, -3.0)
    angle, _, converged = search(np.empty(0), 0.0, _smoothed(apply_motion(reference, truth)))
    # At most one step and a half-step vertex offset at each of the two resolutions.
    assert not converged and abs(angle) <= 2 * 1.5 * 1.5 + 1e-9


def test_a_climb_whose_last_step_reaches_the_peak_is_converged():
    """Cut off by ``max_steps`` right at the peak (one step of 1.5 deg from 4.5 to 6 deg, the
    truth 6.2), the climb still reports a local maximum; one step short of it, none."""
    reference = _scene()
    smoothed = _smoothed(reference)
    template = RotatedTemplate(smoothed, 44)
    search = RotationSearch(template, half_resolution_template(smoothed, 44), Refinements())
    current = _smoothed(apply_motion(reference, Motion(6.2, 5.0, -3.0)))
    for start, converged in ((4.5, True), (3.0, False)):
        angle, _, flag = search._climb(template, current, start, template.match(current, start),
                                       max_steps=1)
        assert flag is converged and abs(angle - start) <= 1.5 * 1.5 + 1e-9  # a step, half more


class _ParabolicPeak:
    """A template whose correlation over rotation is the parabola -(angle - peak)^2, whose
    shift grows linearly with the angle, and which records where each match is asked near."""

    def __init__(self, peak_deg: float):
        self.peak_deg, self.asked = peak_deg, []

    def match(self, image, angle_deg, near=None):
        self.asked.append((angle_deg, near))
        return TemplateMatch(10.0 * angle_deg, -5.0 * angle_deg, 1.0, False,
                             -(angle_deg - self.peak_deg) ** 2)


def _default_climb_from_zero(template: _ParabolicPeak):
    """The default search's climb on ``template`` from rotation 0: (angle, match, converged)."""
    smoothed = _smoothed(_scene())
    search = RotationSearch(RotatedTemplate(smoothed, 44), half_resolution_template(smoothed, 44),
                            Refinements())
    return search._climb(template, None, 0.0, template.match(None, 0.0))


def test_the_climb_ends_at_the_vertex_with_the_shift_interpolated_there():
    """Steps of 1.5 deg from 0 towards a peak at 2 deg: the climb stops at 1.5 (above 0 and
    3), the parabola through the three puts the rotation at 2 and the shift where it is at 2
    (20, -10), between the samples'; each step searches near the shift of its new centre."""
    template = _ParabolicPeak(2.0)
    angle, match, converged = _default_climb_from_zero(template)
    assert converged and angle == pytest.approx(2.0)
    assert (match.x, match.y) == (pytest.approx(20.0), pytest.approx(-10.0))
    assert template.asked[-1] == (3.0, (15.0, -7.5))


def test_the_default_climb_reaches_the_rotation_range_from_the_identity():
    """From rotation 0, the candidate every search scores, the default climb reaches a peak
    at 19 deg, just inside ``max_rotation_deg`` (20), and ends there at a local maximum."""
    angle, _, converged = _default_climb_from_zero(_ParabolicPeak(19.0))
    assert converged and angle == pytest.approx(19.0)


def test_the_candidates_are_the_means_of_the_largest_groups_of_angles():
    """Groups split at gaps wider than two climbing steps (3 deg), largest first."""
    reference = _scene()
    smoothed = _smoothed(reference)
    search = RotationSearch(RotatedTemplate(smoothed, 44), half_resolution_template(smoothed, 44),
                            Refinements(search_candidates=2))
    means = search._group_means(np.array([9.0, 1.0, 5.0, 1.1, 9.1, 1.2]))
    assert means == [pytest.approx(1.1), pytest.approx(9.05)]
    # A gap of 2.1 deg, more than one step but not two, does not split a group.
    assert search._group_means(np.array([1.0, 1.1, 3.2])) == [pytest.approx(5.3 / 3)]


def test_the_search_stays_within_the_rotation_range():
    """Candidates beyond ``max_rotation_deg`` are not scored, and the climb stops at it."""
    reference = _scene()
    smoothed = _smoothed(reference)
    search = RotationSearch(RotatedTemplate(smoothed, 44), half_resolution_template(smoothed, 44),
                            Refinements(max_rotation_deg=4.0))
    truth = Motion(9.0, 0.0, 0.0)
    angle, _, converged = search(np.array([9.0]), 9.0, _smoothed(apply_motion(reference, truth)))
    assert abs(angle) <= 4.0 + 1.5 and not converged


def test_an_unbounded_rotation_range_is_accepted_and_searched():
    """``max_rotation_deg=math.inf``, the refinements before the range existed
    (benchmarks/t2fuzzy_failures.py, ``before_refinements``; refused as not finite, which
    broke that script's ``table``): the same search climbs to the 9 degrees a bound of 4 stops
    short of."""
    reference = _scene()
    smoothed = _smoothed(reference)
    search = RotationSearch(RotatedTemplate(smoothed, 44), half_resolution_template(smoothed, 44),
                            Refinements(max_rotation_deg=math.inf))
    truth = Motion(9.0, 0.0, 0.0)
    angle, _, converged = search(np.array([9.0]), 9.0, _smoothed(apply_motion(reference, truth)))
    assert converged and abs(angle - 9.0) < 0.5


def test_off_is_the_paper_pipeline():
    off = Refinements.off()
    assert not off.rotation_search and off.common_disc_passes == off.extra_disc_passes == 0
    assert off.wide_search_px == 0 and not off.search_without_estimates
    assert not off.fail_unconverged and not off.resolve_disagreement
    assert not off.climb_from_optimum and Refinements().climb_from_optimum
    assert off.clip_sigmas == 0 and Refinements().clip_sigmas > 0
    assert Refinements().resolve_disagreement
    assert not off.needs_coarse_template and Refinements().needs_coarse_template


@pytest.mark.parametrize("params", [{"search_step_deg": 0.0}, {"search_max_steps": -1},
                                    {"common_disc_passes": -1}, {"extra_disc_passes": -1},
                                    {"wide_search_px": -1}, {"wide_min_overlap": 0.0},
                                    {"max_rotation_deg": 0.0}, {"max_rotation_deg": -math.inf},
                                    {"max_rotation_deg": math.nan}, {"resolve_margin": -0.1},
                                    {"edge_tie_margin": -0.1}, {"clip_sigmas": -1.0},
                                    {"clip_min_spread": 0.0}, {"rotation_search": "no"},
                                    {"common_disc_passes": 2.5}, {"search_max_steps": math.inf},
                                    {"max_shift_disagreement_px": math.nan},
                                    {"extra_pass_trigger_deg": "5"}, {"wide_search_px": True},
                                    {"clip_sigmas": math.inf}, {"edge_tie_margin": -math.inf},
                                    {"doubtful_offset_deg": math.nan},
                                    {"climb_from_optimum": 1}, {"final_overlap_shift": 0},
                                    # Unbounded: the paper's pipeline's passes cycled for ever.
                                    {"common_disc_passes": 10**6}, {"extra_disc_passes": 10**6},
                                    {"search_max_steps": 10**9}])
def test_bad_refinement_parameters_are_value_errors(params):
    with pytest.raises(ValueError, match=next(iter(params))):
        Refinements(**params)


def test_the_large_template_refines_the_rotation_and_the_shift():
    """From an estimate 1 deg off, the climb on the large template ends at the true rotation,
    and the shift is measured again there."""
    reference = _scene()
    smoothed = _smoothed(reference)
    search = RotationSearch(RotatedTemplate(smoothed, 44), half_resolution_template(smoothed, 44),
                            Refinements())
    truth = Motion(5.0, 6.0, -4.0)
    image = _smoothed(apply_motion(reference, truth))
    start = search.template.match(image, 6.0, (truth.dx, truth.dy))
    angle, match = search.refine_on_large_template(cv2.pyrDown(image), image, 6.0, start)
    np.testing.assert_allclose((angle, match.x, match.y), truth.as_tuple(), atol=0.4)
    # A shift that leaves no template larger than the search's own: no refinement (the search
    # then climbs the search's own template).
    far = search.template.match(image, 6.0, (40.0, 0.0))
    far = type(far)(40.0, far.y, far.peak, far.at_border, far.height)
    assert search.refine_on_large_template(cv2.pyrDown(image), image, 6.0, far) is None
    assert Refinements.off().large_template_border_px == 0


@pytest.mark.parametrize("half", [False, True])
def test_overlap_near_follows_the_peak_to_the_shift(half):
    """Searched from a shift 9 px off (beyond its +-3 px window, at either resolution), the
    masked FNCC of the whole overlap near a motion follows its peak to the true shift."""
    truth = Motion(8.0, 10.0, -5.0)
    search, image, current = _wide_search_setup(truth)
    valid = current > 0
    near = search.wide.near(half)
    current = (near.spectra(cv2.pyrDown(image), half_resolution_valid(valid)) if half
               else near.spectra(image, valid))
    found = near.match(current, truth.angle_deg, (truth.dx - 6.0, truth.dy + 7.0))
    np.testing.assert_allclose((found.x, found.y), (truth.dx, truth.dy), atol=0.6)
    assert found.height > 0.98 and not found.at_border
    # A wrong rotation correlates less at its best shift.
    assert near.match(current, 0.0, (truth.dx, truth.dy)).height < found.height - 0.01


@pytest.mark.parametrize("truth", [Motion(-8.0, 58.0, 20.0), Motion(-4.3, -47.0, 8.0)])
def test_beyond_the_central_templates_reach_the_climb_ends_at_full_resolution(truth):
    """A shift the central template cannot reach is climbed over rotation on the whole overlap,
    at half resolution and then at full resolution: the estimate is as fine as a full-resolution
    match (at half resolution alone y was 0.25 px off for the second motion)."""
    search, image, current = _wide_search_setup(truth)
    angle, match, converged = search(np.array([0.0]), 0.0, image, valid=current > 0)
    assert converged and max(abs(match.x), abs(match.y)) > search.template.margin - 4
    np.testing.assert_allclose((angle, match.x, match.y), truth.as_tuple(), atol=0.2)
    assert abs(angle - truth.angle_deg) < 0.05


def test_a_disagreement_is_resolved_on_the_whole_overlap():
    """The wide search scored rotation 0 only (its shift is that of a wrong rotation), and the
    central estimate is 9 px off in y: climbed on the whole overlap, the motion is the truth."""
    truth = Motion(8.0, 10.0, -5.0)
    search, image, current = _wide_search_setup(truth)
    valid = current > 0
    search(np.array([0.0]), 0.0, image, valid=valid)
    assert search.wide_angle == 0.0
    wrong = TemplateMatch(truth.dx, truth.dy - 9.0, 0.9, False, 0.9)
    angle, match = search.resolve_disagreement(truth.angle_deg + 0.5, wrong, image, current)
    np.testing.assert_allclose((angle, match.x, match.y), truth.as_tuple(), atol=0.3)


@pytest.mark.parametrize("limit_px, meet", [(5.0, False), (40.0, False), (60.0, True)])
def test_two_peaks_that_correlate_alike_stay_a_disagreement(limit_px, meet):
    """Stripes 24 px apart: shifts one period apart correlate alike on the whole overlap, so
    the two climbs end apart with no clear lead, and the disagreement is not resolved, unless
    the climbs end within half of ``max_shift_disagreement_px`` of each other (here 30 px):
    then they found one peak, and the higher of the two is taken."""
    reference = np.full((144, 176), 40, np.uint8)
    for left in range(0, 176, 24):
        reference[:, left:left + 12] = 160
    reference[100:] += 30  # a horizon fixes y
    smoothed = _smoothed(reference)
    search = RotationSearch(RotatedTemplate(smoothed, 44), half_resolution_template(smoothed, 44),
                            Refinements(max_shift_disagreement_px=limit_px),
                            WideSearch(smoothed, reference > 0, 72, 0.3))
    current = apply_motion(reference, Motion(0.0, 5.0, 3.0))
    image, valid = _smoothed(current), current > 0
    search(np.array([0.0]), 0.0, image, valid=valid)
    search.wide_angle, search.wide_shift = 0.0, (5.0 + 24.0, 3.0)
    estimate = TemplateMatch(5.0, 3.0, 0.9, False, 0.9)
    resolved = search.resolve_disagreement(0.0, estimate, image, current)
    if meet:
        assert resolved is not None and abs(resolved[1].x - 5.0) < 0.5
    else:
        assert resolved is None
        # With no margin asked for, the higher of the two is taken.
        search.resolve_margin = 0.0
        assert search.resolve_disagreement(0.0, estimate, image, current) is not None


def test_depth_edges_settle_two_climbs_whose_correlations_tie():
    """Of two motions (the truth and one 6 degrees and 4 px off), the one whose depth edges
    line up is kept, in either order; motions that line them up alike stay undecided, as does
    every tie without the reference frame or with an infinite margin."""
    reference = stabilizer.depth_to_disparity(make_depth_scene(3))
    truth = Motion(5.0, 8.0, -4.0)
    current = apply_motion(reference, truth)
    smoothed = _smoothed(reference)

    def search(refinements=Refinements(), frame=reference):
        return RotationSearch(RotatedTemplate(smoothed, 44),
                              half_resolution_template(smoothed, 44), refinements, None, frame)

    right = (truth.angle_deg, TemplateMatch(truth.dx, truth.dy, 0.9, False, 0.9), True)
    wrong = (truth.angle_deg + 6.0, TemplateMatch(truth.dx + 4.0, truth.dy, 0.9, False, 0.9),
             True)
    assert search()._edge_tie_break([right, wrong], current) is right
    assert search()._edge_tie_break([wrong, right], current) is right
    assert search()._edge_tie_break([right, right], current) is None
    assert search(frame=None)._edge_tie_break([right, wrong], current) is None
    assert search(Refinements(edge_tie_margin=np.inf))._edge_tie_break([right, wrong],
                                                                        current) is None


def test_depth_edges_of_the_tie_break_end_at_the_frames_borders_as_the_checks_do():
    """The tie-break makes its edges as the trust check does, with the frame ending at its
    borders. A room of the varied corpus (floor and ceiling slopes, dropouts) moved by -3
    degrees and (20, 6) px: smoothing reflected at the borders (creases where the slopes run
    into them) lines the frames up better unmoved than at the truth, by more than the margin;
    with the borders the truth leads."""
    reference, frames, motions = corpus_frames("invalid_pixels", 1, 3)
    current, truth = frames[2], motions[2]
    smoothed = _smoothed(reference)
    right = (truth.angle_deg, TemplateMatch(truth.dx, truth.dy, 0.9, False, 0.9), True)
    unmoved = (0.0, TemplateMatch(0.0, 0.0, 0.9, False, 0.9), True)
    search = RotationSearch(RotatedTemplate(smoothed, 44), half_resolution_template(smoothed, 44),
                            Refinements(), None, reference)
    assert search._edge_tie_break([unmoved, right], current) is right
    search.edge_params = VerificationParams(image_border=False)
    search._reference_edges = None
    assert search._edge_tie_break([unmoved, right], current) is unmoved

def test_the_estimator_resolves_a_disagreement_only_when_asked_to():
    """Every estimate disagrees with the wide search at a 1e-6 px limit: without the
    resolution it is a failure; with it (and no margin asked for) the estimate is the whole
    overlap's peak, and the central template's motion stays in the diagnostics."""
    reference = stabilizer.depth_to_disparity(make_depth_scene(7))
    truth = Motion(4.0, 9.0, -6.0)
    current = apply_motion(reference, truth)
    strict = dict(max_shift_disagreement_px=1e-6, resolve_margin=0.0)
    failed = stabilizer.estimate(reference, current, verification=None,
                                 refinements=Refinements(resolve_disagreement=False, **strict))
    assert failed.status == TRANSLATION_DISAGREEMENT
    resolved = stabilizer.estimate(reference, current, verification=None,
                                   refinements=Refinements(**strict))
    assert resolved.ok
    np.testing.assert_allclose(resolved.as_tuple(), truth.as_tuple(), atol=0.5)
    np.testing.assert_allclose(resolved.diagnostics["disagreeing_motion"],
                               failed.diagnostics["disagreeing_motion"])


def test_the_final_overlap_climb_takes_a_motion_to_the_whole_overlaps_peak():
    """A motion 3 degrees and a few pixels off the truth, climbed on the whole overlap, ends at
    the truth."""
    truth = Motion(8.0, 10.0, -5.0)
    search, image, current = _wide_search_setup(truth)
    valid = current > 0
    off = (truth.dx + 3.0, truth.dy - 2.0)
    angle, match = search.climb_on_overlap(truth.angle_deg - 3.0, off, image, valid)
    np.testing.assert_allclose((angle, match.x, match.y), truth.as_tuple(), atol=0.3)


def _moved_scene() -> tuple[np.ndarray, np.ndarray, Motion]:
    """A reference, the current frame and their motion, for the estimator's final steps."""
    reference = stabilizer.depth_to_disparity(make_depth_scene(7))
    truth = Motion(4.0, 9.0, -6.0)
    return reference, apply_motion(reference, truth), truth


def _results_of(monkeypatch, name: str) -> list:
    """What every later call of ``RotationSearch.<name>`` returns, in order."""
    results = []
    original = getattr(RotationSearch, name)

    def kept(self, *args):
        results.append(original(self, *args))
        return results[-1]

    monkeypatch.setattr(RotationSearch, name, kept)
    return results


def test_the_estimator_climbs_on_the_overlap_only_when_asked_to(monkeypatch):
    """Off by default; on, the converged search ends with the climb, and the estimate is the
    truth."""
    reference, current, truth = _moved_scene()
    calls = _results_of(monkeypatch, "climb_on_overlap")
    default = stabilizer.estimate(reference, current, verification=None)
    assert calls == [] and default.ok
    climbed = stabilizer.estimate(reference, current, verification=None,
                                  refinements=Refinements(final_overlap_climb=True))
    assert len(calls) == 1 and climbed.ok
    np.testing.assert_allclose(climbed.as_tuple(), truth.as_tuple(), atol=0.5)


def test_the_final_overlap_shift_takes_a_shift_to_the_whole_overlaps_peak():
    """At the true rotation, a shift 2-3 pixels off the truth, measured again on the whole
    overlap, ends at the truth."""
    truth = Motion(8.0, 10.0, -5.0)
    search, image, current = _wide_search_setup(truth)
    found = search.shift_on_overlap(truth.angle_deg, (truth.dx + 3.0, truth.dy - 2.0), image,
                                    current > 0)
    np.testing.assert_allclose((found.x, found.y), (truth.dx, truth.dy), atol=0.3)


def test_the_estimator_measures_the_shift_on_the_overlap_only_when_asked_to(monkeypatch):
    """Off by default; on, the converged search's shift is the whole overlap's, and the
    estimate is the truth; with the final climb, which ends on the whole overlap, it is not
    measured again."""
    reference, current, truth = _moved_scene()
    shifts = _results_of(monkeypatch, "shift_on_overlap")
    assert stabilizer.estimate(reference, current, verification=None).ok and shifts == []
    shifted = stabilizer.estimate(reference, current, verification=None,
                                  refinements=Refinements(final_overlap_shift=True))
    assert len(shifts) == 1 and shifted.ok
    assert (shifted.dx, shifted.dy) == (shifts[0].x, shifts[0].y)
    np.testing.assert_allclose(shifted.as_tuple(), truth.as_tuple(), atol=0.5)
    both = Refinements(final_overlap_shift=True, final_overlap_climb=True)
    climbed = stabilizer.estimate(reference, current, verification=None,
                                  refinements=Refinements(final_overlap_climb=True))
    assert stabilizer.estimate(reference, current, verification=None,
                               refinements=both).as_tuple() == climbed.as_tuple()
    assert len(shifts) == 1


def _speckled(image: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """``image`` with its left 30% above the floor bright random speckle, as an SR4000 shows a
    surface beyond its range (phase-wrapped), drawn anew for each frame."""
    out = image.copy()
    height, width = image.shape
    region = out[: height * 3 // 4, : width * 3 // 10]
    region[...] = rng.integers(180, 256, region.shape)
    return out


def test_clipping_keeps_speckle_from_outweighing_the_scene():
    """Known motions of twelve scenes whose frames each carry a region of bright speckle: the
    correlation of stage 6 on frames clipped to the reference's robust range finds the motion
    better than on the frames as they are, where the speckle's spread dominates the NCC."""
    errors = {True: [], False: []}
    for seed in range(12):
        rng = np.random.default_rng(seed)
        reference = stabilizer.depth_to_disparity(make_depth_scene(seed, floor=True))
        truth = Motion(float(rng.uniform(-6, 6)), float(rng.uniform(-10, 10)),
                       float(rng.uniform(-8, 8)))
        reference, current = (_speckled(frame, rng)
                              for frame in (reference, apply_motion(reference, truth)))
        for clip in (True, False):
            refinements = Refinements() if clip else Refinements(clip_sigmas=0.0)
            motion = stabilizer.estimate(reference, current, verification=None,
                                         refinements=refinements)
            assert motion.ok
            errors[clip].append((abs(motion.angle_deg - truth.angle_deg),
                                 np.hypot(motion.dx - truth.dx, motion.dy - truth.dy)))
    clipped, raw = (np.mean(errors[clip], axis=0) for clip in (True, False))
    assert clipped[1] < 0.5 * raw[1] and clipped[0] < raw[0]


def _doubted(motion: Motion, offset_deg: float) -> Motion:
    """``motion`` as the trust check passes it with its optimum ``offset_deg`` away."""
    return Motion(*motion.as_tuple(), diagnostics={"verify_offset_deg": offset_deg,
                                                   "ncc_peak": 0.9})


def test_a_second_look_climbs_a_doubted_estimate_to_the_whole_overlaps_peak():
    """An estimate 3 degrees and a few pixels off the truth that passed the check, whose
    optimum lies 3 degrees away, is climbed on the whole overlap to the truth; the first
    estimate is recorded."""
    reference = _scene()
    truth = Motion(8.0, 10.0, -5.0)
    current = apply_motion(reference, truth)
    first = Motion(truth.angle_deg - 3.0, truth.dx + 3.0, truth.dy - 2.0)
    again = T2FuzzyEstimator(reference).second_look(current, _doubted(first, 3.0))
    assert again.ok
    np.testing.assert_allclose(again.as_tuple(), truth.as_tuple(), atol=0.3)
    assert again.diagnostics["second_look_from"] == first.as_tuple()
    assert not any(key.startswith("verify_") for key in again.diagnostics)


def _not_optimum(motion: Motion, optimum: Motion) -> Motion:
    """``motion`` as the trust check rejects it, its optimum ``optimum`` beyond the limits."""
    return Motion.failed("unverified", verify_failed="not_optimum",
                         verify_optimum=optimum.as_tuple(), unverified_motion=motion.as_tuple(),
                         ncc_peak=0.9)


def test_no_second_look_unless_the_check_passed_and_doubts_the_estimate():
    """Within ``doubtful_offset_deg`` of the check's optimum, after a check failed by another
    test than the optimum's, with the settings off, or in the paper's pipeline, there is no
    second look."""
    reference = _scene()
    truth = Motion(8.0, 10.0, -5.0)
    current = apply_motion(reference, truth)
    first = Motion(truth.angle_deg - 3.0, truth.dx, truth.dy)
    estimator = T2FuzzyEstimator(reference)
    assert estimator.second_look(current, _doubted(first, 0.9)) is None
    failed = Motion.failed("unverified", verify_failed="correlation", verify_offset_deg=3.0,
                           unverified_motion=first.as_tuple())
    assert estimator.second_look(current, failed) is None
    for refinements in (Refinements(doubtful_offset_deg=math.inf), Refinements.off()):
        assert T2FuzzyEstimator(reference, refinements=refinements).second_look(
            current, _doubted(first, 3.0)) is None
    for refinements in (Refinements(climb_from_optimum=False), Refinements.off()):
        assert T2FuzzyEstimator(reference, refinements=refinements).second_look(
            current, _not_optimum(first, truth)) is None


def test_a_second_look_climbs_from_the_checks_optimum_after_a_not_optimum_rejection():
    """An estimate 6 degrees and 8 px off that the check rejected as not at its optimum, which
    lies 2 degrees and a few pixels from the truth: the climb on the whole overlap starts from
    that optimum and ends at the truth; the new estimate keeps none of the check's diagnostics
    and records where it started."""
    reference = _scene()
    truth = Motion(8.0, 10.0, -5.0)
    current = apply_motion(reference, truth)
    first = Motion(truth.angle_deg - 6.0, truth.dx + 8.0, truth.dy)
    optimum = Motion(truth.angle_deg - 2.0, truth.dx + 2.0, truth.dy - 1.0)
    again = T2FuzzyEstimator(reference).second_look(current, _not_optimum(first, optimum))
    assert again.ok
    np.testing.assert_allclose(again.as_tuple(), truth.as_tuple(), atol=0.3)
    assert again.diagnostics["second_look_from"] == optimum.as_tuple()
    assert not any(key.startswith("verify_") or key == "unverified_motion"
                   for key in again.diagnostics)


def test_a_climb_that_went_astray_is_climbed_again_on_the_whole_overlap():
    """Frames 253 (the reference) and 276 of the corridor walk that
    `python benchmarks/t2fuzzy_failures.py record` makes with the default gait and tuning scene
    seed 2003: the half-resolution climb wanders from the wide search's best candidate to a
    rotation near -7 degrees, where the central template finds no peak near its shift and the
    whole overlap correlates lower. The wide search's best motion, climbed on the whole
    overlap, is the truth; without the recovery the estimate is the astray climb's end."""
    reference, current = walking_frames("corridor_2003", 253, 276)
    truth = Motion(4.682722655798959, 11.588255050880445, -5.881942480627788)
    recovered = stabilizer.estimate(reference, current, verification=None)
    assert recovered.ok
    np.testing.assert_allclose(recovered.as_tuple(), truth.as_tuple(), atol=1.0)
    assert recovered.diagnostics["astray_climb"][0] < -5.0
    astray = stabilizer.estimate(reference, current, verification=None,
                                 refinements=Refinements(astray_climb_recovery=False))
    assert astray.angle_deg < -5.0 and "astray_climb" not in astray.diagnostics
