"""Input checks and the one depth -> disparity-like mapping used everywhere.

The stabilizer takes 8-bit disparity-like images, as the paper's input is a disparity map with
256 gray levels, "the brighter levels representing the points closer to the camera" (Kang, Zhang
& Park 2009, section III-A); 0 = no measurement. Metric depth (float, metres), as a ToF camera
gives it, is converted by :func:`depth_to_disparity` (docs/method.md, section 0).
"""

from __future__ import annotations

import math
import numbers
from typing import Any

import numpy as np

#: Depth (m) that maps to gray level 255: the SR4000's near limit of calibrated range.
DEFAULT_NEAR_M = 0.5
#: Depths beyond this are treated as no measurement by the mapping.
DEFAULT_FAR_M = 10.0
#: Smallest side (pixels) of any frame; each method has its own, larger minimum
#: (``stabilizer.api``, docs/method.md section 9, docs/peers.md "Image sizes").
MIN_SIDE = 8
#: Largest side (pixels) of a method's filter kernels (median, Gaussian, morphology) and of its
#: margins: the methods are made for frames like the SR4000's 176 x 144, which a kernel this
#: wide already covers; a wider one only costs time and memory (a median of side 10^6 ran for
#: minutes, a Gaussian of sigma 10^9 asked for 8 GB).
MAX_KERNEL_SIDE = 255
#: Largest Gaussian scale (pixels) of a method: its kernel, 6 sigma wide, stays within
#: :data:`MAX_KERNEL_SIDE`.
MAX_SIGMA_PX = 40.0
#: Most iterations of a method's iterative steps (IT2-FCM, ECC, ICP, the rotation climb, the
#: trust check's ECC): each settles within tens of iterations where it settles at all (defaults
#: 8-100); one that has not by 1000 oscillates, and more only cost time (ICP on a noise frame
#: never stopped; IT2-FCM with a tolerance of 1e-300 ran for minutes).
MAX_ITERATIONS = 1000


def depth_to_disparity(
    depth_m: np.ndarray, near_m: float = DEFAULT_NEAR_M, far_m: float = DEFAULT_FAR_M
) -> np.ndarray:
    """Map metric depth to the 8-bit disparity-like image g = clip(round(K / d), 1, 255).

    K = 255 * ``near_m``, so a surface at the near limit is 255 and g falls as 1/d, as the
    disparity of a stereo pair does (docs/method.md, section 0). Pixels that are not finite,
    not positive, nearer than ``near_m`` or farther than ``far_m`` are 0 (invalid).

    Parameters
    ----------
    depth_m : (H, W) ndarray of float32 or float64
        Depth in metres (NaN, inf, 0 = no measurement).
    near_m : float, optional
        Depth mapped to 255. Default 0.5 m (the SR4000's near limit of calibrated range).
    far_m : float, optional
        Largest depth kept. Default 10 m.

    Returns
    -------
    (H, W) ndarray of uint8
        The disparity-like image, 0 = invalid.

    References
    ----------
    .. [1] T.-K. Kang, H. Zhang and G.-T. Park, "Stereo-vision based motion stabilization of a
           humanoid robot for the environment recognition by type-2 fuzzy logic", MED 2009,
           section III-A (the disparity maps' 256 gray levels).
    """
    depth = np.asarray(depth_m)
    if depth.ndim != 2:
        raise ValueError(f"depth must be a 2-D H x W array; got shape {depth.shape}")
    if not np.issubdtype(depth.dtype, np.floating):
        raise ValueError(f"depth must be float32 or float64 metres; got dtype {depth.dtype}")
    if not (0 < near_m < far_m):
        raise ValueError(f"need 0 < near_m < far_m; got near_m={near_m}, far_m={far_m}")
    with np.errstate(invalid="ignore", divide="ignore"):
        valid = np.isfinite(depth) & (depth >= near_m) & (depth <= far_m)
        gray = np.where(valid, np.rint(255.0 * near_m / np.where(valid, depth, 1.0)), 0)
    gray = np.clip(gray, 0, 255).astype(np.uint8)
    gray[valid & (gray == 0)] = 1
    return gray


