"""SIFT peer (Kang et al. 2009, Table I "SIFT"; Lowe 2004): keypoints, ratio test, rigid RANSAC.

SIFT keypoints and descriptors are found on the valid interior of each median-filtered
(:func:`stabilizer.peers.preparation.denoised`) disparity image (never on the step to 0 = no
measurement), matched to the reference's by Lowe's ratio test, and a
rotation + translation (no scale) is fitted robustly: a rigid two-point RANSAC (every pair of
matches proposes a motion; see :func:`_rigid_ransac_inliers` for why not OpenCV's similarity
RANSAC) picks the consensus set, then the closed-form rigid fit about the image centre is
refitted on the matches within the RANSAC threshold of it, until that set settles (at most 3
fits; :func:`stabilizer.rigid_fit.fit_rigid`). Matches are counted once per point pair: SIFT
makes one keypoint per dominant orientation, and duplicates would inflate a consensus. Parameters
and why: docs/peers.md, "SIFT".

Statuses (``Motion.status``) besides ``"ok"``:
    ``empty_reference`` / ``empty_current``: (almost) no valid pixel.
    ``flat_reference`` / ``flat_current``: all valid pixels have one value.
    ``too_few_keypoints``: fewer than 2 keypoints in the reference or the current frame.
    ``too_few_matches``: fewer than ``min_inliers`` matches pass the ratio test.
    ``too_few_inliers``: RANSAC found no model or fewer than ``min_inliers`` inliers.

Diagnostics: ``n_reference_keypoints``, ``n_keypoints``, ``n_matches``, ``n_inliers``,
``residual_px`` (RMS of the inliers' residuals).
"""

from __future__ import annotations

import cv2
import numpy as np

from stabilizer.inputs import MAX_KERNEL_SIDE, check_integer, check_number
from stabilizer.motion import Motion, image_centre, transform_points
from stabilizer.peers.preparation import (
    check_median_ksize,
    denoised,
    frame_problem,
    peer_min_side,
    valid_interior,
)
from stabilizer.rigid_fit import fit_rigid

#: Most keypoints kept per frame: OpenCV takes the count as a C int (a larger one was a
#: cv2.error); a count above a frame's keypoints keeps them all, as 0 does.
MAX_FEATURES = 2**31 - 1
#: Most RANSAC hypotheses: 10,000 pairs of matches hold a pair of inliers with probability
#: 99.9% down to 2.6% inliers (log(0.001) / log(1 - 0.026^2)); every hypothesis scores every
#: match, so memory grows as their product (10^9 asked for 5 GB at 1,100 matches).
MAX_HYPOTHESES = 10_000


