"""The paper's motion estimator: Kang, Zhang & Park (2009), "Stereo-vision based motion
stabilization of a humanoid robot for the environment recognition by type-2 fuzzy logic".

:class:`T2FuzzyEstimator` runs the paper's stages in the paper's order (docs/method.md,
sections 1-7), each a call into its own module:

1. cluster count and seeds from the histogram peaks (:mod:`stabilizer.histogram_seeds`);
2. IT2-FCM on the valid gray levels, eqs. (1)-(5), hard labels and morphological clean-up
   (:mod:`stabilizer.it2fcm`);
3. two-level wavelet point sets of every object, Fig. 5 (:mod:`stabilizer.wavelet_features`);
4. direct least-squares ellipse of every point set, Fig. 6 (:mod:`stabilizer.ellipse`); the
   angle differences of the same subbands of corresponding objects (:func:`match_objects`) are
   the rotation estimates;
5. type-2 fuzzy thresholds cut the left and right outliers, eq. (6) and Fig. 7; the rotation is
   the mean of the estimates between them (:mod:`stabilizer.t2_threshold`);
6. rotation compensation, then the translation by FNCC, eq. (7) (:mod:`stabilizer.fncc`).

The parameters come in one frozen group per part of the pipeline: :class:`SegmentationParams`
(stages 1-2), :class:`FeatureParams` (3-4), :class:`ThresholdParams` (5),
:class:`TranslationParams` (6), and
:class:`~stabilizer.t2fuzzy_refinements.Refinements`, the steps ``t2fuzzy`` adds to the
paper's pipeline (:mod:`stabilizer.t2fuzzy_refinements`). ``Refinements.off()`` is the paper's
pipeline as written, the ``t2fuzzy_paper`` method.

Statuses of a Motion that carries no estimate (``Motion.failed``):

- ``"no_structure"``: the reference or the current frame has no valid pixel, a single valid
  gray level, no segmented object, or no object whose outline is in the scene (see
  :class:`FeatureParams`); ``diagnostics["frame"]`` says which frame;
- ``"no_rotation_estimate"``: no matched object subband has an orientable ellipse in both
  frames (with the refinement ``search_without_estimates``, the default of ``t2fuzzy``, such a
  frame is searched from rotation 0 instead);
- ``"no_translation_estimate"``: the correlation is undefined (flat template or image) or its
  peak is below ``min_ncc``;
- ``"rotation_unconverged"`` (refinement ``fail_unconverged``): the rotation search ended
  without a local maximum of the correlation; the estimate it stopped at is in
  ``diagnostics["unconverged_motion"]``;
- ``"translation_disagreement"`` (refinement ``max_shift_disagreement_px``): the shift of the
  central template and the best shift of the whole overlap (``wide_shift``) differ by more than
  that; the estimate is in ``diagnostics["disagreeing_motion"]``.

With the refinement ``resolve_disagreement`` (the default of ``t2fuzzy``) the last two are
failures only when climbs on the whole overlap cannot settle the motion; a settled frame keeps
the doubtful estimate in the same diagnostic.

Diagnostics of every Motion: ``n_clusters``, ``centres`` (gray levels), ``labels`` (H x W int32
label image of the current frame; 0 = invalid or unlabelled, 1..C), ``object_angles`` (the
rotation estimates of stage 4, degrees), ``angle_sources`` (one row (reference label, current
label, subband index) per estimate; subband names in ``subbands``), ``thresholds`` (lower,
upper), ``inliers`` (mask over ``object_angles``), ``threshold_fallback`` (None or
``"median"``), ``rotation_by_thresholds`` (the rotation of stage 5, before any rotation
search), ``ncc_peak``, ``ncc_at_border``, with the rotation search ``search_converged`` and
``wide_shift`` (the wide search's best (dx, dy), None when it did not run), ``astray_climb``
(only when the search's climb went astray and was replaced: the (angle, dx, dy) it ended at;
refinement ``astray_climb_recovery``), ``refine_passes`` (common-disc passes run; 0: the
whole frames), ``ellipses`` (the current frame's fitted ellipses, on the common disc after a
disc pass, as (cx, cy, half_major, half_minor, angle_deg) in image pixels, the angle of the
major axis from +x toward +y), ``fcm_iterations`` and ``fcm_converged``. Keys not reached before
a failure are absent; after several disc passes the angle keys describe the last one.

References:
    T.-K. Kang, H. Zhang and G.-T. Park, "Stereo-vision based motion stabilization of a
    humanoid robot for the environment recognition by type-2 fuzzy logic", 17th Mediterranean
    Conference on Control & Automation, 2009, pp. 772-777. Measured accuracy, and how to
    regenerate it: docs/method.md, section 10.
"""

