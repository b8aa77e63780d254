"""The exact image motion of a frame against its reference, from the simulator's poses.

docs/design.md, "Ground truth": unproject every valid reference pixel with its depth and the
intrinsics, move the 3-D point by the exact relative camera pose, project it into the current
camera, drop points that fall behind the camera, outside the image or behind a nearer surface,
and fit the 2-D rigid transform (rotation about the image centre, then translation; the
``stabilizer.motion`` convention) that maps the reference pixels to those projections in least
squares (``stabilizer.rigid_fit``, the fit the point-based peers use too). The residual RMS of
that fit is the part of the image motion no 2-D rigid model can explain (parallax, the zoom of
walking forward).

The ground truth keeps the sampled correspondences (:class:`Correspondences`), so an estimate
can be scored by its end-point error: the distance between where the estimate sends each
reference point and where that point truly went. The least-squares fit minimises the squared
end-point error, so the fit's own RMS end-point error (its residual RMS) is the exact lower
bound of the RMS end-point error of any 2-D rigid estimate on those points; the fit's mean
end-point error is close to, but not exactly, the lower bound of the mean.

Camera frames follow MuJoCo: ``cam_mat`` columns are the camera's x (right), y (up) and z
(backward) axes in the world, the camera looks along -z, and image rows grow downward, so a
camera point (X, Y, Z) with planar depth d = -Z projects to u = cx + fx X / d, v = cy - fy Y / d.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import lru_cache

import numpy as np

from sim.world.camera import SR4000_INTRINSICS, CameraIntrinsics, Frame
from stabilizer.motion import OK, Motion, motion_matrix, transform_points
from stabilizer.rigid_fit import fit_rigid

#: Fewest surviving correspondences for a fit; fewer gives Motion.failed(NO_OVERLAP).
MIN_POINTS = 50
#: The status of a truth that could not be fitted, and every status a truth can have (the
#: ``truth_status`` column of frames.csv and truth.csv; compared as written, case included).
NO_OVERLAP = "no_overlap"
TRUTH_STATUSES = (OK, NO_OVERLAP)
#: Occlusion test: a projected point farther than the current measured depth by more than
#: ``abs + rel * depth`` is hidden. Generous enough for the SR4000's mm-level noise and the
#: mixed pixels at depth edges, tight enough to catch a real foreground object (>= 0.1 m).
OCCLUSION_ABS_M = 0.05
OCCLUSION_REL = 0.03
#: Points nearer than this to the current camera plane are treated as behind it.
MIN_DEPTH_M = 1e-3
#: Depths at or beyond this are no surface: the renderer gives pixels that see nothing its far
#: clip plane (20 m in an assembled world, 30 m in a scene compiled alone). Safely below both,
#: above the farthest wall of the shipped scenes at their default sizes (the back of the
#: corridor's end room, at most about 11 m from the start) and above the SR4000's 10 m reach.
MAX_DEPTH_M = 15.0


@dataclass(frozen=True, eq=False)
class Correspondences:
    """Sampled reference pixels and where each truly went in the current frame.

    Attributes:
        source_px: N x 2 float32 (x, y) reference pixels (every ``stride``-th pixel).
        target_px: N x 2 float32 (x, y) projections of the same surface points in the current
            frame.
        shape: (height, width) of the images (the centre of rotation of a Motion).
    """

    source_px: np.ndarray
    target_px: np.ndarray
    shape: tuple[int, int]

    def __post_init__(self):
        # Column-major: x and y each contiguous, for the column arithmetic below.
        for name in ("source_px", "target_px"):
            object.__setattr__(self, name, np.asfortranarray(getattr(self, name), np.float32))

    def end_point_error(self, motion: Motion) -> tuple[float, float]:
        """Mean and RMS distance (px) between where ``motion`` sends each source pixel and its
        true target.

        The ``motion_matrix`` applied column by column in float32 (about 35 us for 6,000
        points, half of a float64 matrix product; the rounding, ~1e-5 px, is far below any
        error worth reporting), summed in float64 from first to last. Element-wise arithmetic
        and a sequential sum (``cumsum``; ``np.sum``'s pairwise SIMD order depends on the
        buffer's alignment, OpenCV's ``magnitude`` on threads), so the same frame gives the same
        figure bit for bit in any process.
        """
        (x, y), (to_x, to_y) = self.source_px.T, self.target_px.T
        squared = np.zeros(len(x), np.float32)
        with np.errstate(over="ignore", invalid="ignore"):
            matrix = motion_matrix(motion, self.shape).astype(np.float32)
            for row, target in zip(matrix, (to_x, to_y)):
                miss = x * row[0]
                miss += y * row[1]
                miss += row[2]
                miss -= target
                miss *= miss
                squared += miss
        total = float(np.cumsum(squared, dtype=np.float64)[-1])
        np.sqrt(squared, out=squared)
        n = len(squared)
        mean = float(np.cumsum(squared, dtype=np.float64)[-1]) / n
        if math.isfinite(mean) and math.isfinite(total):
            return mean, math.sqrt(total / n)
        return self._wide_end_point_error(motion)

    def _wide_end_point_error(self, motion: Motion) -> tuple[float, float]:
        """:meth:`end_point_error` of a motion whose misses overflow float32 (beyond about
        1e19 px): in float64, with distances scaled by the largest so that squares do not
        overflow either; infinite only beyond float64's range."""
        matrix = motion_matrix(motion, self.shape)
        source = self.source_px.astype(np.float64)
        miss = source @ matrix[:, :2].T + matrix[:, 2] - self.target_px
        distance = np.hypot(miss[:, 0], miss[:, 1])
        largest = float(distance.max())
        if not math.isfinite(largest) or largest == 0.0:
            return largest, largest
        scaled = distance / largest
        return (largest * float(np.cumsum(scaled)[-1]) / len(distance),
                largest * math.sqrt(float(np.cumsum(scaled * scaled)[-1]) / len(distance)))


