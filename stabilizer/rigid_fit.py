"""The 2-D rigid least-squares fit: the rotation about the image centre and the translation that
best carry one point set onto another, in the Motion convention (docs/design.md).

The closed form of Kabsch and Umeyama in two dimensions, without scale: for point sets p
(reference) and q (current), each taken about its centroid, the angle a that maximises
sum q . R(a) p, with R(a) the convention's rotation (:func:`stabilizer.motion.rotation_matrix`),
is

    a = atan2(sum (q_x p_y - q_y p_x), sum p . q),

and the translation carries the reference centroid onto the current one. One fit serves the
ground truth (sim/harness/ground_truth.py), SIFT and point-to-point ICP (docs/peers.md).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from stabilizer.motion import Motion, motion_from_rotation, rotation_matrix


@dataclass(frozen=True)
class RigidFit:
    """Result of :func:`fit_rigid`.

    Attributes:
        motion: the least-squares rigid Motion (reference -> current points).
        rotation: its 2 x 2 rotation R(a).
        reference_centred, current_centred: the two point sets about their centroids (N x 2).
    """

    motion: Motion
    rotation: np.ndarray
    reference_centred: np.ndarray
    current_centred: np.ndarray

    @cached_property
    def residual(self) -> np.ndarray:
        """The reference points moved by ``motion`` less the current points (N x 2, px): the
        part of the point motion no 2-D rigid model explains. Computed when first asked (the
        peers' iterations do not need it)."""
        return self.reference_centred @ self.rotation.T - self.current_centred

    @property
    def residual_rms_px(self) -> float:
        """RMS length (px) of :attr:`residual`."""
        return float(np.sqrt(np.mean(self.squared_residual)))

    @cached_property
    def squared_residual(self) -> np.ndarray:
        """The squared length of each row of :attr:`residual` (N, px²)."""
        residual = self.residual
        x, y = residual[:, 0], residual[:, 1]
        return x * x + y * y


def fit_rigid(reference_pts: np.ndarray, current_pts: np.ndarray,
              shape: tuple[int, ...]) -> RigidFit:
    """Least-squares rotation about the image centre plus translation (no scale) mapping
    reference points onto current ones.

    Parameters
    ----------
    reference_pts, current_pts : (N, 2) array_like
        Corresponding (x, y) pixel coordinates, N >= 2, row i of one matching row i of the
        other.
    shape : tuple of int
        Shape (H, W, ...) of the images the points lie in; the rotation is about their centre
        ((W - 1) / 2, (H - 1) / 2).

    Returns
    -------
    RigidFit
        The Motion, and on request the residual RMS of the fit.

    References
    ----------
    .. [1] W. Kabsch, "A solution for the best rotation to relate two sets of vectors", Acta
           Crystallographica A32, 922-923, 1976.
    .. [2] S. Umeyama, "Least-squares estimation of transformation parameters between two point
           patterns", IEEE Trans. PAMI 13(4), 376-380, 1991.
    """
    reference_pts = np.ascontiguousarray(reference_pts, np.float64)
    current_pts = np.ascontiguousarray(current_pts, np.float64)
    if (reference_pts.ndim != 2 or reference_pts.shape[1] != 2
            or reference_pts.shape != current_pts.shape):
        raise ValueError(f"reference_pts and current_pts must both be N x 2 arrays; got "
                         f"{reference_pts.shape} and {current_pts.shape}")
    if reference_pts.shape[0] < 2:
        raise ValueError(f"a rigid fit needs at least 2 points; got {reference_pts.shape[0]}")
    reference_mean, p = _centred(reference_pts)
    current_mean, q = _centred(current_pts)
    angle = math.atan2(float(np.sum(q[:, 0] * p[:, 1] - q[:, 1] * p[:, 0])), float(np.sum(p * q)))
    motion = motion_from_rotation(angle, reference_mean, current_mean, shape)
    return RigidFit(motion, rotation_matrix(angle), p, q)


def _centred(points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The centroid of C-contiguous N x 2 ``points`` and the points about it, column by column:
    the values of ``points.mean(axis=0)`` (which sums such an array from its first row to its
    last) and ``points - mean``, bit for bit, at a third of their cost (numpy reduces and
    broadcasts along an axis of length 2 slowly)."""
    n = points.shape[0]
    mean = np.array([np.cumsum(points[:, 0])[-1], np.cumsum(points[:, 1])[-1]]) / n
    centred = points.copy()
    centred[:, 0] -= mean[0]
    centred[:, 1] -= mean[1]
    return mean, centred