class SiftEstimator:
    """Rigid motion from SIFT matches against a reference analysed once.

    Parameters
    ----------
    reference : (H, W) uint8 ndarray
        Disparity-like reference, 0 = invalid.
    median_ksize : int, optional
        Median filter applied to both frames (0 or 1 = none). Default 5: ToF noise and speckle
        otherwise make keypoints of their own.
    ratio : float, optional
        Lowe's ratio test: a match is kept when its descriptor distance is below ``ratio``
        times the second-best one's. Default 0.75.
    ransac_threshold_px : float, optional
        Reprojection error (px) under which a match is an inlier. Default 3.
    min_inliers : int, optional
        Fewest inliers accepted as an estimate. Default 3 (two fix a rigid motion, the third
        confirms it).
    border_margin_px : int, optional
        Keypoints are detected only this far (px) from invalid pixels, at most 255. Default 3.
    contrast_threshold : float, optional
        SIFT's contrast threshold. Default 0.003, far below OpenCV's 0.04: disparity images
        have few, low-contrast corners (walls differ by a few gray levels).
    max_features : int, optional
        Keep the best N keypoints per frame (by response); 0 = all (OpenCV's default); at most
        :data:`MAX_FEATURES` (2**31 - 1). Default
        4000: matching is brute force, quadratic in the keypoints, and a frame of noise has
        about 600 per 176 x 144 pixels (30,000 at 1280 x 1024 took 40-65 s a frame); walking
        frames have about 100, so the cap binds only on large or noisy images.
    max_hypotheses : int, optional
        Most two-match rigid hypotheses RANSAC scores, at most :data:`MAX_HYPOTHESES` (10,000).
        Default 2000.
    edge_threshold : float, optional
        SIFT's edge threshold (keypoints whose principal curvature ratio exceeds it lie on an
        edge and are dropped). Default 20, OpenCV's 10 doubled: a disparity image's structure
        is mostly depth steps, and the corners of steps (a stair edge meeting a pillar) have
        strongly unequal curvatures.

    References
    ----------
    .. [1] D. G. Lowe, "Distinctive image features from scale-invariant keypoints", IJCV 60(2),
           91-110, 2004.
    .. [2] T.-K. Kang, H. Zhang and G.-T. Park, "Stereo-vision based motion stabilization of a
           humanoid robot for the environment recognition by type-2 fuzzy logic", MED 2009,
           Table I ("SIFT").
    """

    #: Smallest image side (pixels) whatever the parameters (docs/peers.md, "Image sizes").
    min_side = staticmethod(peer_min_side)

    def __init__(self, reference: np.ndarray, median_ksize: int = 5, ratio: float = 0.75,
                 ransac_threshold_px: float = 3.0, min_inliers: int = 3,
                 border_margin_px: int = 3, contrast_threshold: float = 0.003,
                 max_features: int = 4000, max_hypotheses: int = 2000,
                 edge_threshold: float = 20.0):
        check_number("ratio", ratio, 0.0, 1.0, open_low=True, open_high=True)
        check_number("ransac_threshold_px", ransac_threshold_px, 0.0, open_low=True)
        check_integer("min_inliers", min_inliers, 2)  # a rigid motion needs 2 points
        check_integer("border_margin_px", border_margin_px, 0, MAX_KERNEL_SIDE)
        check_number("contrast_threshold", contrast_threshold, 0.0)
        check_integer("max_features", max_features, 0, MAX_FEATURES)  # 0: every feature
        check_integer("max_hypotheses", max_hypotheses, 1, MAX_HYPOTHESES)
        check_number("edge_threshold", edge_threshold, 0.0, open_low=True)
        check_median_ksize(median_ksize)
        self.median_ksize = median_ksize
        self.ratio = ratio
        self.ransac_threshold_px = ransac_threshold_px
        self.min_inliers = min_inliers
        self.border_margin_px = border_margin_px
        self.max_hypotheses = max_hypotheses
        self._shape = reference.shape
        self._detector_params = dict(nfeatures=max_features, contrastThreshold=contrast_threshold,
                                     edgeThreshold=edge_threshold)
        self._sift, self._matcher = self._detector_and_matcher()
        self._reference_problem = frame_problem(reference, "reference")
        self._reference_points, self._reference_descriptors = self._features(
            denoised(reference, median_ksize))

    def _detector_and_matcher(self) -> tuple[cv2.SIFT, cv2.BFMatcher]:
        return cv2.SIFT_create(**self._detector_params), cv2.BFMatcher(cv2.NORM_L2)

    # OpenCV's detector and matcher do not pickle (a Stabilizer sent to another process): they
    # hold no state of the frames, so they are rebuilt from the parameters.
    def __getstate__(self) -> dict:
        state = self.__dict__.copy()
        del state["_sift"], state["_matcher"]
        return state

    def __setstate__(self, state: dict) -> None:
        self.__dict__.update(state)
        self._sift, self._matcher = self._detector_and_matcher()

    def _features(self, image: np.ndarray) -> tuple[np.ndarray, np.ndarray | None]:
        mask = valid_interior(image, self.border_margin_px)
        keypoints, descriptors = self._sift.detectAndCompute(image, mask)
        points = np.array([kp.pt for kp in keypoints], np.float64).reshape(-1, 2)
        return points, descriptors

    def estimate(self, current: np.ndarray) -> Motion:
        """Motion of ``current`` (uint8, same shape as the reference) relative to the reference."""
        problem = self._reference_problem or frame_problem(current, "current")
        if problem:
            return Motion.failed(problem)
        points, descriptors = self._features(denoised(current, self.median_ksize))
        diagnostics = {"n_reference_keypoints": len(self._reference_points),
                       "n_keypoints": len(points)}
        if min(len(self._reference_points), len(points)) < 2:
            return Motion.failed("too_few_keypoints", **diagnostics)
        pairs = self._matcher.knnMatch(self._reference_descriptors, descriptors, k=2)
        good = [first for first, second in pairs if first.distance < self.ratio * second.distance]
        diagnostics["n_matches"] = len(good)
        if len(good) < self.min_inliers:
            return Motion.failed("too_few_matches", **diagnostics)
        # SIFT gives one keypoint per dominant orientation: count each point pair once.
        pairs_xy = np.unique(np.hstack([self._reference_points[[m.queryIdx for m in good]],
                                        points[[m.trainIdx for m in good]]]), axis=0)
        reference_pts, current_pts = pairs_xy[:, :2], pairs_xy[:, 2:]
        inlier = _rigid_ransac_inliers(reference_pts, current_pts, self._shape,
                                       self.ransac_threshold_px, self.max_hypotheses)
        # Refit on the consensus set and re-select under the refined model until it settles.
        for _ in range(3):
            if inlier.sum() < self.min_inliers:
                return Motion.failed("too_few_inliers", **diagnostics)
            motion = fit_rigid(reference_pts[inlier], current_pts[inlier], self._shape).motion
            residuals = _residuals(motion, reference_pts, current_pts, self._shape)
            refined = residuals < self.ransac_threshold_px
            if np.array_equal(refined, inlier):
                break
            inlier = refined
        diagnostics.update(n_inliers=int(refined.sum()),
                           residual_px=float(np.sqrt(np.mean(residuals[refined] ** 2))))
        return Motion(motion.angle_deg, motion.dx, motion.dy, diagnostics=diagnostics)


