"""The trust check of every estimate: does the compensated current frame match the reference?

Every method's ``"ok"`` passes through :class:`Verifier` (``stabilizer.Stabilizer`` applies it
after the method's own criteria): the current frame, compensated by the estimated motion, is
compared with the reference on the pixels both measure, and an estimate that does not line the
two frames up, or that is not where they line up best, becomes a failure with the status
``"unverified"``. The comparison is :func:`structure_correlation`, the correlation of the frames'
depth edges; the check climbs from the estimate to the nearest optimum of that correlation
(:meth:`Verifier.local_optimum`) and judges the estimate against it; the depths themselves must
agree too (:func:`depth_disagreement`). Why these measures, the tests and these thresholds:
docs/method.md, section 11.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from typing import NamedTuple

import cv2
import numpy as np

from stabilizer.fncc import MaskedCorrelation, MaskedSpectra, surface_peak
from stabilizer.inputs import (
    MAX_ITERATIONS,
    MAX_SIGMA_PX,
    check_angles,
    check_flag,
    check_integer,
    check_number,
)
from stabilizer.motion import (
    Motion,
    image_centre,
    motion_from_matrix,
    motion_matrix,
    rotation_matrix,
    wrap_angle_deg,
)
from stabilizer.peers.preparation import even_dft_size

#: Status of an estimate that fails the check (docs/method.md, section 11).
UNVERIFIED = "unverified"
#: How far (full-resolution pixels along each axis) :meth:`Verifier.shift_rival` looks for a
#: rival shift. Farther shifts keep too little of the frames to outscore the estimate: on the
#: walking frames of docs/method.md, section 11, the whole frame decided as this did, at 0.6x
#: the cost.
RIVAL_REACH_PX = 72
#: How far (full-resolution pixels along each axis) :meth:`Verifier.far_offset` looks for the
#: shift that lines up the far depths' edges best: beyond the largest offset an estimate may
#: leave them at (:attr:`VerificationParams.max_far_offset_px`).
FAR_REACH_PX = 16
#: Every uint8 disparity, for the depth test's table of tolerances.
_LEVELS = np.arange(256, dtype=np.float32)
#: Smallest clip limit of the edge responses (gray levels per pixel²): a scene of flat
#: surfaces has a median response of 0, and its depth steps then count by their sign.
MIN_CLIP = 0.01


@dataclass(frozen=True)
class VerificationParams:
    """Thresholds and scales of the trust check (docs/method.md, section 11).

    Attributes:
        min_correlation: the least :func:`structure_correlation` of an ``"ok"`` estimate, taken
            at the better of the estimate and the check's own optimum near it. Default 0.40:
            on walking frames it keeps more accurate estimates and fewer large errors than
            0.35 on the estimate alone (docs/method.md, section 11).
        min_overlap: the least share of the reference's measured pixels that the compensated
            current frame also measures. Default 0.25: a walking camera's frames share well
            over half of the view; a check on less compares too little of it.
        max_offset_deg, max_offset_px: the largest distance in angle and in translation (at the
            image centre) between the estimate and the optimum of the check's correlation
            found from it (:meth:`Verifier.local_optimum`). An estimate farther away is not where
            the frames line up best. Defaults 3 degrees and 5 px: accurate walking estimates
            (within 2 degrees and 4 px of the truth) lie within them 99.9% of the time.
        null_margin: the frames did not move, as far as the check can tell, when the
            uncompensated current frame correlates with the reference no more than this below
            the optimum. Default 0.01: with 0.05, the long, straight edges of a corridor
            seen down its length correlated that well after accurate 1-2 px motions, and the
            check failed a third of those walking frames (docs/method.md, section 11).
        still_deg, still_px: on frames that did not move, the largest angle and translation an
            ``"ok"`` estimate may have. Defaults 1 degree and 1 px.
        moved_depth_share: the frames moved, whatever their edges say, when the uncompensated
            current frame disagrees in depth (:func:`depth_disagreement`) on at least this share
            more of the pixels both frames measure than the frame compensated by the estimate.
            Default 0.01: down a corridor, the far door's edges stay put while the near walls
            and floor move by 10-15 px; the edges then called accurate walking estimates
            invented motions (docs/method.md, section 11, "Still edges, moved depth"). 1: the
            edges alone decide.
        sigma_px: Gaussian scale (pixels) of the edge image; it sets the misalignment the check
            tolerates, about a pixel or two. At most 40 (:data:`~stabilizer.inputs.MAX_SIGMA_PX`).
            Default 2.
        clip_factor: edge responses (the Laplacian of the smoothed disparity) are clipped to
            +- this many times their median magnitude, so that a few strong depth steps (near
            objects: disparity grows as 1 / depth) do not outweigh all the others. Default 5.
        edge_floor_levels: where the clip limit (``clip_factor`` times the median response)
            of the reference or the current frame is below the response of a depth step this
            many gray levels deep (:func:`step_response`), the clip gives every response the
            weight of the strongest depth steps, a one-level step's too; on a surface that
            slopes away from the camera the quantized disparity steps by one level along
            contour lines, which slide over the surface as the camera walks along it and line
            up at motions the camera did not make. There tests 2 and 6 (the correlation and
            whether the frames moved) must pass on the strong edges as well, without the
            responses below that floor: they can fail an estimate that every response passes,
            never pass one it fails. Default 1.5 (docs/method.md, section 11, "Contours");
            0: never.
        optimum_iterations: most iterations of the climb to the optimum (ECC; it also stops
            when an iteration changes ECC's correlation coefficient by less than 1e-3, the
            termination epsilon of ``cv2.findTransformECC``). At most 1000
            (:data:`~stabilizer.inputs.MAX_ITERATIONS`). Default 10.
        full_resolution_offset_deg: when the climb, at half resolution, ends more than this
            from the estimate in rotation, it goes on from there at full resolution, where the
            optimum may lie a few degrees farther: test 3 then judges the estimate against the
            optimum of the frames' full edge images. Default 1.5 degrees, half the offset
            limit (docs/method.md, section 11, "Fresh seeds"); ``math.inf``: never.
        full_resolution_travel_deg: when the climb from the grid's candidate
            (:meth:`Verifier.candidate`), at half resolution, ends more than this from it, the
            candidate is climbed at full resolution too, and either end may be the rival of
            test 5. Default 2.5 degrees, half the grid's step: a climb that ends nearer the
            next angle of the grid, which the search ranked below the candidate, than the
            candidate may have gone astray on the coarse edges (docs/method.md, section 11,
            "Astray climbs" and "Half a step astray"); ``math.inf``: never.
        convincing_correlation: an estimate that turns beyond the grid of angles (plus
            ``max_offset_deg``), where no search looks for rivals, is ambiguous when its
            optimum scores below this. Default 0.7: the median accurate walking estimate's
            optimum scores about 0.68.
        candidate_margin: another explanation fails the estimate when it scores better than
            the estimate less this: the frames are then explained about as well elsewhere, and
            the check cannot tell which motion is right. Default 0.05 (docs/method.md, section
            11, "Ambiguity" and "Every shift").
        outside_margin: the same margin against an estimate that turns beyond the searched
            angles, which must explain the frames clearly better than a turn within them.
            Default 0.1.
        ridge_margin: the best shift at the estimate's rotation within the offset limits is
            pinned down when every shift just beyond its own offset limits (up to 2 px farther)
            scores more than this below it (plain masked NCC of the edge images); otherwise the
            estimate fails: the frames do not fix the motion within the limits (a ridge, such
            as a floor's horizon under a sideways shift). A shift there that cannot be scored
            (it leaves less than ``min_overlap``, or a flat overlap) fails the estimate too.
            A negative margin asks the next shifts to score better than the best. Default 0.03
            (docs/method.md, section 11, "Ridges").
        strong_edge_ridge: the shift must be pinned down on the strong edges too (the depth
            steps deeper than ``edge_floor_levels``, :func:`edge_images`): the same test of
            ``ridge_margin`` on their plain masked NCC. A wall that fills the view, seen at a
            slant above the floor, has no depth step but the floor's crease, which does not fix
            a sideways shift; the one-level contours of its disparity and the sensor's noise
            can, by a little, and at a motion the camera did not make (docs/method.md, section
            11, "Ridges of the depth steps"). Default True; False, or ``edge_floor_levels`` 0:
            every response alone.
        weighted_rivals: the end of a climb from the grid's candidate beyond the offset limits
            (test 5) is a rival also when its :func:`structure_correlation` weighted by the
            shares of both frames' edges that its overlap holds (``weighted=True``) exceeds the
            weighted correlation at the estimate's optimum: it lines up more of the frames, and
            better. A structure repeated across the view (a shelf's boards, a tower of alike
            boxes) lined up one period off leaves a smaller overlap that holds the repeated
            structure alone and correlates higher than the truth, whose overlap holds near
            furniture's parallax too (docs/method.md, section 11, "Repeated structures").
            Default True; False: the unweighted correlations alone decide.
        plain_shift_rivals: a peak of test 5's weighted shift surface beyond the offset limits
            (:meth:`Verifier.shift_rival`) that scores below the margin there is then a rival
            still when its plain masked NCC, not weighted, exceeds the best plain NCC within
            the limits: it lines up less of the frames, and better; where the two measures
            disagree, the check cannot tell which motion is right, as over the grid of angles
            with ``weighted_rivals``. The weight is for a repeated structure lined up one
            period off, whose smaller overlap correlates higher than the truth; but a wrong
            shift whose overlap keeps more of a smooth wall and floor can outscore, weighted,
            the truth that lines up the furniture's edges better. Default True, with
            ``image_border`` (docs/method.md, section 11, "Both measures" and "The image's
            borders": alone, with the borders' creases, it failed accurate estimates far more
            often than wrong ones); False: the weighted surface alone decides.
        image_border: the frame ends at the image's borders as at invalid pixels: the
            smoothing is the normalised convolution there too, and the pixels within 1.5
            ``sigma_px`` of a border are left out of the edges (:func:`edge_images`). Otherwise
            the smoothing reflects the frame at its borders, which turns the slope of a wall's
            disparity into a crease along the border: a depth step of the frame's own, the same
            in every frame, that lines up without any motion and can pin an estimate of no
            motion down where the scene does not (docs/method.md, section 11, "The image's
            borders"). Default True; False: the frame reflected at its borders.
        depth_tolerance_levels, depth_tolerance_share, depth_tolerance_noise: a pixel of the
            compensated current frame disagrees in depth with the reference when its disparity
            lies more than the larger of the first two (gray levels; a share of its own
            disparity), plus the third times the current frame's noise (:func:`noise_level`),
            outside the range of the reference's disparities within one pixel of it. Defaults 4
            levels, 0.2 and 2: the walking camera's own translation changes the distances of
            near surfaces by up to a fifth between a frame and its reference (docs/method.md,
            section 11, "Depth").
        max_depth_disagreement: the largest share of the pixels both frames measure that may
            disagree in depth under the estimate (:func:`depth_disagreement`). Default 0.08:
            one rigid scene seen twice agrees in depth where the edges line up; two scenes that
            share only a floor, whose objects' edges a sideways shift lines up, do not
            (docs/method.md, section 11, "Depth"). 1: off.
        max_far_offset_px: the largest shift (full-resolution pixels) at which the far half of
            the reference's depths (at or beyond its median distance) may line its depth edges
            up best with those of the frame compensated by the estimate
            (:meth:`Verifier.far_offset`). The image motion of far surfaces is the camera's
            turn, which stabilization undoes; near ones add the parallax of the camera's own
            translation (a sideways sway moves near furniture across far walls; walking forward
            spreads near walls apart). An estimate that leaves the far surfaces this far out of
            line followed the near ones. Default 7 px (docs/method.md, section 11, "Near and
            far"); ``math.inf``: off.
        far_margin: the far depths lined up best beyond ``max_far_offset_px`` fail the estimate
            only when they score more than this above their score at the estimate (weighted
            masked NCC, as :meth:`Verifier.shift_rival`'s): far surfaces with too little
            structure of their own to pin a shift down (a smooth floor, noise) peak anywhere by
            a little. Default 0.03 (docs/method.md, section 11, "Near and far").
        candidate_angles_deg: the angles the search tries. Default -15 to 15 in steps of 5, the
            walking range (stabilizer.peers.start_search uses the same grid).
        second_look_rivals: a method's second look at an estimate the check doubts (its
            ``second_look``, which :class:`stabilizer.Stabilizer` checks too) that passes the
            check but lines the depth edges up worse than the estimate, and lies beyond
            ``max_offset_deg`` or ``max_offset_px`` of it, fails the estimate as
            ``"ambiguous"``: two motions that far apart both pass, and the method's measure
            and the edges disagree on which is right. Default True (docs/method.md, section 12,
            "A second look", "Rivals"); False: the estimate stands.
        rejected_second_look_rivals: the same for a second look at an estimate that passed,
            climbed by the method's own measure from that estimate (its ``second_look_from``)
            to beyond ``max_offset_deg`` or ``max_offset_px`` of it, that the check rejects only
            for the edges' preference (``"not_optimum"``: the edges' own optimum lies beyond the
            limits of it; or ``"ambiguous"``: they line up another motion as well): the two
            measures disagree by more than the limits, on frames (large turns past near
            furniture) where the edges' optimum may lie between the two and neither can be
            trusted. Default True (docs/method.md, section 12, "Rejected rivals"); False: the
            estimate stands.
    """

    min_correlation: float = 0.40
    min_overlap: float = 0.25
    max_offset_deg: float = 3.0
    max_offset_px: float = 5.0
    null_margin: float = 0.01
    still_deg: float = 1.0
    still_px: float = 1.0
    moved_depth_share: float = 0.01
    sigma_px: float = 2.0
    clip_factor: float = 5.0
    edge_floor_levels: float = 1.5
    optimum_iterations: int = 10
    full_resolution_offset_deg: float = 1.5
    full_resolution_travel_deg: float = 2.5
    convincing_correlation: float = 0.7
    candidate_margin: float = 0.05
    outside_margin: float = 0.1
    ridge_margin: float = 0.03
    depth_tolerance_levels: float = 4.0
    depth_tolerance_share: float = 0.2
    depth_tolerance_noise: float = 2.0
    max_depth_disagreement: float = 0.08
    max_far_offset_px: float = 7.0
    far_margin: float = 0.03
    candidate_angles_deg: tuple[float, ...] = (-15.0, -10.0, -5.0, 0.0, 5.0, 10.0, 15.0)
    second_look_rivals: bool = True
    rejected_second_look_rivals: bool = True
    strong_edge_ridge: bool = True
    weighted_rivals: bool = True
    plain_shift_rivals: bool = True
    image_border: bool = True

    def __post_init__(self):
        # Every test compares with these: a NaN would switch one off silently.
        check_number("min_correlation", self.min_correlation, -1.0, 1.0)
        for name in ("min_overlap", "moved_depth_share", "max_depth_disagreement"):
            check_number(name, getattr(self, name), 0.0, 1.0)
        for name in ("max_offset_deg", "max_offset_px", "null_margin", "still_deg", "still_px",
                     "depth_tolerance_levels", "depth_tolerance_share", "depth_tolerance_noise"):
            check_number(name, getattr(self, name), 0.0)
        check_number("sigma_px", self.sigma_px, 0.0, MAX_SIGMA_PX, open_low=True)
        check_number("clip_factor", self.clip_factor, 0.0, open_low=True)
        check_number("edge_floor_levels", self.edge_floor_levels, 0.0, 255.0)
        check_integer("optimum_iterations", self.optimum_iterations, 1, MAX_ITERATIONS)
        for name in ("full_resolution_offset_deg", "full_resolution_travel_deg",
                     "max_far_offset_px"):
            if getattr(self, name) != math.inf:  # math.inf: never
                check_number(name, getattr(self, name), 0.0)
        check_number("convincing_correlation", self.convincing_correlation, -1.0, 1.0)
        for name in ("candidate_margin", "outside_margin", "ridge_margin",
                     "far_margin"):  # may be < 0
            check_number(name, getattr(self, name))
        check_angles("candidate_angles_deg", self.candidate_angles_deg)
        check_flag("second_look_rivals", self.second_look_rivals)
        check_flag("rejected_second_look_rivals", self.rejected_second_look_rivals)
        check_flag("strong_edge_ridge", self.strong_edge_ridge)
        check_flag("weighted_rivals", self.weighted_rivals)
        check_flag("plain_shift_rivals", self.plain_shift_rivals)
        check_flag("image_border", self.image_border)

    def beyond_offset(self, motion: Motion, other: Motion) -> bool:
        """Whether ``motion`` lies beyond ``max_offset_deg`` or ``max_offset_px`` of ``other``."""
        return (abs(float(wrap_angle_deg(motion.angle_deg - other.angle_deg)))
                > self.max_offset_deg
                or math.hypot(motion.dx - other.dx, motion.dy - other.dy) > self.max_offset_px)


def edge_image(image: np.ndarray, sigma_px: float, clip_factor: float,
               image_border: bool) -> tuple[np.ndarray, np.ndarray]:
    """Clipped Laplacian of the Gaussian-smoothed disparity, and where it is measured:
    :func:`edge_images` without a floor."""
    edges, _, measured, _ = edge_images(image, sigma_px, clip_factor, 0.0, image_border)
    return edges, measured


def edge_images(image: np.ndarray, sigma_px: float, clip_factor: float,
                floor_levels: float, image_border: bool
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray, bool]:
    """Clipped Laplacian of the Gaussian-smoothed disparity, the same without its weak
    responses, where they are measured, and whether the clip limit lies below the floor.

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
    floor_levels : float
        The responses whose magnitude (before the clip) is below ``floor_levels`` times the
        largest response of a one-level depth step (:func:`step_response`) are 0 in
        ``strong``.
    image_border : bool
        The frame ends at its borders as at invalid pixels (the outside counts as invalid,
        and the pixels within 1.5 ``sigma_px`` of a border are not measured); False: the
        smoothing reflects the frame at its borders (``cv2.BORDER_REFLECT_101``), and a slope
        becomes a crease there. No default: callers pass their check's
        (``VerificationParams.image_border``).

    Returns
    -------
    edges : (H, W) float32 ndarray
        The clipped response, 0 where it is not measured.
    strong : (H, W) float32 ndarray
        ``edges`` without the weak responses; ``edges`` itself when no response is weak.
    measured : (H, W) uint8 ndarray
        1 where the response is measured, else 0.
    floored : bool
        Whether the clip limit lies below the floor: the clip then gives a weak response the
        weight of the strongest depth steps.
    """
    valid = (image > 0).view(np.uint8)
    # The Gaussian to 3 sigma, filtered straight from uint8 to float32 (cv2.GaussianBlur's
    # kernel and border, without a float copy of the frame first).
    gaussian = cv2.getGaussianKernel(2 * math.ceil(3 * sigma_px) + 1, sigma_px, cv2.CV_32F)
    border = cv2.BORDER_CONSTANT if image_border else cv2.BORDER_REFLECT_101
    smoothed = cv2.sepFilter2D(image, cv2.CV_32F, gaussian, gaussian, borderType=border)
    if image_border or cv2.countNonZero(valid) < valid.size:
        # Normalised convolution: divide by the weight of the valid pixels.
        weight = cv2.sepFilter2D(valid, cv2.CV_32F, gaussian, gaussian, borderType=border)
        smoothed = cv2.divide(smoothed, cv2.max(weight, 1e-3))
    laplacian = cv2.Laplacian(smoothed, cv2.CV_32F, ksize=3)
    measured = cv2.erode(valid, _step_reach(sigma_px), borderValue=0 if image_border else 1)
    laplacian *= measured
    # A robust scale of the responses: their median over every other row and column.
    responses = np.abs(laplacian[::2, ::2][measured[::2, ::2].view(bool)])
    scale = clip_factor * _median(responses) if responses.size else 0.0
    limit = max(scale, MIN_CLIP)
    floor = floor_levels * step_response(sigma_px)
    weak = np.abs(laplacian) < floor if floor > 0 else None  # no response is below a floor of 0
    edges = np.clip(laplacian, -limit, limit, out=laplacian)
    if weak is None or not weak.any():
        return edges, edges, measured, limit < floor
    strong = edges.copy()
    strong[weak] = 0.0
    return edges, strong, measured, limit < floor


@functools.lru_cache(maxsize=8)
def step_response(sigma_px: float) -> float:
    """The largest magnitude of :func:`edge_images`' Laplacian (before its clip) across a
    straight depth step of one gray level: about 0.225 at ``sigma_px`` 2."""
    radius = math.ceil(3 * sigma_px)
    step = np.full((4 * radius + 8, 4 * radius + 8), 100, np.uint8)
    step[:, step.shape[1] // 2:] = 101
    gaussian = cv2.getGaussianKernel(2 * radius + 1, sigma_px, cv2.CV_32F)
    laplacian = cv2.Laplacian(cv2.sepFilter2D(step, cv2.CV_32F, gaussian, gaussian),
                              cv2.CV_32F, ksize=3)
    return float(np.abs(laplacian[:, radius:-radius]).max())


def _step_reach(sigma_px: float) -> np.ndarray:
    """The square of pixels within 1.5 ``sigma_px`` of a pixel (at least 1): how far the edge
    image's smoothing still sees a depth step, as a structuring element for ``cv2.erode`` and
    ``cv2.dilate``."""
    radius = max(1, math.ceil(1.5 * sigma_px))
    return cv2.getStructuringElement(cv2.MORPH_RECT, (2 * radius + 1, 2 * radius + 1))


def _median(values: np.ndarray) -> float:
    """``np.median`` of a 1-D float32 array, the same value at a quarter of its cost (it
    partitions in place)."""
    middle = values.size // 2
    if values.size % 2:
        values.partition(middle)
        return float(values[middle])
    values.partition((middle - 1, middle))
    return float((values[middle - 1] + values[middle]) / np.float32(2))


def structure_correlation(reference_edges: np.ndarray, reference_measured: np.ndarray,
                          current_edges: np.ndarray, current_measured: np.ndarray,
                          motion: Motion | None = None,
                          weighted: bool = False) -> tuple[float, float]:
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
    weighted : bool, optional
        Normalise by the whole frames' edges, sqrt(sum(A²) sum(B²)) over each whole frame
        (its edges are 0 where unmeasured, as :func:`edge_image` makes them), rather than by
        the overlap's: the cosine similarity times the geometric
        mean of the shares of each frame's edges (sum of squares) that the overlap holds, as
        :meth:`Verifier.shift_rival` weighs its shifts. A motion that lines up part of the
        frames well then scores below one that lines up most of them about as well.

    Returns
    -------
    correlation : float
        In [-1, 1]; -1 when no edge is measured in both.
    overlap : float
        Share of the reference's measured pixels that are measured in both.
    """
    if weighted:
        energies = float(np.dot(reference_edges.ravel(), reference_edges.ravel())) * float(
            np.dot(current_edges.ravel(), current_edges.ravel()))
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
    norm = math.sqrt(energies) if weighted else math.sqrt(float(np.dot(a, a))
                                                          * float(np.dot(b, b)))
    return (float(np.dot(a, b)) / norm if norm > 0 else -1.0), overlap


def disparity_range(image: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The smallest and the largest disparity within one pixel of each pixel (3 x 3 erosion
    and dilation of ``image``, a uint8 disparity-like frame, 0 = invalid): the values a pixel
    of another frame lined up with it to within a pixel may take."""
    window = np.ones((3, 3), np.uint8)
    return cv2.erode(image, window), cv2.dilate(image, window)


def noise_level(image: np.ndarray) -> float:
    """A robust standard deviation of ``image``'s noise (uint8, 0 = invalid), in gray levels:
    1.4826 times the median absolute difference from the 3 x 3 median, over the pixels whose
    3 x 3 neighbourhood is measured; 0 when there are none. Smooth surfaces and depth steps
    leave the median as it is, noise does not. (The pixel noise of
    :func:`stabilizer.peers.preparation.robust_value_range`, from the differences of horizontal
    neighbours, counts the one-level steps of a quantised ramp as noise: about 1 gray level on
    every noise-free walking frame, where this gives 0.)"""
    valid = (image > 0).view(np.uint8)
    inner = cv2.erode(valid, np.ones((3, 3), np.uint8), borderValue=0)
    residuals = cv2.absdiff(image, cv2.medianBlur(image, 3))
    # The median from the residuals' histogram (uint8): np.median's value, without a sort.
    counts = cv2.calcHist([residuals], [0], inner, [256], [0, 256]).ravel()
    n = int(counts.sum())
    if not n:
        return 0.0
    cumulative = np.cumsum(counts)

    def smallest(k: int) -> int:  # the k-th smallest residual, from 0
        return int(np.searchsorted(cumulative, k + 1))

    median = smallest(n // 2) if n % 2 else (smallest(n // 2 - 1) + smallest(n // 2)) / 2.0
    return 1.4826 * float(median)


def depth_disagreement(reference: np.ndarray, reference_range: tuple[np.ndarray, np.ndarray],
                       current: np.ndarray, motion: Motion, tolerance_levels: float,
                       tolerance_share: float, noise_allowance: float) -> float:
    """Share of the pixels measured in both frames where the compensated current frame
    disagrees in depth with the reference.

    The current frame is compensated by ``motion`` (the inverse warp, nearest neighbour, so
    that no disparity is invented between a near and a far surface) and a pixel disagrees when
    its disparity d lies more than max(``tolerance_levels``, ``tolerance_share`` d) +
    ``noise_allowance`` below the smallest or above the largest of the reference's within one
    pixel (:func:`disparity_range`), the allowance being a multiple of the current frame's
    :func:`noise_level`: a misalignment of a pixel at a depth step, a surface the camera's
    translation brought a fifth closer, or the current pixel's own noise (the reference's is
    within its range) still agrees. Two views of one rigid scene agree almost everywhere once
    lined up; two scenes that only share a floor disagree wherever one has an object and the
    other does not, even where the edges of their objects line up.

    Parameters
    ----------
    reference : (H, W) uint8 ndarray
        Disparity-like reference, 0 = invalid.
    reference_range : ((H, W) uint8, (H, W) uint8)
        :func:`disparity_range` of ``reference``.
    current : (H, W) uint8 ndarray
        Disparity-like current frame, 0 = invalid.
    motion : Motion
        The estimate (docs/design.md convention).
    tolerance_levels, tolerance_share, noise_allowance : float
        The tolerance: gray levels, a share of the current pixel's disparity, and gray levels
        for the current frame's noise.

    Returns
    -------
    float
        In [0, 1]; 1 when no pixel is measured in both.
    """
    height, width = reference.shape
    compensated = cv2.warpAffine(current, motion_matrix(motion, reference.shape), (width, height),
                                 flags=cv2.INTER_NEAREST | cv2.WARP_INVERSE_MAP,
                                 borderMode=cv2.BORDER_CONSTANT, borderValue=0)
    both = cv2.min(reference, compensated) > 0
    n_both = int(np.count_nonzero(both))
    if not n_both:
        return 1.0
    # The tolerance of every disparity d, floored: for integers, d < low - t exactly when
    # low - d > floor(t) (and d > high + t when d - high > floor(t)), so uint8 arithmetic
    # (cv2.subtract saturates at 0) decides as the float comparison would.
    tolerance = (np.maximum(np.float32(tolerance_levels), np.float32(tolerance_share) * _LEVELS)
                 + np.float32(noise_allowance))
    allowed = cv2.LUT(compensated, np.minimum(np.floor(tolerance), 255).astype(np.uint8))
    low, high = reference_range
    disagree = ((cv2.subtract(low, compensated) > allowed)
                | (cv2.subtract(compensated, high) > allowed))
    return float(np.count_nonzero(disagree & both)) / n_both


class Verifier:
    """The trust check of estimates against one reference, whose edge image is made once.

    From the estimate, the check first finds the nearest optimum of its own measure: ECC
    (``cv2.findTransformECCWithMask``, Euclidean; Evangelidis & Psarakis 2008) maximises the
    correlation of the two edge images, at half resolution, starting at the estimate
    (:meth:`local_optimum`), and on at full resolution when it ends more than
    ``full_resolution_offset_deg`` from the estimate (:meth:`full_resolution_optimum`). An
    ``"ok"`` estimate then passes when

    1. the compensated current frame covers at least ``min_overlap`` of the reference's
       measured pixels;
    2. the better of the estimate's and the optimum's :func:`structure_correlation` is at least
       ``min_correlation``: the depth edges line up there;
    3. the estimate lies within ``max_offset_deg`` and ``max_offset_px`` of the optimum: no
       nearby motion explains the frames clearly better (a wrong estimate that still overlaps
       some edges is not at the optimum);
    4. at most ``max_depth_disagreement`` of the pixels both frames measure disagree in depth
       under the estimate (:func:`depth_disagreement`): the frames show the same surfaces at
       the same distances, not only depth steps in the same places;
    5. an estimate that turns beyond the searched angles ``candidate_angles_deg`` (plus
       ``max_offset_deg``) has a convincing optimum (correlation at least
       ``convincing_correlation``): no search looks for rivals that far out; and no motion
       beyond the offset limits explains the frames about as well or better: not a
       shift at the estimate's rotation (every shift is scored, :meth:`shift_rival`; the
       continuation of a ridge through the estimate counts), nor the best motion of a search
       over the grid of angles (:meth:`candidate`, climbed to its own optimum;
       :meth:`_rival_candidate`): the estimate is not on a false peak, nor on one of two peaks
       the check cannot tell apart;
    6. when the uncompensated frame scores within ``null_margin`` of the optimum and agrees in
       depth about as well as the compensated one (less than ``moved_depth_share`` more of the
       pixels disagree: the frames did not move, as far as the check can tell), the estimate
       moves by at most ``still_deg`` and ``still_px``: no invented motion;
    7. (checked before the searches of test 5, which cost more) the far half of the
       reference's depths lines its depth edges up best within ``max_far_offset_px`` of the
       estimate, or not by more than ``far_margin`` better than at the estimate
       (:meth:`far_offset`): the estimate undoes the camera's turn, which moves the far
       surfaces, and did not follow the near ones' parallax.

    Judging the correlation at the optimum rather than at the estimate makes the check fair to
    estimates a pixel or two off on noisy frames, whose own correlation drops steeply with the
    offset (docs/method.md, section 11).

    Parameters
    ----------
    reference : (H, W) uint8 ndarray
        Disparity-like reference, 0 = invalid.
    params : VerificationParams, optional
        Thresholds and scales; default :class:`VerificationParams` ().
    """

    def __init__(self, reference: np.ndarray, params: VerificationParams = VerificationParams()):
        self.params = params
        self._last_measured: CurrentEdges | None = None  # see measure
        self._reference_disparity = reference
        self._reference_range = disparity_range(reference)
        edges, strong, measured, floored = edge_images(reference, params.sigma_px,
                                                       params.clip_factor,
                                                       params.edge_floor_levels,
                                                       params.image_border)
        # Tests 2 and 6 on the strong edges only where the floor applies to a frame.
        self._reference = (edges, measured)
        self._reference_strong = (strong if floored else edges, measured)
        self._reference_floored = floored
        self._reference_half = _half_resolution(*self._reference)
        half = self._reference_half[0]
        self._window = cv2.createHanningWindow(half.shape[::-1], cv2.CV_32F)
        self._padded_shape = tuple(even_dft_size(n) for n in half.shape)
        self._reference_windowed = self._windowed(half)
        # Every shift with an overlap, at half resolution (test 5).
        reach = min(RIVAL_REACH_PX // 2, min(half.shape) - 1)
        self._shifts = MaskedCorrelation(half.shape, reach, params.min_overlap)
        self._reference_shifts = self._shifts.spectra(half, self._reference_half[1].view(bool),
                                                      moving=False)
        self._within_offset = _within_offset(reach, params.max_offset_px)
        # Offsets (rows, columns) of the shifts one half-resolution pixel beyond the offset
        # limits of a shift: where a ridge through it continues.
        rows, cols = np.nonzero(~self._within_offset
                                & _within_offset(reach, params.max_offset_px + 2.0))
        self._ring = (rows - reach, cols - reach)
        # The shifts of test 5's ridge on the strong edges: those within the offset limits
        # and their rings, no farther (a smaller transform than every shift's).
        self._step_shifts = None
        if params.strong_edge_ridge and params.edge_floor_levels > 0:
            near = min(math.ceil(params.max_offset_px + 1.0), min(half.shape) - 1)
            self._step_shifts = MaskedCorrelation(half.shape, near, params.min_overlap)
            self._step_within = _within_offset(near, params.max_offset_px)
            steps_half = _half_resolution(strong, measured)
            self._reference_steps = self._step_shifts.spectra(
                steps_half[0], steps_half[1].view(bool), moving=False)
        # The far half of the reference's depths (test 7).
        self._far = MaskedCorrelation(half.shape, min(FAR_REACH_PX // 2, min(half.shape) - 1),
                                      params.min_overlap)
        self._reference_far = (self._far_spectra(reference)
                               if params.max_far_offset_px != math.inf else None)
        # The search's turn-backs depend on the frame size alone: made once per reference.
        centre = tuple(value / 2.0 for value in image_centre(self._reference[0].shape))
        self._turn_backs = [(angle, cv2.getRotationMatrix2D(centre, -angle, 1.0),
                             rotation_matrix(math.radians(angle)))
                            for angle in params.candidate_angles_deg]

    def _far_spectra(self, reference: np.ndarray) -> MaskedSpectra | None:
        """The reference's half-resolution edge image on its far depths, as the fixed frame of
        the far depths' masked correlation: the pixels at or below the median disparity of its
        measured pixels, with those within 1.5 ``sigma_px`` of them (:func:`_step_reach`, where
        the smoothing still sees their depth steps); None without such a pixel."""
        measured = reference[reference > 0]
        if not measured.size:
            return None
        far = ((reference > 0) & (reference <= np.median(measured))).view(np.uint8)
        half, half_measured = self._reference_half
        mask = cv2.resize(cv2.dilate(far, _step_reach(self.params.sigma_px)), half.shape[::-1],
                          interpolation=cv2.INTER_NEAREST)
        mask = cv2.bitwise_and(mask, half_measured)
        return self._far.spectra(half, mask.view(bool), moving=False) \
            if cv2.countNonZero(mask) else None

    def far_offset(self, compensated_half: tuple[np.ndarray, np.ndarray]
                   ) -> tuple[float, float] | None:
        """The length (full-resolution pixels) of the shift that lines the reference's far
        depths' edges (:meth:`_far_spectra`) up best with the current frame's compensated by
        the estimate (``compensated_half``: its half-resolution edge image and measured mask,
        bool), and how much better it scores there than at no shift (at the estimate):
        weighted masked NCC over every shift up to :data:`FAR_REACH_PX` along each axis
        (:class:`~stabilizer.fncc.MaskedCorrelation`, Padfield 2012; weighted as in
        :meth:`shift_rival`). None when there are no far depths, or their overlap is too small
        or flat at every shift."""
        if self._reference_far is None:
            return None
        reach = self._far.max_shift
        scores = self._far.surface(self._reference_far,
                                   self._far.spectra(*compensated_half, moving=True),
                                   weighted=True)
        found = surface_peak(scores, reach)
        if not math.isfinite(found.peak):
            return None
        return 2.0 * math.hypot(found.x, found.y), found.peak - float(scores[reach, reach])

    def _compensated_half(self, current_half: tuple[np.ndarray, np.ndarray],
                          motion: Motion) -> tuple[np.ndarray, np.ndarray]:
        """The current frame's half-resolution edge image and measured mask (bool), compensated
        by ``motion`` (the inverse warp; bilinear, the mask by nearest neighbour)."""
        half, measured = current_half
        size = half.shape[::-1]
        warp = motion_matrix(motion, self._reference[0].shape)
        warp[:, 2] *= 0.5  # a half-resolution pixel is x / 2: the rotation stays
        inverse = cv2.WARP_INVERSE_MAP
        return (cv2.warpAffine(half, warp, size, flags=cv2.INTER_LINEAR | inverse),
                cv2.warpAffine(measured, warp, size, flags=cv2.INTER_NEAREST | inverse).view(bool))

    def _windowed(self, half: np.ndarray, padded: np.ndarray | None = None) -> np.ndarray:
        """A half-resolution edge image times the Hanning window, zero-padded to even DFT sizes
        (an odd size biases ``cv2.phaseCorrelate``; stabilizer.peers.preparation.even_dft_size).
        ``padded``: a zero-padded array of that size to fill in place (its padding stays 0)."""
        if padded is None:
            padded = np.zeros(self._padded_shape, np.float32)
        np.multiply(half, self._window, out=padded[:half.shape[0], :half.shape[1]])
        return padded

    def candidate(self, current_half: tuple[np.ndarray, np.ndarray]) -> Motion:
        """The most likely motion over the angle grid ``candidate_angles_deg``, independent of
        any estimate.

        For each angle a, the current half-resolution edge image is turned back by a and the
        remaining shift t' found by phase correlation (``cv2.phaseCorrelate``); turning back
        about the image centre leaves t' = R(a)^-1 t, so the candidate is (a, R(a) t'), as in
        stabilizer.peers.start_search. The angle with the sharpest peak wins.
        """
        half, _ = current_half
        padded = np.zeros(self._padded_shape, np.float32)
        best_response, best = -math.inf, Motion(0.0, 0.0, 0.0)
        for angle, turn_back, turn in self._turn_backs:
            derotated = cv2.warpAffine(half, turn_back, half.shape[::-1], flags=cv2.INTER_LINEAR)
            shift_half, response = cv2.phaseCorrelate(self._reference_windowed,
                                                      self._windowed(derotated, padded))
            if response > best_response:
                shift = turn @ (2.0 * np.asarray(shift_half))
                best_response, best = response, Motion(angle, float(shift[0]), float(shift[1]))
        return best

    def local_optimum(self, current_half: tuple[np.ndarray, np.ndarray],
                      motion: Motion) -> Motion | None:
        """The motion near ``motion`` that maximises the edge images' correlation, or None
        when ECC gives up (too little structure in common).

        ECC runs on the edge images halved by ``cv2.pyrDown`` (a quarter of the cost; a half-
        resolution pixel is x / 2, so the warp's translation halves and its rotation stays).

        Parameters
        ----------
        current_half : ((H', W') float32, (H', W') uint8)
            :func:`edge_image` of the current frame at half resolution.
        motion : Motion
            The start (docs/design.md convention).
        """
        return self._ecc(self._reference_half, current_half, motion, 0.5)

    def full_resolution_optimum(self, current_edges: tuple[np.ndarray, np.ndarray],
                                motion: Motion) -> Motion | None:
        """:meth:`local_optimum` on the full-resolution edge images (:func:`edge_image` of
        the current frame), at four times the cost."""
        return self._ecc(self._reference, current_edges, motion, 1.0)

    def _ecc(self, reference_edges: tuple[np.ndarray, np.ndarray],
             current_edges: tuple[np.ndarray, np.ndarray], motion: Motion,
             scale: float) -> Motion | None:
        """ECC (Euclidean) from ``motion`` on edge images at ``scale`` times full resolution,
        or None when it gives up."""
        shape = self._reference[0].shape
        with np.errstate(over="ignore"):
            warp = motion_matrix(motion, shape).astype(np.float32)
        if not np.isfinite(warp).all():  # a shift beyond float32's range has no optimum
            return None
        warp[:, 2] *= scale
        (reference, reference_mask), (current, current_mask) = reference_edges, current_edges
        criteria = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS,
                    self.params.optimum_iterations, 1e-3)
        # ECC raises when its iterations do not converge (noisy frames, a start far down the
        # peak); its own 5 x 5 Gaussian pre-smoothing widens the basin enough. Only then: used
        # on every frame, it failed twice the accurate walking estimates (docs/method.md, 11).
        for gauss_size in (1, 5):
            try:
                _, found = cv2.findTransformECCWithMask(reference, current, reference_mask,
                                                        current_mask, warp.copy(),
                                                        cv2.MOTION_EUCLIDEAN, criteria,
                                                        gauss_size)
            except cv2.error:
                continue
            found[:, 2] /= scale
            return motion_from_matrix(found, shape)
        return None

    def measure(self, current: np.ndarray) -> CurrentEdges:
        """The check's measurements of ``current`` that no estimate changes, for
        :meth:`check` (one set serves the checks of several estimates of one frame, also of
        several methods' estimates: the last frame measured is kept, and a frame equal to it
        gets the same set, with what its checks have found so far)."""
        last = self._last_measured
        if last is not None and np.array_equal(last.disparity, current):
            return last
        params = self.params
        edges, steps, measured, floored = edge_images(current, params.sigma_px,
                                                      params.clip_factor,
                                                      params.edge_floor_levels,
                                                      params.image_border)
        strong = steps if floored else edges
        null_correlation, _ = structure_correlation(*self._reference, edges, measured)
        strong_null = (structure_correlation(*self._reference_strong, strong, measured)[0]
                       if floored or self._reference_floored else None)
        # A copy: the caller may reuse its array for the next frame.
        self._last_measured = CurrentEdges(current.copy(), noise_level(current),
                                           (edges, measured), (strong, measured),
                                           _half_resolution(edges, measured), null_correlation,
                                           strong_null, (steps, measured))
        return self._last_measured

    def __call__(self, current: np.ndarray, motion: Motion) -> Motion:
        """:meth:`check` of ``motion`` on the :meth:`measure` of ``current``."""
        return self.check(self.measure(current), motion) if motion.ok else motion

    def check(self, current: CurrentEdges, motion: Motion) -> Motion:
        """``motion`` with the check's measurements added to its diagnostics when it passes:
        ``verify_correlation``, ``verify_overlap``, ``verify_null_correlation`` (the
        uncompensated frame's), ``verify_optimum`` (angle, dx, dy), ``verify_optimum_correlation``,
        ``verify_offset_deg`` and ``verify_offset_px`` (the estimate's distance from the
        optimum), ``verify_depth_disagreement``, ``verify_far_offset`` (the offset and score
        gain of test 7) where it was measured, ``verify_null_depth_disagreement`` (the
        uncompensated frame's) where test 6 needed it, and where the floor applies
        (``edge_floor_levels``) ``verify_strong_correlation``,
        ``verify_strong_optimum_correlation`` and ``verify_strong_null_correlation`` (the same
        on the strong edges); otherwise a failed Motion with the
        status ``"unverified"``, the same diagnostics, ``verify_failed`` (``"overlap"``,
        ``"correlation"``, ``"not_optimum"``, ``"depth"``, ``"parallax"``, ``"ambiguous"`` or
        ``"no_motion"``: the first test failed; a turn beyond the searched angles without a
        convincing optimum adds ``verify_beyond_search`` (True), a rival ``verify_candidate`` and
        ``verify_candidate_correlation`` (and, where the weighted correlations decided,
        ``verify_candidate_weighted_correlation`` and ``verify_weighted_optimum_correlation``),
        and a rival shift (:meth:`shift_rival`, whose scores are its own)
        ``verify_shift_correlation``, the estimate's score on the same scale, ``verify_ridge``,
        ``verify_ridge_on_steps`` and ``verify_plain_shift``) and the rejected estimate as
        ``unverified_motion``. A Motion that is already a failure is returned as it is."""
        if not motion.ok:
            return motion
        params = self.params
        current_edges, current_half = current.edges, current.half
        null_correlation = current.null_correlation
        correlation, overlap = structure_correlation(*self._reference, *current_edges, motion)
        optimum = self.local_optimum(current_half, motion)
        if optimum is not None:  # the half-resolution climb may stop short of the optimum
            turn = abs(float(wrap_angle_deg(optimum.angle_deg - motion.angle_deg)))
            if turn > params.full_resolution_offset_deg:
                optimum = self.full_resolution_optimum(current_edges, optimum) or optimum
        if optimum is None:  # no optimum found: the estimate is judged by itself
            optimum, optimum_correlation = motion, correlation
        else:
            optimum_correlation, _ = structure_correlation(*self._reference, *current_edges,
                                                           optimum)
        offset_deg = abs(float(wrap_angle_deg(optimum.angle_deg - motion.angle_deg)))
        offset_px = math.hypot(optimum.dx - motion.dx, optimum.dy - motion.dy)
        disagreement = self._depth_disagreement(current, motion)
        diagnostics = dict(motion.diagnostics, verify_correlation=correlation,
                           verify_overlap=overlap, verify_null_correlation=null_correlation,
                           verify_optimum=optimum.as_tuple(),
                           verify_optimum_correlation=optimum_correlation,
                           verify_offset_deg=offset_deg, verify_offset_px=offset_px,
                           verify_depth_disagreement=disagreement)
        strong_correlations = None  # at the estimate and the optimum, where the floor applies
        if current.strong_null_correlation is not None:
            strong_correlations = [
                structure_correlation(*self._reference_strong, *current.strong, at)[0]
                for at in (motion, optimum)]
            diagnostics.update(verify_strong_correlation=strong_correlations[0],
                               verify_strong_optimum_correlation=strong_correlations[1],
                               verify_strong_null_correlation=current.strong_null_correlation)
        failed = ("overlap" if overlap < params.min_overlap else
                  "correlation" if (max(correlation, optimum_correlation) < params.min_correlation
                                    or (strong_correlations is not None
                                        and max(strong_correlations) < params.min_correlation))
                  else "not_optimum" if (offset_deg > params.max_offset_deg
                                         or offset_px > params.max_offset_px)
                  else "depth" if disagreement > params.max_depth_disagreement else None)
        beyond = self._beyond_search(motion)
        if failed is None and beyond and optimum_correlation < params.convincing_correlation:
            # No search looks for rivals near a turn beyond the grid of angles: only a
            # convincing optimum vouches for it.
            failed = "ambiguous"
            diagnostics["verify_beyond_search"] = True
        if failed is None:
            compensated_half = self._compensated_half(current_half, motion)
            far = self.far_offset(compensated_half)
            if far is not None:
                diagnostics["verify_far_offset"] = far
                if far[0] > params.max_far_offset_px and far[1] > params.far_margin:
                    failed = "parallax"
        if failed is None:
            rival = self.shift_rival(compensated_half, motion, current)
            if rival is not None:
                failed = "ambiguous"
                diagnostics.update(verify_candidate=rival.motion.as_tuple(),
                                   verify_candidate_correlation=rival.score,
                                   verify_shift_correlation=rival.estimate_score,
                                   verify_ridge=rival.ridge,
                                   verify_ridge_on_steps=rival.on_steps,
                                   verify_plain_shift=rival.plain)
        if failed is None:  # the search costs most of the check: only for what passed so far
            rival = self._rival_candidate(current, motion, optimum, optimum_correlation,
                                           beyond)
            if rival is not None:
                failed = "ambiguous"
                diagnostics.update(verify_candidate=rival[0].as_tuple(),
                                   verify_candidate_correlation=rival[1])
                if rival[2] is not None:  # the weighted correlations decided
                    diagnostics.update(verify_candidate_weighted_correlation=rival[2][0],
                                       verify_weighted_optimum_correlation=rival[2][1])
        if failed is None and (abs(float(wrap_angle_deg(motion.angle_deg))) > params.still_deg
                               or math.hypot(motion.dx, motion.dy) > params.still_px):
            still = (null_correlation >= optimum_correlation - params.null_margin
                     or (strong_correlations is not None and current.strong_null_correlation
                         >= strong_correlations[1] - params.null_margin))
            if still:  # the edges stayed put; the depth may say the frames moved all the same
                if current.null_disagreement is None:
                    current.null_disagreement = self._depth_disagreement(
                        current, Motion(0.0, 0.0, 0.0))
                diagnostics["verify_null_depth_disagreement"] = current.null_disagreement
                still = current.null_disagreement < disagreement + params.moved_depth_share
            failed = "no_motion" if still else None
        if failed is not None:
            return Motion.failed(UNVERIFIED, verify_failed=failed,
                                 unverified_motion=motion.as_tuple(), **diagnostics)
        return Motion(motion.angle_deg, motion.dx, motion.dy, diagnostics=diagnostics)

    def _depth_disagreement(self, current: CurrentEdges, motion: Motion) -> float:
        """:func:`depth_disagreement` of ``current`` compensated by ``motion``."""
        params = self.params
        return depth_disagreement(self._reference_disparity, self._reference_range,
                                  current.disparity, motion, params.depth_tolerance_levels,
                                  params.depth_tolerance_share,
                                  params.depth_tolerance_noise * current.noise)

    def shift_rival(self, compensated_half: tuple[np.ndarray, np.ndarray], motion: Motion,
                    current: CurrentEdges | None = None) -> ShiftRival | None:
        """A motion at the rotation of ``motion``, with a shift beyond the offset limits, that
        lines the depth edges up about as well as the estimate or better; None if there is none.

        The current frame's half-resolution edge image, compensated by ``motion``
        (``compensated_half``: edges and measured mask, bool), is correlated
        with the reference's at every shift that keeps ``min_overlap`` of the reference's
        measured pixels, all at once (masked NCC, :class:`~stabilizer.fncc.MaskedCorrelation`,
        Padfield 2012), each NCC weighted by the share of both frames' edges its overlap holds
        (a shift that lines up one of two alike objects lines up half the edges). A peak of that
        surface beyond the offset limits (a local maximum over its 3 x 3 neighbours, not the
        flank of the estimate's own peak) that scores more than the best shift within them less
        ``candidate_margin`` is a rival: a second object like the one the estimate lined up, or
        a ridge along which the edges fit many shifts (a floor's horizon under a sideways
        shift); the check cannot tell which motion is right. With ``plain_shift_rivals``, so is
        such a peak whose plain NCC, not weighted, exceeds the best plain NCC within the offset
        limits: it lines up less of the frames, and better. A ridge without a second peak (a
        single straight edge across the overlap) is a rival too: when no peak is, the best
        shift just beyond the offset limits of the best shift within them (up to 2 px farther)
        is one if its plain NCC, not weighted, is within ``ridge_margin`` of that best shift's,
        or if it cannot be scored (too little overlap, a flat one): the frames do not pin the
        shift down to the limits. With ``strong_edge_ridge`` and the frame's measurements
        (``current``), the same ridge test on the strong edges (``CurrentEdges.steps``) follows,
        over the shifts it needs alone: the depth steps must pin the shift down too.
        """
        compensated = self._shifts.spectra(*compensated_half, moving=True)
        plain, scores = self._shifts.surfaces(self._reference_shifts, compensated)
        here = float(scores[self._within_offset].max())
        peaks = cv2.dilate(scores, np.ones((3, 3), np.uint8)) == scores
        no_rival = self._within_offset | ~peaks  # within the limits, or no local maximum
        found = surface_peak(np.where(no_rival, -np.inf, scores), self._shifts.max_shift)
        if math.isfinite(here) and found.peak > here - self.params.candidate_margin:
            return self._shift_rival(motion, (found.x, found.y), here, found.peak)
        if self.params.plain_shift_rivals:
            plain_here = float(plain[self._within_offset].max())
            lined_up = surface_peak(np.where(no_rival, -np.inf, plain), self._shifts.max_shift)
            if math.isfinite(plain_here) and lined_up.peak > plain_here:
                return self._shift_rival(motion, (lined_up.x, lined_up.y), plain_here,
                                         lined_up.peak, plain=True)
        # No second peak; along a ridge there is none, but the next shifts score as high.
        ridge = _ridge_end(plain, self._within_offset, self._ring, self.params.ridge_margin)
        if ridge is None and self._step_shifts is not None and current is not None:
            if current.steps_half is None:
                current.steps_half = _half_resolution(*current.steps)
            steps = self._step_shifts.spectra(*self._compensated_half(current.steps_half, motion),
                                              moving=True)
            ridge = _ridge_end(self._step_shifts.surface(self._reference_steps, steps),
                               self._step_within, self._ring, self.params.ridge_margin)
            if ridge is not None:
                return self._shift_rival(motion, *ridge, ridge=True, on_steps=True)
        return None if ridge is None else self._shift_rival(motion, *ridge, ridge=True)

    @staticmethod
    def _shift_rival(motion: Motion, shift: tuple[float, float], here: float, score: float,
                     ridge: bool = False, on_steps: bool = False,
                     plain: bool = False) -> ShiftRival:
        """The :class:`ShiftRival` of a half-resolution ``shift`` from ``motion``."""
        turned = rotation_matrix(math.radians(motion.angle_deg)) @ (2.0 * np.asarray(shift))
        return ShiftRival(Motion(motion.angle_deg, motion.dx + float(turned[0]),
                                 motion.dy + float(turned[1])), here, score, ridge, on_steps,
                          plain)

    def _rival_candidate(self, current: CurrentEdges, motion: Motion, optimum: Motion,
                         optimum_correlation: float, beyond: bool
                         ) -> tuple[Motion, float, tuple[float, float] | None] | None:
        """A motion at another rotation than ``motion`` that explains the frames about as well
        or better, with its correlation and, where the weighted correlations decided
        (``weighted_rivals``), its weighted correlation and the optimum's; or None.

        The :meth:`candidate` of the grid of angles is searched for every estimate, however
        well its optimum (``optimum``, within the offset limits of ``motion``) scores: a false
        peak of a repeated or symmetric structure can score as high as the truth (the
        estimate's own rotation is searched by :meth:`shift_rival`). The candidate is climbed to
        its :meth:`local_optimum`, and also to its :meth:`full_resolution_optimum` when the
        half-resolution climb ends more than ``full_resolution_travel_deg`` from it. The better
        end beyond the offset limits of the estimate wins when it correlates better than the
        estimate's optimum less ``candidate_margin`` (two peaks
        that close cannot be told apart); against an estimate outside the searched angles, less
        ``outside_margin``: a turn beyond the walking range must explain the frames clearly
        better than one within it (a half turn can line up a point-symmetric object, say a
        box, as well as the truth). The candidate itself, on the grid, is no rival: a grid
        angle 2.5 degrees from a true turn lines the frames up almost as well as the turn
        (docs/method.md, section 11, "Fresh seeds"). With ``weighted_rivals``, an end that
        passes neither margin still wins when its correlation weighted by the shares of the
        frames' edges its overlap holds exceeds the optimum's.

        A candidate within the offset limits of both ``optimum`` and the estimate agrees with
        the estimate and is not climbed: the climb from there ends at that optimum (of 393 such
        candidates on the walking frames of docs/method.md, section 11, "Cost", climbed anyway,
        one ended beyond the offset limits of the estimate). The ends of the climbs depend on
        the frame alone: they are kept with its measurements (``CurrentEdges.candidate_ends``)
        for the checks of its other estimates, with the correlation of each once measured. Nor
        is the correlation of an end within the offset limits of the estimate measured: it
        cannot fail the estimate.
        """
        params = self.params
        if current.candidate is None:
            current.candidate = self.candidate(current.half)
        candidate = current.candidate
        if not (params.beyond_offset(candidate, optimum)
                or params.beyond_offset(candidate, motion)):
            return None
        if current.candidate_ends is None:
            ends = [self.local_optimum(current.half, candidate) or candidate]
            travel = abs(float(wrap_angle_deg(ends[0].angle_deg - candidate.angle_deg)))
            if travel > params.full_resolution_travel_deg:
                # Astray at half resolution: the full-resolution climb may stay near the
                # candidate.
                ends.append(self.full_resolution_optimum(current.edges, candidate) or candidate)
            current.candidate_ends = [[end, None] for end in ends]
        rivals = []
        for kept in current.candidate_ends:  # [end, its correlation once measured]
            if params.beyond_offset(kept[0], motion):
                if kept[1] is None:
                    kept[1] = structure_correlation(*self._reference, *current.edges,
                                                    kept[0])[0]
                rivals.append((kept[1], kept[0]))
        if not rivals:
            return None
        correlation, refined = max(rivals, key=lambda rival: rival[0])
        margin = params.outside_margin if beyond else params.candidate_margin
        if correlation > optimum_correlation - margin:
            return refined, correlation, None
        if params.weighted_rivals:
            at_optimum = structure_correlation(*self._reference, *current.edges, optimum,
                                               weighted=True)[0]
            for correlation, end in rivals:
                weighted = structure_correlation(*self._reference, *current.edges, end,
                                                 weighted=True)[0]
                if weighted > at_optimum:
                    return end, correlation, (weighted, at_optimum)
        return None

    def _beyond_search(self, motion: Motion) -> bool:
        """Whether ``motion`` turns beyond the searched angles ``candidate_angles_deg`` by more
        than ``max_offset_deg``."""
        widest = max(abs(angle) for angle in self.params.candidate_angles_deg)
        return (abs(float(wrap_angle_deg(motion.angle_deg)))
                > widest + self.params.max_offset_deg)



#: How many verifiers :func:`shared_verifier` keeps, the most recently asked for.
SHARED_VERIFIERS_KEPT = 4
_shared_verifiers: list[Verifier] = []


def shared_verifier(reference: np.ndarray,
                    params: VerificationParams = VerificationParams()) -> Verifier:
    """The :class:`Verifier` of ``reference`` with ``params``, made once for every estimator
    of an equal reference with equal parameters among the last :data:`SHARED_VERIFIERS_KEPT`
    asked for.

    Several methods scoring the same frames then analyse the reference once, and measure each
    current frame once (:meth:`Verifier.measure` keeps the last frame's measurements, the
    search over the grid of angles and its climbs among them, none of which depends on the
    estimate): the checks of six methods cost about a fifth less than six separate ones, with
    the same results. The verifier holds its own copy of the reference.
    """
    for index, verifier in enumerate(_shared_verifiers):
        if verifier.params == params and np.array_equal(verifier._reference_disparity,
                                                        reference):
            _shared_verifiers.append(_shared_verifiers.pop(index))
            return verifier
    verifier = Verifier(reference.copy(), params)
    _shared_verifiers.append(verifier)
    del _shared_verifiers[:-SHARED_VERIFIERS_KEPT]
    return verifier


@dataclass
class CurrentEdges:
    """What the check measures of a current frame whatever the estimate
    (:meth:`Verifier.measure`).

    Attributes:
        disparity: the frame itself (uint8, 0 = invalid), for :func:`depth_disagreement`.
        noise: its :func:`noise_level`.
        edges: the frame's edge image (response, measured mask; :func:`edge_images`).
        strong: the same without the weak responses where the floor applies
            (``edge_floor_levels``; :func:`edge_images`), else the same arrays.
        half: the edges at half resolution.
        null_correlation: the :func:`structure_correlation` of the uncompensated frame.
        strong_null_correlation: the same on the strong edges, where the floor applies to the
            frame or to the reference; None elsewhere.
        steps: the edges without the weak responses, wherever the floor applies or not.
        steps_half: the same at half resolution, once a check has needed it; None before.
        candidate: the best motion of the search over the grid of angles
            (:meth:`Verifier.candidate`), once a check has needed it; None before.
        candidate_ends: the ends of the candidate's climbs (:meth:`Verifier._rival_candidate`),
            each as [end, its :func:`structure_correlation` or None until a check needs it],
            once a check has needed them; None before.
        null_disagreement: the :func:`depth_disagreement` of the uncompensated frame, once a
            check has needed it (test 6); None before.
    """

    disparity: np.ndarray
    noise: float
    edges: tuple[np.ndarray, np.ndarray]
    strong: tuple[np.ndarray, np.ndarray]
    half: tuple[np.ndarray, np.ndarray]
    null_correlation: float
    strong_null_correlation: float | None
    steps: tuple[np.ndarray, np.ndarray]
    steps_half: tuple[np.ndarray, np.ndarray] | None = None
    candidate: Motion | None = None
    candidate_ends: list[list] | None = None
    null_disagreement: float | None = None


class ShiftRival(NamedTuple):
    """A rival of :meth:`Verifier.shift_rival`.

    Attributes:
        motion: the rival: the estimate's rotation; its shift, in whole half-resolution pixels
            (a peak is searched among the local maxima alone, so no neighbour refines it),
            turned by that rotation, added to the estimate's.
        estimate_score: the best score within the offset limits of the estimate.
        score: the rival's score, on the same scale (weighted for a peak, plain for a ridge
            and for ``plain``; -inf for a shift that cannot be scored).
        ridge: whether it continues a ridge rather than being a peak of its own.
        on_steps: whether that ridge is the strong edges' (``strong_edge_ridge``); the scores
            are then theirs.
        plain: whether a peak won on its plain NCC (``plain_shift_rivals``).
    """

    motion: Motion
    estimate_score: float
    score: float
    ridge: bool
    on_steps: bool
    plain: bool


def _ridge_end(plain: np.ndarray, within: np.ndarray, ring: tuple[np.ndarray, np.ndarray],
               margin: float) -> tuple[tuple[float, float], float, float] | None:
    """Where a ridge through the best shift within the offset limits goes on, for
    :meth:`Verifier.shift_rival`: the best shift within them (``within``) on the surface
    ``plain`` (rows dy, columns dx, centred on no shift), and the shifts of ``ring`` around it
    (row and column offsets); the best of those, as ((dx, dy) from no shift, the best shift's
    score, its score), when it scores within ``margin`` of the best shift or cannot be scored
    (-inf: too little overlap, a flat one, beyond the surface); None when every one scores
    lower, or no shift within the limits can be scored."""
    scored = np.where(within, plain, -np.inf)
    best = np.unravel_index(int(np.argmax(scored)), scored.shape)
    here = float(scored[best])
    if not math.isfinite(here):
        return None
    rows, cols = best[0] + ring[0], best[1] + ring[1]
    inside = (rows >= 0) & (rows < plain.shape[0]) & (cols >= 0) & (cols < plain.shape[1])
    beyond = np.full(rows.shape, -np.inf, np.float32)
    beyond[inside] = plain[rows[inside], cols[inside]]
    # A shift that cannot be scored is not shown to score lower: the frames do not pin the
    # shift down on that side.
    unscored = ~np.isfinite(beyond)
    if unscored.any():
        index = int(np.argmax(unscored))
    else:
        index = int(np.argmax(beyond))
        if not beyond[index] > here - margin:
            return None
    reach = plain.shape[0] // 2
    return (float(cols[index] - reach), float(rows[index] - reach)), here, float(beyond[index])


def _within_offset(reach: int, offset_px: float) -> np.ndarray:
    """Which half-resolution shifts of a surface over [-``reach``, ``reach``]² (rows dy,
    columns dx) lie within ``offset_px`` full-resolution pixels of no shift."""
    steps = np.arange(-reach, reach + 1)
    return 2.0 * np.hypot(*np.meshgrid(steps, steps, indexing="ij")) <= offset_px


def _half_resolution(edges: np.ndarray, measured: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """An edge image and its measured mask at half resolution (``cv2.pyrDown``; the mask by
    nearest neighbour)."""
    half = cv2.pyrDown(edges)
    return half, cv2.resize(measured, half.shape[::-1], interpolation=cv2.INTER_NEAREST)
