"""ORB features and a RANSAC similarity fit: an egostab stabilizer that lives outside egostab.

An example of the plugin contract of egostab (docs/plugins.md): a class built as
``OrbEstimator(reference, **params)`` whose ``estimate(current)`` returns a
``stabilizer.motion.Motion``. ORB keypoints (Rublee et al. 2011) are found on the valid pixels
of the reference once and of each current frame, matched by Hamming distance with a cross
check, and ``cv2.estimateAffinePartial2D`` fits rotation, uniform scale and translation by
RANSAC; the scale is dropped and the matrix re-expressed in egostab's Motion convention (a
rotation about the image centre ((W - 1) / 2, (H - 1) / 2), counter-clockwise positive as
displayed) by ``stabilizer.motion.motion_from_matrix``.

Statuses (``Motion.status``) besides ``"ok"``:
    ``too_few_keypoints``: fewer than ``min_matches`` keypoints in the reference or the frame.
    ``too_few_matches``: fewer than ``min_matches`` cross-checked matches.
    ``too_few_inliers``: RANSAC found no model or fewer than ``min_matches`` inliers.

Diagnostics: ``n_reference_keypoints``, ``n_keypoints``, ``n_matches``, ``n_inliers``,
``scale`` (the fitted scale, near 1 for a rigid motion).
"""

from __future__ import annotations

import dataclasses
import math

import cv2
import numpy as np

from stabilizer.motion import Motion, motion_from_matrix

__version__ = "0.1.0"


class OrbEstimator:
    """Rigid motion from ORB matches against a reference analysed once.

    Parameters
    ----------
    reference : (H, W) uint8 ndarray
        Disparity-like reference, 0 = invalid (as egostab passes it).
    n_features : int, optional
        Most keypoints kept per frame. Default 500.
    fast_threshold : int, optional
        FAST corner threshold, gray levels. Default 10: disparity images have few strong
        corners, mostly at depth steps.
    ransac_threshold_px : float, optional
        Reprojection error (px) under which a match is an inlier. Default 3.
    min_matches : int, optional
        Fewest keypoints, matches and inliers accepted. Default 6.

    References
    ----------
    .. [1] E. Rublee, V. Rabaud, K. Konolige and G. Bradski, "ORB: an efficient alternative to
           SIFT or SURF", ICCV 2011.
    """

    def __init__(self, reference: np.ndarray, n_features: int = 500, fast_threshold: int = 10,
                 ransac_threshold_px: float = 3.0, min_matches: int = 6):
        if min_matches < 2:
            raise ValueError(f"min_matches must be >= 2 (a rigid motion needs two); "
                             f"got {min_matches}")
        self.shape = reference.shape
        self.ransac_threshold_px = float(ransac_threshold_px)
        self.min_matches = int(min_matches)
        # Small patches: the SR4000's 176 x 144 frames leave little room inside ORB's border.
        self._orb = cv2.ORB_create(nfeatures=n_features, fastThreshold=fast_threshold,
                                   edgeThreshold=15, patchSize=15)
        self._matcher = cv2.BFMatcher(cv2.NORM_HAMMING, crossCheck=True)
        self._reference_points, self._reference_descriptors = self._features(reference)

    def _features(self, image: np.ndarray):
        """Keypoint positions (N x 2, x y) and descriptors on the valid pixels of ``image``."""
        mask = np.where(image > 0, 255, 0).astype(np.uint8)
        keypoints, descriptors = self._orb.detectAndCompute(image, mask)
        points = np.array([keypoint.pt for keypoint in keypoints], np.float32).reshape(-1, 2)
        return points, descriptors

    def estimate(self, current: np.ndarray) -> Motion:
        """Motion of ``current`` relative to the reference (egostab's Motion convention)."""
        points, descriptors = self._features(current)
        diagnostics = {"n_reference_keypoints": len(self._reference_points),
                       "n_keypoints": len(points)}
        if min(len(self._reference_points), len(points)) < self.min_matches:
            return Motion.failed("too_few_keypoints", **diagnostics)
        matches = self._matcher.match(self._reference_descriptors, descriptors)
        diagnostics["n_matches"] = len(matches)
        if len(matches) < self.min_matches:
            return Motion.failed("too_few_matches", **diagnostics)
        source = self._reference_points[[match.queryIdx for match in matches]]
        target = points[[match.trainIdx for match in matches]]
        matrix, inliers = cv2.estimateAffinePartial2D(
            source, target, method=cv2.RANSAC, ransacReprojThreshold=self.ransac_threshold_px)
        diagnostics["n_inliers"] = 0 if inliers is None else int(inliers.sum())
        if matrix is None or diagnostics["n_inliers"] < self.min_matches:
            return Motion.failed("too_few_inliers", **diagnostics)
        diagnostics["scale"] = math.hypot(matrix[0, 0], matrix[1, 0])
        return dataclasses.replace(motion_from_matrix(matrix, self.shape),
                                   diagnostics=diagnostics)
