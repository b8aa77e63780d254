"""The SR4000's pinhole intrinsics and one rendered frame of it."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class CameraIntrinsics:
    """Pinhole intrinsics in pixels; image x right, y down; (cx, cy) the principal point."""

    width: int
    height: int
    fx: float
    fy: float
    cx: float
    cy: float

    @classmethod
    def from_fov(cls, width: int, height: int, hfov_deg: float, vfov_deg: float):
        """Square-pixel intrinsics from a field of view, principal point at the image centre."""
        fx = (width / 2.0) / math.tan(math.radians(hfov_deg) / 2.0)
        fy = (height / 2.0) / math.tan(math.radians(vfov_deg) / 2.0)
        return cls(width, height, fx, fy, (width - 1) / 2.0, (height - 1) / 2.0)

    @property
    def matrix(self) -> np.ndarray:
        return np.array([[self.fx, 0.0, self.cx], [0.0, self.fy, self.cy], [0.0, 0.0, 1.0]])


#: SR4000 standard lens: 176 x 144 pixels, 43.6 deg x 34.6 deg (MESA SR4000 datasheet).
SR4000_INTRINSICS = CameraIntrinsics.from_fov(176, 144, 43.6, 34.6)


@dataclass(frozen=True)
class Frame:
    """One SR4000 frame and the exact pose it was taken from.

    Attributes:
        index: frame number in the run, from 0.
        time_s: simulation time at the middle of the integration window.
        depth_m: H x W float32 depth along the optical axis, metres; 0 where invalid.
        valid: H x W bool, True where the sensor reports a measurement.
        disparity8: H x W uint8 disparity-like image (stabilizer.depth_to_disparity), 0 invalid.
        cam_pos: (3,) camera position in the world, metres.
        cam_mat: (3, 3) camera orientation, columns = camera axes in world coordinates, in
            MuJoCo's camera convention (x right, y up, looking along -z), as ``data.cam_xmat``.
        true_depth_m: H x W float32 exact planar depth of the scene at mid-exposure (no sensor
            effects), when the frame comes from a simulator; the ground truth uses it.
    """

    index: int
    time_s: float
    depth_m: np.ndarray
    valid: np.ndarray
    disparity8: np.ndarray
    cam_pos: np.ndarray
    cam_mat: np.ndarray
    true_depth_m: np.ndarray | None = None
