"""Rotation-aware starting guesses for the local peers (ICP, ECC).

A local registration converges only from near the answer, and a walking camera turns by up to
about +-12 degrees and shifts by up to about +-40 px between a gait cycle's frames (Kang et al.
2009, section III-B). Phase correlation alone finds a shift but no rotation, so the search tries a
grid of angles: for each angle a the current frame is turned back by a, and windowed phase
correlation (``cv2.phaseCorrelate``) finds the shift t' that remains. Turning back about the
image centre leaves t' = R(a)^-1 t, so the start is (a, t = R(a) t'). Starts are ranked by the
phase-correlation peak response: the angle closest to the truth usually gives the sharpest peak.
Why a grid and not one shift: docs/peers.md, "Starts of the local methods".
"""

from __future__ import annotations

import math

import cv2
import numpy as np

from stabilizer.inputs import check_angles
from stabilizer.motion import Motion, image_centre, rotation_matrix
from stabilizer.peers.preparation import even_dft_size, zero_mean_float

#: Start angles (degrees): the walking camera's turns of up to about +-12 degrees, with margin.
START_ANGLES_DEG = (-15.0, -10.0, -5.0, 0.0, 5.0, 10.0, 15.0)


class StartSearch:
    """Ranked starting Motions for a local registration, the reference analysed once.

    The search runs on half-resolution images (``cv2.pyrDown``) of :func:`zero_mean_float`
    frames: a start only has to fall in the local method's basin, and the half-size transforms
    cost a quarter.

    Parameters
    ----------
    reference : (H, W) uint8 ndarray
        Disparity-like reference, 0 = invalid, already prepared (denoised, clipped).
    angles_deg : tuple of float, optional
        The angle grid. Default :data:`START_ANGLES_DEG` (-15 to 15 in steps of 5).
    """

    def __init__(self, reference: np.ndarray, angles_deg: tuple[float, ...] = START_ANGLES_DEG):
        check_angles("start_angles_deg", angles_deg)
        self.angles_deg = tuple(angles_deg)
        reference_half = cv2.pyrDown(zero_mean_float(reference))
        self._window = cv2.createHanningWindow(reference_half.shape[::-1], cv2.CV_32F)
        self._padded_shape = tuple(even_dft_size(n) for n in reference_half.shape)
        self._reference = self._windowed(reference_half)
        # pyrDown maps full-resolution x to x / 2, so the image centre c to c / 2.
        self._half_centre = tuple(value / 2.0 for value in image_centre(reference.shape))

    def _windowed(self, image_half: np.ndarray) -> np.ndarray:
        """``image_half`` times the Hanning window, zero-padded to even DFT sizes (an odd size
        biases ``cv2.phaseCorrelate`` by half a pixel, :func:`even_dft_size`)."""
        padded = np.zeros(self._padded_shape, np.float32)
        height, width = image_half.shape
        padded[:height, :width] = image_half * self._window
        return padded

    def ranked(self, current: np.ndarray) -> list[tuple[Motion, float]]:
        """(start Motion, phase-correlation response) for every angle, best response first.

        Parameters
        ----------
        current : (H, W) uint8 ndarray
            The current frame, prepared as the reference was.
        """
        current_half = cv2.pyrDown(zero_mean_float(current))
        size = current_half.shape[::-1]
        starts = []
        for angle in self.angles_deg:
            # Turning the frame back by a: warp with the rotation by -a about the centre.
            turn_back = cv2.getRotationMatrix2D(self._half_centre, -angle, 1.0)
            derotated = cv2.warpAffine(current_half, turn_back, size, flags=cv2.INTER_LINEAR)
            shift_half, response = cv2.phaseCorrelate(self._reference, self._windowed(derotated))
            shift = rotation_matrix(math.radians(angle)) @ (2.0 * np.asarray(shift_half))
            starts.append((Motion(angle, float(shift[0]), float(shift[1])), float(response)))
        return sorted(starts, key=lambda start: -start[1])