def _residuals(motion: Motion, reference_pts: np.ndarray, current_pts: np.ndarray,
               shape: tuple[int, ...]) -> np.ndarray:
    """Distance (px) between each current point and its reference point moved by ``motion``."""
    return np.linalg.norm(transform_points(motion, reference_pts, shape) - current_pts, axis=1)


def _rigid_ransac_inliers(reference_pts: np.ndarray, current_pts: np.ndarray,
                          shape: tuple[int, ...], threshold_px: float,
                          max_hypotheses: int) -> np.ndarray:
    """Inlier mask of the best rigid motion hypothesised from two matches (RANSAC, rigid model).

    A similarity RANSAC (``cv2.estimateAffinePartial2D``) lets the scale absorb wrong matches
    on the few keypoints a disparity image has, so hypotheses here are rigid: every pair of
    matches whose two point distances agree within the threshold proposes an angle and a
    translation (all pairs when there are at most ``max_hypotheses``, else a seeded random
    subset, so results are repeatable). The hypothesis with most inliers wins, ties broken by the
    smaller sum of truncated residuals (MSAC).
    """
    n = len(reference_pts)
    first, second = np.triu_indices(n, k=1)
    if first.size > max_hypotheses:
        chosen = np.random.default_rng(0).choice(first.size, max_hypotheses, replace=False)
        first, second = first[chosen], second[chosen]
    ref_step = reference_pts[second] - reference_pts[first]
    cur_step = current_pts[second] - current_pts[first]
    ref_len = np.linalg.norm(ref_step, axis=1)
    rigid = (np.abs(np.linalg.norm(cur_step, axis=1) - ref_len) < 2 * threshold_px) & (
        ref_len > 2 * threshold_px)
    if not rigid.any():
        return np.zeros(n, bool)
    first, second = first[rigid], second[rigid]
    ref_step, cur_step = ref_step[rigid], cur_step[rigid]
    # R(a) turns a vector by -a in atan2's (y-down) measure, so a = atan2(p) - atan2(q).
    angles = (np.arctan2(ref_step[:, 1], ref_step[:, 0])
              - np.arctan2(cur_step[:, 1], cur_step[:, 0]))
    cos_a, sin_a = np.cos(angles)[:, None], np.sin(angles)[:, None]
    centre = np.array(image_centre(shape))
    ref_mid = (reference_pts[first] + reference_pts[second]) / 2 - centre
    cur_mid = (current_pts[first] + current_pts[second]) / 2 - centre
    shift_x = cur_mid[:, :1] - (cos_a * ref_mid[:, :1] + sin_a * ref_mid[:, 1:])
    shift_y = cur_mid[:, 1:] - (-sin_a * ref_mid[:, :1] + cos_a * ref_mid[:, 1:])
    p = reference_pts - centre  # hypotheses x points below
    q = current_pts - centre
    error_x = cos_a * p[:, 0] + sin_a * p[:, 1] + shift_x - q[:, 0]
    error_y = -sin_a * p[:, 0] + cos_a * p[:, 1] + shift_y - q[:, 1]
    residuals = np.minimum(np.hypot(error_x, error_y), threshold_px)
    inliers = residuals < threshold_px
    cost = residuals.sum(axis=1) - inliers.sum(axis=1) * (threshold_px * n)
    return inliers[int(np.argmin(cost))]
