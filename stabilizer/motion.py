"""The motion contract shared by every estimator, the ground truth and the harness.

docs/design.md, "Motion convention": images are H x W arrays, x to the right, y down; rotations
are about the image centre c = ((W - 1) / 2, (H - 1) / 2), as in Kang, Zhang & Park (2009): "the
origin of the coordinate in each frame is the centre of the image".

``Motion(angle_deg, dx, dy)`` says how the *current* frame is displaced from the *reference*:
warping the reference with ``A = cv2.getRotationMatrix2D(c, angle_deg, 1.0)`` and ``(dx, dy)``
added to A's last column yields the current frame. Positive angles are counter-clockwise as
displayed (OpenCV's convention); in image coordinates that rotation is
R(a) = [[cos a, sin a], [-sin a, cos a]] (:func:`rotation_matrix`), and a reference pixel x goes
to R(a) (x - c) + c + (dx, dy). Compensation applies the inverse warp to the current frame.

This module holds the contract and its conversions: images (:func:`apply_motion`,
:func:`compensate`), points (:func:`transform_points`) and 2 x 3 matrices
(:func:`motion_matrix`, :func:`motion_from_matrix`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import cv2
import numpy as np

#: Status of an estimate that succeeded.
OK = "ok"


@dataclass(frozen=True)
class Motion:
    """Rigid image motion of the current frame relative to the reference.

    Attributes:
        angle_deg: rotation about the image centre, degrees, counter-clockwise positive.
        dx, dy: translation in pixels added after the rotation (x right, y down).
        status: ``"ok"`` when the values are an estimate; otherwise a short machine-readable
            reason (for example ``"no_structure"``) and the values are NaN.
        diagnostics: what the estimator saw, for inspection (method specific).
    """

    angle_deg: float
    dx: float
    dy: float
    status: str = OK
    diagnostics: dict[str, Any] = field(default_factory=dict, compare=False, repr=False)

    @property
    def ok(self) -> bool:
        return self.status == OK

    @classmethod
    def failed(cls, status: str, /, **diagnostics: Any) -> Motion:
        """A Motion that carries no estimate, only the reason why (``status``; the diagnostics
        may hold a key "status" of their own)."""
        if status == OK:
            raise ValueError("a failed Motion needs a status other than 'ok'")
        return cls(math.nan, math.nan, math.nan, status, dict(diagnostics))

    def as_tuple(self) -> tuple[float, float, float]:
        return (self.angle_deg, self.dx, self.dy)


def image_centre(shape: tuple[int, ...]) -> tuple[float, float]:
    """Centre of rotation ((W - 1) / 2, (H - 1) / 2) of an image of the given shape."""
    height, width = shape[:2]
    return ((width - 1) / 2.0, (height - 1) / 2.0)


def rotation_matrix(angle_rad: float) -> np.ndarray:
    """R(a) = [[cos a, sin a], [-sin a, cos a]]: counter-clockwise as displayed for a > 0.

    The 2 x 2 part of ``cv2.getRotationMatrix2D`` (scale 1) in image coordinates (y down).
    """
    cos_a, sin_a = math.cos(angle_rad), math.sin(angle_rad)
    return np.array([[cos_a, sin_a], [-sin_a, cos_a]])


def motion_from_rotation(angle_rad: float, reference_point: np.ndarray,
                         current_point: np.ndarray, shape: tuple[int, ...]) -> Motion:
    """The Motion that rotates by ``angle_rad`` and carries ``reference_point`` (x, y) onto
    ``current_point``: its translation is t = q - c - R(a) (p - c)."""
    centre = np.array(image_centre(shape))
    shift = current_point - centre - rotation_matrix(angle_rad) @ (reference_point - centre)
    return Motion(math.degrees(angle_rad), float(shift[0]), float(shift[1]))


def motion_matrix(motion: Motion, shape: tuple[int, ...]) -> np.ndarray:
    """The 2 x 3 affine matrix that maps reference pixel coordinates to current ones."""
    matrix = cv2.getRotationMatrix2D(image_centre(shape), float(motion.angle_deg), 1.0)
    matrix[0, 2] += motion.dx
    matrix[1, 2] += motion.dy
    return matrix


def motion_from_matrix(matrix: np.ndarray, shape: tuple[int, ...]) -> Motion:
    """The Motion of a 2 x 3 matrix x' = M [x, y, 1] whose 2 x 2 part is a rotation.

    The inverse of :func:`motion_matrix` for a matrix whose rotation is about any origin (for
    example the pixel origin, as ``cv2.findTransformECC`` returns it). The angle is read from the
    first row (a uniform scale, if any, is ignored); the translation is re-expressed for a
    rotation about the image centre: M x + b = R (x - c) + c + t, so t = b + R c - c.
    """
    matrix = np.asarray(matrix, np.float64)
    if matrix.shape != (2, 3):
        raise ValueError(f"matrix must be 2 x 3; got shape {matrix.shape}")
    angle = math.atan2(matrix[0, 1], matrix[0, 0])
    return motion_from_rotation(angle, np.zeros(2), matrix[:, 2], shape)


def transform_points(motion: Motion, points: np.ndarray, shape: tuple[int, ...],
                     inverse: bool = False) -> np.ndarray:
    """Reference pixel coordinates (N x 2, x y) moved by ``motion`` into the current frame.

    With ``inverse=True``, current coordinates moved back into the reference frame.
    """
    matrix = motion_matrix(motion, shape)
    if inverse:
        matrix = cv2.invertAffineTransform(matrix)
    return points @ matrix[:, :2].T + matrix[:, 2]


def apply_motion(
    image: np.ndarray, motion: Motion, interpolation: int = cv2.INTER_NEAREST
) -> np.ndarray:
    """Warp ``image`` by ``motion`` (reference -> current); uncovered pixels become 0 (invalid).

    Nearest-neighbour interpolation by default, because disparity values must not be blended
    across depth edges.
    """
    _check_warp(image, motion, interpolation)
    return _warped(image, motion_matrix(motion, image.shape), interpolation)


def compensate(
    frame: np.ndarray, motion: Motion, interpolation: int = cv2.INTER_NEAREST
) -> np.ndarray:
    """Stabilize ``frame``: undo ``motion`` so the frame lines up with the reference.

    A failed Motion (no estimate) leaves the frame as it is, returned as a copy.
    """
    _check_warp(frame, motion, interpolation)
    if not motion.ok:
        return np.array(frame, copy=True)
    return _warped(frame, motion_matrix(motion, frame.shape),
                   interpolation | cv2.WARP_INVERSE_MAP)


def _warped(image: np.ndarray, matrix: np.ndarray, flags: int) -> np.ndarray:
    """``image`` warped by ``matrix``, uncovered pixels 0, in ``image``'s shape (OpenCV drops
    a single channel's axis)."""
    height, width = image.shape[:2]
    return cv2.warpAffine(image, matrix, (width, height), flags=flags,
                          borderMode=cv2.BORDER_CONSTANT, borderValue=0).reshape(image.shape)


