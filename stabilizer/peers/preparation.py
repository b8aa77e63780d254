"""Frame preparation for the peer estimators: checks, denoising, range clipping and masks.

Disparity-like frames (uint8, brighter = closer, 0 = no measurement) from a ToF camera are noisy,
speckled, and show surfaces beyond the camera's range phase-wrapped as very near. Before
registration the peers check that a frame shows any scene (:func:`frame_problem`), median filter
it (:func:`denoised`), clip its valid values to a robust range of the reference's
(:func:`robust_value_range`, :func:`clipped`; both steps together: :class:`FramePreparation`),
and keep features off the step to invalid pixels (:func:`valid_interior`, :func:`zero_mean_float`).
Why each step: docs/peers.md, "Frame preparation".
"""

from __future__ import annotations

import math

import cv2
import numpy as np

from stabilizer.inputs import MAX_KERNEL_SIDE, check_integer, check_number

#: A frame needs at least this many valid (non-zero) pixels to show any scene.
MIN_VALID_PIXELS = 64
#: Smallest image side (pixels) of every peer. The start search works at half resolution and
#: ECC's coarsest level at a quarter, and a frame must hold enough depth steps for edges,
#: keypoints and the trust check: smaller frames gave "ok" estimates of motions that were not
#: there (docs/peers.md, "Image sizes").
MIN_SIDE = 64


def peer_min_side(**_params) -> int:
    """Smallest image side of a peer, :data:`MIN_SIDE` whatever its parameters."""
    return MIN_SIDE


def frame_problem(image: np.ndarray, role: str) -> str | None:
    """Why ``image`` cannot be registered, or None when it can.

    Parameters
    ----------
    image : (H, W) uint8 ndarray
        Disparity-like frame, 0 = invalid.
    role : str
        ``"reference"`` or ``"current"``; names the status.

    Returns
    -------
    str or None
        ``"empty_<role>"`` when fewer than :data:`MIN_VALID_PIXELS` pixels are valid,
        ``"flat_<role>"`` when every valid pixel has the same value (no structure to
        register), else None.
    """
    values = image[image > 0]
    if values.size < MIN_VALID_PIXELS:
        return f"empty_{role}"
    if values.min() == values.max():
        return f"flat_{role}"
    return None


def valid_interior(image: np.ndarray, margin_px: int) -> np.ndarray:
    """uint8 mask (255/0) of the valid pixels at least ``margin_px`` pixels from any invalid one.

    The step from scene to 0 (no measurement) is not scene structure, so features must not sit
    on it. The image border itself does not count as invalid (erosion pads with "valid").

    Parameters
    ----------
    image : (H, W) uint8 ndarray
        Disparity-like frame, 0 = invalid.
    margin_px : int
        Distance kept from invalid pixels (elliptical erosion); 0 or less = the valid mask.

    Returns
    -------
    (H, W) uint8 ndarray
        255 inside, 0 elsewhere (an OpenCV mask).
    """
    valid = np.where(image > 0, 255, 0).astype(np.uint8)
    if margin_px <= 0:
        return valid
    kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * margin_px + 1, 2 * margin_px + 1))
    return cv2.erode(valid, kernel)


