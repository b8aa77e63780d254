"""The paper's stabilizer: Kang, Zhang & Park (2009), "Stereo-vision based motion stabilization of
a humanoid robot for the environment recognition by type-2 fuzzy logic".

Pipeline (docs/method.md, sections 1-7), each stage in its own module:

1. cluster count and seeds from the histogram peaks (:mod:`stabilizer.histogram_seeds`);
2. IT2-FCM on the weighted histogram of valid levels, hard labels, morphological clean-up
   (:mod:`stabilizer.it2fcm`);
3. two-level wavelet point sets of every object (:mod:`stabilizer.wavelet_features`);
4. direct least-squares ellipse of every point set and its major-axis angle
   (:mod:`stabilizer.ellipse`); reference and current objects are put in correspondence and
   the angle differences of the same subbands of matched objects are the rotation estimates;
5. type-2 fuzzy (ultrafuzziness) thresholds cut the left and right outliers; the rotation is
   the mean of the estimates between them (:mod:`stabilizer.t2_threshold`);
6. rotation compensation, then translation by FNCC with sub-pixel peak (:mod:`stabilizer.fncc`).

Correspondence (stage 4): pairs (reference object, current object) are ranked by the difference
of their cluster centres (gray levels), then by the log ratio of their areas, and taken greedily
one-to-one; pairs whose centres differ by more than ``max_centre_shift`` levels are not matched.
Angles are axis angles, so differences are taken modulo 180 deg and wrapped to (-90, 90].

Rotation compensation and the Motion convention (stage 6): the current frame is the reference
rotated by theta about the image centre c, then shifted by t = (dx, dy). Rotating the reference
by the estimated theta about c therefore leaves exactly the shift t between it and the current
frame, so the template (the central region of the reference, ``max_shift_px`` in from each side)
is cut from the rotation-compensated reference and searched in the current frame: its offset is
(dx, dy) in the docs/design.md convention, with no further conversion. Only the template region is
warped. (Un-rotating the current frame instead would leave the shift R(-theta) t, which must be
rotated back and needs a larger search range for the same t.)

Objects and structure. Every segmented label is an object, and one object is enough: its
subband point sets give angles. An object whose every edge is the measurement's (next to
invalid pixels or the image border: no detail point survives ``edge_margin``) has no outline in
the scene, and its approximation band is only the shape of the measured area; its point sets
carry no angle, unless the frame has a far region: an unmeasured area holding a
``min_hole_size`` square (the out-of-range end of a corridor, not dropouts or the thin lines of
mixed pixels), which moves with the scene and gives the measured area a shape. A frame with no
usable ellipse at all has no structure.

Beyond the paper, each a parameter (measured on the 100 synthetic scenes of the tests,
+-15 deg, +-40 px, and on simulated SR4000 walking frames):

- ``overlap_passes``: the ellipses of two frames are compared only on one disc of the scene
  that both frames see whole. An object cut by the image border in one frame but not in the
  other changes shape between them, and on walking frames (shifts up to 40 px of a 176-px
  width) that shape change, not the rotation, dominates the ellipse angles: the stages as
  written (``overlap_passes=0``) gave 21 deg mean (14 deg median) rotation error on simulated
  SR4000 walking frames, 5.5 deg mean (2.4 deg median) with one pass. A disc rather than the
  overlap itself, because the overlap's straight edges cut every large region along lines set
  by the guessed motion and pull the angles toward the guess (measured: 6.8 deg mean, 5.5 deg
  median with the overlap). The first pass uses a translation-only guess (half-resolution FNCC
  at rotation 0), so the paper's stages are not started from their own full-frame estimate;
  if no pass succeeds, the full-frame stages run as written. Default: one pass without
  ``refine_rotation``, none with it (its correlation search is as accurate without).
- ``refine_rotation``: the FNCC of stage 6 also scores rotations. The thresholded rotation, the
  means of the main groups of angle estimates and 0 are candidates; the best-correlating one
  (at half resolution) is climbed in ``refine_step_deg`` steps to the local maximum of the
  correlation peak, first at half and then at full resolution, and a parabola through the last
  three gives the rotation.
- ``refine_iterations``: with ``refine_rotation``, further overlap passes while that rotation
  and the thresholded one disagree by more than ``refine_trigger_deg`` (default 0: on the
  walking frames the passes changed the mean errors by less than 0.01 deg / px at twice the
  cost, once the identity is a candidate and the climb starts at half resolution).
- ``weighted_fit``, ``merge_details``, ``ncc_sigma``: points weighted by their coefficient
  magnitude, one detail point set per level (see :mod:`stabilizer.wavelet_features`), and light
  smoothing before the correlation, which makes its peak a smooth function of the motion.

The paper's pipeline as written is ``refine_rotation=False, overlap_passes=0``. On the synthetic
scenes it recovers the rotation with a median error of 1.7 deg (1.4 deg with the default overlap
pass); with all additions the median is 0.05 deg and 97% of cases are within 0.5 deg / 0.5 px.
The ellipses of wavelet point sets are only good to a degree or two on compact objects; on real
frames, whose labels are large regions with complex outlines, the detail-band ellipses are the
least stable estimates (see the report of the walking benchmarks).

Statuses of a Motion that carries no estimate (``Motion.failed``):

- ``"no_structure"``: the reference or the current frame has no valid pixel, a single valid gray
  level (flat), no segmented object, or no object with an outline in the scene (see above);
  ``diagnostics["frame"]`` says which frame;
- ``"no_rotation_estimate"``: no matched object subband has an orientable ellipse in both frames;
- ``"no_translation_estimate"``: the correlation is undefined (flat template or image) or its
  peak is below ``min_ncc``.

Diagnostics of every Motion (what the estimator saw): ``n_clusters``, ``centres`` (gray levels),
``labels`` (H x W int32 label image of the current frame; 0 = invalid or unlabelled, 1..C),
``object_angles`` (rotation estimates, degrees), ``angle_sources`` (one row (reference label,
current label, subband index) per estimate; subband names in ``subbands``), ``thresholds``
(lower, upper), ``inliers`` (mask over ``object_angles``), ``threshold_fallback`` (None or
"median"), ``rotation_by_thresholds`` (the stage-5 rotation before refinement), ``ncc_peak``,
``ncc_at_border``, ``refine_passes`` (overlap passes run; 0: the full-frame stages),
``ellipses`` (the current frame's fitted ellipses, on the overlap after an overlap pass, as (cx, cy, half_major, half_minor, angle_deg) in image pixels, angle of the
major axis from +x toward +y), ``fcm_iterations`` and ``fcm_converged``. Keys not reached before
a failure are absent; after restricted passes, the angle keys describe the last pass.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

import cv2
import numpy as np

from stabilizer.ellipse import (
    MIN_POINTS,
    EllipseFits,
    axis_angle_difference,
    fit_ellipses,
)
from stabilizer.fncc import RotatedTemplate, TemplateMatch, parabolic_vertex
from stabilizer.histogram_seeds import HistogramSeeds
from stabilizer.it2fcm import IT2FCM, LabelCleaner
from stabilizer.motion import Motion, image_centre, motion_matrix
from stabilizer.t2_threshold import Type2FuzzyThreshold
from stabilizer.wavelet_features import WaveletFeatures

NO_STRUCTURE = "no_structure"
NO_ROTATION = "no_rotation_estimate"
NO_TRANSLATION = "no_translation_estimate"
#: Half-width (pixels) of the translation search around a previous translation; a peak on its
#: edge falls back to the whole range.
NEAR_RADIUS_PX = 4


@dataclass(frozen=True)
class FrameAnalysis:
    """Stages 1-4 applied to one frame.

    Attributes:
        centres: crisp cluster centres (gray levels) of the C clusters.
        labels: cleaned uint8 label image (0 = invalid / unlabelled, 1..C).
        objects: labels of the objects kept after clean-up, ascending.
        areas: pixel count of each kept object.
        fits: ellipse fits of every (object, subband) point set, object-major order.
        fcm_iterations, fcm_converged: how the clustering ended.
        status: None, or the reason the frame has no usable structure.
        far_region: the frame has an unmeasured region of at least a ``min_hole_size`` square of pixels,
            whose outline gives objects bordering it a shape (see ``T2FuzzyEstimator``).
    """

    centres: np.ndarray
    labels: np.ndarray
    objects: np.ndarray
    areas: np.ndarray
    fits: EllipseFits | None
    fcm_iterations: int
    fcm_converged: bool
    status: str | None
    far_region: bool = False

    def diagnostics(self) -> dict[str, Any]:
        return {"n_clusters": int(self.centres.size), "centres": self.centres.copy(),
                "labels": self.labels.astype(np.int32), "fcm_iterations": self.fcm_iterations,
                "fcm_converged": self.fcm_converged}


class T2FuzzyEstimator:
    """Kang, Zhang & Park (2009) motion estimator against a reference analysed once.

    Args (the paper's values as defaults where it gives one):
        reference: uint8 disparity-like image (0 = no measurement), validated by the caller.
        bin_width: histogram bin width for the cluster count, gray levels; paper: 20.
        min_ratio: fraction of valid pixels a histogram peak must exceed; paper: 2%.
        m1, m2: IT2-FCM fuzzifiers (paper: none given). Measured on the whole-pipeline test
            (100 synthetic scenes), (1.5, 2.5), (2, 3), (1.5, 4) and (2, 5) all gave 97% of
            cases within 0.5 deg / 0.5 px and the same medians; (2, 5), the common choice, kept.
        fcm_tol, fcm_max_iter: IT2-FCM stopping rule (largest centre change in gray levels,
            iterations); 0.01 levels is far below the one-level resolution of the labels.
            (0.1 saves 3 of 8.5 iterations, 0.15 ms, on the walking frames, but changes a few
            labels: median rotation error of the unrefined stages on the synthetic scenes
            1.78 instead of 1.69 deg.)
        warm_start: start the current frame's IT2-FCM from the reference's centres when its
            histogram gives as many seeds (the same scene converges in a few iterations, and
            to the same labels as from the histogram seeds on the test scenes).
        morph_size: side of the square for the morphological opening/closing; default 3.
        min_object_area: objects with fewer pixels after clean-up are dropped.
        wavelet, wavelet_level: PyWavelets wavelet and decomposition levels; paper: 2 levels.
        significance: fraction of a subband's largest coefficient magnitude that makes a
            coefficient a feature point (0: every non-zero coefficient).
        merge_details: one point set per level for the three detail subbands (see
            :mod:`stabilizer.wavelet_features`) rather than one per subband.
        edge_margin: detail points this close (pixels) to invalid pixels or the image border
            are not scene edges and are dropped.
        weighted_fit: weight each point of the ellipse fit by its coefficient's magnitude
            (for the LL band: the fraction of the block the object covers).
        min_axis_ratio: ellipses rounder than this (major / minor) carry no angle.
        max_centre_shift: largest cluster-centre difference (gray levels) of matched objects.
        alpha: type-2 thresholding exponent, (1, 2]; paper eq. (6), default 2.
        bandwidth_deg, resolution_deg: membership half-width and histogram step of the angle
            thresholding.
        max_shift_px: translation search range; the FNCC template is the reference's central
            region this far in from every side (the paper gives no template size).
        ncc_sigma: Gaussian smoothing (pixels) of both frames before the correlation; 0: none.
        min_ncc: a correlation peak below this gives ``"no_translation_estimate"``.
        refine_rotation: refine the thresholded rotation by the FNCC peak (see the module
            docstring); False (with ``overlap_passes=0``) gives the paper's pipeline as written.
        refine_step_deg, refine_max_steps, refine_candidates: step and largest number of
            steps of that climb, and how many groups of angle estimates are candidates.
        refine_iterations, refine_trigger_deg: with ``refine_rotation``, at most this many
            further overlap passes, run while the refined rotation and the thresholded one
            differ by more than the trigger.
        overlap_passes: passes of stages 3-6 restricted to a disc both frames see, the first
            under a translation-only guess, later ones under the previous estimate (stopping
            when the rotation changes by less than ``resolution_deg``); 0: the whole frames,
            as the paper does. Default (None): 1 without ``refine_rotation``, 0 with it (the
            refinement's correlation search gave the same accuracy on the walking frames
            without the pass, at 85% of the time). On the walking frames a second pass gave a lower median but a
            higher mean rotation error (more outliers) at 1.5 times the cost.
        min_hole_size: side (pixels) of the square an unmeasured region must hold to be a far
            region of the scene (see the module docstring).
    """

    def __init__(self, reference: np.ndarray, *, bin_width: int = 20, min_ratio: float = 0.02,
                 m1: float = 2.0, m2: float = 5.0, fcm_tol: float = 1e-2,
                 fcm_max_iter: int = 100, warm_start: bool = True, morph_size: int = 3,
                 min_object_area: int = 30, wavelet: str = "haar", wavelet_level: int = 2,
                 significance: float = 0.0, merge_details: bool = True, edge_margin: int = 2,
                 weighted_fit: bool = True, min_axis_ratio: float = 1.05,
                 max_centre_shift: float = 20.0, alpha: float = 2.0,
                 bandwidth_deg: float = 1.0, resolution_deg: float = 0.1,
                 max_shift_px: int = 44, ncc_sigma: float = 1.0, min_ncc: float = 0.3,
                 refine_rotation: bool = True, refine_step_deg: float = 1.5,
                 refine_max_steps: int = 8, refine_candidates: int = 3,
                 refine_iterations: int = 0, refine_trigger_deg: float = 2.0,
                 overlap_passes: int | None = None, min_hole_size: int = 9):
        height, width = reference.shape
        if not (0 <= int(max_shift_px) and 2 * int(max_shift_px) + 8 <= min(height, width)):
            raise ValueError(f"max_shift_px must leave a template of at least 8 x 8 pixels in a "
                             f"{width} x {height} image; got {max_shift_px}")
        if overlap_passes is None:
            overlap_passes = 0 if refine_rotation else 1
        if int(min_hole_size) < 1:
            raise ValueError(f"min_hole_size must be >= 1; got {min_hole_size}")
        if ncc_sigma < 0 or refine_step_deg <= 0 or min(refine_max_steps, refine_candidates,
                                                         refine_iterations, overlap_passes) < 0:
            raise ValueError("need ncc_sigma >= 0, refine_step_deg > 0 and non-negative "
                             "refine_max_steps, refine_candidates, refine_iterations, "
                             "overlap_passes")
        self.seeds = HistogramSeeds(bin_width, min_ratio)
        self.fcm = IT2FCM(m1, m2, fcm_tol, fcm_max_iter)
        self.warm_start = bool(warm_start)
        self.cleaner = LabelCleaner(morph_size, min_object_area)
        self.features = WaveletFeatures(wavelet, wavelet_level, significance, edge_margin,
                                        merge_details)
        self.subbands = self.features.subband_names
        self._detail_sets = np.array([not name.startswith("cA") for name in self.subbands])
        self.weighted_fit = bool(weighted_fit)
        self.min_axis_ratio = float(min_axis_ratio)
        self.max_centre_shift = float(max_centre_shift)
        self.threshold = Type2FuzzyThreshold(alpha, bandwidth_deg, resolution_deg)
        self.max_shift = int(max_shift_px)
        self.ncc_sigma = float(ncc_sigma)
        self.min_ncc = float(min_ncc)
        self.refine_rotation = bool(refine_rotation)
        self.refine_step = float(refine_step_deg)
        self.refine_max_steps = int(refine_max_steps)
        self.refine_candidates = int(refine_candidates)
        self.refine_iterations = int(refine_iterations)
        self.refine_trigger = float(refine_trigger_deg)
        self._hole_kernel = cv2.getStructuringElement(cv2.MORPH_RECT, (int(min_hole_size),) * 2)
        self.overlap_passes = int(overlap_passes)

        self.reference = reference
        self._reference_valid = reference > 0
        smoothed = self._smooth(reference)
        self.template = RotatedTemplate(smoothed, self.max_shift, valid=self._reference_valid)
        # Half resolution (Gaussian pyramid) for choosing among candidate rotations cheaply.
        centre_x, centre_y = image_centre(reference.shape)
        self.coarse_template = RotatedTemplate(cv2.pyrDown(smoothed), self.max_shift // 2,
                                               (centre_x / 2.0, centre_y / 2.0))
        self._reference_analysis = self.analyse(reference)

    def analyse(self, image: np.ndarray, start: np.ndarray | None = None,
                with_fits: bool = True) -> FrameAnalysis:
        """Stages 1-4 on one frame: clusters, labels, objects, ellipse fits.

        ``start``: centres to start IT2-FCM from instead of the histogram seeds, used when the
        histogram gives as many seeds (the cluster count is always the histogram's).
        ``with_fits`` False stops after the labels (see :meth:`with_fits`).
        """
        seeds = self.seeds(image)
        empty = np.zeros(image.shape, np.uint8)
        if np.count_nonzero(seeds.level_counts) < 2:
            return FrameAnalysis(seeds.seeds, empty, np.empty(0, np.int32), np.empty(0), None,
                                 0, True, NO_STRUCTURE)
        far_region = self._has_far_region(image)
        initial = start if start is not None and start.size == seeds.n_clusters else seeds.seeds
        clusters = self.fcm.fit(seeds.level_counts, initial)
        labels, areas = self.cleaner.with_areas(cv2.LUT(image, clusters.level_labels),
                                                clusters.centres.size)
        objects = (np.flatnonzero(areas) + 1).astype(np.int32)
        analysis = FrameAnalysis(clusters.centres, labels, objects, areas[objects - 1], None,
                                 clusters.iterations, clusters.converged,
                                 None if objects.size else NO_STRUCTURE, far_region)
        return self.with_fits(analysis, image) if with_fits else analysis

    def with_fits(self, analysis: FrameAnalysis, image: np.ndarray) -> FrameAnalysis:
        """``analysis`` of ``image`` with the ellipse fits of the whole frame (stages 3-4);
        no valid ellipse at all means no structure."""
        if analysis.status is not None or analysis.fits is not None:
            return analysis
        fits = self._fits(analysis.labels, analysis.objects, image > 0, analysis.far_region,
                          True)
        return replace(analysis, fits=fits, status=None if fits.valid.any() else NO_STRUCTURE)

    def _has_far_region(self, image: np.ndarray) -> bool:
        """Whether the unmeasured pixels hold a ``min_hole_size`` square (a wide region, not
        dropouts or the thin lines of mixed pixels along depth edges)."""
        unmeasured = (image == 0).view(np.uint8)
        return cv2.countNonZero(cv2.erode(unmeasured, self._hole_kernel, borderValue=0)) > 0

    def _fits(self, labels: np.ndarray, objects: np.ndarray, valid: np.ndarray,
              far_region: bool, valid_only: bool = False) -> EllipseFits:
        """Stages 3-4: ellipse fits of the wavelet point sets of ``objects`` within ``valid``
        (``valid_only``: the labels are already 0 outside it). Without ``far_region``, objects
        with no scene edge carry no angle."""
        points = self.features(labels if valid_only else np.where(valid, labels, 0), objects,
                               valid)
        fits = fit_ellipses(points.x, points.y, points.set_id, points.n_sets,
                            self.min_axis_ratio, points.weight if self.weighted_fit else None)
        # An object with no detail point has no outline in the scene (all its edges are the
        # measurement's): its approximation band is only the shape of the measured area, which
        # is a shape of the scene only when that area has a large unmeasured hole.
        per_object = fits.n_points.reshape(objects.size, -1)
        outlined = np.repeat(far_region | (per_object[:, self._detail_sets].sum(axis=1)
                                           >= MIN_POINTS), per_object.shape[1])
        return replace(fits, valid=fits.valid & outlined, oriented=fits.oriented & outlined)

    def estimate(self, current: np.ndarray) -> Motion:
        """Motion of ``current`` relative to the reference (docs/design.md convention)."""
        reference = self._reference_analysis
        # With overlap passes the whole-frame fits of the current frame are only needed if the
        # first pass fails.
        frame = self.analyse(current, reference.centres if self.warm_start else None,
                             with_fits=self.overlap_passes == 0)
        diagnostics = frame.diagnostics()
        if reference.status is not None or frame.status is not None:
            which = "reference" if reference.status is not None else "current"
            return Motion.failed(NO_STRUCTURE, frame=which, **diagnostics)
        image = self._smooth(current)
        motion, n_passes = None, 0
        if self.overlap_passes > 0:
            # Translation first (rotation 0, half resolution), only to know which area both
            # frames see; no estimate until a pass on that area succeeds.
            guess = self.coarse_template.match(cv2.pyrDown(image), 0.0)
            if guess.peak >= self.min_ncc:
                n_passes = self.overlap_passes
                motion = self._overlap_pass(Motion(0.0, 2.0 * guess.x, 2.0 * guess.y),
                                            reference, frame, current, image,
                                            dict(diagnostics, refine_passes=1))
        if motion is None or not motion.ok:
            n_passes = 0
            frame = self.with_fits(frame, current)
            diagnostics["ellipses"] = frame.fits.as_tuples() if frame.fits is not None else []
            if frame.status is not None:
                return Motion.failed(NO_STRUCTURE, frame="current", **diagnostics)
            motion = self._rotation_translation(reference.fits, frame.fits, reference, frame,
                                                image, dict(diagnostics, refine_passes=0))
        extra = self.refine_iterations if self.refine_rotation else 0
        # Further passes: the rest of the overlap passes, then (refined only) up to
        # refine_iterations more while the refined and thresholded rotations disagree.
        for passes in range(min(n_passes, 1) + 1, n_passes + extra + 1):
            if not motion.ok or (passes > n_passes and abs(
                    motion.angle_deg - motion.diagnostics["rotation_by_thresholds"])
                    <= self.refine_trigger):
                break
            restricted = self._overlap_pass(motion, reference, frame, current, image,
                                            dict(diagnostics, refine_passes=passes))
            if not restricted.ok:  # keep the last estimate rather than lose it
                break
            converged = abs(restricted.angle_deg - motion.angle_deg) < self.threshold.resolution
            motion = restricted
            if converged:
                break
        return motion

    def _overlap_pass(self, motion: Motion, reference: FrameAnalysis, frame: FrameAnalysis,
                      current: np.ndarray, image: np.ndarray,
                      diagnostics: dict[str, Any]) -> Motion:
        """Stages 3-6 on the disc of the scene both frames see under ``motion`` (objects cut by
        the image border in one frame would otherwise change shape between them)."""
        in_reference, in_current = self._common_disc(motion)
        ref_fits = self._fits(reference.labels, reference.objects,
                              in_reference & self._reference_valid, reference.far_region)
        cur_fits = self._fits(frame.labels, frame.objects, in_current & (current > 0),
                              frame.far_region)
        diagnostics["ellipses"] = cur_fits.as_tuples()
        return self._rotation_translation(ref_fits, cur_fits, reference, frame, image,
                                          diagnostics, (motion.dx, motion.dy))

    def _common_disc(self, motion: Motion) -> tuple[np.ndarray, np.ndarray]:
        """Masks of one disc of the scene in the reference and in the current frame under
        ``motion``: the largest inside both images, centred half-way along the shift.

        A disc, not the overlap itself: the overlap's straight edges would cut the objects
        along lines whose orientation depends on the motion guessed, and pull the ellipse
        angles toward that guess; a disc cuts alike at any rotation.
        """
        height, width = self.reference.shape
        matrix = motion_matrix(motion, self.reference.shape)
        centre_ref = np.array(image_centre(self.reference.shape)) - np.array(
            [motion.dx, motion.dy]) / 2.0
        centre_cur = matrix[:, :2] @ centre_ref + matrix[:, 2]
        # One pixel in from the images' last pixel centres.
        radius = min(min(c[0], width - 1 - c[0], c[1], height - 1 - c[1])
                     for c in (centre_ref, centre_cur)) - 1.0
        masks = []
        for c in (centre_ref, centre_cur):
            mask = np.zeros(self.reference.shape, np.uint8)
            # Sub-pixel centre and radius (4 fractional bits).
            cv2.circle(mask, (round(c[0] * 16), round(c[1] * 16)), max(int(radius * 16), 0), 1,
                       -1, cv2.LINE_8, 4)
            masks.append(mask.view(bool))
        return masks[0], masks[1]

    def _rotation_translation(self, ref_fits: EllipseFits, cur_fits: EllipseFits,
                              reference: FrameAnalysis, frame: FrameAnalysis,
                              image: np.ndarray, diagnostics: dict[str, Any],
                              near: tuple[float, float] | None = None) -> Motion:
        """Stages 4-6 from the ellipse fits of both frames; adds to ``diagnostics``.

        ``image``: the current frame smoothed for the correlation; ``near``: a previous
        translation to search around (see :meth:`_translation`)."""
        angles, sources = self._angle_estimates(ref_fits, cur_fits, reference, frame)
        diagnostics.update(object_angles=angles, angle_sources=sources, subbands=self.subbands)
        robust = self.threshold(angles)
        diagnostics.update(thresholds=(robust.lower, robust.upper), inliers=robust.inliers,
                           threshold_fallback=robust.fallback,
                           rotation_by_thresholds=robust.value)
        if angles.size == 0:
            return Motion.failed(NO_ROTATION, **diagnostics)
        if self.refine_rotation:
            angle, match = self._refined(angles, robust.value, image, near)
        else:
            angle, match = robust.value, self._translation(robust.value, image, near)
        diagnostics.update(ncc_peak=match.peak, ncc_at_border=match.at_border)
        if not (match.peak >= self.min_ncc):
            return Motion.failed(NO_TRANSLATION, angle_deg=angle, **diagnostics)
        return Motion(angle, match.x, match.y, diagnostics=diagnostics)

    def _angle_estimates(self, ref_fits: EllipseFits, cur_fits: EllipseFits,
                         reference: FrameAnalysis,
                         frame: FrameAnalysis) -> tuple[np.ndarray, np.ndarray]:
        """Angle differences of the same subbands of corresponding objects, and their sources
        (pair by pair, each pair's subbands in order)."""
        pairs = np.array(self._correspondence(reference, frame), np.intp).reshape(-1, 2)
        subbands = np.arange(len(self.subbands))
        ref_sets = pairs[:, :1] * subbands.size + subbands
        cur_sets = pairs[:, 1:] * subbands.size + subbands
        usable = ref_fits.oriented[ref_sets] & cur_fits.oriented[cur_sets]
        angles = axis_angle_difference(ref_fits.angle_deg[ref_sets[usable]],
                                       cur_fits.angle_deg[cur_sets[usable]])
        pair, subband = np.nonzero(usable)
        sources = np.column_stack((reference.objects[pairs[pair, 0]],
                                   frame.objects[pairs[pair, 1]], subband)).astype(np.int32)
        return angles, sources

    def _correspondence(self, reference: FrameAnalysis,
                        frame: FrameAnalysis) -> list[tuple[int, int]]:
        """One-to-one object pairs (indices into ``objects``): nearest centre, then area."""
        ref_centres = reference.centres[reference.objects - 1]
        cur_centres = frame.centres[frame.objects - 1]
        centre_gap = np.abs(ref_centres[:, None] - cur_centres[None, :])
        area_gap = np.abs(np.log(reference.areas[:, None] / frame.areas[None, :]))
        order = np.lexsort((area_gap.ravel(), centre_gap.ravel()))
        pairs, used_ref, used_cur = [], set(), set()
        for flat in order:
            ref_index, cur_index = divmod(int(flat), cur_centres.size)
            if centre_gap[ref_index, cur_index] > self.max_centre_shift:
                break
            if ref_index not in used_ref and cur_index not in used_cur:
                pairs.append((ref_index, cur_index))
                used_ref.add(ref_index)
                used_cur.add(cur_index)
        return pairs

    def _translation(self, angle_deg: float, image: np.ndarray,
                     near: tuple[float, float] | None = None) -> TemplateMatch:
        """FNCC offset of the rotation-compensated reference template in the smoothed current
        frame: near a previous translation if given (the translation hardly depends on the
        rotation about the image centre), the whole range if not or if the peak is at the
        edge of the small search."""
        if near is not None:
            match = self.template.match(image, angle_deg, near, NEAR_RADIUS_PX)
            if not match.at_border:
                return match
        return self.template.match(image, angle_deg)

    def _smooth(self, image: np.ndarray) -> np.ndarray:
        """Float32 copy, Gaussian-smoothed by ``ncc_sigma`` (0: none) for the correlation.

        The smoothing reaches about 2 sigma into invalid (0) areas; the template mask still
        leaves out every pixel that is invalid in the reference.
        """
        image = image.astype(np.float32)
        if self.ncc_sigma > 0:
            image = cv2.GaussianBlur(image, (0, 0), self.ncc_sigma)
        return image

    def _refined(self, angles: np.ndarray, first_guess: float, image: np.ndarray,
                 near: tuple[float, float] | None = None) -> tuple[float, TemplateMatch]:
        """Rotation refined by the FNCC peak, and the match at it.

        The candidates are the thresholded estimate, the mean of each large group of
        agreeing angle estimates and 0; the one whose rotated template correlates best at half
        resolution is climbed in steps of ``refine_step_deg``, at half and then at full
        resolution (searching only near the shift found, or near ``near``), to the local
        maximum of the correlation peak, whose parabolic vertex is the rotation (see
        :meth:`_climb`).
        """
        half = cv2.pyrDown(image)
        candidates = [first_guess]
        # The identity too: when every group of estimates is wrong, no rotation is the
        # likeliest alternative for a camera that stays roughly upright.
        for mean in self._group_means(angles) + [0.0]:
            if min(abs(mean - c) for c in candidates) > self.refine_step:
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
        step = self.refine_step
        below = template.match(image, angle - step, near)
        above = template.match(image, angle + step, near)
        for _ in range(self.refine_max_steps):
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
        groups = np.split(ordered, np.flatnonzero(np.diff(ordered) > 2 * self.refine_step) + 1)
        groups.sort(key=len, reverse=True)
        return [float(g.mean()) for g in groups[:self.refine_candidates]]
