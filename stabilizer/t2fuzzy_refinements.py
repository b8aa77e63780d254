"""Refinements of the paper's pipeline in the ``t2fuzzy`` method, each a switchable parameter.

Kang, Zhang & Park (2009) take the rotation from the ellipse angles alone (stages 4-5) and then
the translation from the FNCC of the rotation-compensated reference (stage 6), both on the whole
frames. ``t2fuzzy`` adds two steps, described with their reasons in docs/method.md, section 8;
``t2fuzzy_paper`` (:meth:`Refinements.off`) runs without them:

- Rotation search (:class:`RotationSearch`): the FNCC of stage 6 also scores rotations. The
  candidates are the thresholded rotation of stage 5, the means of the largest groups of angle
  estimates, and 0; the best-correlating one at half resolution is climbed in steps of
  ``search_step_deg`` to the local maximum of the correlation peak, first at half and then at
  full resolution, and the vertex of a parabola through the last three steps is the rotation.
  The ellipse angles then choose where the search starts rather than give the rotation.
- Common-disc comparison (:func:`common_disc`): stages 3-6 are run on one disc of the scene that
  both frames see whole under a first estimate of the motion, so that an object cut by the image
  border in one frame only is compared with the same part of it in the other frame. The first
  estimate is a translation-only guess (:func:`translation_guess`), each further pass starts
  from the previous pass's estimate.

The half-resolution template that both use is :func:`half_resolution_template`.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from stabilizer.fncc import RotatedTemplate, TemplateMatch, parabolic_vertex
from stabilizer.motion import Motion, image_centre, motion_matrix


@dataclass(frozen=True)
class Refinements:
    """Which refinements run, and their settings. The defaults are the ``t2fuzzy`` method's.

    Attributes:
        rotation_search: refine the thresholded rotation of stage 5 by the FNCC peak
            (:class:`RotationSearch`); default True.
        search_step_deg: step of the climb over rotations, degrees; default 1.5. Candidates
            within one step of an earlier candidate are not scored, and groups of angle
            estimates are split at gaps wider than two steps.
        search_max_steps: most steps of the climb at each resolution; default 8.
        search_candidates: how many of the largest groups of angle estimates give a candidate;
            default 3.
        common_disc_passes: passes of stages 3-6 on a common disc (:func:`common_disc`): the
            first under a translation-only guess, each later one under the previous estimate,
            stopping early when the rotation changes by less than the angle resolution of stage
            5. If the first pass fails, the whole frames are used. 0 (default): the whole frames,
            as the paper does; the rotation search is as accurate without the disc
            (docs/method.md, section 8).
        extra_disc_passes: with ``rotation_search``, at most this many further common-disc
            passes, run while the searched rotation and the thresholded one differ by more than
            ``extra_pass_trigger_deg``; default 0.
        extra_pass_trigger_deg: see ``extra_disc_passes``; default 2 degrees.
    """

    rotation_search: bool = True
    search_step_deg: float = 1.5
    search_max_steps: int = 8
    search_candidates: int = 3
    common_disc_passes: int = 0
    extra_disc_passes: int = 0
    extra_pass_trigger_deg: float = 2.0

    def __post_init__(self):
        if not self.search_step_deg > 0:
            raise ValueError(f"search_step_deg must be > 0; got {self.search_step_deg}")
        for name in ("search_max_steps", "search_candidates", "common_disc_passes",
                     "extra_disc_passes"):
            if getattr(self, name) < 0:
                raise ValueError(f"{name} must be >= 0; got {getattr(self, name)}")

    @classmethod
    def off(cls) -> Refinements:
        """No refinement: the paper's pipeline as written (the ``t2fuzzy_paper`` method)."""
        return cls(rotation_search=False, common_disc_passes=0, extra_disc_passes=0)

    @property
    def needs_coarse_template(self) -> bool:
        """Whether any refinement runs (each one uses the half-resolution template)."""
        return self.rotation_search or self.common_disc_passes > 0


def half_resolution_template(smoothed_reference: np.ndarray, max_shift: int) -> RotatedTemplate:
    """The FNCC template of the (smoothed) reference at half resolution (Gaussian pyramid),
    rotated about the full frame's centre: a cheap first look at many rotations or shifts."""
    centre_x, centre_y = image_centre(smoothed_reference.shape)
    return RotatedTemplate(cv2.pyrDown(smoothed_reference), max_shift // 2,
                           (centre_x / 2.0, centre_y / 2.0))


def translation_guess(coarse_template: RotatedTemplate, image: np.ndarray,
                      min_ncc: float) -> Motion | None:
    """The motion (rotation 0) of the half-resolution FNCC of the smoothed current ``image``,
    only to know which area both frames see; None if the peak is below ``min_ncc``."""
    guess = coarse_template.match(cv2.pyrDown(image), 0.0)
    if not guess.peak >= min_ncc:
        return None
    return Motion(0.0, 2.0 * guess.x, 2.0 * guess.y)


