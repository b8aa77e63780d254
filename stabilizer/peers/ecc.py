"""ECC peer (Evangelidis & Psarakis 2008): ``cv2.findTransformECC`` with a Euclidean model.

Area-based alignment that maximises the enhanced correlation coefficient between the reference
(template) and the warped current frame, coarse to fine on a Gaussian pyramid (``cv2.pyrDown``)
built once for the reference. Invalid pixels (0 = no measurement) are masked in both frames
(``cv2.findTransformECCWithMask``: only pixels valid in both count).

ECC's warp W maps template coordinates to input coordinates: input(W x) ~ template(x). With the
reference as template, W is the Motion's reference -> current matrix, but its rotation is about
the pixel origin (0, 0); :func:`stabilizer.motion.motion_from_matrix` re-expresses it about the
image centre. A level-l pyramid image has coordinates x / 2**l, so W's translation scales by
2**-l between levels and its rotation does not.

Both frames are first prepared (:class:`stabilizer.peers.preparation.FramePreparation`): median
filtered, which removes ToF speckle and lowers the noise that caps the correlation, and clipped
to the reference's robust range.

Starts (ECC's basin is only a few pixels at the coarsest level): from
:class:`stabilizer.peers.start_search.StartSearch`, angles ``start_angles_deg`` each with the
shift found by phase correlation after turning the frame back, best phase-correlation response
first; at most ``max_starts`` are run. The search stops at the first result with a final
correlation of at least ``min_correlation``; otherwise the best correlation wins. Parameters and
why: docs/peers.md, "ECC".

Statuses (``Motion.status``) besides ``"ok"``:
    ``empty_reference`` / ``empty_current``: (almost) no valid pixel.
    ``flat_reference`` / ``flat_current``: all valid pixels have one value.
    ``not_converged``: OpenCV raised (no convergence, or too few valid pixels left) from
        every start.
    ``low_correlation``: the best final correlation is below ``min_correlation``.

Diagnostics: ``correlation`` (final ECC value at full resolution), ``levels``, ``starts`` (how
many starts were run), ``start_angle_deg`` (of the winner).
"""

from __future__ import annotations

import math

import cv2
import numpy as np

from stabilizer.inputs import MAX_ITERATIONS, MAX_KERNEL_SIDE, check_integer, check_number
from stabilizer.motion import Motion, motion_from_matrix, motion_matrix
from stabilizer.peers.preparation import FramePreparation, frame_problem, peer_min_side
from stabilizer.peers.start_search import START_ANGLES_DEG, StartSearch

#: Most pyramid levels: the largest frame side accepted (4096, ``stabilizer.api.MAX_SIDE``)
#: halves to one pixel in 12; more levels add only 1-pixel images.
MAX_LEVELS = 12


