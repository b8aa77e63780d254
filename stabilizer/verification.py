"""The trust check of every estimate: does the compensated current frame match the reference?

Every method's ``"ok"`` passes through :class:`Verifier` (``stabilizer.Stabilizer`` applies it
after the method's own criteria): the current frame, compensated by the estimated motion, is
compared with the reference on the pixels both measure, and an estimate that does not line the
two frames up becomes a failure with the status ``"unverified"``. The comparison is
:func:`structure_correlation`, the correlation of the frames' depth edges; why that measure and
these thresholds: docs/method.md, section 11.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

from stabilizer.motion import Motion, motion_matrix

#: Status of an estimate that fails the check (docs/method.md, section 11).
UNVERIFIED = "unverified"
#: Smallest clip limit of the edge responses (gray levels per pixel²): a scene of flat
#: surfaces has a median response of 0, and its depth steps then count by their sign.
MIN_CLIP = 0.01


@dataclass(frozen=True)
class VerificationParams:
    """Thresholds and scales of the trust check (docs/method.md, section 11).

    Attributes:
        min_correlation: the least :func:`structure_correlation` of an ``"ok"`` estimate.
            Default 0.35, between what estimates off by more than 5 degrees or 10 px and
            accurate ones score on walking frames (docs/method.md, section 11).
        min_overlap: the least share of the reference's measured pixels that the compensated
            current frame also measures. Default 0.25: a walking camera's frames share well
            over half of the view; a check on less compares too little of it.
        null_margin: an estimate fails when the uncompensated current frame correlates with
            the reference more than this above the compensated one: the estimate explains the
            frames worse than no motion (a motion invented on frames that did not move).
            Default 0.05.
        sigma_px: Gaussian scale (pixels) of the edge image; it sets the misalignment the check
            tolerates, about a pixel or two. Default 2.
        clip_factor: edge responses (the Laplacian of the smoothed disparity) are clipped to
            +- this many times their median magnitude, so that a few strong depth steps (near
            objects: disparity grows as 1 / depth) do not outweigh all the others. Default 5.
    """

    min_correlation: float = 0.35
    min_overlap: float = 0.25
    null_margin: float = 0.05
    sigma_px: float = 2.0
    clip_factor: float = 5.0

    def __post_init__(self):
        if not -1.0 <= self.min_correlation <= 1.0:
            raise ValueError(f"min_correlation must be in [-1, 1]; got {self.min_correlation}")
        if self.null_margin < 0:
            raise ValueError(f"null_margin must be >= 0; got {self.null_margin}")
        if not 0.0 <= self.min_overlap <= 1.0:
            raise ValueError(f"min_overlap must be in [0, 1]; got {self.min_overlap}")
        if not (self.sigma_px > 0 and self.clip_factor > 0):
            raise ValueError(f"sigma_px and clip_factor must be > 0; "
                             f"got {self.sigma_px}, {self.clip_factor}")


def edge_image(image: np.ndarray, sigma_px: float,
               clip_factor: float) -> tuple[np.ndarray, np.ndarray]:
    """Clipped Laplacian of the Gaussian-smoothed disparity, and where it is measured.

    The smoothing is a normalised convolution (the blurred image divided by the blurred valid
    mask), so invalid pixels (0) do not leak in as a step; pixels closer than 1.5 ``sigma_px``
    to an invalid one, where the smoothing still sees the step, are left out.

    Parameters
    ----------
    image : (H, W) uint8 ndarray
        Disparity-like frame, 0 = invalid.
    sigma_px : float
        Gaussian scale in pixels.
    clip_factor : float
        Responses are clipped to +- ``clip_factor`` times their median magnitude over the
        measured pixels (at least +- :data:`MIN_CLIP`).

    Returns
    -------
    edges : (H, W) float32 ndarray
        The clipped response, 0 where it is not measured.
    measured : (H, W) uint8 ndarray
        1 where the response is measured, else 0.
    """
    valid = (image > 0).view(np.uint8)
    size = 2 * math.ceil(3 * sigma_px) + 1  # the Gaussian to 3 sigma
    smoothed = cv2.GaussianBlur(image.astype(np.float32), (size, size), sigma_px)
    if cv2.countNonZero(valid) < valid.size:  # normalised convolution: divide by the weight
        weight = cv2.GaussianBlur(valid.astype(np.float32), (size, size), sigma_px)
        smoothed = cv2.divide(smoothed, cv2.max(weight, 1e-3))
    laplacian = cv2.Laplacian(smoothed, cv2.CV_32F, ksize=3)
    radius = max(1, math.ceil(1.5 * sigma_px))
    kernel = cv2.getStructuringElement(cv2.MORPH_RECT, (2 * radius + 1, 2 * radius + 1))
    measured = cv2.erode(valid, kernel, borderValue=1)
    laplacian *= measured
    # A robust scale of the responses: their median over every other row and column.
    responses = np.abs(laplacian[::2, ::2][measured[::2, ::2].view(bool)])
    scale = clip_factor * float(np.median(responses)) if responses.size else 0.0
    limit = max(scale, MIN_CLIP)
    edges = np.clip(laplacian, -limit, limit)
    return edges, measured


def structure_correlation(reference_edges: np.ndarray, reference_measured: np.ndarray,
                          current_edges: np.ndarray, current_measured: np.ndarray,
                          motion: Motion | None = None) -> tuple[float, float]:
    """Correlation of the reference's and the compensated current frame's edge images.

    The current frame's :func:`edge_image` is compensated by ``motion`` (the inverse warp,
    bilinear) and compared with the reference's on the pixels measured in both: the cosine
    similarity sum(a b) / sqrt(sum(a²) sum(b²)), 1 for the same edges in the same places, about
    0 for unrelated frames. The Laplacian vanishes on planes (the disparity of a plane is an
    affine function of the pixel coordinates), so only depth steps and creases count: smooth
    ramps such as a floor, which correlate under any small rotation, carry no weight.

    Parameters
    ----------
    reference_edges, reference_measured : (H, W) ndarrays
        :func:`edge_image` of the reference.
    current_edges, current_measured : (H, W) ndarrays
        :func:`edge_image` of the current frame.
    motion : Motion, optional
        The estimate to check (docs/design.md convention); None: the frames as they are.

    Returns
    -------
    correlation : float
        In [-1, 1]; -1 when no edge is measured in both.
    overlap : float
        Share of the reference's measured pixels that are measured in both.
    """
    if motion is not None:
        height, width = reference_edges.shape
        matrix = motion_matrix(motion, reference_edges.shape)
        current_edges = cv2.warpAffine(current_edges, matrix, (width, height),
                                       flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP,
                                       borderMode=cv2.BORDER_CONSTANT, borderValue=0)
        current_measured = cv2.warpAffine(current_measured, matrix, (width, height),
                                          flags=cv2.INTER_NEAREST | cv2.WARP_INVERSE_MAP,
                                          borderMode=cv2.BORDER_CONSTANT, borderValue=0)
    both = cv2.bitwise_and(reference_measured, current_measured)
    n_reference = cv2.countNonZero(reference_measured)
    overlap = cv2.countNonZero(both) / n_reference if n_reference else 0.0
    a = (reference_edges * both).ravel()
    b = (current_edges * both).ravel()
    norm = math.sqrt(float(np.dot(a, a)) * float(np.dot(b, b)))
    return (float(np.dot(a, b)) / norm if norm > 0 else -1.0), overlap


class Verifier:
    """The trust check of estimates against one reference, whose edge image is made once.

    An ``"ok"`` estimate passes when the compensated current frame

    1. covers at least ``min_overlap`` of the reference's measured pixels,
    2. has a :func:`structure_correlation` with the reference of at least
       ``min_correlation``, and
    3. matches the reference no worse than the uncompensated frame does, within
       ``null_margin``: an estimate must explain the frames better than no motion at all
       (this catches motions invented on frames that did not move).

    Parameters
    ----------
    reference : (H, W) uint8 ndarray
        Disparity-like reference, 0 = invalid.
    params : VerificationParams, optional
        Thresholds and scales; default :class:`VerificationParams` ().
    """

    def __init__(self, reference: np.ndarray, params: VerificationParams = VerificationParams()):
        self.params = params
        self._reference = edge_image(reference, params.sigma_px, params.clip_factor)

    def __call__(self, current: np.ndarray, motion: Motion) -> Motion:
        """``motion`` with the measured ``verify_correlation``, ``verify_overlap`` and
        ``verify_null_correlation`` (the uncompensated frame's) added to its diagnostics when it
        passes; otherwise a failed Motion with the status ``"unverified"``, the same
        diagnostics, ``verify_failed`` (``"overlap"``, ``"correlation"`` or ``"no_motion"``: the
        first test failed) and the rejected estimate as ``unverified_motion``. A Motion that
        is already a failure is returned as it is."""
        if not motion.ok:
            return motion
        params = self.params
        current_edges = edge_image(current, params.sigma_px, params.clip_factor)
        correlation, overlap = structure_correlation(*self._reference, *current_edges, motion)
        null_correlation, _ = structure_correlation(*self._reference, *current_edges)
        diagnostics = dict(motion.diagnostics, verify_correlation=correlation,
                           verify_overlap=overlap, verify_null_correlation=null_correlation)
        failed = ("overlap" if overlap < params.min_overlap else
                  "correlation" if correlation < params.min_correlation else
                  "no_motion" if null_correlation > correlation + params.null_margin else None)
        if failed is not None:
            return Motion.failed(UNVERIFIED, verify_failed=failed,
                                 unverified_motion=motion.as_tuple(), **diagnostics)
        return Motion(motion.angle_deg, motion.dx, motion.dy, diagnostics=diagnostics)