from __future__ import annotations

import math
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
from stabilizer.fncc import RotatedTemplate, TemplateMatch
from stabilizer.histogram_seeds import HistogramSeeds
from stabilizer.inputs import (
    MAX_ITERATIONS,
    MAX_KERNEL_SIDE,
    MAX_SIGMA_PX,
    check_flag,
    check_integer,
    check_number,
)
from stabilizer.it2fcm import IT2FCM, LabelCleaner
from stabilizer.motion import Motion
from stabilizer.peers.preparation import clipped, robust_value_range
from stabilizer.t2_threshold import MAX_BANDWIDTH_DEG, MIN_RESOLUTION_DEG, Type2FuzzyThreshold
from stabilizer.t2fuzzy_refinements import (
    Refinements,
    RotationSearch,
    WideSearch,
    common_disc,
    half_resolution_template,
    translation_guess,
)
from stabilizer.wavelet_features import MAX_EDGE_MARGIN, MAX_LEVEL, WaveletFeatures

NO_STRUCTURE = "no_structure"
NO_ROTATION = "no_rotation_estimate"
NO_TRANSLATION = "no_translation_estimate"
ROTATION_UNCONVERGED = "rotation_unconverged"
TRANSLATION_DISAGREEMENT = "translation_disagreement"
#: Half-width (pixels) of the translation search around a previous translation; a peak on its
#: edge falls back to the whole range.
NEAR_RADIUS_PX = 4
#: Smallest side (pixels) of the correlation template of stage 6.
TEMPLATE_MIN_SIDE = 8


@dataclass(frozen=True)
class SegmentationParams:
    """Stages 1-2: cluster count and seeds, IT2-FCM, clean-up (docs/method.md, sections 1-2).

    Attributes:
        bin_width: histogram bin width for the cluster count, gray levels; paper: 20.
        min_ratio: fraction of the valid pixels a histogram peak must exceed; paper: 2%.
        m1, m2: IT2-FCM fuzzifiers of eqs. (2)-(3); the paper gives none. Default 2 and 5.
        fcm_tol: IT2-FCM stops when no centre moves more than this many gray levels; default
            0.01, far below the one-level resolution of the labels.
        fcm_max_iter: most IT2-FCM iterations, at most 1000
            (:data:`~stabilizer.inputs.MAX_ITERATIONS`); default 100.
        warm_start: start the current frame's IT2-FCM from the reference's centres when its
            histogram gives as many seeds (the same scene converges in a few iterations);
            default True.
        morph_size: side of the square of the morphological opening and closing, odd, at
            most 255 (:data:`~stabilizer.inputs.MAX_KERNEL_SIDE`); the paper gives none.
            Default 3.
        min_object_area: objects with fewer pixels after the clean-up are dropped; default 30.
    """

    bin_width: int = 20
    min_ratio: float = 0.02
    m1: float = 2.0
    m2: float = 5.0
    fcm_tol: float = 1e-2
    fcm_max_iter: int = 100
    warm_start: bool = True
    morph_size: int = 3
    min_object_area: int = 30

    def __post_init__(self):
        check_integer("bin_width", self.bin_width, 1, 255)
        check_number("min_ratio", self.min_ratio, 0.0, 1.0, open_high=True)
        check_number("m1", self.m1, 1.0, open_low=True)
        check_number("m2", self.m2, self.m1, open_low=True)  # eqs. (2)-(3): 1 < m1 < m2
        check_number("fcm_tol", self.fcm_tol, 0.0, open_low=True)
        check_integer("fcm_max_iter", self.fcm_max_iter, 1, MAX_ITERATIONS)
        check_flag("warm_start", self.warm_start)
        check_integer("morph_size", self.morph_size, 1, MAX_KERNEL_SIDE)
        if self.morph_size % 2 == 0:
            raise ValueError(f"morph_size must be odd; got {self.morph_size}")
        check_integer("min_object_area", self.min_object_area, 0)


