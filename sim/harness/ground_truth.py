"""The exact image motion of a frame against its reference, from the simulator's poses.

docs/design.md, "Ground truth": unproject every valid reference pixel with its depth and the
intrinsics, move the 3-D point by the exact relative camera pose, project it into the current
camera, drop points that fall behind the camera, outside the image or behind a nearer surface,
and fit the 2-D rigid transform (rotation about the image centre, then translation; the
``stabilizer.motion`` convention) that maps the reference pixels to those projections in least
squares (``stabilizer.rigid_fit``, the fit the point-based peers use too). The residual RMS of
that fit is the part of the image motion no 2-D rigid model can explain (parallax, the zoom of
walking forward).

Camera frames follow MuJoCo: ``cam_mat`` columns are the camera's x (right), y (up) and z
(backward) axes in the world, the camera looks along -z, and image rows grow downward, so a
camera point (X, Y, Z) with planar depth d = -Z projects to u = cx + fx X / d, v = cy - fy Y / d.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from sim.world.camera import SR4000_INTRINSICS, CameraIntrinsics, Frame
from stabilizer.motion import Motion
from stabilizer.rigid_fit import fit_rigid

#: Fewest surviving correspondences for a fit; fewer gives Motion.failed("no_overlap").
MIN_POINTS = 50
#: Occlusion test: a projected point farther than the current measured depth by more than
#: ``abs + rel * depth`` is hidden. Generous enough for the SR4000's mm-level noise and the
#: mixed pixels at depth edges, tight enough to catch a real foreground object (>= 0.1 m).
OCCLUSION_ABS_M = 0.05
OCCLUSION_REL = 0.03
#: Points nearer than this to the current camera plane are treated as behind it.
MIN_DEPTH_M = 1e-3


@dataclass(frozen=True)
class GroundTruth:
    """The ground-truth motion of one frame and how well a 2-D rigid model explains it.

    Attributes:
        motion: the least-squares rigid motion (reference -> current pixels), or
            ``Motion.failed("no_overlap")`` when too few points survive.
        residual_rms_px: RMS distance (px) between the fitted and the true projections; NaN
            when the fit failed.
        n_points: number of correspondences that entered the fit.
    """

    motion: Motion
    residual_rms_px: float
    n_points: int

    @property
    def ok(self) -> bool:
        return self.motion.ok


@lru_cache(maxsize=8)
def _pixel_rays(intrinsics: CameraIntrinsics, stride: int):
    """Sampled pixel indices and their camera-frame rays per metre of planar depth."""
    rows, cols = np.mgrid[0:intrinsics.height:stride, 0:intrinsics.width:stride]
    rows, cols = rows.ravel(), cols.ravel()
    rays = np.stack([(cols - intrinsics.cx) / intrinsics.fx,
                     -(rows - intrinsics.cy) / intrinsics.fy,
                     -np.ones(rows.size)], axis=1)
    for array in (rows, cols, rays):
        array.flags.writeable = False  # shared by every call through the cache
    return rows, cols, rays


def _check_frames(reference: Frame, current: Frame, intrinsics: CameraIntrinsics, stride: int,
                  exact_depths: tuple[np.ndarray | None, np.ndarray | None]) -> None:
    expected = (intrinsics.height, intrinsics.width)
    for name, frame, exact in (("reference", reference, exact_depths[0]),
                               ("current", current, exact_depths[1])):
        if np.shape(frame.depth_m) != expected or np.shape(frame.valid) != expected:
            raise ValueError(f"{name} depth_m and valid must be {expected[0]} x {expected[1]} "
                             f"(the intrinsics' image size); got {np.shape(frame.depth_m)} and "
                             f"{np.shape(frame.valid)}")
        if exact is not None and np.shape(exact) != expected:
            raise ValueError(f"{name}_depth_m must be {expected[0]} x {expected[1]}; got "
                             f"{np.shape(exact)}")
        if np.shape(frame.cam_pos) != (3,) or np.shape(frame.cam_mat) != (3, 3):
            raise ValueError(f"{name} cam_pos must have shape (3,) and cam_mat (3, 3); got "
                             f"{np.shape(frame.cam_pos)} and {np.shape(frame.cam_mat)}")
    if isinstance(stride, bool) or not isinstance(stride, (int, np.integer)) or stride < 1:
        raise ValueError(f"stride must be a positive integer; got {stride!r}")


def _sample_depth(frame: Frame, exact: np.ndarray | None, rows: np.ndarray, cols: np.ndarray):
    """Depth at the given pixels and whether it is a surface: the exact depth when given."""
    depth = np.asarray(frame.depth_m if exact is None else exact)[rows, cols].astype(np.float64)
    surface = np.isfinite(depth) & (depth > 0)
    if exact is None:
        surface &= np.asarray(frame.valid)[rows, cols]
    return depth, surface


def ground_truth(reference: Frame, current: Frame,
                 intrinsics: CameraIntrinsics = SR4000_INTRINSICS, stride: int = 2, *,
                 reference_depth_m: np.ndarray | None = None,
                 current_depth_m: np.ndarray | None = None,
                 min_points: int = MIN_POINTS, occlusion_abs_m: float = OCCLUSION_ABS_M,
                 occlusion_rel: float = OCCLUSION_REL) -> GroundTruth:
    """Ground-truth Motion of ``current`` against ``reference`` (docs/design.md, "Ground truth").

    Args:
        reference, current: frames with planar depth, validity and exact camera poses.
        intrinsics: the pinhole both frames were taken with; default the SR4000's.
        stride: use every ``stride``-th pixel in x and y (2 keeps 1/4 of the pixels; the fit
            of thousands of points does not need more).
        reference_depth_m, current_depth_m: the exact planar depth of each frame (the
            noise-free render; 0 or non-finite where no surface), used instead of the frames'
            reported depth and validity. The reported depth is fine for sensor noise (it moves
            the truth by ~0.03 px) but not for phase-wrapped pixels (a surface beyond the
            unambiguous range reported at ~1 m has a false parallax: several px of error
            when the camera translates). Default: the frames' own depth and ``valid``.
        min_points: fewest surviving correspondences; below it the result is
            ``Motion.failed("no_overlap")``.
        occlusion_abs_m, occlusion_rel: a projected point is occluded when it lies farther
            than the current frame's valid depth at its pixel by more than
            ``occlusion_abs_m + occlusion_rel * depth``. Points landing on invalid current
            pixels are kept: their projection is exact whether or not the sensor saw them.
    """
    _check_frames(reference, current, intrinsics, stride, (reference_depth_m, current_depth_m))
    rows, cols, rays = _pixel_rays(intrinsics, int(stride))
    depth, usable = _sample_depth(reference, reference_depth_m, rows, cols)
    points = rays[usable] * depth[usable, None]

    # Relative pose: current_from_reference = cur_mat^T [ref_mat | ref_pos - cur_pos].
    current_mat = np.asarray(current.cam_mat, dtype=np.float64)
    rotation = current_mat.T @ np.asarray(reference.cam_mat, dtype=np.float64)
    translation = current_mat.T @ (np.asarray(reference.cam_pos, dtype=np.float64)
                                   - np.asarray(current.cam_pos, dtype=np.float64))
    moved = points @ rotation.T + translation
    moved_depth = -moved[:, 2]
    in_front = moved_depth > MIN_DEPTH_M
    safe_depth = np.where(in_front, moved_depth, 1.0)
    u = intrinsics.cx + intrinsics.fx * moved[:, 0] / safe_depth
    v = intrinsics.cy - intrinsics.fy * moved[:, 1] / safe_depth
    # Pixel centres are integers, so pixel j covers [j - 0.5, j + 0.5).
    inside = (in_front & (u >= -0.5) & (u < intrinsics.width - 0.5)
              & (v >= -0.5) & (v < intrinsics.height - 0.5))
    col_hit = np.clip(np.floor(u + 0.5), 0, intrinsics.width - 1).astype(np.intp)
    row_hit = np.clip(np.floor(v + 0.5), 0, intrinsics.height - 1).astype(np.intp)
    measured, measured_valid = _sample_depth(current, current_depth_m, row_hit, col_hit)
    occluded = measured_valid & (moved_depth > measured + occlusion_abs_m
                                 + occlusion_rel * measured)
    keep = inside & ~occluded
    n_points = int(np.count_nonzero(keep))
    if n_points < max(min_points, 2):
        return GroundTruth(Motion.failed("no_overlap", n_points=n_points), math.nan, n_points)

    source = np.stack([cols[usable][keep], rows[usable][keep]], axis=1).astype(np.float64)
    target = np.stack([u[keep], v[keep]], axis=1)
    fit = fit_rigid(source, target, (intrinsics.height, intrinsics.width))
    return GroundTruth(fit.motion, fit.residual_rms_px, n_points)
