"""Fourier-Mellin peer (Reddy & Chatterji 1996): rotation from the log-polar magnitude spectrum,
translation by phase correlation.

The magnitude of an image's Fourier transform does not change when the image shifts and turns
with it when the image turns, so in log-polar coordinates of the (centred) magnitude spectrum a
rotation becomes a shift along the angle axis, found by phase correlation
(``cv2.phaseCorrelate``). Scale would be the shift along the log-radius axis; the model here is
rigid, so it is reported in the diagnostics and not used.

Details (why each: docs/peers.md, "Fourier-Mellin"):
- Both frames' valid values are clipped to the reference's robust range, median -+
  ``clip_sigmas`` spreads (:class:`stabilizer.peers.preparation.FramePreparation`): surfaces
  beyond the SR4000's range come back phase-wrapped as bright, noisy, speckled columns whose
  noise would fill the spectrum. No median filter by default: it removes detail the spectrum
  needs.
- Invalid pixels (0 = no measurement) are set to the mean of the valid ones
  (:func:`stabilizer.peers.preparation.zero_mean_float`), so the step to no measurement adds no
  structure; a Hanning window (``cv2.createHanningWindow``) removes the image border's.
- The windowed image is zero-padded to a square of DFT-friendly size, so that a rotation of the
  image is a rotation of the spectrum's sample grid too.
- The magnitude (not its logarithm) is weighted by Reddy & Chatterji's high-pass filter
  (1 - X)(2 - X), X = cos(pi u) cos(pi v), which suppresses the low frequencies where the
  window dominates, and resampled by ``cv2.warpPolar`` with ``WARP_POLAR_LOG``.
- The log-polar image is tapered along the log-radius axis by a Hann window before phase
  correlation: phase correlation treats both axes as periodic, and the angle axis is, but the
  log-radius axis is not; the taper also lowers the weight of the highest frequencies, where ToF
  noise lives.
- A magnitude spectrum is symmetric under a half turn, so the angle a and a + 180 degrees both
  fit; the current frame is turned back by each and the translation found by phase correlation
  (turning back about the image centre leaves the shift t' = R(a)^-1 t, so t = R(a) t'). The
  candidate whose compensated frame correlates better with the reference on the pixels valid in
  both wins (the two phase-correlation peaks cannot tell scenes that look alike upside down).

Statuses (``Motion.status``) besides ``"ok"``:
    ``empty_reference`` / ``empty_current``: (almost) no valid pixel.
    ``flat_reference`` / ``flat_current``: all valid pixels have one value.
    ``low_response``: the translation's phase-correlation peak holds less than
        ``min_response`` of the correlation energy (no clear match).
    ``poor_overlap``: the compensated current frame correlates with the reference by less than
        ``min_overlap_correlation`` on the pixels valid in both (the estimate does not align
        the frames).

Diagnostics: ``rotation_response``, ``translation_response`` (peak strengths in [0, 1]),
``overlap_correlation`` (of the winner), ``scale`` (the current frame's zoom against the
reference, 1 for a rigid motion: estimated and ignored), ``half_turn`` (whether the a + 180
candidate won).
"""

from __future__ import annotations

import math

import cv2
import numpy as np

from stabilizer.inputs import check_integer, check_number
from stabilizer.motion import Motion, compensate, rotation_matrix
from stabilizer.peers.preparation import (
    FramePreparation,
    frame_problem,
    even_dft_size,
    peer_min_side,
    zero_mean_float,
)

#: Most bins along either axis of the log-polar spectrum: OpenCV's remap, behind warpPolar,
#: takes images of fewer than 32767 pixels a side, and 4096 bins resolve 0.09 degrees.
MAX_BINS = 4096