@dataclass(frozen=True)
class FeatureParams:
    """Stages 3-4: wavelet point sets, their ellipses, object correspondence (docs/method.md,
    sections 3-4).

    Every segmented object is one object, and one is enough: its subband point sets give
    angles. An object none of whose detail points survives ``edge_margin`` has no outline in the
    scene (all its edges are the measurement's: invalid pixels or the image border), and its
    approximation band is only the shape of the measured area, so its point sets carry no
    angle; unless the frame has a far region, an unmeasured area holding a ``min_hole_size``
    square (the out-of-range end of a corridor, not dropouts or the thin lines of mixed pixels),
    which moves with the scene and gives the measured area a shape.

    Attributes:
        wavelet: PyWavelets wavelet; default ``"haar"``.
        wavelet_level: decomposition levels; paper: 2.
        significance: fraction of a subband's largest coefficient magnitude that makes a
            coefficient a feature point; default 0 (every non-zero coefficient).
        merge_details: one point set per level for the three detail subbands (see
            :mod:`stabilizer.wavelet_features`) rather than one per subband; default True.
        edge_margin: detail points this close (pixels) to invalid pixels or the image border
            are not scene edges and are dropped; default 2.
        min_hole_size: side (pixels) of the square an unmeasured region must hold to be a far
            region of the scene; default 9.
        weighted_fit: weight each point of the ellipse fit by its coefficient's magnitude (for
            the LL band: the fraction of the block the object covers); default True.
        min_axis_ratio: ellipses rounder than this (major / minor) carry no angle; default 1.05.
        max_centre_shift: largest cluster-centre difference (gray levels) of matched objects;
            default 20.
    """

    wavelet: str = "haar"
    wavelet_level: int = 2
    significance: float = 0.0
    merge_details: bool = True
    edge_margin: int = 2
    min_hole_size: int = 9
    weighted_fit: bool = True
    min_axis_ratio: float = 1.05
    max_centre_shift: float = 20.0

    def __post_init__(self):
        if not isinstance(self.wavelet, str):
            raise ValueError(f"wavelet must be the name of a discrete PyWavelets wavelet; got "
                             f"{self.wavelet!r}")
        check_integer("wavelet_level", self.wavelet_level, 1, MAX_LEVEL)
        check_number("significance", self.significance, 0.0, 1.0, open_high=True)
        check_flag("merge_details", self.merge_details)
        check_integer("edge_margin", self.edge_margin, 0, MAX_EDGE_MARGIN)
        check_integer("min_hole_size", self.min_hole_size, 1, 1000)
        check_flag("weighted_fit", self.weighted_fit)
        check_number("min_axis_ratio", self.min_axis_ratio, 1.0)
        check_number("max_centre_shift", self.max_centre_shift, 0.0)