@dataclass(frozen=True)
class GroundTruth:
    """The ground-truth motion of one frame and how well a 2-D rigid model explains it.

    Attributes:
        motion: the least-squares rigid motion (reference -> current pixels), or
            ``Motion.failed("no_overlap")`` when too few points survive.
        residual_rms_px: RMS distance (px) between the fitted and the true projections; NaN
            when the fit failed.
        n_points: number of correspondences that entered the fit.
        residual_mean_px: mean distance (px) between the fitted and the true projections (the
            fit's mean end-point error); NaN when the fit failed or is not known.
        correspondences: the points of the fit, to score estimates by their end-point error;
            None when the fit failed or the truth was given without them. Not compared.
    """

    motion: Motion
    residual_rms_px: float
    n_points: int
    residual_mean_px: float = math.nan
    correspondences: Correspondences | None = field(default=None, compare=False, repr=False)

    @property
    def ok(self) -> bool:
        return self.motion.ok

    @classmethod
    def exact(cls, motion: Motion, source_px: np.ndarray, shape: tuple[int, ...]) -> "GroundTruth":
        """The truth of a motion known exactly (a synthetic warp), with a residual of 0.

        ``source_px`` (N x 2, x y) go exactly where ``motion`` sends them; those that leave
        the image are dropped, as in :func:`ground_truth`.
        """
        height, width = int(shape[0]), int(shape[1])
        source = np.asarray(source_px, dtype=np.float32).reshape(-1, 2)
        with np.errstate(over="ignore"):  # a motion far out of view: inf, dropped below
            target = transform_points(motion, source, shape).astype(np.float32)
        inside = ((target[:, 0] >= -0.5) & (target[:, 0] < width - 0.5)
                  & (target[:, 1] >= -0.5) & (target[:, 1] < height - 0.5))
        n_points = int(np.count_nonzero(inside))
        if n_points == 0:
            return cls(motion, 0.0, 0)
        return cls(motion, 0.0, n_points, 0.0,
                   Correspondences(source[inside], target[inside], (height, width)))

    def end_point_error(self, estimate: Motion) -> tuple[float, float]:
        """Mean and RMS end-point error (px) of ``estimate`` on the truth's correspondences;
        NaN when the estimate or the truth failed, or the truth has no correspondences."""
        if not (estimate.ok and self.ok) or self.correspondences is None:
            return math.nan, math.nan
        return self.correspondences.end_point_error(estimate)


