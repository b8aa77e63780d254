"""Input checks and the one depth -> disparity-like mapping used everywhere.

The stabilizer takes 8-bit disparity-like images, as the paper's input is a disparity map with
256 gray levels, "the brighter levels representing the points closer to the camera" (Kang, Zhang
& Park 2009, section III-A); 0 = no measurement. Metric depth (float, metres), as a ToF camera
gives it, is converted by :func:`depth_to_disparity` (docs/method.md, section 0).
"""

from __future__ import annotations

import numpy as np

#: Depth (m) that maps to gray level 255: the SR4000's near limit of calibrated range.
DEFAULT_NEAR_M = 0.5
#: Depths beyond this are treated as no measurement by the mapping.
DEFAULT_FAR_M = 10.0


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


def as_disparity(image: np.ndarray, name: str = "image") -> np.ndarray:
    """Check an input frame and return it as a uint8 disparity-like image.

    Parameters
    ----------
    image : ndarray
        A 2-D uint8 disparity-like image (0 = invalid), or a 2-D float32/float64 depth image
        in metres (converted by :func:`depth_to_disparity`), at least 8 x 8. Anything else is
        a ValueError that says what was given and what is accepted.
    name : str, optional
        What to call the frame in error messages. Default ``"image"``.

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
    if min(image.shape) < 8:
        raise ValueError(f"{name} must be at least 8 x 8 pixels; got shape {image.shape}")
    if image.dtype == np.uint8:
        return image
    if image.dtype in (np.float32, np.float64):
        return depth_to_disparity(image)
    raise ValueError(
        f"{name} has dtype {image.dtype}; accepted: uint8 disparity-like image "
        "(brighter = closer, 0 = invalid) or float32/float64 depth in metres"
    )


def check_same_shape(reference: np.ndarray, current: np.ndarray) -> None:
    """ValueError unless the two frames have the same shape."""
    if reference.shape != current.shape:
        raise ValueError(
            f"reference and current frames must have the same shape; "
            f"got {reference.shape} and {current.shape}"
        )