def robust_value_range(image: np.ndarray, clip_sigmas: float, noise_factor: float = 5.0,
                       min_spread: float = 1.0) -> tuple[float, float] | None:
    """(low, high) = median -+ ``clip_sigmas`` spreads of the valid pixels.

    spread = the larger of the values' robust standard deviation (1.4826 x their median
    absolute deviation) and ``noise_factor`` x the pixel noise (the robust standard deviation
    of the differences of horizontal neighbours, over sqrt 2), and at least ``min_spread``.
    Clipping to this range keeps the outline of outlying surfaces and drops their weight (an
    SR4000 shows surfaces beyond its range phase-wrapped, as bright, noisy, speckled columns).
    The noise floor keeps the range wide enough that noise does not dominate what is left of a
    scene that is mostly one flat wall, whose values' own spread is the noise alone.

    Parameters
    ----------
    image : (H, W) uint8 ndarray
        Disparity-like frame, 0 = invalid.
    clip_sigmas : float
        Half-width of the range in spreads.
    noise_factor : float, optional
        The spread is at least this many times the pixel noise. Default 5.
    min_spread : float, optional
        The spread is at least this many gray levels. Default 1.

    Returns
    -------
    (float, float) or None
        The range, or None when no pixel is valid.
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
    """``image`` with its valid pixels clipped to ``value_range``; invalid pixels stay 0.

    Parameters
    ----------
    image : (H, W) uint8 ndarray
        Disparity-like frame, 0 = invalid.
    value_range : (float, float) or None
        (low, high), rounded to gray levels and kept >= 1 so that valid pixels stay valid;
        None = no clipping.

    Returns
    -------
    (H, W) uint8 ndarray
        The clipped frame; ``image`` itself when ``value_range`` is None.
    """
    if value_range is None:
        return image
    low, high = max(1, round(value_range[0])), min(255, round(value_range[1]))
    return np.where(image > 0, np.clip(image, low, max(low, high)), 0).astype(np.uint8)


def zero_mean_float(image: np.ndarray) -> np.ndarray:
    """float32 copy with the valid pixels' mean subtracted and the invalid pixels set to 0.

    For phase correlation and Fourier-Mellin: afterwards invalid pixels carry the mean scene
    value, so the step from scene to no measurement adds no false structure.
    """
    valid = image > 0
    mean = float(image[valid].mean()) if valid.any() else 0.0
    return np.where(valid, image.astype(np.float32) - np.float32(mean), np.float32(0.0))


def even_dft_size(size: int) -> int:
    """The smallest even size >= ``size`` that ``cv2.getOptimalDFTSize`` returns.

    ``cv2.phaseCorrelate`` zero-pads its inputs to ``cv2.getOptimalDFTSize``; when that size is
    odd (125 for 122 pixels) its peak is off by half a pixel, so identical frames seem moved.
    Inputs padded to an even DFT size first are correlated without that bias.
    """
    optimal = cv2.getOptimalDFTSize(size)
    while optimal % 2:
        optimal = cv2.getOptimalDFTSize(optimal + 1)
    return optimal


def check_median_ksize(median_ksize: int) -> None:
    """ValueError unless ``median_ksize`` is 0, 1 (no filter) or an odd size from 3 to
    :data:`~stabilizer.inputs.MAX_KERNEL_SIDE`."""
    check_integer("median_ksize", median_ksize, 0, MAX_KERNEL_SIDE)
    if median_ksize > 1 and median_ksize % 2 == 0:
        raise ValueError(f"median_ksize must be 0, 1 (no filter) or an odd integer from 3 to "
                         f"{MAX_KERNEL_SIDE}; got {median_ksize}")


def denoised(image: np.ndarray, median_ksize: int) -> np.ndarray:
    """``image`` after a ``median_ksize`` x ``median_ksize`` median filter (``cv2.medianBlur``).

    A median filter removes ToF noise and speckle (isolated dropouts to 0, isolated stray pixels
    in invalid regions) and keeps depth steps sharp, so edges, keypoints and spectra describe the
    scene, not the noise. The valid mask is read after filtering: an isolated dropout is filled
    from its neighbours, an isolated stray pixel is dropped.

    Parameters
    ----------
    image : (H, W) uint8 ndarray
        Disparity-like frame, 0 = invalid.
    median_ksize : int
        Filter size, odd; 0 or 1 = no filter.

    Returns
    -------
    (H, W) uint8 ndarray
        Always a plain ndarray (an ``np.matrix`` input would break the array arithmetic after).
    """
    if median_ksize <= 1:
        return np.asarray(image)
    return cv2.medianBlur(image, median_ksize)


class FramePreparation:
    """Denoising and robust clipping of frames, the clip range taken once from the reference.

    A frame is median filtered (:func:`denoised`), then its valid values are clipped
    (:func:`clipped`) to the reference's :func:`robust_value_range`; the reference's range
    treats both frames alike.

    Parameters
    ----------
    reference : (H, W) uint8 ndarray
        Disparity-like reference frame, 0 = invalid.
    median_ksize : int
        Median filter size (0 or 1 = none).
    clip_sigmas : float
        Half-width of the clip range in spreads (0 = no clipping).
    min_spread : float
        The spread is at least this many gray levels.
    """

    def __init__(self, reference: np.ndarray, median_ksize: int, clip_sigmas: float,
                 min_spread: float):
        check_median_ksize(median_ksize)
        check_number("clip_sigmas", clip_sigmas, 0.0)
        check_number("clip_min_spread", min_spread, 0.0, open_low=True)
        self.median_ksize = median_ksize
        self.value_range = (robust_value_range(denoised(reference, median_ksize), clip_sigmas,
                                               min_spread=min_spread)
                            if clip_sigmas > 0 else None)

    def __call__(self, image: np.ndarray) -> np.ndarray:
        """``image`` denoised and clipped to the reference's range (uint8, 0 = invalid)."""
        return clipped(denoised(image, self.median_ksize), self.value_range)