def common_disc(motion: Motion, shape: tuple[int, int]) -> tuple[np.ndarray, np.ndarray]:
    """Masks of one disc of the scene in the reference and in the current frame under
    ``motion``: the largest inside both images, centred half-way along the shift.

    A disc rather than the overlap of the two frames: the overlap's straight edges would cut
    the objects along lines whose orientation depends on the motion guessed, and pull the
    ellipse angles toward that guess; a disc cuts alike at any rotation.

    Args:
        motion: the motion of the current frame (docs/design.md convention).
        shape: (height, width) of both frames.

    Returns:
        Boolean masks of the disc in the reference and in the current frame.
    """
    height, width = shape
    matrix = motion_matrix(motion, shape)
    centre_ref = np.array(image_centre(shape)) - np.array([motion.dx, motion.dy]) / 2.0
    centre_cur = matrix[:, :2] @ centre_ref + matrix[:, 2]
    # One pixel in from the images' last pixel centres.
    radius = min(min(c[0], width - 1 - c[0], c[1], height - 1 - c[1])
                 for c in (centre_ref, centre_cur)) - 1.0
    masks = []
    for c in (centre_ref, centre_cur):
        mask = np.zeros(shape, np.uint8)
        # Sub-pixel centre and radius (4 fractional bits).
        cv2.circle(mask, (round(c[0] * 16), round(c[1] * 16)), max(int(radius * 16), 0), 1,
                   -1, cv2.LINE_8, 4)
        masks.append(mask.view(bool))
    return masks[0], masks[1]


class RotationSearch:
    """The rotation that maximises the FNCC peak, searched around the ellipse estimates.

    Args:
        template: the reference's FNCC template (stage 6) at full resolution.
        coarse_template: the same at half resolution (:func:`half_resolution_template`).
        refinements: ``search_step_deg``, ``search_max_steps`` and ``search_candidates``.
    """

    def __init__(self, template: RotatedTemplate, coarse_template: RotatedTemplate,
                 refinements: Refinements):
        self.template = template
        self.coarse_template = coarse_template
        self.step = float(refinements.search_step_deg)
        self.max_steps = int(refinements.search_max_steps)
        self.n_candidates = int(refinements.search_candidates)

    def __call__(self, angles: np.ndarray, first_guess: float, image: np.ndarray,
                 near: tuple[float, float] | None = None) -> tuple[float, TemplateMatch]:
        """The searched rotation and the FNCC match at it.

        Args:
            angles: the rotation estimates of stage 4, degrees.
            first_guess: the thresholded rotation of stage 5.
            image: the current frame, smoothed as the template was.
            near: a previous translation to search around (the whole range if None).
        """
        half = cv2.pyrDown(image)
        candidates = [first_guess]
        # The identity too: when every group of estimates is wrong, no rotation is the
        # likeliest alternative for a camera that stays roughly upright.
        for mean in self._group_means(angles) + [0.0]:
            if min(abs(mean - c) for c in candidates) > self.step:
                candidates.append(mean)
        coarse = [self._coarse_match(half, candidates[0], near)]
        if near is None and np.isfinite(coarse[0].peak):
            # The shift hardly depends on the rotation about the image centre: search the
            # other candidates near the first one's.
            near = (2.0 * coarse[0].x, 2.0 * coarse[0].y)
        coarse += [self._coarse_match(half, angle, near) for angle in candidates[1:]]
        heights = [m.height if np.isfinite(m.height) else -np.inf for m in coarse]
        best = int(np.argmax(heights))
        angle = candidates[best]
        if not np.isfinite(heights[best]):
            return angle, self.template.match(image, angle)
        # Climb at half resolution first (a fraction of the cost), then finish at full.
        angle, top = self._climb(self.coarse_template, half, angle, coarse[best])
        near = (2.0 * top.x, 2.0 * top.y)
        centre = self.template.match(image, angle, near)
        if centre.at_border:  # the coarse shift was off: search the whole range once
            centre = self.template.match(image, angle)
        return self._climb(self.template, image, angle, centre)

    def _coarse_match(self, half: np.ndarray, angle: float,
                      near: tuple[float, float] | None) -> TemplateMatch:
        """Half-resolution match, near a previous full-resolution translation if given (the
        whole range if its peak is at the edge of that small search)."""
        if near is not None:
            match = self.coarse_template.match(half, angle, (near[0] / 2.0, near[1] / 2.0))
            if not match.at_border:
                return match
        return self.coarse_template.match(half, angle)

    def _climb(self, template: RotatedTemplate, image: np.ndarray, angle: float,
               centre: TemplateMatch) -> tuple[float, TemplateMatch]:
        """Hill-climb the correlation peak over rotation; parabolic vertex of the last three.

        The shift at the vertex is interpolated on the same parabola from the three matches
        (it changes smoothly with the rotation), which saves one more correlation.
        """
        near = (centre.x, centre.y)
        step = self.step
        below = template.match(image, angle - step, near)
        above = template.match(image, angle + step, near)
        for _ in range(self.max_steps):
            if centre.height >= below.height and centre.height >= above.height:
                break
            if above.height > below.height:
                angle, below, centre = angle + step, centre, above
                near = (centre.x, centre.y)  # the shift drifts with the rotation
                above = template.match(image, angle + step, near)
            else:
                angle, above, centre = angle - step, centre, below
                near = (centre.x, centre.y)
                below = template.match(image, angle - step, near)
        offset, _ = parabolic_vertex(below.height, centre.height, above.height)
        # The match at the vertex: each quantity on the parabola through the three matches.
        weights = (offset * (offset - 1) / 2, 1 - offset * offset, offset * (offset + 1) / 2)
        trio = (below, centre, above)
        x = sum(w * m.x for w, m in zip(weights, trio))
        y = sum(w * m.y for w, m in zip(weights, trio))
        return angle + offset * step, TemplateMatch(x, y, centre.peak, centre.at_border,
                                                    centre.height)

    def _group_means(self, angles: np.ndarray) -> list[float]:
        """Means of the largest groups of the sorted angles (groups split at gaps wider than two
        climbing steps), largest first."""
        if angles.size == 0:
            return []
        ordered = np.sort(angles)
        groups = np.split(ordered, np.flatnonzero(np.diff(ordered) > 2 * self.step) + 1)
        groups.sort(key=len, reverse=True)
        return [float(g.mean()) for g in groups[:self.n_candidates]]
