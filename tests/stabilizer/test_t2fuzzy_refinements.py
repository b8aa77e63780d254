"""The refinements of ``t2fuzzy`` over the paper's pipeline, one by one."""

import cv2
import numpy as np
import pytest

from stabilizer.fncc import RotatedTemplate
from stabilizer.motion import Motion, apply_motion
from stabilizer.t2fuzzy_refinements import (
    Refinements,
    RotationSearch,
    common_disc,
    half_resolution_template,
    translation_guess,
)


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


def test_translation_guess_finds_the_shift_at_half_resolution():
    reference = _scene()
    coarse = half_resolution_template(_smoothed(reference), 44)
    guess = translation_guess(coarse, _smoothed(apply_motion(reference, Motion(0, 12, -8))), 0.3)
    assert guess.angle_deg == 0.0
    np.testing.assert_allclose((guess.dx, guess.dy), (12, -8), atol=1.0)
    assert translation_guess(coarse, _smoothed(reference), 1.01) is None


@pytest.mark.parametrize("start", [0.0, 6.0, 12.0])
def test_rotation_search_climbs_to_the_correlation_peak(start):
    """Whatever the ellipse estimates, the search ends at the rotation that matches best."""
    reference = _scene()
    smoothed = _smoothed(reference)
    search = RotationSearch(RotatedTemplate(smoothed, 44), half_resolution_template(smoothed, 44),
                            Refinements())
    truth = Motion(7.0, 5.0, -3.0)
    angle, match = search(np.array([start]), start, _smoothed(apply_motion(reference, truth)))
    np.testing.assert_allclose((angle, match.x, match.y), truth.as_tuple(), atol=0.5)


def test_off_is_the_paper_pipeline():
    off = Refinements.off()
    assert not off.rotation_search and off.common_disc_passes == off.extra_disc_passes == 0
    assert not off.needs_coarse_template and Refinements().needs_coarse_template


@pytest.mark.parametrize("params", [{"search_step_deg": 0.0}, {"search_max_steps": -1},
                                    {"common_disc_passes": -1}, {"extra_disc_passes": -1}])
def test_bad_refinement_parameters_are_value_errors(params):
    with pytest.raises(ValueError, match=next(iter(params))):
        Refinements(**params)
