"""ECC peer (Evangelidis & Psarakis 2008): ``cv2.findTransformECC`` with a Euclidean model.

Area-based alignment that maximises the enhanced correlation coefficient between the reference
(template) and the warped current frame, coarse to fine on a Gaussian pyramid (``cv2.pyrDown``)
built once for the reference. Invalid pixels (0 = no measurement) are masked in both frames
(``cv2.findTransformECCWithMask``: only pixels valid in both count).

ECC's warp W maps template coordinates to input coordinates: input(W x) ~ template(x). With the
reference as template, W is the Motion's reference -> current matrix, but its rotation is about
the pixel origin (0, 0); :func:`stabilizer.peers.common.motion_from_matrix` re-expresses it about
the image centre. A level-l pyramid image has coordinates x / 2**l, so W's translation scales by
2**-l between levels and its rotation does not.

Starts (ECC's basin is only a few pixels at the coarsest level): the translation from windowed
phase correlation, then zero translation, each with the angles ``start_angles_deg`` (default 0,
-10, +10 degrees), in that order (:func:`stabilizer.peers.common.coarse_starts`). The search
stops at the first result with a final correlation of at least ``min_correlation``; otherwise
the best correlation wins.

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

from stabilizer.motion import Motion, motion_matrix
from stabilizer.peers.common import (coarse_starts, frame_problem, motion_from_matrix,
                                     zero_mean_float)


class EccEstimator:
    """Rigid motion by coarse-to-fine masked ECC, reference pyramid built once.

    Args:
        reference: uint8 disparity-like image (0 = invalid).
        levels: pyramid levels (1 = full resolution only). Default 3.
        iterations: most ECC iterations per level. Default 50.
        epsilon: ECC stops when the correlation gains less than this. Default 1e-4.
        gauss_filter_size: ECC's Gaussian pre-smoothing kernel (odd). Default 5.
        min_correlation: the search over starts ends at the first result with at least this
            final correlation; a best result below it is a failure. Default 0.9.
        start_angles_deg: start angles, each with the two start translations. Default
            (0, -10, 10).
    """

    def __init__(self, reference: np.ndarray, levels: int = 3, iterations: int = 50,
                 epsilon: float = 1e-4, gauss_filter_size: int = 5,
                 min_correlation: float = 0.9,
                 start_angles_deg: tuple[float, ...] = (0.0, -10.0, 10.0)):
        if levels < 1 or iterations < 1:
            raise ValueError(f"need levels >= 1 and iterations >= 1; got {levels}, {iterations}")
        if gauss_filter_size < 1 or gauss_filter_size % 2 == 0:
            raise ValueError(f"gauss_filter_size must be a positive odd integer; "
                             f"got {gauss_filter_size}")
        self.levels = levels
        self.criteria = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, iterations, epsilon)
        self.gauss_filter_size = gauss_filter_size
        self.min_correlation = min_correlation
        if not start_angles_deg:
            raise ValueError("start_angles_deg must hold at least one angle")
        self.start_angles_deg = tuple(start_angles_deg)
        self._shape = reference.shape
        self._window = cv2.createHanningWindow(reference.shape[::-1], cv2.CV_32F)
        self._reference_problem = frame_problem(reference, "reference")
        self._reference_float = zero_mean_float(reference)
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
        problem = self._reference_problem or frame_problem(current, "current")
        if problem:
            return Motion.failed(problem)
        pyramid = self._pyramid(current)
        starts = coarse_starts(self._reference_float, zero_mean_float(current), self._window,
                               self.start_angles_deg)
        best = None
        for count, start in enumerate(starts, start=1):
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
