"""What the peer estimators share: the frame check, denoising, valid-scene masks, the start
search of the local methods and 2-D rigid geometry.

All geometry speaks the Motion convention of docs/design.md (stabilizer/motion.py): a rotation about
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

#: Start angles of the local methods (ICP, ECC): a walking camera turns by up to about +-12
#: degrees within a gait cycle (Kang et al. 2009); 16 degrees were seen in simulated walks.
START_ANGLES_DEG = (-15.0, -10.0, -5.0, 0.0, 5.0, 10.0, 15.0)


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


def robust_value_range(image: np.ndarray, clip_sigmas: float, noise_factor: float = 5.0,
                       min_spread: float = 1.0) -> tuple[float, float] | None:
    """(low, high) = median -+ ``clip_sigmas`` x spread of the valid pixels; None if none valid.

    spread = the larger of the values' robust standard deviation (1.4826 x their median
    absolute deviation) and ``noise_factor`` x the pixel noise (the robust standard deviation
    of differences of horizontal neighbours, over sqrt 2), and at least ``min_spread`` gray
    levels.
    Clipping to this range keeps the outline of outlying surfaces and drops their weight. Why:
    an SR4000 reports surfaces beyond its 5 m range phase-wrapped, as very near (+150 gray
    levels), speckled with dropouts and noisy (+-15 gray levels), so such columns hold most of
    a frame's energy and their noise most of its high frequencies. The noise floor keeps the
    range wide enough that noise does not dominate what remains of a scene that is mostly one
    flat wall (then the values' own spread is the noise alone): on 100 synthetic scenes with
    noise of 3 gray levels, Fourier-Mellin clipped at 2 spreads without it made 4 estimates.
    """
    valid = image > 0
    values = image[valid].astype(np.float32)
    if values.size == 0:
        return None
    median = float(np.median(values))
    spread = 1.4826 * float(np.median(np.abs(values - median)))
    both = valid[:, 1:] & valid[:, :-1]
    if both.any():
        steps = (image[:, 1:].astype(np.float32) - image[:, :-1])[both]
        noise = 1.4826 * float(np.median(np.abs(steps - np.median(steps)))) / math.sqrt(2.0)
        spread = max(spread, noise_factor * noise)
    spread = max(spread, min_spread)
    return median - clip_sigmas * spread, median + clip_sigmas * spread


def clipped(image: np.ndarray, value_range: tuple[float, float] | None) -> np.ndarray:
    """uint8 ``image`` with its valid pixels clipped to ``value_range`` (rounded, kept >= 1 so
    that they stay valid); invalid pixels stay 0. None = unchanged."""
    if value_range is None:
        return image
    low, high = max(1, round(value_range[0])), min(255, round(value_range[1]))
    return np.where(image > 0, np.clip(image, low, max(low, high)), 0).astype(np.uint8)


def zero_mean_float(image: np.ndarray) -> np.ndarray:
    """float32 copy with the valid pixels' mean subtracted and invalid pixels set to 0.

    For phase correlation and Fourier-Mellin: after this, invalid pixels carry the
    mean scene value, so the step from scene to no measurement adds no false structure.
    """
    valid = image > 0
    mean = float(image[valid].mean()) if valid.any() else 0.0
    return np.where(valid, image.astype(np.float32) - np.float32(mean), np.float32(0.0))


def denoised(image: np.ndarray, median_ksize: int) -> np.ndarray:
    """``image`` after a ``median_ksize`` x ``median_ksize`` median filter (``cv2.medianBlur``).

    ToF disparity is noisy (a few gray levels on far walls) and speckled (isolated dropouts to 0,
    isolated phase-wrapped pixels in invalid regions). A median filter removes both and keeps
    depth steps sharp, so edges, keypoints and spectra describe the scene, not the noise. The
    valid mask is read after filtering: an isolated dropout is filled from its neighbours, an
    isolated stray pixel in an invalid region is dropped. ``median_ksize`` 0 or 1 = unchanged.
    Always a plain ndarray (an ``np.matrix`` input would break the array arithmetic after).
    """
    if median_ksize <= 1:
        return np.asarray(image)
    return cv2.medianBlur(image, median_ksize)


def check_median_ksize(median_ksize: int) -> None:
    """ValueError unless ``median_ksize`` is 0, 1 (no filter) or an odd size >= 3."""
    if median_ksize < 0 or (median_ksize > 1 and median_ksize % 2 == 0):
        raise ValueError(f"median_ksize must be 0, 1 (no filter) or an odd integer >= 3; "
                         f"got {median_ksize}")


class FramePreparation:
    """Denoising and robust clipping of frames, the clip range taken once from the reference.

    A frame is median filtered (:func:`denoised`), then its valid values are clipped
    (:func:`clipped`) to the reference's :func:`robust_value_range`; clipping with the
    reference's range treats both frames alike.

    Args:
        reference: uint8 disparity-like image (0 = invalid).
        median_ksize: median filter size (0 or 1 = none).
        clip_sigmas: half-width of the clip range in spreads (0 = no clipping).
        min_spread: the spread is at least this many gray levels.
    """

    def __init__(self, reference: np.ndarray, median_ksize: int, clip_sigmas: float,
                 min_spread: float):
        check_median_ksize(median_ksize)
        if clip_sigmas < 0 or min_spread <= 0:
            raise ValueError(f"need clip_sigmas >= 0 and min_spread > 0; "
                             f"got {clip_sigmas}, {min_spread}")
        self.median_ksize = median_ksize
        self.value_range = (robust_value_range(denoised(reference, median_ksize), clip_sigmas,
                                               min_spread=min_spread)
                            if clip_sigmas > 0 else None)

    def __call__(self, image: np.ndarray) -> np.ndarray:
        return clipped(denoised(image, self.median_ksize), self.value_range)


class StartSearch:
    """Ranked starting guesses for a local registration (ICP, ECC), from a reference analysed once.

    Local methods converge only from near the answer, and a walking camera turns by up to
    +-12 degrees and shifts by up to +-40 px between a cycle's frames (Kang et al. 2009). For
    each angle a of ``angles_deg`` the current frame is turned back by a, and windowed phase
    correlation (``cv2.phaseCorrelate``) finds the shift t' that remains; the start is
    (a, t = R(a) t') (turning back about the image centre leaves t' = R(a)^-1 t). Starts are
    ranked by the phase-correlation peak response: the angle closest to the truth usually gives
    the sharpest peak. The search runs on half-resolution images (``cv2.pyrDown``) of
    :func:`zero_mean_float` frames: a start only has to fall in the local method's basin, and
    the half-size transforms cost a quarter.

    Args:
        reference: uint8 disparity-like image (0 = invalid), already denoised.
        angles_deg: the angle grid. Default :data:`START_ANGLES_DEG` (-15 to 15 in steps of 5).
    """

    def __init__(self, reference: np.ndarray, angles_deg: tuple[float, ...] = START_ANGLES_DEG):
        if not angles_deg:
            raise ValueError("angles_deg must hold at least one angle")
        self.angles_deg = tuple(angles_deg)
        self._reference = cv2.pyrDown(zero_mean_float(reference))
        self._window = cv2.createHanningWindow(self._reference.shape[::-1], cv2.CV_32F)
        # pyrDown maps full-resolution x to x / 2, so the image centre c to c / 2.
        self._half_centre = tuple(value / 2.0 for value in image_centre(reference.shape))

    def ranked(self, current: np.ndarray) -> list[tuple[Motion, float]]:
        """(start Motion, phase-correlation response) for every angle, best response first."""
        current_half = cv2.pyrDown(zero_mean_float(current))
        size = current_half.shape[::-1]
        starts = []
        for angle in self.angles_deg:
            # Turning the frame back by a: warp with the rotation by -a about the centre.
            turn_back = cv2.getRotationMatrix2D(self._half_centre, -angle, 1.0)
            derotated = cv2.warpAffine(current_half, turn_back, size, flags=cv2.INTER_LINEAR)
            shift_half, response = cv2.phaseCorrelate(self._reference, derotated, self._window)
            shift = rotation_matrix(math.radians(angle)) @ (2.0 * np.asarray(shift_half))
            starts.append((Motion(angle, float(shift[0]), float(shift[1])), float(response)))
        return sorted(starts, key=lambda start: -start[1])


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
