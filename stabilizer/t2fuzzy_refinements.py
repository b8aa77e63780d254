"""Refinements of the paper's pipeline in the ``t2fuzzy`` method, each a switchable parameter.

Kang, Zhang & Park (2009) take the rotation from the ellipse angles alone (stages 4-5) and then
the translation from the FNCC of the rotation-compensated reference (stage 6), both on the whole
frames. ``t2fuzzy`` adds the steps below, described with their reasons in docs/method.md,
sections 8 and 12; ``t2fuzzy_paper`` (:meth:`Refinements.off`) runs without them:

- Rotation search (:class:`RotationSearch`): the FNCC of stage 6 also scores rotations. The
  candidates are the thresholded rotation of stage 5, the means of the largest groups of angle
  estimates, and 0; the best-correlating one at half resolution is climbed in steps of
  ``search_step_deg`` to the local maximum of the correlation peak, first at half resolution,
  then on the largest template the shift allows (``large_template_border_px``) or at full
  resolution, and the vertex of a parabola through the last three steps is the rotation.
  The ellipse angles then choose where the search starts rather than give the rotation.
- Common-disc comparison (:func:`common_disc`): stages 3-6 are run on one disc of the scene that
  both frames see whole under a first estimate of the motion, so that an object cut by the image
  border in one frame only is compared with the same part of it in the other frame. The first
  estimate is a translation-only guess (:func:`translation_guess`), each further pass starts
  from the previous pass's estimate.
- Wide masked search (:class:`WideSearch`): the rotation search scores its candidates first by
  the masked FNCC of the whole overlap of the two frames at half resolution (Padfield 2012,
  :class:`~stabilizer.fncc.MaskedCorrelation`), over shifts up to ``wide_search_px``: the
  central template of stage 6 sees neither the structures near the border nor shifts beyond its
  margin. Its shift is where the finer search starts; a shift beyond the central template's
  reach is climbed over rotations on the whole overlap instead, at half and then at full
  resolution (:meth:`RotationSearch.climb_on_overlap`). So is the wide search's best motion
  when the finer search's climb went astray (``astray_climb_recovery``): when the central
  template finds no peak near the shift the climb reached, and the whole overlap correlates
  lower at the climb's rotation than at the wide search's best candidate.
- Search without ellipse estimates (``search_without_estimates``): a frame whose ellipses give
  no rotation estimate is searched from rotation 0 rather than failed.
- Resolving a disagreement (``resolve_disagreement``): when the central template's shift and
  the wide search's disagree, or the search's climb ended without a maximum, the estimate and
  the wide search's motion are climbed over rotation on the masked FNCC of the
  whole overlap (:class:`OverlapNear`), and the higher peak is kept if the two climbs meet or
  it leads by ``resolve_margin``; a tie is settled by the frames' depth edges, the trust check's
  measure, when one motion lines them up better by ``edge_tie_margin``
  (:meth:`RotationSearch.resolve_disagreement`).
- Clipping (``clip_sigmas``): stage 6 compares the frames with their values clipped to the
  reference's robust range, as the ECC and ICP peers do, so that phase-wrapped speckle does not
  outweigh the rest of the frame in the correlation.
- A second look (``doubtful_offset_deg``): an estimate that passed the trust check but lies
  more than this far in rotation from the optimum of the check's own measure is climbed once
  more over rotation on the masked FNCC of the whole overlap at full resolution
  (:meth:`RotationSearch.climb_on_overlap`) and checked again
  (:meth:`~stabilizer.t2fuzzy.T2FuzzyEstimator.second_look`). An estimate the check rejects
  because its optimum lies beyond the check's offset limits gets the same climb from that
  optimum (``climb_from_optimum``).
- Confidence of the search, each turning a doubtful estimate into a failure: the rotation range
  (``max_rotation_deg``) bounds the candidates and the climb; a climb that ends without a local
  maximum of the correlation is ``"rotation_unconverged"`` (``fail_unconverged``); an estimate
  whose shift disagrees with the wide search's is ``"translation_disagreement"``
  (``max_shift_disagreement_px``).

Why each step, and what it changes on walking frames: docs/method.md, sections 8 and 12.
The half-resolution template that the refinements use is :func:`half_resolution_template`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

from stabilizer.fncc import (
    MaskedCorrelation,
    MaskedSpectra,
    RotatedTemplate,
    TemplateMatch,
    parabolic_vertex,
)
from stabilizer.inputs import MAX_ITERATIONS, check_flag, check_integer, check_number
from stabilizer.motion import Motion, image_centre, motion_matrix
from stabilizer.verification import VerificationParams, edge_image, structure_correlation

#: Half-width (pixels) of the full-resolution search around a shift found at half resolution.
FINE_RADIUS_PX = 4
#: Half-width (pixels of its resolution) of the shifts :class:`OverlapNear` searches.
NEAR_OVERLAP_RADIUS_PX = 3
#: Most searches :class:`OverlapNear` makes for one match, each from the last one's peak while
#: that peak is on the edge of the searched shifts.
NEAR_OVERLAP_MOVES = 4
#: The margins of the large templates (:meth:`RotationSearch.refine_on_large_template`) are
#: multiples of this many pixels, so that a few templates serve all frames of a reference.
LARGE_MARGIN_STEP_PX = 4
#: Most common-disc passes (``common_disc_passes``, ``extra_disc_passes``), each a whole
#: estimate: on the 30 pairs of the test frames (tests/stabilizer/data), passes that settled did
#: so within 19; the others (5 with the paper's pipeline) cycled among 2-4 estimates for ever.
MAX_DISC_PASSES = 100


@dataclass(frozen=True)
class Refinements:
    """Which refinements run, and their settings. The defaults are the ``t2fuzzy`` method's.

    Attributes:
        rotation_search: refine the thresholded rotation of stage 5 by the FNCC peak
            (:class:`RotationSearch`); default True.
        search_step_deg: step of the climb over rotations, degrees; default 1.5. Candidates
            within one step of an earlier candidate are not scored, and groups of angle
            estimates are split at gaps wider than two steps.
        search_max_steps: most steps of the climb at each resolution, at most 1000
            (:data:`~stabilizer.inputs.MAX_ITERATIONS`); default 14, the steps that carry a
            climb from rotation 0, the candidate every search scores, to ``max_rotation_deg``
            (14 x 1.5 >= 20 degrees): a shorter climb stops short of the turns it may reach
            (docs/method.md, section 12, "Climbs long enough for the turn").
        search_candidates: how many of the largest groups of angle estimates give a candidate;
            default 3.
        common_disc_passes: passes of stages 3-6 on a common disc (:func:`common_disc`): the
            first under a translation-only guess, each later one under the previous estimate,
            stopping early when the rotation changes by less than the angle resolution of stage
            5. If the first pass fails, the whole frames are used. 0 (default): the whole frames,
            as the paper does; the rotation search is as accurate without the disc
            (docs/method.md, section 8). At most :data:`MAX_DISC_PASSES` (100).
        extra_disc_passes: with ``rotation_search``, at most this many further common-disc
            passes, run while the searched rotation and the thresholded one differ by more than
            ``extra_pass_trigger_deg``; at most :data:`MAX_DISC_PASSES` (100); default 0.
        extra_pass_trigger_deg: see ``extra_disc_passes``; default 2 degrees.
        wide_search_px: with ``rotation_search``, the candidates are first scored by the masked
            FNCC of the whole overlap at half resolution over shifts up to this many pixels
            (:class:`WideSearch`), whose shift starts the finer search; 0: off (the central
            template alone, within ``TranslationParams.max_shift_px``). Default 72, half the
            SR4000's height: shifts that leave a quarter of the frame or more.
        wide_min_overlap: shifts whose overlap keeps less than this share of the reference's
            valid pixels are not scored by the wide search (a small overlap correlates well by
            chance); default 0.3.
        search_without_estimates: with ``rotation_search``, a frame whose ellipses give no
            rotation estimate is searched from rotation 0 instead of getting the status
            ``"no_rotation_estimate"``; default True.
        max_rotation_deg: with ``rotation_search``, the largest rotation searched: candidates
            beyond it are dropped and the climb does not pass it, as ``max_shift_px`` bounds
            the shift; ``math.inf``: no bound. Default 20 degrees (the paper's walking robot
            turns its camera by up to about 12 degrees; the peers' start searches span +-15).
        fail_unconverged: with ``rotation_search``, a climb that ends without a local maximum
            of the correlation (after ``search_max_steps`` steps, or at ``max_rotation_deg``)
            gives the status ``"rotation_unconverged"`` rather than an estimate: the peak it
            was climbing to was not found. Default True.
        max_shift_disagreement_px: with the wide search, an estimate whose shift lies farther
            than this from the wide search's best shift gives the status
            ``"translation_disagreement"``: the central template and the whole overlap point to
            different peaks, and one of them is wrong (unless ``resolve_disagreement`` settles
            it). 0: no such test. Default 5 pixels (docs/method.md, section 12, measures the
            choice).
        resolve_disagreement: with the wide search, an estimate whose shift disagrees with the
            wide search's (see ``max_shift_disagreement_px``), or whose climb ended without a
            maximum (see ``fail_unconverged``), is not failed at once: it and the wide search's
            motion are climbed over rotation on the masked FNCC of the whole overlap, at half
            resolution and then at full resolution
            (:meth:`RotationSearch.resolve_disagreement`), and the winner is the estimate.
            Default True.
        resolve_margin: with ``resolve_disagreement``, when the two climbs end at different
            motions (more than one ``search_step_deg`` or ``max_shift_disagreement_px`` / 2
            apart) the higher peak must lead by at least this much FNCC, or the depth edges
            decide (``edge_tie_margin``); default 0.02.
        edge_tie_margin: with ``resolve_disagreement``, two climbs that end apart with FNCC
            peaks within ``resolve_margin`` are told apart by the correlation of the frames'
            depth edges at each motion (:func:`~stabilizer.verification.structure_correlation`,
            the measure of the trust check, which the smooth surfaces that flatten the FNCC
            over rotation do not dominate): the motion whose edge correlation leads by at least
            this much is the estimate; otherwise the frame keeps the status
            ``"translation_disagreement"`` (or ``"rotation_unconverged"``). ``math.inf``: the
            edges never decide. Default 0.05 (docs/method.md, section 12).
        large_template_border_px: with ``rotation_search``, after the climb the rotation is
            climbed once more (at half resolution) and the shift measured again (at full
            resolution) on the largest central template the found shift allows, the reference
            ``max(|dx|, |dy|)`` plus this many pixels in from every side
            (:meth:`RotationSearch.refine_on_large_template`): its pixels lie farther from the
            centre of rotation than those of the ``max_shift_px`` template, and fix the
            rotation better. 0: off. Default 6.
        clip_sigmas, clip_min_spread: stage 6 (the FNCC of the central templates, of the wide
            search and of the climbs on the whole overlap) compares both frames with their
            values clipped to the reference's robust range, its median +- ``clip_sigmas``
            spreads of at least ``clip_min_spread`` gray levels
            (:func:`~stabilizer.peers.preparation.robust_value_range`): the SR4000 shows
            surfaces beyond its range phase-wrapped, as bright speckle, which then keeps its
            outline but no longer outweighs the rest of the frame in the correlation. Stages 1-5
            and the trust check see the frames as they are. 0: off. Defaults 1.5 and 20, the ECC
            and ICP peers' clip (docs/method.md, section 12, "Clipping").
        final_overlap_climb: with the wide search, the search's estimate is climbed once more
            over rotation on the masked FNCC of the whole overlap at full resolution, near its
            own shift (:meth:`RotationSearch.climb_on_overlap`): every pixel both frames
            measure then fixes the motion, not only the central template's.
            Default False: on walking frames it makes the method about as accurate as the ECC
            peer (with ``large_template_border_px=0``, which it makes redundant), but adds
            about 45% to the method's own time on them, 2-3.5 ms a frame (docs/method.md,
            section 12).
        final_overlap_shift: with the wide search, the shift of the search's estimate is
            measured once more on the masked FNCC of the whole overlap at full resolution, at
            its rotation and near its shift (:meth:`RotationSearch.shift_on_overlap`): the
            shift half of ``final_overlap_climb``, at a third of its added time (about 17%);
            on walking frames it takes most of the climb's gain in y and in failures, little
            of its gain in rotation, and loses a little in x on most walks, as the climb does.
            Default False, for the cost (docs/method.md, section 12, "A final shift on the
            whole overlap"); with ``final_overlap_climb`` it changes nothing (the climb ends
            on the whole overlap).
        doubtful_offset_deg: with the wide search and the trust check
            (:class:`stabilizer.Stabilizer`'s ``verification``), an estimate that passed the
            check but whose check optimum (``verify_offset_deg``) lies more than this many
            degrees from it gets a second look: the climb of ``final_overlap_climb`` from it,
            checked again, whose result replaces it if it passes and lines up the frames' depth
            edges at least as well
            (:meth:`~stabilizer.t2fuzzy.T2FuzzyEstimator.second_look`). The climb then runs
            only where the check doubts the estimate. ``math.inf``: off. Default 1 degree
            (docs/method.md, section 12, "A second look").
        climb_from_optimum: with the wide search and the trust check, an estimate the check
            rejects as ``"not_optimum"`` (the optimum of its measure near the estimate,
            ``verify_optimum``, lies beyond its offset limits) gets a second look from that
            optimum: the climb of ``final_overlap_climb``, on this method's own FNCC, starts
            there, and its end replaces the estimate if it passes the check. Default True
            (docs/method.md, section 12, "A second look from the check's optimum").
        astray_climb_recovery: with the wide search, when the central template finds no peak
            near the shift that the half-resolution climb reached, and the whole overlap
            correlates lower at the climb's rotation than at the wide search's best candidate,
            the climb is taken to have gone astray: the wide search's best motion is climbed on
            the whole overlap instead, as a shift beyond the template's reach is. Default True
            (docs/method.md, section 12, "Astray climbs of the search").
    """

    rotation_search: bool = True
    search_step_deg: float = 1.5
    search_max_steps: int = 14
    search_candidates: int = 3
    common_disc_passes: int = 0
    extra_disc_passes: int = 0
    extra_pass_trigger_deg: float = 2.0
    wide_search_px: int = 72
    wide_min_overlap: float = 0.3
    search_without_estimates: bool = True
    max_rotation_deg: float = 20.0
    fail_unconverged: bool = True
    max_shift_disagreement_px: float = 5.0
    large_template_border_px: int = 6
    resolve_disagreement: bool = True
    resolve_margin: float = 0.02
    edge_tie_margin: float = 0.05
    clip_sigmas: float = 1.5
    clip_min_spread: float = 20.0
    final_overlap_climb: bool = False
    final_overlap_shift: bool = False
    doubtful_offset_deg: float = 1.0
    climb_from_optimum: bool = True
    astray_climb_recovery: bool = True

    def __post_init__(self):
        for name in ("rotation_search", "search_without_estimates", "fail_unconverged",
                     "resolve_disagreement", "final_overlap_climb", "final_overlap_shift",
                     "climb_from_optimum", "astray_climb_recovery"):
            check_flag(name, getattr(self, name))
        for name in ("search_candidates", "wide_search_px", "large_template_border_px"):
            check_integer(name, getattr(self, name), 0)
        check_integer("search_max_steps", self.search_max_steps, 0, MAX_ITERATIONS)
        for name in ("common_disc_passes", "extra_disc_passes"):
            check_integer(name, getattr(self, name), 0, MAX_DISC_PASSES)
        for name in ("search_step_deg", "clip_min_spread"):
            check_number(name, getattr(self, name), 0.0, open_low=True)
        if self.max_rotation_deg != math.inf:  # math.inf: no bound
            check_number("max_rotation_deg (or math.inf: no bound)", self.max_rotation_deg, 0.0,
                         open_low=True)
        for name in ("extra_pass_trigger_deg", "max_shift_disagreement_px", "resolve_margin",
                     "clip_sigmas"):
            check_number(name, getattr(self, name), 0.0)
        check_number("wide_min_overlap", self.wide_min_overlap, 0.0, 1.0, open_low=True)
        for name in ("edge_tie_margin", "doubtful_offset_deg"):
            if getattr(self, name) != math.inf:  # math.inf: never (off)
                check_number(f"{name} (or math.inf: off)", getattr(self, name), 0.0)

    @classmethod
    def off(cls) -> Refinements:
        """No refinement: the paper's pipeline as written (the ``t2fuzzy_paper`` method)."""
        return cls(rotation_search=False, common_disc_passes=0, extra_disc_passes=0,
                   wide_search_px=0, search_without_estimates=False, fail_unconverged=False,
                   max_shift_disagreement_px=0.0, large_template_border_px=0,
                   resolve_disagreement=False, clip_sigmas=0.0,
                   doubtful_offset_deg=math.inf, climb_from_optimum=False,
                   astray_climb_recovery=False)

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


class WideSearch:
    """Masked FNCC of the whole overlap of the rotated reference and the current frame, at half
    resolution (:class:`~stabilizer.fncc.MaskedCorrelation`, Padfield 2012).

    The central template of stage 6 is the reference ``max_shift_px`` in from every side: on
    walking frames the structures that pin the shift down often lie outside it (the pillars at
    the sides of a hall leave only the horizon in it, which fixes y but not x), and shifts beyond
    its margin cannot be found at all. The masked correlation compares every pixel both frames
    measure, at every shift that keeps ``min_overlap`` of the reference.

    Args:
        smoothed_reference: the reference as stage 6 correlates it (float32, smoothed).
        valid: the reference's measured pixels (bool).
        max_shift: largest shift searched along each axis, full-resolution pixels.
        min_overlap: see :class:`~stabilizer.fncc.MaskedCorrelation`.
    """

    def __init__(self, smoothed_reference: np.ndarray, valid: np.ndarray, max_shift: int,
                 min_overlap: float):
        self.reference = cv2.pyrDown(smoothed_reference)
        self.valid = half_resolution_valid(valid).view(np.uint8)
        centre_x, centre_y = image_centre(smoothed_reference.shape)
        self.centre = (centre_x / 2.0, centre_y / 2.0)
        self.min_overlap = float(min_overlap)
        self._full = (smoothed_reference, valid)
        # The searches near a motion (OverlapNear), made when first asked for.
        self._near: dict[bool, OverlapNear] = {}
        # No shift beyond the frame can keep an overlap.
        half_shift = min(max(int(max_shift) // 2, 1), min(self.reference.shape) - 1)
        self.correlation = MaskedCorrelation(self.reference.shape, half_shift, min_overlap)
        # The reference's share at rotation 0, a candidate on most frames: made once, when
        # first asked for.
        self._upright: MaskedSpectra | None = None

    def spectra(self, half_image: np.ndarray, half_valid: np.ndarray) -> MaskedSpectra:
        """The current frame's share of the correlation, once per frame (half resolution)."""
        return self.correlation.spectra(half_image, half_valid, moving=True)

    def match(self, current: MaskedSpectra, angle_deg: float,
              near: tuple[float, float] | None = None) -> TemplateMatch:
        """Shift (dx, dy), full-resolution pixels, of the current frame for ``angle_deg``;
        ``near`` is ignored (every shift is scored; the signature is
        :meth:`~stabilizer.fncc.RotatedTemplate.match`'s, so that the climb takes either)."""
        found = self.correlation.match(self._reference_spectra(float(angle_deg)), current)
        return TemplateMatch(2.0 * found.x, 2.0 * found.y, found.peak, found.at_border,
                             found.height)

    def near(self, half: bool) -> OverlapNear:
        """The same masked FNCC near a given motion (:class:`OverlapNear`), at half or at full
        resolution; made once per reference."""
        if half not in self._near:
            self._near[half] = (
                OverlapNear(self.reference, self.valid.view(bool), self.centre, 2.0,
                            self.min_overlap) if half else
                OverlapNear(*self._full, image_centre(self._full[0].shape), 1.0,
                            self.min_overlap))
        return self._near[half]

    def _reference_spectra(self, angle_deg: float) -> MaskedSpectra:
        """The rotated reference's share of the correlation."""
        if angle_deg == 0.0 and self._upright is not None:
            return self._upright
        height, width = self.reference.shape
        rotation = cv2.getRotationMatrix2D(self.centre, angle_deg, 1.0)
        rotated = cv2.warpAffine(self.reference, rotation, (width, height),
                                 flags=cv2.INTER_LINEAR)
        valid = cv2.warpAffine(self.valid, rotation, (width, height), flags=cv2.INTER_NEAREST)
        spectra = self.correlation.spectra(rotated, valid.view(bool), moving=False)
        if angle_deg == 0.0:
            self._upright = spectra
        return spectra


class OverlapNear:
    """Masked FNCC of the whole overlap (:class:`~stabilizer.fncc.MaskedCorrelation`, Padfield
    2012) over shifts within ``NEAR_OVERLAP_RADIUS_PX`` pixels of this resolution around a
    given motion: the reference is warped by the whole motion (rotation about the centre, then
    the shift), so the search is small and, unlike the central template, every pixel both
    frames measure counts. A peak on the edge of the searched shifts is followed: the search
    is repeated from it, up to ``NEAR_OVERLAP_MOVES`` times. Its :meth:`match` has the
    signature of
    :meth:`~stabilizer.fncc.RotatedTemplate.match`, so that the rotation climb takes it.

    Args:
        reference: the smoothed reference at this resolution (float32).
        valid: its measured pixels (bool).
        centre: the centre of rotation in this resolution's pixels.
        scale: full-resolution pixels per pixel of this resolution (1 or 2).
        min_overlap: see :class:`~stabilizer.fncc.MaskedCorrelation`.
    """

    def __init__(self, reference: np.ndarray, valid: np.ndarray, centre: tuple[float, float],
                 scale: float, min_overlap: float):
        self.reference = reference
        self.valid = valid.view(np.uint8)
        self.centre = centre
        self.scale = float(scale)
        self.correlation = MaskedCorrelation(reference.shape, NEAR_OVERLAP_RADIUS_PX,
                                             min_overlap)

    def spectra(self, image: np.ndarray, valid: np.ndarray) -> MaskedSpectra:
        """The current frame's share of the correlation (this resolution), once per frame."""
        return self.correlation.spectra(image, valid, moving=True)

    def match(self, current: MaskedSpectra, angle_deg: float,
              near: tuple[float, float]) -> TemplateMatch:
        """The best shift (dx, dy), full-resolution pixels, near ``near`` for ``angle_deg``."""
        for _ in range(NEAR_OVERLAP_MOVES):
            matrix = cv2.getRotationMatrix2D(self.centre, float(angle_deg), 1.0)
            matrix[:, 2] += np.asarray(near, np.float64) / self.scale
            size = self.reference.shape[::-1]
            warped = cv2.warpAffine(self.reference, matrix, size, flags=cv2.INTER_LINEAR)
            valid = cv2.warpAffine(self.valid, matrix, size, flags=cv2.INTER_NEAREST)
            found = self.correlation.match(
                self.correlation.spectra(warped, valid.view(bool), moving=False), current)
            near = (near[0] + self.scale * found.x, near[1] + self.scale * found.y)
            if not (found.at_border and np.isfinite(found.height)):
                break
        return TemplateMatch(near[0], near[1], found.peak, found.at_border, found.height)


def half_resolution_valid(valid: np.ndarray) -> np.ndarray:
    """Half-resolution validity (bool) of a ``cv2.pyrDown`` image: a pixel whose 5 x 5 kernel
    saw an unmeasured pixel blends in a 0 and is no measurement."""
    return cv2.pyrDown(valid.astype(np.float32)) > 0.999


class RotationSearch:
    """The rotation that maximises the FNCC peak, searched around the ellipse estimates.

    Args:
        template: the reference's FNCC template (stage 6) at full resolution.
        coarse_template: the same at half resolution (:func:`half_resolution_template`).
        refinements: ``search_step_deg``, ``search_max_steps``, ``search_candidates``,
            ``max_rotation_deg``, ``large_template_border_px``, ``max_shift_disagreement_px``,
            ``resolve_margin``, ``edge_tie_margin``, ``astray_climb_recovery``,
            ``final_overlap_climb`` and ``final_overlap_shift``.
        wide: the masked search of the whole overlap (:class:`WideSearch`), or None.
        reference: the reference frame itself, whose depth edges settle a disagreement that
            the FNCC cannot (``edge_tie_margin``); None: they never do.
    """

    #: The scales and borders of the depth edges that settle a tie (:meth:`_edge_tie_break`):
    #: the trust check's defaults.
    edge_params: VerificationParams = VerificationParams()

    def __init__(self, template: RotatedTemplate, coarse_template: RotatedTemplate,
                 refinements: Refinements, wide: WideSearch | None = None,
                 reference: np.ndarray | None = None):
        self.template = template
        self.coarse_template = coarse_template
        self.step = float(refinements.search_step_deg)
        self.max_steps = int(refinements.search_max_steps)
        self.n_candidates = int(refinements.search_candidates)
        self.max_rotation = float(refinements.max_rotation_deg)
        self.large_border = int(refinements.large_template_border_px)
        # Large templates by margin (full-resolution pixels), made once per reference.
        self._large_templates: dict[tuple[int, bool], RotatedTemplate] = {}
        self.wide = wide
        #: The wide search's best (dx, dy) in the last call, None if it did not run.
        self.wide_shift: tuple[float, float] | None = None
        #: The candidate rotation at which the wide search found ``wide_shift``.
        self.wide_angle: float | None = None
        self.astray_climb_recovery = bool(refinements.astray_climb_recovery)
        #: The end (angle, dx, dy) of the finer search's climb in the last call when it went
        #: astray and was replaced (``astray_climb_recovery``), else None.
        self.astray_climb: tuple[float, float, float] | None = None
        self.shift_tolerance = float(refinements.max_shift_disagreement_px) / 2.0
        self.resolve_margin = float(refinements.resolve_margin)
        self.edge_tie_margin = float(refinements.edge_tie_margin)
        self._reference = reference
        self._reference_edges: tuple[np.ndarray, np.ndarray] | None = None  # when first needed
        self.final_overlap_climb = bool(refinements.final_overlap_climb)
        self.final_overlap_shift = bool(refinements.final_overlap_shift)

    def __call__(self, angles: np.ndarray, first_guess: float, image: np.ndarray,
                 near: tuple[float, float] | None = None,
                 valid: np.ndarray | None = None) -> tuple[float, TemplateMatch, bool]:
        """The searched rotation, the FNCC match at it, and whether the climb ended at a local
        maximum of the correlation within ``max_rotation_deg``; with ``final_overlap_climb``,
        a converged estimate climbed on the whole overlap (:meth:`climb_on_overlap`), with
        ``final_overlap_shift`` its shift measured there (:meth:`shift_on_overlap`).

        Args:
            angles: the rotation estimates of stage 4, degrees.
            first_guess: the thresholded rotation of stage 5.
            image: the current frame, smoothed as the template was.
            near: a previous translation to search around (the whole range if None).
            valid: the current frame's measured pixels (bool), for the wide search; without
                it, or with ``near``, the wide search is not run.
        """
        angle, match, converged = self._search(angles, first_guess, image, near, valid)
        if not (converged and self.wide_shift is not None and np.isfinite(match.height)):
            return angle, match, converged
        if self.final_overlap_climb:
            climbed = self.climb_on_overlap(angle, (match.x, match.y), image, valid)
            if climbed is not None:
                angle, match = climbed
        elif self.final_overlap_shift:
            shifted = self.shift_on_overlap(angle, (match.x, match.y), image, valid)
            if shifted is not None:
                match = shifted
        return angle, match, converged

    def _search(self, angles: np.ndarray, first_guess: float, image: np.ndarray,
                near: tuple[float, float] | None = None,
                valid: np.ndarray | None = None) -> tuple[float, TemplateMatch, bool]:
        """The search of :meth:`__call__` before the final climb on the whole overlap."""
        half = cv2.pyrDown(image)
        candidates = []
        # The identity too: when every group of estimates is wrong, no rotation is the
        # likeliest alternative for a camera that stays roughly upright.
        for mean in [first_guess] + self._group_means(angles) + [0.0]:
            if abs(mean) <= self.max_rotation and all(abs(mean - c) > self.step
                                                      for c in candidates):
                candidates.append(mean)
        self.wide_shift = self.wide_angle = self.astray_climb = None
        if self.wide is not None and near is None and valid is not None:
            spectra = self.wide.spectra(half, half_resolution_valid(valid))
            wide = [self.wide.match(spectra, angle) for angle in candidates]
            wide_heights = [m.height if np.isfinite(m.height) else -np.inf for m in wide]
            widest = int(np.argmax(wide_heights))
            self.wide_shift = (wide[widest].x, wide[widest].y)
            self.wide_angle = candidates[widest]
            if not np.isfinite(wide_heights[widest]):
                return candidates[widest], wide[widest], False
            reach = self.template.margin - FINE_RADIUS_PX
            if max(abs(wide[widest].x), abs(wide[widest].y)) > reach:
                # Beyond the central template's reach: climb on the whole overlap instead.
                return self._climb_whole_overlap(spectra, candidates[widest], wide[widest],
                                                 image, valid)
            # Every candidate near the wide search's shift, and only there.
            coarse = [self.coarse_template.match(half, angle, (wide[widest].x / 2.0,
                                                                wide[widest].y / 2.0))
                      for angle in candidates]
        else:
            spectra = None
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
            return angle, (self.wide.match(spectra, angle) if spectra is not None
                           else self.template.match(image, angle)), False
        # Climb at half resolution first (a fraction of the cost), then finish at full.
        angle, top, converged = self._climb(self.coarse_template, half, angle, coarse[best])
        near = (2.0 * top.x, 2.0 * top.y)
        centre = self.template.match(image, angle, near)
        if centre.at_border:  # the coarse shift was off
            if spectra is not None:  # the shift of the whole overlap at this rotation
                found = self.wide.match(spectra, angle)
                if self.astray_climb_recovery and not found.height >= wide_heights[widest]:
                    # The climb left the wide search's shift for a worse motion of the whole
                    # overlap: start again from the wide search's best, on the whole overlap.
                    self.astray_climb = (angle, found.x, found.y)
                    return self._climb_whole_overlap(spectra, candidates[widest], wide[widest],
                                                     image, valid)
                return angle, found, converged
            centre = self.template.match(image, angle)  # search the whole range once
        if self.large_border > 0:
            refined = self.refine_on_large_template(half, image, angle, centre)
            if refined is not None:
                return (*refined, converged)
        angle, match, fine_converged = self._climb(self.template, image, angle, centre)
        return angle, match, converged and fine_converged

    def _climb_whole_overlap(self, spectra: MaskedSpectra, angle: float, start: TemplateMatch,
                             image: np.ndarray, valid: np.ndarray
                             ) -> tuple[float, TemplateMatch, bool]:
        """The wide search's match ``start`` at ``angle`` climbed over rotation on the whole
        overlap, at half resolution and then, like every other path, at full resolution
        (:meth:`climb_on_overlap`); the rotation, the match and whether the climb converged."""
        angle, top, converged = self._climb(self.wide, spectra, angle, start)
        if converged and np.isfinite(top.height):
            climbed = self.climb_on_overlap(angle, (top.x, top.y), image, valid)
            if climbed is not None:
                angle, top = climbed
        return angle, top, converged

    def resolve_disagreement(self, angle: float, match: TemplateMatch, image: np.ndarray,
                             current: np.ndarray) -> tuple[float, TemplateMatch] | None:
        """The motion at the higher of two peaks of the masked FNCC of the whole overlap, or
        None when the two cannot be told apart; after a search whose estimate (``angle``,
        ``match``) disagrees with the wide search's shift, or whose climb found no maximum.

        The wide search scored only the candidate rotations, so its shift is off when all of
        them are (on the frames where the camera turns by 5-12 degrees it often ran at 0); the
        central template's peak may lie on a ridge. Each motion starts a climb over rotation
        (:meth:`_climb`) on the whole overlap near its own shift (:class:`OverlapNear`) at half
        resolution; the higher peak is climbed again at full resolution (kept only if that ends
        at a local maximum within two steps). The whole overlap's peak over rotation is broad
        (smooth surfaces dominate it), so two climbs that end apart are told apart by a lead of
        ``resolve_margin`` in FNCC, or else by a lead of ``edge_tie_margin`` in the correlation
        of the frames' depth edges (:meth:`_edge_tie_break`); otherwise, or if either climb has
        no maximum within the rotation range, the frame stays a failure.

        Args:
            image: the current frame, smoothed as the template was.
            current: the current frame itself (0 = unmeasured).
        """
        if self.wide is None or self.wide_shift is None:
            return None
        valid = current > 0
        half_search = self.wide.near(half=True)
        spectra = half_search.spectra(cv2.pyrDown(image), half_resolution_valid(valid))
        climbs = [self._climb(half_search, spectra, start,
                              half_search.match(spectra, start, shift))
                  for start, shift in ((angle, (match.x, match.y)),
                                       (self.wide_angle, self.wide_shift))]
        if not all(converged and np.isfinite(top.height) for _, top, converged in climbs):
            return None
        (angle_a, top_a, _), (angle_b, top_b, _) = climbs
        meet = (abs(angle_a - angle_b) <= self.step
                and math.hypot(top_a.x - top_b.x, top_a.y - top_b.y) <= self.shift_tolerance)
        if meet or abs(top_a.height - top_b.height) >= self.resolve_margin:
            angle, top, _ = climbs[0] if top_a.height >= top_b.height else climbs[1]
        else:
            chosen = self._edge_tie_break(climbs, current)
            if chosen is None:
                return None
            angle, top, _ = chosen
        # A climb beyond two steps is not kept: it need not be walked.
        found = self._full_overlap_climb(angle, (top.x, top.y), image, valid, 2)
        if found is None:
            return None
        start, (fine_angle, fine, converged) = found
        if converged and abs(fine_angle - angle) < 2.0 * self.step:
            return fine_angle, fine
        return angle, start

    def _edge_tie_break(self, climbs: list[tuple[float, TemplateMatch, bool]],
                        current: np.ndarray) -> tuple[float, TemplateMatch, bool] | None:
        """Of two climbs whose FNCC peaks tie, the one whose motion lines up the frames' depth
        edges better by ``edge_tie_margin`` (:func:`~stabilizer.verification.edge_image` and
        :func:`~stabilizer.verification.structure_correlation`, with :attr:`edge_params`), or
        None."""
        if self._reference is None or not math.isfinite(self.edge_tie_margin):
            return None
        scales = self.edge_params
        if self._reference_edges is None:
            self._reference_edges = edge_image(self._reference, scales.sigma_px,
                                               scales.clip_factor, scales.image_border)
        current_edges = edge_image(current, scales.sigma_px, scales.clip_factor,
                                   scales.image_border)
        first, second = (structure_correlation(*self._reference_edges, *current_edges,
                                               Motion(angle, top.x, top.y))[0]
                         for angle, top, _ in climbs)
        if abs(first - second) < self.edge_tie_margin:
            return None
        return climbs[0] if first > second else climbs[1]

    def climb_on_overlap(self, angle: float, shift: tuple[float, float], image: np.ndarray,
                         valid: np.ndarray) -> tuple[float, TemplateMatch] | None:
        """The motion (``angle``, ``shift``) climbed over rotation on the masked FNCC of the
        whole overlap near its own shift (:class:`OverlapNear`), at full resolution; None when
        the overlap has no defined correlation there or the climb finds no maximum (the motion
        is then kept as it is)."""
        found = self._full_overlap_climb(angle, shift, image, valid)
        if found is None:
            return None
        _, (angle, top, converged) = found
        return (angle, top) if converged else None

    def shift_on_overlap(self, angle: float, shift: tuple[float, float], image: np.ndarray,
                         valid: np.ndarray) -> TemplateMatch | None:
        """The whole overlap's full-resolution match (:class:`OverlapNear`) at ``angle`` near
        ``shift``: every pixel both frames measure fixes the shift, not only the central
        template's; None when the correlation is undefined there."""
        full_search = self.wide.near(half=False)
        found = full_search.match(full_search.spectra(image, valid), angle, shift)
        return found if np.isfinite(found.height) else None

    def _full_overlap_climb(self, angle: float, shift: tuple[float, float], image: np.ndarray,
                            valid: np.ndarray, max_steps: int | None = None
                            ) -> tuple[TemplateMatch, tuple[float, TemplateMatch, bool]] | None:
        """The whole overlap's full-resolution match at ``angle`` near ``shift``, and the climb
        over rotation from it (:meth:`_climb`); None when the correlation is undefined there."""
        full_search = self.wide.near(half=False)
        current = full_search.spectra(image, valid)
        start = full_search.match(current, angle, shift)
        if not np.isfinite(start.height):
            return None
        return start, self._climb(full_search, current, angle, start, max_steps)

    def refine_on_large_template(self, half: np.ndarray, image: np.ndarray, angle: float,
                                 match: TemplateMatch) -> tuple[float, TemplateMatch] | None:
        """The rotation climbed at half resolution, and the shift at it at full resolution, on
        the largest central template that stays in the current frame near the shift of
        ``match``; None when no larger template fits or its climb is not kept.

        The ``max_shift_px`` template must fit every shift of the search range; once the shift
        is known, a template ``max(|dx|, |dy|)`` + ``large_template_border_px`` in from every
        side fits it, and its pixels, farther from the centre of rotation, move more under a
        rotation: it fixes the rotation better, so the search's last climb is on it (the
        ``max_shift_px`` template is climbed at full resolution only when it is not kept). The
        climb's result is kept only if it ends at a local maximum within two steps of
        ``angle``; the shift is the large template's at full resolution (the ``max_shift_px``
        template's if the large one's peak is on the edge of its search).
        """
        # Margins in steps of LARGE_MARGIN_STEP_PX: a few templates serve a reference's frames.
        reach = LARGE_MARGIN_STEP_PX * math.ceil((max(abs(match.x), abs(match.y))
                                                  + self.large_border) / LARGE_MARGIN_STEP_PX)
        if not reach < self.template.margin:  # no larger template fits
            return None
        half_template = self._large_template(reach // 2, True)
        start = half_template.match(half, angle, (match.x / 2.0, match.y / 2.0))
        climbed, _, converged = self._climb(half_template, half, angle, start)
        if not (converged and abs(climbed - angle) < 2.0 * self.step):
            return None
        near = (match.x, match.y)
        for template in (self._large_template(reach, False), self.template):
            found = template.match(image, climbed, near)
            if not found.at_border:
                return climbed, found
        return None

    def _large_template(self, margin: int, half: bool) -> RotatedTemplate:
        """The central template ``margin`` pixels (of its resolution) in from every side."""
        key = (int(margin), half)
        if key not in self._large_templates:
            like = self.coarse_template if half else self.template
            self._large_templates[key] = like.with_margin(int(margin))
        return self._large_templates[key]

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
               centre: TemplateMatch,
               max_steps: int | None = None) -> tuple[float, TemplateMatch, bool]:
        """Hill-climb the correlation peak over rotation; parabolic vertex of the last three.

        The shift at the vertex is interpolated on the same parabola from the three matches
        (it changes smoothly with the rotation), which saves one more correlation. The flag
        says whether the climb ended at a local maximum (not after ``search_max_steps`` steps
        or at ``max_rotation_deg``); ``max_steps`` caps the steps below that.
        """
        near = (centre.x, centre.y)
        step = self.step
        below = template.match(image, angle - step, near)
        above = template.match(image, angle + step, near)
        converged = False
        for _ in range(self.max_steps if max_steps is None else min(max_steps, self.max_steps)):
            if centre.height >= below.height and centre.height >= above.height:
                converged = True
                break
            if abs(angle + (step if above.height > below.height else -step)) > self.max_rotation:
                break  # the next step would leave the searched range
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
        if not converged:  # the maximum of the last three need not be the middle one
            converged = centre.height >= below.height and centre.height >= above.height
        return angle + offset * step, TemplateMatch(x, y, centre.peak, centre.at_border,
                                                    centre.height), converged

    def _group_means(self, angles: np.ndarray) -> list[float]:
        """Means of the largest groups of the sorted angles (groups split at gaps wider than two
        climbing steps), largest first."""
        if angles.size == 0:
            return []
        ordered = np.sort(angles)
        groups = np.split(ordered, np.flatnonzero(np.diff(ordered) > 2 * self.step) + 1)
        groups.sort(key=len, reverse=True)
        return [float(g.mean()) for g in groups[:self.n_candidates]]