#: The most channels ``cv2.warpAffine`` warps (opencv-python 5.1).
MAX_WARP_CHANNELS = 128
#: Image types ``cv2.warpAffine`` keeps as they are.
WARP_DTYPES = (np.uint8, np.uint16, np.int16, np.float32, np.float64)
#: Interpolations ``cv2.warpAffine`` takes.
WARP_INTERPOLATIONS = {cv2.INTER_NEAREST: "INTER_NEAREST", cv2.INTER_LINEAR: "INTER_LINEAR",
                       cv2.INTER_CUBIC: "INTER_CUBIC", cv2.INTER_LANCZOS4: "INTER_LANCZOS4"}


def _check_warp(image: np.ndarray, motion: Motion, interpolation: int) -> None:
    """TypeError or ValueError, naming what was given and what is accepted, unless ``image``,
    ``motion`` and ``interpolation`` can be warped as they are."""
    if not isinstance(motion, Motion):
        raise TypeError(f"motion must be a stabilizer.motion.Motion; got "
                        f"{type(motion).__name__}")
    if motion.ok and not all(math.isfinite(value) for value in motion.as_tuple()):
        raise ValueError(f"an ok motion must have finite values; got {motion.as_tuple()}")
    if not isinstance(image, np.ndarray) or image.dtype not in WARP_DTYPES \
            or image.ndim not in (2, 3) or 0 in image.shape[:2]:
        described = (f"{image.dtype} with shape {image.shape}" if isinstance(image, np.ndarray)
                     else type(image).__name__)
        raise ValueError(f"image must be a non-empty 2-D (or 2-D with channels) array of "
                         f"{', '.join(np.dtype(kind).name for kind in WARP_DTYPES)}; "
                         f"got {described}")
    if image.ndim == 3 and image.shape[2] > MAX_WARP_CHANNELS:
        raise ValueError(f"image must have at most {MAX_WARP_CHANNELS} channels (OpenCV's warp); "
                         f"got {image.shape[2]}")
    if interpolation not in WARP_INTERPOLATIONS:
        accepted = ", ".join(f"cv2.{name}" for name in WARP_INTERPOLATIONS.values())
        raise ValueError(f"interpolation must be one of {accepted}; got {interpolation!r}")


def wrap_angle_deg(angle: np.ndarray | float, period: float = 360.0):
    """Wrap angles (degrees) into (-period/2, period/2]."""
    half = period / 2.0
    return half - np.mod(half - np.asarray(angle, dtype=np.float64), period)
