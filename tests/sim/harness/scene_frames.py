"""Frames of a tiny ray-cast world of rectangles, with exact poses, for the harness's tests.

The world is a few planar rectangles (a back wall and boxes' faces); each frame is ray-cast from
a camera pose in MuJoCo's camera convention (columns of ``cam_mat`` = camera x right, y up,
z backward; the camera looks along -z), independently of the ground-truth code under test.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from sim.world.camera import SR4000_INTRINSICS, CameraIntrinsics, Frame
from stabilizer.inputs import depth_to_disparity

#: A camera at the origin looking along world +x with world +z up: x_cam = -y, y_cam = +z,
#: z_cam = -x.
LOOK_ALONG_X = np.array([[0.0, 0.0, -1.0], [-1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])


@dataclass(frozen=True)
class Rectangle:
    """A planar rectangle: centre and two orthogonal half-extent vectors (metres)."""

    centre: tuple[float, float, float]
    half_u: tuple[float, float, float]
    half_v: tuple[float, float, float]


def facing_rectangle(distance: float, lateral: float, height: float, half_width: float,
                     half_height: float) -> Rectangle:
    """A rectangle facing a camera that looks along +x: at x = ``distance``."""
    return Rectangle((distance, lateral, height), (0.0, half_width, 0.0), (0.0, 0.0, half_height))


def box_world(wall_m: float = 3.0) -> list[Rectangle]:
    """A wall at ``wall_m`` and three rectangles nearer the camera, off centre."""
    return [
        facing_rectangle(wall_m, 0.0, 0.0, 20.0, 20.0),
        facing_rectangle(1.2, 0.25, 0.1, 0.12, 0.18),
        facing_rectangle(1.8, -0.4, -0.2, 0.2, 0.1),
        facing_rectangle(2.2, 0.1, 0.35, 0.25, 0.08),
    ]


def camera_matrix(roll_deg: float = 0.0, yaw_deg: float = 0.0, pitch_deg: float = 0.0,
                  base: np.ndarray = LOOK_ALONG_X) -> np.ndarray:
    """``base`` turned about the camera's own axes: roll about z, yaw about y (up), pitch
    about x (right); positive by the right-hand rule about each camera axis."""
    turn = Rotation.from_euler("zyx", [roll_deg, yaw_deg, pitch_deg], degrees=True)
    return base @ turn.as_matrix()


def ray_cast(world: list[Rectangle], cam_pos: np.ndarray, cam_mat: np.ndarray,
             intrinsics: CameraIntrinsics = SR4000_INTRINSICS) -> np.ndarray:
    """Planar depth (float32, 0 where no surface) of ``world`` seen from the pose."""
    rows, cols = np.mgrid[0:intrinsics.height, 0:intrinsics.width]
    # A ray (x, y, -1) in camera coordinates reaches planar depth d at parameter t = d.
    rays_cam = np.stack([(cols - intrinsics.cx) / intrinsics.fx,
                         -(rows - intrinsics.cy) / intrinsics.fy,
                         -np.ones(rows.shape)], axis=-1).reshape(-1, 3)
    rays = rays_cam @ np.asarray(cam_mat).T
    origin = np.asarray(cam_pos, dtype=np.float64)
    best = np.full(rays.shape[0], np.inf)
    for rect in world:
        centre, half_u, half_v = (np.asarray(a, dtype=np.float64)
                                  for a in (rect.centre, rect.half_u, rect.half_v))
        normal = np.cross(half_u, half_v)
        with np.errstate(divide="ignore", invalid="ignore"):
            t = (normal @ (centre - origin)) / (rays @ normal)
        hit = origin + t[:, None] * rays - centre
        inside = ((np.abs(hit @ half_u) <= half_u @ half_u)
                  & (np.abs(hit @ half_v) <= half_v @ half_v) & (t > 0))
        best = np.where(inside & (t < best), t, best)
    depth = np.where(np.isfinite(best), best, 0.0)
    return depth.reshape(intrinsics.height, intrinsics.width).astype(np.float32)


def render_frame(world: list[Rectangle], cam_pos, cam_mat, index: int = 0, time_s: float = 0.0,
                 intrinsics: CameraIntrinsics = SR4000_INTRINSICS) -> Frame:
    """A noise-free Frame of ``world`` from the pose."""
    cam_pos = np.asarray(cam_pos, dtype=np.float64)
    depth = ray_cast(world, cam_pos, cam_mat, intrinsics)
    return Frame(index=index, time_s=time_s, depth_m=depth, valid=depth > 0,
                 disparity8=depth_to_disparity(depth), cam_pos=cam_pos,
                 cam_mat=np.asarray(cam_mat, dtype=np.float64))