@dataclass(frozen=True)
class ThresholdParams:
    """Stage 5: the type-2 fuzzy thresholds of the angle estimates (docs/method.md, section 5).

    Attributes:
        alpha: exponent of the footprint of uncertainty, in (1, 2]; paper eq. (6). Default 2.
        bandwidth_deg: half-width of the triangular membership function, at most 90 degrees
            (:data:`~stabilizer.t2_threshold.MAX_BANDWIDTH_DEG`); default 1 degree.
        resolution_deg: histogram step of the angle estimates, at least 0.01 degree
            (:data:`~stabilizer.t2_threshold.MIN_RESOLUTION_DEG`); default 0.1 degree.
    """

    alpha: float = 2.0
    bandwidth_deg: float = 1.0
    resolution_deg: float = 0.1

    def __post_init__(self):
        check_number("alpha", self.alpha, 1.0, 2.0, open_low=True)
        check_number("bandwidth_deg", self.bandwidth_deg, 0.0, MAX_BANDWIDTH_DEG, open_low=True)
        check_number("resolution_deg", self.resolution_deg, MIN_RESOLUTION_DEG)


@dataclass(frozen=True)
class TranslationParams:
    """Stage 6: FNCC of the rotation-compensated reference (docs/method.md, section 6).

    Attributes:
        max_shift_px: translation search range; the template is the reference's central region
            this far in from every side (the paper gives no template size). Default 44 (a
            quarter of the SR4000's 176-pixel width); it must leave a template of at least
            8 x 8 pixels, so with the default the frames need at least 96 pixels per side.
        ncc_sigma: Gaussian smoothing (pixels) of both frames before the correlation, which
            makes its peak a smooth function of the motion; 0: none; at most 40
            (:data:`~stabilizer.inputs.MAX_SIGMA_PX`). Default 1.
        min_ncc: a correlation peak below this gives ``"no_translation_estimate"``; default 0.3.
    """

    max_shift_px: int = 44
    ncc_sigma: float = 1.0
    min_ncc: float = 0.3

    def __post_init__(self):
        check_integer("max_shift_px", self.max_shift_px, 0)
        check_number("ncc_sigma", self.ncc_sigma, 0.0, MAX_SIGMA_PX)
        check_number("min_ncc", self.min_ncc)  # above 1: no peak is accepted


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
        far_region: the frame has an unmeasured region of at least a ``min_hole_size`` square,
            whose outline gives the objects bordering it a shape (see :class:`FeatureParams`).
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


def match_objects(reference: FrameAnalysis, frame: FrameAnalysis,
                  max_centre_shift: float) -> list[tuple[int, int]]:
    """One-to-one pairs of reference and current objects (indices into ``objects``).

    Pairs are ranked by the difference of their cluster centres (gray levels), then by the log
    ratio of their areas, and taken greedily; objects whose centres differ by more than
    ``max_centre_shift`` levels are not matched (docs/method.md, section 4).
    """
    ref_centres = reference.centres[reference.objects - 1]
    cur_centres = frame.centres[frame.objects - 1]
    centre_gap = np.abs(ref_centres[:, None] - cur_centres[None, :])
    area_gap = np.abs(np.log(reference.areas[:, None] / frame.areas[None, :]))
    order = np.lexsort((area_gap.ravel(), centre_gap.ravel()))
    pairs, used_ref, used_cur = [], set(), set()
    for flat in order:
        ref_index, cur_index = divmod(int(flat), cur_centres.size)
        if centre_gap[ref_index, cur_index] > max_centre_shift:
            break
        if ref_index not in used_ref and cur_index not in used_cur:
            pairs.append((ref_index, cur_index))
            used_ref.add(ref_index)
            used_cur.add(cur_index)
    return pairs


def _check_parameter_classes(**params: Any) -> None:
    """TypeError naming the first of ``params`` that is unknown or not an instance of its
    class."""
    classes = {"segmentation": SegmentationParams, "features": FeatureParams,
               "threshold": ThresholdParams, "translation": TranslationParams,
               "refinements": Refinements}
    for name, value in params.items():
        expected = classes.get(name)
        if expected is None:
            raise TypeError(f"t2fuzzy has no parameter {name!r}; accepted: "
                             f"{', '.join(classes)}")
        if not isinstance(value, expected):
            raise TypeError(f"{name} must be a {expected.__name__} "
                             f"({expected.__module__}); got {value!r}")