class FourierMellinEstimator:
    """Rigid motion by Fourier-Mellin registration, the reference's log-polar spectrum cached.

    Parameters
    ----------
    reference : (H, W) uint8 ndarray
        Disparity-like reference, 0 = invalid.
    median_ksize : int, optional
        Median filter applied to both frames (0 or 1 = none). Default 0: the filter removes
        fine detail the spectrum uses; frames with dense isolated outliers need one.
    angle_bins : int, optional
        Rows of the log-polar image, spanning 360 degrees. Default 360 (1-degree bins):
        ``cv2.phaseCorrelate`` interpolates the peak to a fraction of a bin, and finer bins
        sample a noisier spectrum.
    radius_bins : int, optional
        Columns of the log-polar image (log radius). Default 128.
    min_response : float, optional
        Translation peaks weaker than this are failures. Default 0.1, between what gross errors
        and correct estimates reach.
    min_overlap_correlation : float, optional
        The least correlation of the aligned frames, on the pixels valid in both, accepted.
        Default 0.8, between what gross errors and correct estimates reach.
    clip_sigmas : float, optional
        Valid values are clipped to median -+ this many spreads of the reference (0 = no
        clipping; :func:`stabilizer.peers.preparation.robust_value_range`). Default 1.5.
    clip_min_spread : float, optional
        The spread is at least this many gray levels. Default 10: a clean scene of a few flat
        levels has a robust spread near 0, and a smaller floor clips it to an almost binary
        image.

    References
    ----------
    .. [1] B. S. Reddy and B. N. Chatterji, "An FFT-based technique for translation, rotation,
           and scale-invariant image registration", IEEE Trans. Image Processing 5(8),
           1266-1271, 1996.
    """

    #: Smallest image side (pixels) whatever the parameters (docs/peers.md, "Image sizes").
    min_side = staticmethod(peer_min_side)

    def __init__(self, reference: np.ndarray, median_ksize: int = 0, angle_bins: int = 360,
                 radius_bins: int = 128, min_response: float = 0.1,
                 min_overlap_correlation: float = 0.8, clip_sigmas: float = 1.5,
                 clip_min_spread: float = 10.0):
        check_integer("angle_bins", angle_bins, 8, MAX_BINS)
        check_integer("radius_bins", radius_bins, 8, MAX_BINS)
        check_number("min_response", min_response, 0.0, 1.0)
        check_number("min_overlap_correlation", min_overlap_correlation, -1.0, 1.0)
        self._prepare = FramePreparation(reference, median_ksize, clip_sigmas, clip_min_spread)
        self.angle_bins = angle_bins
        self.radius_bins = radius_bins
        self.min_response = min_response
        self.min_overlap_correlation = min_overlap_correlation
        self._shape = reference.shape
        self._window = cv2.createHanningWindow(reference.shape[::-1], cv2.CV_32F)
        self._side = cv2.getOptimalDFTSize(max(reference.shape))
        self._highpass = _highpass(self._side)
        # phaseCorrelate treats the log-polar image as periodic along both axes; the angle axis
        # is, the log-radius axis is not: a Hann taper along it removes the wrap-around step.
        self._radius_window = np.hanning(radius_bins).astype(np.float32)[None, :]
        self._reference_problem = frame_problem(reference, "reference")
        self._reference = self._prepare(reference).copy()
        self._reference_float = zero_mean_float(self._reference)
        self._reference_log_polar = self._log_polar_spectrum(self._reference_float)
        self._correlation_shape = tuple(even_dft_size(n) for n in reference.shape)
        self._reference_windowed = self._windowed(self._reference_float)

    def _windowed(self, image_float: np.ndarray) -> np.ndarray:
        """``image_float`` times the Hanning window, zero-padded to even DFT sizes.

        ``cv2.phaseCorrelate`` would pad to an odd size for some frames
        (:func:`stabilizer.peers.preparation.even_dft_size`).
        """
        padded = np.zeros(self._correlation_shape, np.float32)
        height, width = self._shape
        padded[:height, :width] = image_float * self._window
        return padded

    def _log_polar_spectrum(self, image_float: np.ndarray) -> np.ndarray:
        """Log-polar resampling of the high-passed magnitude spectrum, tapered along the
        log-radius axis (float32)."""
        padded = np.zeros((self._side, self._side), np.float32)
        height, width = self._shape
        padded[:height, :width] = image_float * self._window
        magnitude = np.abs(np.fft.fftshift(np.fft.fft2(padded)))
        spectrum = (magnitude * self._highpass).astype(np.float32)
        centre = (self._side / 2.0, self._side / 2.0)
        log_polar = cv2.warpPolar(spectrum, (self.radius_bins, self.angle_bins), centre,
                                  self._side / 2.0, cv2.WARP_POLAR_LOG | cv2.INTER_LINEAR)
        return log_polar * self._radius_window

    def estimate(self, current: np.ndarray) -> Motion:
        """Motion of ``current`` (uint8, same shape as the reference) relative to the reference."""
        problem = self._reference_problem or frame_problem(current, "current")
        if problem:
            return Motion.failed(problem)
        current = self._prepare(current)
        current_float = zero_mean_float(current)
        (log_radius_shift, angle_shift), rotation_response = cv2.phaseCorrelate(
            self._reference_log_polar, self._log_polar_spectrum(current_float))
        # warpPolar's angle grows clockwise as displayed (y down); Motion's is counter-clockwise.
        angle = -angle_shift * 360.0 / self.angle_bins
        # A frame zoomed by s has its spectrum shrunk by s: the log-radius shift is -log s.
        scale = math.exp(-log_radius_shift * math.log(self._side / 2.0) / self.radius_bins)
        candidates = []
        for turn in (0.0, 180.0):
            candidate_angle = float(np.mod(angle + turn + 180.0, 360.0) - 180.0)
            dx, dy, response = self._translation(current, candidate_angle)
            candidate = Motion(candidate_angle, dx, dy)
            candidates.append((_overlap_correlation(self._reference, current, candidate),
                               response, candidate))
        half_turn = candidates[1][0] > candidates[0][0]
        correlation, response, motion = candidates[int(half_turn)]
        diagnostics = {"rotation_response": float(rotation_response),
                       "translation_response": response, "overlap_correlation": correlation,
                       "scale": scale, "half_turn": bool(half_turn)}
        if response < self.min_response:
            return Motion.failed("low_response", **diagnostics)
        if correlation < self.min_overlap_correlation:
            return Motion.failed("poor_overlap", **diagnostics)
        return Motion(motion.angle_deg, motion.dx, motion.dy, diagnostics=diagnostics)

    def _translation(self, current: np.ndarray, angle_deg: float) -> tuple[float, float, float]:
        """(dx, dy, peak response) of ``current`` after turning it back by ``angle_deg``."""
        derotated = compensate(current, Motion(angle_deg, 0.0, 0.0))
        (shift_x, shift_y), response = cv2.phaseCorrelate(
            self._reference_windowed, self._windowed(zero_mean_float(derotated)))
        dx, dy = rotation_matrix(math.radians(angle_deg)) @ np.array([shift_x, shift_y])
        return float(dx), float(dy), float(response)


def _highpass(side: int) -> np.ndarray:
    """Reddy & Chatterji's high-pass emphasis (1 - X)(2 - X), X = cos(pi u) cos(pi v), centred."""
    frequencies = np.linspace(-0.5, 0.5, side, endpoint=False)
    x = np.outer(np.cos(np.pi * frequencies), np.cos(np.pi * frequencies))
    return (1.0 - x) * (2.0 - x)


def _overlap_correlation(reference: np.ndarray, current: np.ndarray, motion: Motion) -> float:
    """Pearson correlation of the reference and the compensated current frame where both are
    valid; -1 when they share fewer than two valid pixels or either is constant there."""
    aligned = compensate(current, motion)
    both = (reference > 0) & (aligned > 0)
    if both.sum() < 2:
        return -1.0
    a = reference[both].astype(np.float64)
    b = aligned[both].astype(np.float64)
    a -= a.mean()
    b -= b.mean()
    norm = math.sqrt(float(a @ a) * float(b @ b))
    return float(a @ b) / norm if norm > 0 else -1.0
