"""What the peer estimators share: the frame check, valid-scene masks and 2-D rigid geometry.

All geometry speaks the Motion convention of DESIGN.md (stabilizer/motion.py): a rotation about
the image centre c = ((W - 1) / 2, (H - 1) / 2), counter-clockwise positive as displayed (OpenCV's
``getRotationMatrix2D``), then a translation; it maps reference pixels to current pixels. In image
coordinates (y down) that rotation is R(a) = [[cos a, sin a], [-sin a, cos a]].
"""

from __future__ import annotations

import math

import cv2
import numpy as np

from stabilizer.motion import Motion, image_centre, motion_matrix

#: A frame needs at least this many valid (non-zero) pixels to show any scene.
MIN_VALID_PIXELS = 64


def frame_problem(image: np.ndarray, role: str) -> str | None:
    """Why ``image`` cannot be registered, or None when it can.

    Returns ``"empty_<role>"`` when fewer than :data:`MIN_VALID_PIXELS` pixels are valid (0 =
    no measurement) and ``"flat_<role>"`` when every valid pixel has the same value (no
    structure to register). ``role`` is ``"reference"`` or ``"current"``.
    """
    values = image[image > 0]
    if values.size < MIN_VALID_PIXELS:
        return f"empty_{role}"
    if values.min() == values.max():
        return f"flat_{role}"
    return None


def valid_interior(image: np.ndarray, margin_px: int) -> np.ndarray:
    """uint8 mask (255/0) of valid pixels at least ``margin_px`` pixels from any invalid pixel.

    The step from scene to 0 (no measurement) is not scene structure, so features must not sit
    on it. The image border itself does not count as invalid (erosion pads with 'valid').
    """
    valid = np.where(image > 0, 255, 0).astype(np.uint8)
    if margin_px <= 0:
        return valid
    kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * margin_px + 1, 2 * margin_px + 1))
    return cv2.erode(valid, kernel)


def zero_mean_float(image: np.ndarray) -> np.ndarray:
    """float32 copy with the valid pixels' mean subtracted and invalid pixels set to 0.

    For phase correlation and Fourier-Mellin: after this, invalid pixels carry the
    mean scene value, so the step from scene to no measurement adds no false structure.
    """
    valid = image > 0
    mean = float(image[valid].mean()) if valid.any() else 0.0
    return np.where(valid, image.astype(np.float32) - np.float32(mean), np.float32(0.0))


def coarse_starts(reference_float: np.ndarray, current_float: np.ndarray, window: np.ndarray,
                  angles_deg: tuple[float, ...]) -> list[Motion]:
    """Starting guesses for a local registration (ICP, ECC), the likeliest first.

    The translation from windowed phase correlation (``cv2.phaseCorrelate``; exact for a pure
    shift, rough under rotation), then zero translation in case phase correlation locked onto
    a wrong peak; each combined with every angle of ``angles_deg``. Images come from
    :func:`zero_mean_float`; ``window`` is ``cv2.createHanningWindow`` of the image size.
    """
    (dx, dy), _ = cv2.phaseCorrelate(reference_float, current_float, window)
    return [Motion(angle, *shift) for shift in ((float(dx), float(dy)), (0.0, 0.0))
            for angle in angles_deg]


def fit_rigid(reference_pts: np.ndarray, current_pts: np.ndarray,
              shape: tuple[int, ...]) -> Motion:
    """Least-squares rotation + translation (no scale) mapping reference points onto current ones.

    Closed-form 2-D Kabsch/Umeyama: with centred point sets p (reference) and q (current), the
    angle maximising sum q . R(a) p is a = atan2(sum(q_x p_y - q_y p_x), sum(p . q)); the
    translation then follows from the centroids. Points are N x 2 arrays of (x, y) pixels.
    """
    reference_pts = np.asarray(reference_pts, np.float64).reshape(-1, 2)
    current_pts = np.asarray(current_pts, np.float64).reshape(-1, 2)
    reference_mean = reference_pts.mean(axis=0)
    current_mean = current_pts.mean(axis=0)
    p = reference_pts - reference_mean
    q = current_pts - current_mean
    angle = math.atan2(float(np.sum(q[:, 0] * p[:, 1] - q[:, 1] * p[:, 0])), float(np.sum(p * q)))
    return _motion_from_rotation(angle, reference_mean, current_mean, shape)


def motion_from_matrix(matrix: np.ndarray, shape: tuple[int, ...]) -> Motion:
    """The Motion of a 2 x 3 matrix x' = M [x, y, 1] whose 2 x 2 part is a rotation.

    The angle is read from the first row (a uniform scale, if any, is ignored); the translation
    is re-expressed for a rotation about the image centre: M x + b = R (x - c) + c + t, so
    t = b + R c - c.
    """
    matrix = np.asarray(matrix, np.float64)
    angle = math.atan2(matrix[0, 1], matrix[0, 0])
    origin = np.zeros(2)
    return _motion_from_rotation(angle, origin, matrix[:, 2], shape)


def transform_points(motion: Motion, points: np.ndarray, shape: tuple[int, ...],
                     inverse: bool = False) -> np.ndarray:
    """Reference pixel coordinates (N x 2, x y) moved by ``motion`` into the current frame.

    With ``inverse=True``, current coordinates moved back into the reference frame.
    """
    matrix = motion_matrix(motion, shape)
    if inverse:
        matrix = cv2.invertAffineTransform(matrix)
    return points @ matrix[:, :2].T + matrix[:, 2]


def rotation_matrix(angle_rad: float) -> np.ndarray:
    """R(a) in image coordinates (y down), counter-clockwise as displayed for a > 0."""
    cos_a, sin_a = math.cos(angle_rad), math.sin(angle_rad)
    return np.array([[cos_a, sin_a], [-sin_a, cos_a]])


def _motion_from_rotation(angle_rad: float, reference_point: np.ndarray,
                          current_point: np.ndarray, shape: tuple[int, ...]) -> Motion:
    """Motion with rotation ``angle_rad`` that maps ``reference_point`` onto ``current_point``."""
    centre = np.array(image_centre(shape))
    shift = current_point - centre - rotation_matrix(angle_rad) @ (reference_point - centre)
    return Motion(math.degrees(angle_rad), float(shift[0]), float(shift[1]))
