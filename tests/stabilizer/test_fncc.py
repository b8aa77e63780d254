"""Stage 6: FNCC (cv2.matchTemplate TM_CCOEFF_NORMED) with parabolic sub-pixel peak."""

import math

import cv2
import numpy as np
import pytest

from stabilizer.fncc import (
    DIRECT_SEARCH_SHIFTS,
    MaskedCorrelation,
    RotatedTemplate,
    masked_ncc_direct,
    match_template,
    parabolic_vertex,
    surface_peak,
)
from stabilizer.motion import Motion, apply_motion


def _textured(shape=(144, 176), seed=0):
    noise = np.random.default_rng(seed).uniform(0, 255, shape).astype(np.float32)
    return cv2.GaussianBlur(noise, (0, 0), 3.0)


def test_parabolic_vertex_of_a_sampled_parabola():
    vertex, top = 0.3, 2.0
    c = [top - (k - vertex) ** 2 for k in (-1, 0, 1)]
    assert parabolic_vertex(*c) == (pytest.approx(vertex), pytest.approx(top))
    assert parabolic_vertex(1.0, 1.0, 1.0) == (0.0, 1.0)  # flat: no refinement
    assert parabolic_vertex(0.0, 1.0, 1.5)[0] == 0.5  # vertex beyond a neighbour: clipped


def test_integer_shift_is_exact():
    image = _textured()
    template = image[40:90, 50:120]
    match = match_template(image, template)
    assert (match.x, match.y) == (pytest.approx(50, abs=0.01), pytest.approx(40, abs=0.01))
    assert match.peak == pytest.approx(1.0, abs=1e-4)


@pytest.mark.parametrize("dx, dy", [(0.25, -0.4), (-0.3, 0.1), (0.5, 0.5), (0.1, -0.2)])
def test_known_sub_pixel_shift(dx, dy):
    image = _textured(seed=1)
    shifted = cv2.warpAffine(image, np.float32([[1, 0, dx], [0, 1, dy]]), image.shape[::-1],
                             flags=cv2.INTER_LINEAR)
    template = image[40:100, 40:130]
    match = match_template(shifted, template)
    assert match.x - 40 == pytest.approx(dx, abs=0.1)
    assert match.y - 40 == pytest.approx(dy, abs=0.1)
    assert not match.at_border
    # The parabolas' top lies above the best sample, near the 1 of the continuous match.
    assert match.peak < match.height < 1.001


def test_a_match_at_the_edge_of_the_shifts_is_flagged_and_not_refined_there():
    # The template is the image's top-left corner: the peak is at shift (0, 0), the first
    # row and column of the scores, which have no neighbour on one side.
    image = _textured(seed=1)
    match = match_template(image, image[:60, :90])
    assert match.at_border and (match.x, match.y) == (0.0, 0.0)
    corner = match_template(image, image[-60:, -90:])
    assert corner.at_border and (corner.x, corner.y) == (image.shape[1] - 90, image.shape[0] - 60)


def test_scores_match_scikit_image():
    feature = pytest.importorskip("skimage.feature")
    image = _textured(seed=2)
    template = image[30:70, 60:110].copy()
    ours = cv2.matchTemplate(image, template, cv2.TM_CCOEFF_NORMED)
    theirs = feature.match_template(image, template)
    np.testing.assert_allclose(ours, theirs, atol=1e-3)
    match = match_template(image, template)
    row, col = np.unravel_index(np.argmax(theirs), theirs.shape)
    assert (round(match.x), round(match.y)) == (col, row)


def test_masked_template_ignores_invalid_pixels():
    image = _textured(seed=3)
    template = image[50:90, 60:120].copy()
    mask = np.ones_like(template)
    template[:10] = 0.0  # "invalid" rows
    mask[:10] = 0.0
    match = match_template(image, template, mask)
    assert (match.x, match.y) == (pytest.approx(60, abs=0.05), pytest.approx(50, abs=0.05))


@pytest.mark.parametrize("dtype", [np.float32, np.uint8])
@pytest.mark.parametrize("template_shape, search", [((28, 44), 5), ((104, 136), 5), ((40, 60), 9),
                                                    ((30, 30), 1), ((50, 70), 17)])