class EccEstimator:
    """Rigid motion by coarse-to-fine masked ECC, the reference pyramid built once.

    Parameters
    ----------
    reference : (H, W) uint8 ndarray
        Disparity-like reference, 0 = invalid.
    median_ksize : int, optional
        Median filter applied to both frames (0 or 1 = none; odd, at most 255). Default 5.
    levels : int, optional
        Pyramid levels (1 = full resolution only), at most :data:`MAX_LEVELS`. Default 3.
    iterations : int, optional
        Most ECC iterations per level, at most 1000 (:data:`~stabilizer.inputs.MAX_ITERATIONS`).
        Default 50.
    epsilon : float, optional
        ECC stops when the correlation gains less than this. Default 1e-4.
    gauss_filter_size : int, optional
        ECC's Gaussian pre-smoothing kernel (odd, at most 255). Default 5.
    min_correlation : float, optional
        The search over starts ends at the first result with at least this final correlation;
        a best result below it is a failure. Default 0.9, between what correct and wrong
        alignments reach.
    start_angles_deg : tuple of float, optional
        The start angle grid. Default
        :data:`stabilizer.peers.start_search.START_ANGLES_DEG` (-15 to 15 in steps of 5).
    max_starts : int, optional
        Most starts run, best phase-correlation response first. Default 3.
    clip_sigmas : float, optional
        After the median filter, valid values are clipped to the reference's median -+ this
        many spreads (:class:`stabilizer.peers.preparation.FramePreparation`; 0 = no clipping).
        Default 1.5: surfaces beyond the SR4000's range show as bright, noisy columns that
        otherwise dominate the correlation.
    clip_min_spread : float, optional
        The clip range's spread is at least this many gray levels, so that scenes of one flat
        wall keep their depth steps (ECC's gradients need contrast). Default 20.

    References
    ----------
    .. [1] G. D. Evangelidis and E. Z. Psarakis, "Parametric image alignment using enhanced
           correlation coefficient maximization", IEEE Trans. PAMI 30(10), 1858-1865, 2008.
    """

    #: Smallest image side (pixels) whatever the parameters (docs/peers.md, "Image sizes").
    min_side = staticmethod(peer_min_side)

    def __init__(self, reference: np.ndarray, median_ksize: int = 5, levels: int = 3,
                 iterations: int = 50, epsilon: float = 1e-4, gauss_filter_size: int = 5,
                 min_correlation: float = 0.9,
                 start_angles_deg: tuple[float, ...] = START_ANGLES_DEG,
                 max_starts: int = 3, clip_sigmas: float = 1.5, clip_min_spread: float = 20.0):
        check_integer("levels", levels, 1, MAX_LEVELS)
        check_integer("iterations", iterations, 1, MAX_ITERATIONS)
        check_number("epsilon", epsilon, 0.0, open_low=True)
        check_integer("gauss_filter_size", gauss_filter_size, 1, MAX_KERNEL_SIDE)
        if gauss_filter_size % 2 == 0:
            raise ValueError(f"gauss_filter_size must be an odd integer from 1 to "
                             f"{MAX_KERNEL_SIDE}; got {gauss_filter_size}")
        check_number("min_correlation", min_correlation, -1.0, 1.0)
        check_integer("max_starts", max_starts, 1)
        self.levels = levels
        self.criteria = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, iterations, epsilon)
        self.gauss_filter_size = gauss_filter_size
        self.min_correlation = min_correlation
        self._prepare = FramePreparation(reference, median_ksize, clip_sigmas, clip_min_spread)
        self.max_starts = max_starts
        self._shape = reference.shape
        self._reference_problem = frame_problem(reference, "reference")
        reference = self._prepare(reference)
        self._starts = StartSearch(reference, start_angles_deg)
        self._reference_pyramid = self._pyramid(reference)

    def _pyramid(self, image: np.ndarray) -> list[tuple[np.ndarray, np.ndarray]]:
        """(float image, uint8 valid mask) per level, coarsest first.

        A coarse pixel is valid only when the whole footprint of ``pyrDown``'s 5 x 5 kernel was:
        a blend with an invalid 0 is no measurement.
        """
        level_image = image.astype(np.float32)
        level_mask = np.where(image > 0, 255, 0).astype(np.uint8)
        pyramid = [(level_image, level_mask)]
        for _ in range(self.levels - 1):
            level_image = cv2.pyrDown(level_image)
            level_mask = np.where(cv2.pyrDown(level_mask) == 255, 255, 0).astype(np.uint8)
            pyramid.append((level_image, level_mask))
        return pyramid[::-1]

    def estimate(self, current: np.ndarray) -> Motion:
        """Motion of ``current`` (uint8, same shape as the reference) relative to the reference."""
        problem = self._reference_problem or frame_problem(current, "current")
        if problem:
            return Motion.failed(problem)
        current = self._prepare(current)
        pyramid = self._pyramid(current)
        best = None
        for count, (start, _) in enumerate(self._starts.ranked(current)[:self.max_starts],
                                           start=1):
            result = self._align(pyramid, start)
            if result is not None and (best is None or result[1] > best[1]):
                best = (*result, start.angle_deg)
            if best is not None and best[1] >= self.min_correlation:
                break  # a good fit: the remaining starts cannot do meaningfully better
        if best is None:
            return Motion.failed("not_converged", levels=self.levels, starts=count)
        motion, correlation, angle = best
        diagnostics = {"correlation": correlation, "levels": self.levels, "starts": count,
                       "start_angle_deg": angle}
        if correlation < self.min_correlation:
            return Motion.failed("low_correlation", **diagnostics)
        return Motion(motion.angle_deg, motion.dx, motion.dy, diagnostics=diagnostics)

    def _align(self, pyramid: list[tuple[np.ndarray, np.ndarray]],
               start: Motion) -> tuple[Motion, float] | None:
        """ECC from ``start``, coarse to fine; None when OpenCV gives up at some level."""
        warp = motion_matrix(start, self._shape).astype(np.float32)
        warp[:, 2] *= 0.5 ** (self.levels - 1)
        correlation = math.nan
        for level, ((reference, reference_mask), (current, current_mask)) in enumerate(
                zip(self._reference_pyramid, pyramid)):
            if level:
                warp[:, 2] *= 2.0  # one level finer
            try:
                correlation, warp = cv2.findTransformECCWithMask(
                    reference, current, reference_mask, current_mask, warp,
                    cv2.MOTION_EUCLIDEAN, self.criteria, self.gauss_filter_size)
            except cv2.error:
                return None
        return motion_from_matrix(warp, self._shape), float(correlation)
