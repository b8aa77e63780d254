"""Stage 6: FNCC (cv2.matchTemplate TM_CCOEFF_NORMED) with parabolic sub-pixel peak."""

import cv2
import numpy as np
import pytest

from stabilizer.fncc import RotatedTemplate, match_template, parabolic_vertex
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


def test_half_resolution_template_with_the_full_frame_centre():
    reference = _textured(seed=6)
    motion = Motion(6.0, 20.0, -12.0)
    current = apply_motion(reference, motion, cv2.INTER_LINEAR)
    centre_x, centre_y = (reference.shape[1] - 1) / 2, (reference.shape[0] - 1) / 2
    coarse = RotatedTemplate(cv2.pyrDown(reference), 22, (centre_x / 2, centre_y / 2))
    match = coarse.match(cv2.pyrDown(current), motion.angle_deg)
    assert (2 * match.x, 2 * match.y) == (pytest.approx(motion.dx, abs=0.5),
                                          pytest.approx(motion.dy, abs=0.5))
