"""Synthetic depth scenes with a known answer, for the stabilizer's tests and benchmarks.

A scene is a float32 depth image (metres, 0 = no measurement) of a back wall with a few objects
in front of it at different depths: boxes (rotated rectangles), cylinders seen end-on
(ellipses) and slanted planes (quadrilaterals whose depth varies across them). Everything is
drawn with OpenCV and is a pure function of the seed.
"""

from __future__ import annotations

import cv2
import numpy as np

from stabilizer.motion import Motion

SR4000_SHAPE = (144, 176)


def make_depth_scene(seed: int, shape: tuple[int, int] = SR4000_SHAPE, n_objects: int = 4,
                     wall_m: float = 4.5, floor: bool = False) -> np.ndarray:
    """A depth image of a wall with objects in front of it, a pure function of ``seed``.

    Objects keep clear of the image border by 15% so that moderate motions keep them in view.

    Parameters
    ----------
    seed : int
        Seed of the scene's random layout.
    shape : (int, int), optional
        (H, W). Default the SR4000's 144 x 176.
    n_objects : int, optional
        Objects at 0.8-3.5 m, each a box, an end-on cylinder or a slanted plane. Default 4.
    wall_m : float, optional
        Depth of the back wall in metres. Default 4.5.
    floor : bool, optional
        The lower quarter is a floor plane whose depth grows toward the wall. Default False.

    Returns
    -------
    (H, W) ndarray of float32
        Depth in metres.
    """
    rng = np.random.default_rng(seed)
    height, width = shape
    depth = np.full(shape, wall_m, np.float32)
    if floor:
        rows = np.arange(height * 3 // 4, height)
        ramp = np.linspace(wall_m, 1.2, rows.size, dtype=np.float32)
        depth[rows, :] = ramp[:, None]
    object_depths = np.sort(rng.uniform(0.8, 3.5, n_objects))[::-1]  # far ones drawn first
    for kind, object_depth in zip(rng.integers(0, 3, n_objects), object_depths):
        cx = rng.uniform(0.25, 0.75) * width
        cy = rng.uniform(0.25, 0.75) * height
        half_w = rng.uniform(0.08, 0.18) * width
        half_h = rng.uniform(0.08, 0.2) * height
        angle = rng.uniform(0.0, 180.0)
        mask = np.zeros(shape, np.uint8)
        if kind == 1:  # cylinder seen end-on
            cv2.ellipse(mask, (int(cx), int(cy)), (int(half_w), int(half_h)), angle, 0, 360, 1, -1)
        else:  # box face or slanted plane
            corners = cv2.boxPoints(((cx, cy), (2 * half_w, 2 * half_h), angle))
            cv2.fillPoly(mask, [np.rint(corners).astype(np.int32)], 1)
        inside = mask.astype(bool)
        if kind == 2:  # slanted plane: depth changes by up to 0.3 m across it
            ys, xs = np.nonzero(inside)
            tilt = rng.uniform(-0.3, 0.3) * (xs - cx) / max(half_w, 1.0)
            depth[ys, xs] = object_depth + tilt.astype(np.float32)
        else:
            depth[inside] = object_depth
    return depth


def random_motion(rng: np.random.Generator, max_angle_deg: float = 15.0,
                  max_shift_px: float = 40.0) -> Motion:
    """A rigid motion with angle and shifts drawn uniformly within the given bounds.

    Parameters
    ----------
    rng : numpy.random.Generator
        Source of the draws.
    max_angle_deg : float, optional
        Angles in [-max, max]. Default 15, beyond the +-12 degrees of a walking camera (Kang et
        al. 2009, section III-B).
    max_shift_px : float, optional
        Shifts in [-max, max] along each axis. Default 40, the paper's walking peaks.

    Returns
    -------
    Motion
    """
    return Motion(float(rng.uniform(-max_angle_deg, max_angle_deg)),
                  float(rng.uniform(-max_shift_px, max_shift_px)),
                  float(rng.uniform(-max_shift_px, max_shift_px)))