@lru_cache(maxsize=8)
def pixel_rays(intrinsics: CameraIntrinsics, stride: int):
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


def _sample_depth(frame: Frame, exact: np.ndarray | None, rows: np.ndarray, cols: np.ndarray,
                  max_depth_m: float):
    """Depth at the given pixels and whether it is a surface: the exact depth when given."""
    depth = np.asarray(frame.depth_m if exact is None else exact)[rows, cols].astype(np.float64)
    surface = np.isfinite(depth) & (depth > 0) & (depth < max_depth_m)
    if exact is None:
        surface &= np.asarray(frame.valid)[rows, cols]
    return depth, surface


def ground_truth(reference: Frame, current: Frame,
                 intrinsics: CameraIntrinsics = SR4000_INTRINSICS, stride: int = 2, *,
                 reference_depth_m: np.ndarray | None = None,
                 current_depth_m: np.ndarray | None = None,
                 min_points: int = MIN_POINTS, occlusion_abs_m: float = OCCLUSION_ABS_M,
                 occlusion_rel: float = OCCLUSION_REL,
                 max_depth_m: float = MAX_DEPTH_M) -> GroundTruth:
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
            The raw render gives pixels that see no surface the far clip depth: see
            ``max_depth_m``.
        min_points: fewest surviving correspondences; below it the result is
            ``Motion.failed("no_overlap")``.
        occlusion_abs_m, occlusion_rel: a projected point is occluded when it lies farther
            than the current frame's valid depth at its pixel by more than
            ``occlusion_abs_m + occlusion_rel * depth``. Points landing on invalid current
            pixels are kept: their projection is exact whether or not the sensor saw them.
        max_depth_m: depths (exact or reported) at or beyond this are no surface, in both
            frames: the far clip plane of a render is not a wall.
    """
    _check_frames(reference, current, intrinsics, stride, (reference_depth_m, current_depth_m))
    if not max_depth_m > 0:
        raise ValueError(f"max_depth_m must be a positive depth in metres; got {max_depth_m!r}")
    rows, cols, rays = pixel_rays(intrinsics, int(stride))
    depth, usable = _sample_depth(reference, reference_depth_m, rows, cols, max_depth_m)
    # np.compress: the rows of a boolean mask at a third of the cost of indexing with it.
    points = np.compress(usable, rays, axis=0)
    usable_depth = np.compress(usable, depth)
    # Column by column: the values of broadcasting, which is slow along an axis of length 3.
    for column in range(3):
        points[:, column] *= usable_depth

    # Relative pose: current_from_reference = cur_mat^T [ref_mat | ref_pos - cur_pos].
    current_mat = np.asarray(current.cam_mat, dtype=np.float64)
    rotation = current_mat.T @ np.asarray(reference.cam_mat, dtype=np.float64)
    translation = current_mat.T @ (np.asarray(reference.cam_pos, dtype=np.float64)
                                   - np.asarray(current.cam_pos, dtype=np.float64))
    moved = points @ rotation.T
    for column in range(3):
        moved[:, column] += translation[column]
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
    measured, measured_valid = _sample_depth(current, current_depth_m, row_hit, col_hit,
                                             max_depth_m)
    occluded = measured_valid & (moved_depth > measured + occlusion_abs_m
                                 + occlusion_rel * measured)
    keep = inside & ~occluded
    n_points = int(np.count_nonzero(keep))
    if n_points < max(min_points, 2):
        return GroundTruth(Motion.failed(NO_OVERLAP, n_points=n_points), math.nan, n_points)

    kept = np.flatnonzero(usable)[keep]
    source, target = np.empty((n_points, 2)), np.empty((n_points, 2))
    source[:, 0], source[:, 1] = cols[kept], rows[kept]
    target[:, 0], target[:, 1] = u[keep], v[keep]
    shape = (intrinsics.height, intrinsics.width)
    fit = fit_rigid(source, target, shape)
    residual_mean_px = float(np.sqrt(fit.squared_residual).mean())
    return GroundTruth(fit.motion, fit.residual_rms_px, n_points, residual_mean_px,
                       Correspondences(source, target, shape))