def test_direct_masked_scores_are_opencvs(template_shape, search, dtype):
    rng = np.random.default_rng(sum(template_shape) + search)
    # Disparity-like: far from zero mean, with invalid (0) pixels in the image as well.
    image = (_textured((template_shape[0] + search - 1, template_shape[1] + search - 1)) * 0.3
             + 150.0)
    image[rng.random(image.shape) < 0.1] = 0.0
    image = image.astype(dtype)
    template = image[search // 2:search // 2 + template_shape[0],
                     search // 3:search // 3 + template_shape[1]].copy()
    mask = (rng.random(template_shape) > 0.2).astype(np.float32)
    ours = masked_ncc_direct(image, template, mask)
    theirs = cv2.matchTemplate(image, template, cv2.TM_CCOEFF_NORMED, mask=mask.astype(dtype))
    np.testing.assert_allclose(ours, theirs, atol=2e-5)
    assert np.argmax(ours) == np.argmax(theirs)


def test_direct_masked_scores_are_nan_on_flat_windows():
    """OpenCV's 0 / 0: a window that is flat at any level is not scored, not scored at random."""
    template = _textured((4, 4))
    mask = np.ones(template.shape, np.uint8)
    mask[0, 0] = 0
    image = np.full((12, 12), 37.0, np.float32)
    image[:, 6:] = 0.0
    scores = masked_ncc_direct(image, template, mask)  # 9 x 9 shifts
    # Windows in the left or the right part are flat (at 37 and at 0); the central window
    # (columns 4-7), about whose mean the sums are taken, is not.
    assert np.isnan(scores[:, :3]).all() and np.isnan(scores[:, 6:]).all()
    assert np.isfinite(scores[:, 3:6]).all()
    assert np.isnan(match_template(np.full((40, 60), 37.0, np.float32), _textured((36, 56)),
                                   np.ones((36, 56), np.uint8)).peak)


@pytest.mark.parametrize("image_shape, template_shape, mask_shape, words", [
    ((10, 10), (12, 4), (12, 4), "no larger than image"),
    ((10, 10), (4, 4), (4, 5), "mask of the template's shape"),
    ((10, 10, 3), (4, 4), (4, 4), "must be 2-D"),
])
def test_direct_masked_scores_refuse_bad_shapes(image_shape, template_shape, mask_shape, words):
    with pytest.raises(ValueError, match=words):
        masked_ncc_direct(np.ones(image_shape, np.float32), np.ones(template_shape, np.float32),
                          np.ones(mask_shape, np.uint8))
    with pytest.raises(ValueError, match="at least one template pixel"):
        masked_ncc_direct(np.ones((10, 10), np.float32), np.ones((4, 4), np.float32),
                          np.zeros((4, 4), np.uint8))


def test_small_masked_searches_and_large_ones_find_the_same_match():
    image = _textured(seed=5)
    shifted = cv2.warpAffine(image, np.float32([[1, 0, 0.3], [0, 1, -0.2]]), image.shape[::-1],
                             flags=cv2.INTER_LINEAR)
    template = image[40:100, 40:130].copy()
    mask = np.ones_like(template)
    mask[20:30, 10:50] = 0.0
    window = shifted[38:38 + 60 + 4, 38:38 + 90 + 4]  # 25 shifts: scored directly
    assert 25 <= DIRECT_SEARCH_SHIFTS
    small = match_template(window, template, mask)
    large = match_template(shifted, template, mask)  # every shift: OpenCV's DFTs
    assert small.x + 38 == pytest.approx(large.x, abs=1e-3)
    assert small.y + 38 == pytest.approx(large.y, abs=1e-3)
    assert small.peak == pytest.approx(large.peak, abs=1e-5)


def test_flat_template_gives_no_peak():
    image = _textured(seed=4)
    match = match_template(image, np.full((20, 20), 7.0, np.float32))
    assert np.isnan(match.peak) and np.isnan(match.x)


@pytest.mark.parametrize("motion", [Motion(0.0, 12.3, -7.6), Motion(9.0, -30.2, 15.5),
                                    Motion(-14.0, 40.0, -40.0)])
def test_rotated_template_finds_the_shift_in_the_motion_convention(motion):
    reference = _textured(seed=5)
    current = apply_motion(reference, motion, cv2.INTER_LINEAR)
    template = RotatedTemplate(reference, margin=44)
    whole = template.match(current, motion.angle_deg)
    assert (whole.x, whole.y) == (pytest.approx(motion.dx, abs=0.1),
                                  pytest.approx(motion.dy, abs=0.1))
    local = template.match(current, motion.angle_deg, near=(round(motion.dx), round(motion.dy)))
    # Same peak; the scores differ only by the FFT's rounding on the smaller image.
    assert (local.x, local.y) == (pytest.approx(whole.x, abs=1e-2),
                                  pytest.approx(whole.y, abs=1e-2))
    wrong_angle = template.match(current, motion.angle_deg + 3.0)
    assert wrong_angle.height < whole.height


def test_rotated_templates_mask_the_invalid_pixels_they_carry():
    reference = _textured(seed=5) + 1.0
    reference[70:74, 100:104] = 0.0  # a hole of 16 pixels in the template, off its centre
    template = RotatedTemplate(reference, margin=44)
    _, upright = template.template(0.0)
    np.testing.assert_array_equal(upright > 0, reference[44:-44, 44:-44] > 0)
    _, turned = template.template(12.0)
    assert turned is not None and 12 <= np.count_nonzero(turned == 0) <= 24


def test_a_hole_near_the_templates_corner_is_masked():
    # The template (88 x 56 px about the centre 87.5, 71.5) reaches 52 px from the centre at
    # its corners: a hole 46 px out, near a corner, is in it and must be masked, upright and
    # turned.
    reference = _textured(seed=5) + 1.0
    reference[92:95, 126:129] = 0.0
    template = RotatedTemplate(reference, margin=44)
    _, upright = template.template(0.0)
    assert upright is not None
    np.testing.assert_array_equal(upright > 0, reference[44:-44, 44:-44] > 0)
    _, turned = template.template(-5.0)
    assert turned is not None and np.count_nonzero(turned == 0) >= 4


def test_a_search_near_a_shift_beyond_the_range_stays_inside_the_image():
    # A previous shift far outside the +-44 px range: the window near it (+-2 px) is clamped
    # to the image's edge, and the search gives a match within it, at the range's end.
    reference = _textured(seed=5)
    current = apply_motion(reference, Motion(0.0, 12.0, -7.0), cv2.INTER_LINEAR)
    template = RotatedTemplate(reference, margin=44)
    for near in ((1000.0, 0.0), (-1000.0, 0.0), (0.0, 1000.0), (0.0, -1000.0)):
        found = template.match(current, 0.0, near)
        assert found.at_border and math.isfinite(found.peak)
        assert 40.0 <= max(abs(found.x), abs(found.y)) <= 44.0


def test_a_non_finite_previous_shift_searches_the_whole_range():
    # A match that found no peak has a NaN shift; a search "near" it is a search everywhere.
    reference = _textured(seed=5)
    motion = Motion(4.0, 12.3, -7.6)
    current = apply_motion(reference, motion, cv2.INTER_LINEAR)
    template = RotatedTemplate(reference, margin=44)
    whole = template.match(current, motion.angle_deg)
    for near in ((math.nan, math.nan), (math.nan, 3.0), (math.inf, 0.0)):
        assert template.match(current, motion.angle_deg, near) == whole


def test_half_resolution_template_with_the_full_frame_centre():
    reference = _textured(seed=6)
    motion = Motion(6.0, 20.0, -12.0)
    current = apply_motion(reference, motion, cv2.INTER_LINEAR)
    centre_x, centre_y = (reference.shape[1] - 1) / 2, (reference.shape[0] - 1) / 2
    coarse = RotatedTemplate(cv2.pyrDown(reference), 22, (centre_x / 2, centre_y / 2))
    match = coarse.match(cv2.pyrDown(current), motion.angle_deg)
    assert (2 * match.x, 2 * match.y) == (pytest.approx(motion.dx, abs=0.5),
                                          pytest.approx(motion.dy, abs=0.5))


def _masked_ncc_direct(fixed, fixed_valid, moving, moving_valid, dx, dy):
    """Eq. (7) on the pixels both frames measure, fixed(x) against moving(x + d), by loops."""
    height, width = fixed.shape
    a, b = [], []
    for y in range(height):
        for x in range(width):
            u, v = x + dx, y + dy
            if 0 <= u < width and 0 <= v < height and fixed_valid[y, x] and moving_valid[v, u]:
                a.append(fixed[y, x])
                b.append(moving[v, u])
    a, b = np.array(a) - np.mean(a), np.array(b) - np.mean(b)
    return float(a @ b / np.sqrt((a @ a) * (b @ b))), len(a)


def test_masked_correlation_is_eq_7_on_the_pixels_both_frames_measure():
    rng = np.random.default_rng(6)
    fixed, moving = _textured((20, 24), seed=6), _textured((20, 24), seed=7)
    fixed_valid, moving_valid = rng.random((20, 24)) > 0.2, rng.random((20, 24)) > 0.2
    correlation = MaskedCorrelation((20, 24), 6, 0.3)
    scores = correlation.surface(correlation.spectra(fixed, fixed_valid, False),
                                 correlation.spectra(moving, moving_valid, True))
    for dy in range(-6, 7, 3):
        for dx in range(-6, 7, 2):
            expected, overlap = _masked_ncc_direct(fixed, fixed_valid, moving, moving_valid,
                                                   dx, dy)
            assert overlap >= 0.3 * fixed_valid.sum()
            assert scores[dy + 6, dx + 6] == pytest.approx(expected, abs=1e-4)  # float32 DFTs


def test_masked_correlation_finds_shifts_the_central_template_cannot():
    image = _textured(seed=8)
    motion = Motion(0.0, 57.3, -31.6)  # beyond a 44-px margin along x
    current = apply_motion(image, motion, cv2.INTER_LINEAR)
    # The edge of the moved area blends the image with the 0 outside it: not a measurement.
    current_valid = cv2.erode(apply_motion(np.ones(image.shape, np.uint8), motion),
                              np.ones((3, 3), np.uint8), borderValue=1) > 0
    correlation = MaskedCorrelation(image.shape, 72, 0.3)
    match = correlation.match(correlation.spectra(image, np.ones(image.shape, bool), False),
                              correlation.spectra(current, current_valid, True))
    assert (match.x, match.y) == (pytest.approx(57.3, abs=0.15), pytest.approx(-31.6, abs=0.15))
    assert match.peak > 0.99 and not match.at_border


def test_small_overlaps_and_flat_frames_are_not_scored():
    image = _textured(seed=9)
    correlation = MaskedCorrelation(image.shape, 100, 0.5)
    valid = np.ones(image.shape, bool)
    scores = correlation.surface(correlation.spectra(image, valid, False),
                                 correlation.spectra(image, valid, True))
    # A shift of 100 px along x leaves 76 / 176 of the columns: less than half.
    assert np.isneginf(scores[100, 200]) and np.isfinite(scores[100, 100])
    flat = np.full(image.shape, 9.0, np.float32)
    flat_scores = correlation.surface(correlation.spectra(flat, valid, False),
                                      correlation.spectra(image, valid, True))
    assert np.all(np.isneginf(flat_scores))
    assert np.isnan(correlation.match(correlation.spectra(flat, valid, False),
                                      correlation.spectra(image, valid, True)).peak)


def test_surface_peak_refines_inside_and_flags_the_edge():
    rows, columns = np.mgrid[-3:4, -3:4]
    inside = -((columns - 1.3) ** 2) - (rows + 0.4) ** 2
    match = surface_peak(inside, 3)
    assert (match.x, match.y) == (pytest.approx(1.3), pytest.approx(-0.4))
    assert not match.at_border
    # The height is the surface's top, 0, above the best sample (-0.25): each axis's parabola
    # adds what it rises above the sample.
    assert match.peak == pytest.approx(-0.25) and match.height == pytest.approx(0.0)
    edge = -((columns - 5.0) ** 2) - rows ** 2
    assert surface_peak(edge, 3).at_border and surface_peak(edge, 3).x == 3.0
    # A neighbour that cannot be scored (-inf) is an edge too: the peak is not refined there.
    unscored = inside.copy()
    unscored[3, 3] = -np.inf  # left of the peak, at shift (1, 0)
    match = surface_peak(unscored, 3)
    assert match.at_border and match.x == 1.0 and match.y == pytest.approx(-0.4)


@pytest.mark.parametrize("args", [((144, 176), 0, 0.3), ((144, 176), 144, 0.3),
                                  ((144, 176), 40, 0.0), ((144, 176), 40, 1.5)])
def test_bad_masked_correlation_parameters_are_value_errors(args):
    with pytest.raises(ValueError):
        MaskedCorrelation(*args)


def test_a_template_with_another_margin_matches_alike():
    reference = _textured(seed=10)
    motion = Motion(6.0, -9.4, 5.2)
    current = apply_motion(reference, motion, cv2.INTER_LINEAR)
    small = RotatedTemplate(reference, margin=44)
    large = small.with_margin(12)
    assert large.size == (176 - 24, 144 - 24)
    found = large.match(current, motion.angle_deg, (motion.dx, motion.dy))
    assert (found.x, found.y) == (pytest.approx(motion.dx, abs=0.1),
                                  pytest.approx(motion.dy, abs=0.1))


def test_weighted_scores_favour_the_shift_that_lines_up_all_of_the_frames():
    """Stripes 58 px apart against themselves: one period's shift lines up its overlap as well
    as the zero shift (NCC 1), but keeps only two thirds of the frames; weighted by the shares
    of both frames' spread its overlap holds, it scores that much less."""
    columns = np.arange(176, dtype=np.float32)
    image = np.tile(100.0 + 50.0 * np.sin(2.0 * np.pi * columns / 58.0), (144, 1))
    valid = np.ones(image.shape, bool)
    correlation = MaskedCorrelation(image.shape, 60, 0.3)
    fixed = correlation.spectra(image, valid, moving=False)
    moving = correlation.spectra(image, valid, moving=True)
    plain, weighted = (correlation.surface(fixed, moving, weighted=flag) for flag in (False, True))
    period = (60, 60 + 58)  # rows dy, columns dx; the zero shift at (60, 60)
    assert plain[60, 60] == pytest.approx(1.0, abs=1e-3) == weighted[60, 60]
    assert plain[period] == pytest.approx(1.0, abs=1e-2)
    assert weighted[period] == pytest.approx((176 - 58) / 176, abs=0.03)