def as_disparity(image: np.ndarray, name: str = "image", *, min_side: int = MIN_SIDE,
                 max_side: int | None = None, method: str | None = None,
                 reference_shape: tuple[int, int] | None = None) -> np.ndarray:
    """Check an input frame and return it as a uint8 disparity-like image.

    The type, the dimensions, the dtype and the size are checked before anything is computed.

    Parameters
    ----------
    image : ndarray
        A 2-D uint8 disparity-like image (0 = invalid), or a 2-D float32/float64 depth image
        in metres (converted by :func:`depth_to_disparity`). Anything else is a ValueError
        that says what was given and what is accepted.
    name : str, optional
        What to call the frame in error messages. Default ``"image"``.
    min_side, max_side : int, optional
        Smallest and largest accepted height and width, in pixels. Defaults
        :data:`MIN_SIDE` (8) and no maximum; ``stabilizer.Stabilizer`` passes its method's.
    method : str, optional
        The method the limits are for, named in the error message.
    reference_shape : (int, int), optional
        For a current frame: the reference's shape, which it must have (the reference was
        checked against the limits; the message names both shapes).

    Returns
    -------
    (H, W) ndarray of uint8
        A plain ndarray (array subclasses are viewed as one).
    """
    if not isinstance(image, np.ndarray):
        raise ValueError(f"{name} must be a numpy array; got {type(image).__name__}")
    image = np.asarray(image)  # array subclasses (np.matrix, masked arrays) as plain arrays
    if image.ndim != 2:
        raise ValueError(
            f"{name} must be a 2-D H x W array (uint8 disparity or float depth in metres); "
            f"got shape {image.shape}"
        )
    if image.dtype not in (np.uint8, np.float32, np.float64):
        raise ValueError(
            f"{name} has dtype {image.dtype}; accepted: uint8 disparity-like image "
            "(brighter = closer, 0 = invalid) or float32/float64 depth in metres"
        )
    if reference_shape is not None:
        _check_shapes(reference_shape, image.shape)
    else:
        check_size(image.shape, name, min_side, max_side, method)
    return image if image.dtype == np.uint8 else depth_to_disparity(image)


def check_size(shape: tuple[int, int], name: str, min_side: int, max_side: int | None = None,
               method: str | None = None) -> None:
    """ValueError, in the user's terms, unless both sides of ``shape`` are within the limits.

    The message names the frame's size (width x height and the array shape) and the accepted
    range, for example "reference is 20 x 20 pixels (shape (20, 20)); method 't2fuzzy' needs
    images of at least 96 x 96 pixels and at most 4096 x 4096 (the method table of
    stabilizer.api)".
    """
    height, width = shape
    if min_side <= min(height, width) and (max_side is None or max(height, width) <= max_side):
        return
    who = f"method {method!r}" if method else "the stabilizer"
    limits = f"at least {min_side} x {min_side} pixels"
    if max_side is not None:
        limits += f" and at most {max_side} x {max_side}"
    where = " (the method table of stabilizer.api)" if method else ""
    raise ValueError(f"{name} is {width} x {height} pixels (shape {tuple(shape)}); {who} needs "
                     f"images of {limits}{where}")


def check_same_shape(reference: np.ndarray, current: np.ndarray) -> None:
    """ValueError unless the two frames have the same shape."""
    _check_shapes(reference.shape, current.shape)


def _check_shapes(reference_shape: tuple[int, ...], current_shape: tuple[int, ...]) -> None:
    if tuple(reference_shape) != tuple(current_shape):
        raise ValueError(
            f"reference and current frames must have the same shape; "
            f"got {tuple(reference_shape)} and {tuple(current_shape)}"
        )


def check_integer(name: str, value: Any, least: int, most: int | None = None) -> None:
    """ValueError naming ``name`` unless ``value`` is an integer (not a bool) in
    [``least``, ``most``]."""
    if not (isinstance(value, numbers.Integral) and not isinstance(value, (bool, np.bool_))
            and least <= value and (most is None or value <= most)):
        accepted = f">= {least}" if most is None else f"from {least} to {most}"
        raise ValueError(f"{name} must be an integer {accepted}; got {value!r}")


def check_flag(name: str, value: Any) -> None:
    """ValueError naming ``name`` unless ``value`` is True or False."""
    if not isinstance(value, (bool, np.bool_)):
        raise ValueError(f"{name} must be True or False; got {value!r}")


def check_number(name: str, value: Any, low: float = -math.inf, high: float = math.inf, *,
                 open_low: bool = False, open_high: bool = False) -> None:
    """ValueError naming ``name`` unless ``value`` is a finite real number (not a bool) in the
    interval from ``low`` to ``high``, each end included unless ``open_low``/``open_high``."""
    inside = (isinstance(value, numbers.Real) and not isinstance(value, (bool, np.bool_))
              and math.isfinite(value)
              and (value > low if open_low else value >= low)
              and (value < high if open_high else value <= high))
    if not inside:
        interval = (f"{'(' if open_low or low == -math.inf else '['}{low:g}, "
                    f"{high:g}{')' if open_high or high == math.inf else ']'}")
        raise ValueError(f"{name} must be a finite number in {interval}; got {value!r}")


def check_angles(name: str, value: Any) -> None:
    """ValueError naming ``name`` unless ``value`` is a non-empty sequence of finite angles
    (degrees)."""
    if isinstance(value, (str, bytes)) or not hasattr(value, "__len__") or not len(value):
        raise ValueError(f"{name} must be a non-empty sequence of angles in degrees; "
                         f"got {value!r}")
    for angle in value:
        check_number(f"{name}[...]", angle)