class T2FuzzyEstimator:
    """Kang, Zhang & Park (2009) motion estimator against a reference analysed once.

    Args:
        reference: uint8 disparity-like image (0 = no measurement), validated by the caller.
        segmentation: stages 1-2 (:class:`SegmentationParams`).
        features: stages 3-4 (:class:`FeatureParams`).
        threshold: stage 5 (:class:`ThresholdParams`).
        translation: stage 6 (:class:`TranslationParams`).
        refinements: the steps added to the paper's pipeline
            (:class:`~stabilizer.t2fuzzy_refinements.Refinements`); ``Refinements.off()`` for
            the paper's pipeline as written.

    Each default is the ``t2fuzzy`` method's, and the paper's value where the paper gives one.
    :meth:`estimate` returns the :class:`~stabilizer.motion.Motion` of a current frame (see
    the module docstring for its statuses and diagnostics).
    """

    def __init__(self, reference: np.ndarray, *,
                 segmentation: SegmentationParams = SegmentationParams(),
                 features: FeatureParams = FeatureParams(),
                 threshold: ThresholdParams = ThresholdParams(),
                 translation: TranslationParams = TranslationParams(),
                 refinements: Refinements = Refinements()):
        height, width = reference.shape
        if self.min_side(translation, segmentation=segmentation, features=features,
                         threshold=threshold, refinements=refinements) > min(height, width):
            raise ValueError(f"max_shift_px must leave a template of at least 8 x 8 pixels in a "
                             f"{width} x {height} image; got {translation.max_shift_px}")
        # Stages 1-2.
        self.seeds = HistogramSeeds(segmentation.bin_width, segmentation.min_ratio)
        self.fcm = IT2FCM(segmentation.m1, segmentation.m2, segmentation.fcm_tol,
                          segmentation.fcm_max_iter)
        self.warm_start = bool(segmentation.warm_start)
        self.cleaner = LabelCleaner(segmentation.morph_size, segmentation.min_object_area)
        # Stages 3-4.
        self.wavelets = WaveletFeatures(features.wavelet, features.wavelet_level,
                                        features.significance, features.edge_margin,
                                        features.merge_details)
        self.subbands = self.wavelets.subband_names
        self._detail_sets = np.array([not name.startswith("cA") for name in self.subbands])
        self._hole_kernel = cv2.getStructuringElement(cv2.MORPH_RECT,
                                                      (int(features.min_hole_size),) * 2)
        self.weighted_fit = bool(features.weighted_fit)
        self.min_axis_ratio = float(features.min_axis_ratio)
        self.max_centre_shift = float(features.max_centre_shift)
        # Stage 5.
        self.threshold = Type2FuzzyThreshold(threshold.alpha, threshold.bandwidth_deg,
                                             threshold.resolution_deg)
        # Stage 6.
        self.ncc_sigma = float(translation.ncc_sigma)
        self.min_ncc = float(translation.min_ncc)
        self.reference = reference
        self._reference_valid = reference > 0
        self._value_range = (robust_value_range(reference, refinements.clip_sigmas,
                                                min_spread=refinements.clip_min_spread)
                             if refinements.clip_sigmas > 0 else None)
        smoothed = self._smooth(reference)
        self.template = RotatedTemplate(smoothed, translation.max_shift_px,
                                        valid=self._reference_valid)
        # Refinements.
        self.refinements = refinements
        self.coarse_template = (half_resolution_template(smoothed, translation.max_shift_px)
                                if refinements.needs_coarse_template else None)
        wide = (WideSearch(smoothed, self._reference_valid, refinements.wide_search_px,
                           refinements.wide_min_overlap)
                if refinements.rotation_search and refinements.wide_search_px > 0 else None)
        self.rotation_search = (RotationSearch(self.template, self.coarse_template, refinements,
                                               wide, reference)
                                if refinements.rotation_search else None)
        self.search_without_estimates = (refinements.rotation_search
                                         and refinements.search_without_estimates)
        self.doubtful_offset = float(refinements.doubtful_offset_deg)
        self.climb_from_optimum = bool(refinements.climb_from_optimum)

        self._reference_analysis = self.analyse(reference)

    @staticmethod
    def min_side(translation: TranslationParams = TranslationParams(), **other: Any) -> int:
        """Smallest image side (pixels) with these parameters: the translation search takes
        ``max_shift_px`` from every side and must leave a template of at least 8 x 8 pixels,
        so 2 * ``max_shift_px`` + 8 (96 with the default 44; docs/method.md, section 9).
        TypeError when a parameter is unknown or not of its class (asked first: before any
        work)."""
        _check_parameter_classes(translation=translation, **other)
        return 2 * translation.max_shift_px + TEMPLATE_MIN_SIDE

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
        points = self.wavelets(labels if valid_only else np.where(valid, labels, 0), objects,
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
        disc_passes = self.refinements.common_disc_passes
        # Stages 1-2 (and 3-4 unless a common-disc pass comes first: the whole-frame fits of
        # the current frame are then only needed if that pass fails).
        frame = self.analyse(current, reference.centres if self.warm_start else None,
                             with_fits=disc_passes == 0)
        diagnostics = frame.diagnostics()
        if reference.status is not None or frame.status is not None:
            which = "reference" if reference.status is not None else "current"
            return Motion.failed(NO_STRUCTURE, frame=which, **diagnostics)
        image = self._smooth(current)
        motion, n_passes = None, 0
        if disc_passes > 0:  # refinement: stages 3-6 on a disc both frames see
            guess = translation_guess(self.coarse_template, image, self.min_ncc)
            if guess is not None:
                n_passes = disc_passes
                motion = self._common_disc_pass(guess, reference, frame, current, image,
                                                dict(diagnostics, refine_passes=1))
        if motion is None or not motion.ok:  # stages 3-6 on the whole frames
            n_passes = 0
            frame = self.with_fits(frame, current)
            diagnostics["ellipses"] = frame.fits.as_tuples() if frame.fits is not None else []
            if frame.status is not None:
                return Motion.failed(NO_STRUCTURE, frame="current", **diagnostics)
            motion = self._rotation_translation(reference.fits, frame.fits, reference, frame,
                                                image, dict(diagnostics, refine_passes=0),
                                                current=current)
        # Refinement: the rest of the common-disc passes, then (with the rotation search) up to
        # extra_disc_passes more while the searched and thresholded rotations disagree.
        extra = self.refinements.extra_disc_passes if self.rotation_search is not None else 0
        trigger = float(self.refinements.extra_pass_trigger_deg)
        for passes in range(min(n_passes, 1) + 1, n_passes + extra + 1):
            if not motion.ok or (passes > n_passes and abs(
                    motion.angle_deg - motion.diagnostics["rotation_by_thresholds"])
                    <= trigger):
                break
            restricted = self._common_disc_pass(motion, reference, frame, current, image,
                                                dict(diagnostics, refine_passes=passes))
            if not restricted.ok:  # keep the last estimate rather than lose it
                break
            converged = abs(restricted.angle_deg - motion.angle_deg) < self.threshold.resolution
            motion = restricted
            if converged:
                break
        return motion

    def second_look(self, current: np.ndarray, checked: Motion) -> Motion | None:
        """A new estimate of ``current`` where the trust check doubts the first, or None
        (refinements ``doubtful_offset_deg`` and ``climb_from_optimum``).

        ``checked`` is this estimator's estimate of ``current`` after the trust check
        (:meth:`stabilizer.verification.Verifier.check`). When it passed but the check's optimum
        lies more than ``doubtful_offset_deg`` from it in rotation (``verify_offset_deg``), the
        estimate is climbed over rotation on the masked FNCC of the whole overlap at full
        resolution (:meth:`RotationSearch.climb_on_overlap`): every pixel both frames measure
        then fixes the motion, not only the central template's, whose peak may lie a few degrees
        off. When the check rejected it as ``"not_optimum"`` (its optimum, ``verify_optimum``,
        beyond the check's offset limits) and ``climb_from_optimum`` is on, the same climb starts
        from that optimum. The climb's end is the new estimate, with the first one's own
        diagnostics (not the check's), its ``ncc_peak`` and ``ncc_at_border`` and
        ``second_look_from`` (the motion it started from). None otherwise, when the climb finds
        no maximum or its peak is below ``min_ncc``, and without the wide search.
        :class:`stabilizer.Stabilizer` checks the new estimate and keeps it if it passes and,
        after a first estimate that passed, lines up the frames' depth edges at least as well
        (docs/method.md, section 12, "A second look" and "A second look from the check's
        optimum").
        """
        if self.rotation_search is None or self.rotation_search.wide is None:
            return None
        diagnostics = checked.diagnostics
        if checked.ok:
            offset = diagnostics.get("verify_offset_deg")
            if offset is None or not offset > self.doubtful_offset:
                return None
            start = checked.as_tuple()
        elif self.climb_from_optimum and diagnostics.get("verify_failed") == "not_optimum":
            start = tuple(diagnostics["verify_optimum"])
        else:
            return None
        climbed = self.rotation_search.climb_on_overlap(start[0], (start[1], start[2]),
                                                        self._smooth(current), current > 0)
        if climbed is None or not climbed[1].peak >= self.min_ncc:
            return None
        angle, top = climbed
        kept = {key: value for key, value in diagnostics.items()
                if not key.startswith("verify_") and key != "unverified_motion"}
        return Motion(angle, top.x, top.y, diagnostics=dict(
            kept, ncc_peak=top.peak, ncc_at_border=top.at_border, second_look_from=start))

    def _common_disc_pass(self, motion: Motion, reference: FrameAnalysis, frame: FrameAnalysis,
                          current: np.ndarray, image: np.ndarray,
                          diagnostics: dict[str, Any]) -> Motion:
        """Stages 3-6 on the disc of the scene both frames see under ``motion``
        (:func:`~stabilizer.t2fuzzy_refinements.common_disc`)."""
        in_reference, in_current = common_disc(motion, self.reference.shape)
        ref_fits = self._fits(reference.labels, reference.objects,
                              in_reference & self._reference_valid, reference.far_region)
        cur_fits = self._fits(frame.labels, frame.objects, in_current & (current > 0),
                              frame.far_region)
        diagnostics["ellipses"] = cur_fits.as_tuples()
        return self._rotation_translation(ref_fits, cur_fits, reference, frame, image,
                                          diagnostics, (motion.dx, motion.dy))

    def _rotation_translation(self, ref_fits: EllipseFits, cur_fits: EllipseFits,
                              reference: FrameAnalysis, frame: FrameAnalysis,
                              image: np.ndarray, diagnostics: dict[str, Any],
                              near: tuple[float, float] | None = None,
                              current: np.ndarray | None = None) -> Motion:
        """Stages 4-6 from the ellipse fits of both frames; adds to ``diagnostics``.

        ``image``: the current frame smoothed for the correlation; ``near``: a previous
        translation to search around (see :meth:`_translation`); ``current``: the current
        frame itself, for the wide search and the settling of disagreements of the
        refinements."""
        valid = None if current is None else current > 0
        angles, sources = self._angle_estimates(ref_fits, cur_fits, reference, frame)
        diagnostics.update(object_angles=angles, angle_sources=sources,
                           subbands=list(self.subbands))  # the caller may change it
        robust = self.threshold(angles)
        diagnostics.update(thresholds=(robust.lower, robust.upper), inliers=robust.inliers,
                           threshold_fallback=robust.fallback,
                           rotation_by_thresholds=robust.value)
        if angles.size == 0 and not self.search_without_estimates:
            return Motion.failed(NO_ROTATION, **diagnostics)
        if self.rotation_search is not None:  # refinement
            start = robust.value if angles.size else 0.0
            angle, match, converged = self.rotation_search(angles, start, image, near, valid)
            diagnostics.update(search_converged=converged,
                               wide_shift=self.rotation_search.wide_shift)
            if self.rotation_search.astray_climb is not None:
                diagnostics["astray_climb"] = self.rotation_search.astray_climb
        else:
            angle, match = robust.value, self._translation(robust.value, image, near)
            converged = True
        diagnostics.update(ncc_peak=match.peak, ncc_at_border=match.at_border)
        if not (match.peak >= self.min_ncc):
            return Motion.failed(NO_TRANSLATION, angle_deg=angle, **diagnostics)
        wide_shift = diagnostics.get("wide_shift")
        limit = self.refinements.max_shift_disagreement_px
        if not converged and self.refinements.fail_unconverged:
            status, record = ROTATION_UNCONVERGED, "unconverged_motion"
        elif (wide_shift is not None and limit > 0
                and math.hypot(match.x - wide_shift[0], match.y - wide_shift[1]) > limit):
            status, record = TRANSLATION_DISAGREEMENT, "disagreeing_motion"
        else:
            return Motion(angle, match.x, match.y, diagnostics=diagnostics)
        # Refinement: a doubtful search settled on the whole overlap, or a failure.
        diagnostics[record] = (angle, match.x, match.y)
        resolved = (self.rotation_search.resolve_disagreement(angle, match, image, current)
                    if self.refinements.resolve_disagreement and current is not None else None)
        if resolved is None:
            return Motion.failed(status, **diagnostics)
        angle, match = resolved
        return Motion(angle, match.x, match.y, diagnostics=diagnostics)

    def _angle_estimates(self, ref_fits: EllipseFits, cur_fits: EllipseFits,
                         reference: FrameAnalysis,
                         frame: FrameAnalysis) -> tuple[np.ndarray, np.ndarray]:
        """Angle differences of the same subbands of corresponding objects, and their sources
        (pair by pair, each pair's subbands in order)."""
        pairs = np.array(match_objects(reference, frame, self.max_centre_shift),
                         np.intp).reshape(-1, 2)
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

    def _translation(self, angle_deg: float, image: np.ndarray,
                     near: tuple[float, float] | None = None) -> TemplateMatch:
        """Stage 6: FNCC offset of the reference template rotated by ``angle_deg`` in the
        smoothed current frame.

        The current frame is the reference rotated about the image centre, then shifted:
        rotating the reference by the estimated angle leaves only the shift, so the offset of
        its central region in the current frame is (dx, dy) directly. With ``near`` (a previous
        translation) only its neighbourhood is searched (the translation hardly depends on the
        rotation about the image centre), the whole range if the peak is at its edge.
        """
        if near is not None:
            match = self.template.match(image, angle_deg, near, NEAR_RADIUS_PX)
            if not match.at_border:
                return match
        return self.template.match(image, angle_deg)

    def _smooth(self, image: np.ndarray) -> np.ndarray:
        """Float32 copy for the correlation: clipped to the reference's robust range
        (``Refinements.clip_sigmas``), then Gaussian-smoothed by ``ncc_sigma`` (0: none).

        The smoothing reaches about 2 sigma into invalid (0) areas; the template mask still
        leaves out every pixel that is invalid in the reference.
        """
        image = clipped(image, self._value_range).astype(np.float32)
        if self.ncc_sigma > 0:
            image = cv2.GaussianBlur(image, (0, 0), self.ncc_sigma)
        return image
