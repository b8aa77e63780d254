"""ICP peer (Kang et al. 2009, Table I "ICP"; Besl & McKay 1992): 2-D point-to-line ICP by
default, point-to-point on request.

The depth image's structure is its edge set: Canny edges of the prepared disparity image
(median filtered and clipped to the reference's robust range,
:class:`stabilizer.peers.preparation.FramePreparation`), excluding the step to invalid pixels
(0 = no measurement). Edge pixels of the current frame, evenly subsampled to at most
``max_points``, are matched to their nearest reference edge pixel (a ``scipy.spatial.cKDTree``
built once on the reference), and the motion is updated to fit the matches (``error_metric``,
below), until the stopping rule: at most ``max_iterations``, or an iteration that changes the
angle by less than ``tolerance_deg`` and the translation by less than ``tolerance_px``.

Point-to-line error (Chen & Medioni 1992, point-to-plane in 2-D): a current point x, taken into
the reference by the inverse of the estimate, is charged only its distance n . (x - p) along
the normal n of the reference edge at its match p, not its full distance |x - p| (Besl & McKay's
point-to-point error). Nearest edge pixels lie mostly along the edge, so the point-to-point fit
pulls the points back towards their (wrong) matches along the edge and moves by a fraction of
the error per iteration; its steps can fall below the tolerance degrees from the answer (on
identical small frames; docs/peers.md, "ICP", gives the figures). The point-to-line fit lets
points slide along the edge. Each step solves the linearised least squares of Low (2004), in
2-D: for a small rotation d about the image centre c and a shift (u, v), applied after the
current estimate in the reference frame, x moves to x + d J (x - c) + (u, v) with
J = [[0, 1], [-1, 0]] (the derivative of :func:`stabilizer.motion.rotation_matrix` at 0), so
each match gives one linear equation in (d, u, v):

    (n . J (x - c)) d + n_x u + n_y v = -n . (x - p).

The solution is applied as an exact rotation and composed with the estimate. The normals are the
direction of the image gradient (``cv2.Sobel``, 3 x 3: the gradient Canny thresholds) of the
prepared reference at its edge pixels, computed once.

``error_metric="point_to_point"`` solves Besl & McKay's closed-form rigid fit about the image
centre (:func:`stabilizer.rigid_fit.fit_rigid`) on the matches instead: where a frame's edges
run mostly one way and their ends are unreliable (parallax, occlusion), its slow progress along
the edges keeps the start's shift, which can be the better one (docs/peers.md, "ICP").

Partial overlap (parts of the scene leave or enter the view): matches farther than a gate are
not correspondences. The gate starts at ``max_distance_px`` and follows the registration
(Zhang 1994): after each step it shrinks to ``gate_factor`` times the median match distance
(never below ``min_gate_px``), so edges with no counterpart stop pulling the fit once it has
locked on. Optionally only the closest ``overlap`` fraction of the gated matches is kept
(trimmed ICP, Chetverikov et al. 2002); the default keeps all: trimming the farthest matches
early drops exactly the points whose residuals reveal a rotation error.

Initialisation: ICP converges only from near the answer. The starts come from
:class:`stabilizer.peers.start_search.StartSearch` (angles ``start_angles_deg``, each with the
shift found by phase correlation after turning the frame back), best phase-correlation response
first; at most ``max_starts`` are run. A run is scored by its inlier fraction, the share of
current edge points within ``inlier_px`` of a reference edge point after the fit; the search
stops at the first run scoring at least ``accept_fraction``, else the best run wins. A run that
used all ``max_iterations`` is still an estimate when it fits (diagnostic ``converged`` is
False). The paper's ICP is a plain one; this is the standard robust (gated, multi-start)
variant. Parameters and why: docs/peers.md, "ICP".

Statuses (``Motion.status``) besides ``"ok"``:
    ``empty_reference`` / ``empty_current``: (almost) no valid pixel.
    ``flat_reference`` / ``flat_current``: all valid pixels have one value.
    ``too_few_edge_points``: fewer than ``min_points`` edge pixels in a frame.
    ``too_few_correspondences``: from every start, fewer than ``min_points`` matches fell
        within the gate.
    ``poor_fit``: the best run's inlier fraction is below ``min_fraction`` (ICP settled in a
        wrong local minimum from every start).

Diagnostics: ``n_reference_points``, ``n_points``, ``n_correspondences``, ``iterations``,
``converged``, ``residual_px`` (RMS point-to-point distance of the last matches, whatever the
error minimised), ``gate_px`` (the last gate), ``inlier_fraction``, ``start_angle_deg``,
``starts`` (runs made).
"""

from __future__ import annotations

import math

import cv2
import numpy as np
from scipy.spatial import cKDTree

from stabilizer.inputs import MAX_ITERATIONS, MAX_KERNEL_SIDE, check_integer, check_number
from stabilizer.motion import Motion, image_centre, rotation_matrix, transform_points
from stabilizer.peers.preparation import (
    FramePreparation,
    frame_problem,
    peer_min_side,
    valid_interior,
)
from stabilizer.peers.start_search import START_ANGLES_DEG, StartSearch
from stabilizer.rigid_fit import fit_rigid

#: Values of ``IcpEstimator(error_metric=...)``: what each iteration minimises.
ERROR_METRICS = ("point_to_line", "point_to_point")


class IcpEstimator:
    """Rigid motion by gated point-to-line ICP on edge points, the reference analysed once.

    Parameters
    ----------
    reference : (H, W) uint8 ndarray
        Disparity-like reference, 0 = invalid.
    median_ksize : int, optional
        Median filter before edge detection (0 or 1 = none). Default 5: without it, ToF noise
        on far walls makes thousands of spurious edge pixels.
    canny_low, canny_high : float, optional
        Hysteresis thresholds of ``cv2.Canny`` on the disparity image. Defaults 20 and 40 (a
        depth step of a few gray levels).
    border_margin_px : int, optional
        Edge pixels closer than this to invalid pixels are dropped; at most 255. Default 2.
    max_points : int, optional
        Current-frame edge pixels used, subsampled evenly (bounds the cost of a step).
        Default 1000.
    max_distance_px : float, optional
        The first gate: matches farther than it are not correspondences. Default 20.
    overlap : float, optional
        Fraction of the gated matches kept, the closest ones. Default 1 (all).
    max_iterations : int, optional
        Per start, at most 1000 (:data:`~stabilizer.inputs.MAX_ITERATIONS`). Default 30.
    tolerance_deg, tolerance_px : float, optional
        Convergence when one step changes less. Defaults 0.05 and 0.05 (0.05 deg moves a pixel
        at the image corner by 0.1 px).
    start_angles_deg : tuple of float, optional
        The start angle grid. Default
        :data:`stabilizer.peers.start_search.START_ANGLES_DEG` (-15 to 15 in steps of 5).
    max_starts : int, optional
        Most starts run, best phase-correlation response first. Default 3.
    min_points : int, optional
        Fewest edge pixels and correspondences accepted. Default 20.
    inlier_px : float, optional
        A current edge point within this of a reference one fits. Default 1.5.
    accept_fraction : float, optional
        An inlier fraction that ends the search over starts. Default 0.5, below what correct
        fits score (parallax, zoom and scene entering the view leave some edges unmatched).
    min_fraction : float, optional
        The least inlier fraction accepted as an estimate. Default 0.3, above what wrong local
        minima score.
    gate_factor : float, optional
        The gate shrinks to this times the median match distance. Default 3.
    min_gate_px : float, optional
        The gate never shrinks below this. Default 3.
    clip_sigmas : float, optional
        After the median filter, valid values are clipped to the reference's median -+ this
        many spreads (:class:`stabilizer.peers.preparation.FramePreparation`; 0 = no clipping).
        Default 1.5: surfaces beyond the SR4000's range show as bright, noisy columns that
        otherwise dominate the edge set.
    clip_min_spread : float, optional
        The clip range's spread is at least this many gray levels, so that scenes of one flat
        wall keep their depth steps (Canny needs contrast). Default 20.
    error_metric : {"point_to_line", "point_to_point"}, optional
        What each iteration minimises: the matches' distances along the reference edge normals
        (Chen & Medioni 1992; linearised as Low 2004), or their full distances (Besl & McKay
        1992, closed form). Default ``"point_to_line"``: it converges along edges, where
        point-to-point stalls (identical 64 x 64 frames came out up to 5 degrees off).

    References
    ----------
    .. [1] P. J. Besl and N. D. McKay, "A method for registration of 3-D shapes", IEEE Trans.
           PAMI 14(2), 239-256, 1992.
    .. [2] Z. Zhang, "Iterative point matching for registration of free-form curves and
           surfaces", IJCV 13(2), 119-152, 1994.
    .. [3] D. Chetverikov, D. Svirko, D. Stepanov and P. Krsek, "The trimmed iterative closest
           point algorithm", ICPR 2002.
    .. [4] T.-K. Kang, H. Zhang and G.-T. Park, MED 2009, Table I ("ICP").
    .. [5] Y. Chen and G. Medioni, "Object modelling by registration of multiple range images",
           Image and Vision Computing 10(3), 145-155, 1992.
    .. [6] K.-L. Low, "Linear least-squares optimization for point-to-plane ICP surface
           registration", Technical Report TR04-004, University of North Carolina at Chapel
           Hill, 2004.
    """

    #: Smallest image side (pixels) whatever the parameters (docs/peers.md, "Image sizes").
    min_side = staticmethod(peer_min_side)

    def __init__(self, reference: np.ndarray, median_ksize: int = 5, canny_low: float = 20.0,
                 canny_high: float = 40.0, border_margin_px: int = 2, max_points: int = 1000,
                 max_distance_px: float = 20.0, overlap: float = 1.0, max_iterations: int = 30,
                 tolerance_deg: float = 0.05, tolerance_px: float = 0.05,
                 start_angles_deg: tuple[float, ...] = START_ANGLES_DEG,
                 max_starts: int = 3, min_points: int = 20, inlier_px: float = 1.5,
                 accept_fraction: float = 0.5, min_fraction: float = 0.3,
                 gate_factor: float = 3.0, min_gate_px: float = 3.0, clip_sigmas: float = 1.5,
                 clip_min_spread: float = 20.0, error_metric: str = "point_to_line"):
        if error_metric not in ERROR_METRICS:
            raise ValueError(f"error_metric {error_metric!r} is not accepted; accepted: "
                             f"{', '.join(ERROR_METRICS)}")
        check_number("canny_low", canny_low, 0.0)
        check_number("canny_high", canny_high, canny_low)
        check_integer("border_margin_px", border_margin_px, 0, MAX_KERNEL_SIDE)
        check_integer("max_points", max_points, 2)
        check_number("max_distance_px", max_distance_px, 0.0, open_low=True)
        check_number("overlap", overlap, 0.0, 1.0, open_low=True)
        check_integer("max_iterations", max_iterations, 1, MAX_ITERATIONS)
        check_number("tolerance_deg", tolerance_deg, 0.0)
        check_number("tolerance_px", tolerance_px, 0.0)
        check_integer("max_starts", max_starts, 1)
        check_integer("min_points", min_points, 2)
        check_number("inlier_px", inlier_px, 0.0, open_low=True)
        check_number("accept_fraction", accept_fraction, 0.0, 1.0)
        check_number("min_fraction", min_fraction, 0.0, accept_fraction)
        check_number("gate_factor", gate_factor, 0.0, open_low=True)
        check_number("min_gate_px", min_gate_px, 0.0, open_low=True)
        self._prepare = FramePreparation(reference, median_ksize, clip_sigmas, clip_min_spread)
        self.canny_low, self.canny_high = canny_low, canny_high
        self.border_margin_px = border_margin_px
        self.max_points = max_points
        self.max_distance_px = max_distance_px
        self.overlap = overlap
        self.max_iterations = max_iterations
        self.tolerance_deg, self.tolerance_px = tolerance_deg, tolerance_px
        self.max_starts = max_starts
        self.gate_factor, self.min_gate_px = gate_factor, min_gate_px
        self.min_points = min_points
        self.inlier_px = inlier_px
        self.accept_fraction, self.min_fraction = accept_fraction, min_fraction
        self.error_metric = error_metric
        self._shape = reference.shape
        self._reference_problem = frame_problem(reference, "reference")
        reference = self._prepare(reference)
        self._starts = StartSearch(reference, start_angles_deg)
        self._reference_points = self._edge_points(reference, limit=None)
        self._reference_normals = edge_normals(reference, self._reference_points)
        self._tree = cKDTree(self._reference_points)
        self._centre = np.array(image_centre(self._shape))

    def _edge_points(self, image: np.ndarray, limit: int | None) -> np.ndarray:
        """(x, y) of the scene's edge pixels, evenly subsampled to at most ``limit``."""
        edges = cv2.Canny(image, self.canny_low, self.canny_high)
        edges &= valid_interior(image, self.border_margin_px)
        ys, xs = np.nonzero(edges)
        points = np.column_stack([xs, ys]).astype(np.float64)
        if limit is not None and len(points) > limit:
            points = points[np.linspace(0, len(points) - 1, limit).astype(int)]
        return points

    def estimate(self, current: np.ndarray) -> Motion:
        """Motion of ``current`` (uint8, same shape as the reference) relative to the reference."""
        problem = self._reference_problem or frame_problem(current, "current")
        if problem:
            return Motion.failed(problem)
        current = self._prepare(current)
        points = self._edge_points(current, self.max_points)
        diagnostics = {"n_reference_points": len(self._reference_points),
                       "n_points": len(points)}
        if min(len(points), len(self._reference_points)) < self.min_points:
            return Motion.failed("too_few_edge_points", **diagnostics)
        runs = []
        for start, _ in self._starts.ranked(current)[:self.max_starts]:
            run = self._icp(start, points)
            if run is not None:
                runs.append(run)
                if run[1]["inlier_fraction"] >= self.accept_fraction:
                    break  # fits: later starts rank lower and would only add cost
        diagnostics["starts"] = len(runs)
        if not runs:
            return Motion.failed("too_few_correspondences", **diagnostics)
        motion, run_diagnostics = max(runs, key=lambda run: run[1]["inlier_fraction"])
        diagnostics.update(run_diagnostics)
        if diagnostics["inlier_fraction"] < self.min_fraction:
            return Motion.failed("poor_fit", **diagnostics)
        return Motion(motion.angle_deg, motion.dx, motion.dy, diagnostics=diagnostics)

    def _matches(self, motion: Motion, points: np.ndarray,
                 gate_px: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Distance to, and index of, each current point's nearest reference edge point, and
        the current points taken into the reference by the inverse of ``motion``."""
        in_reference = transform_points(motion, points, self._shape, inverse=True)
        distances, nearest = self._tree.query(in_reference, distance_upper_bound=gate_px)
        return distances, nearest, in_reference

    def _icp(self, start: Motion, points: np.ndarray) -> tuple[Motion, dict] | None:
        """One ICP run from ``start``; None when the matches fall below ``min_points``."""
        motion, converged, gate_px = start, False, self.max_distance_px
        for iteration in range(1, self.max_iterations + 1):
            distances, nearest, in_reference = self._matches(motion, points, gate_px)
            gated = np.flatnonzero(np.isfinite(distances))
            keep = gated[np.argsort(distances[gated])[:math.ceil(self.overlap * gated.size)]]
            if keep.size < self.min_points:
                return None
            if self.error_metric == "point_to_line":
                updated = self._point_to_line_step(motion, in_reference[keep], nearest[keep])
            else:
                updated = fit_rigid(self._reference_points[nearest[keep]], points[keep],
                                    self._shape).motion
            converged = (abs(updated.angle_deg - motion.angle_deg) < self.tolerance_deg and
                         math.hypot(updated.dx - motion.dx, updated.dy - motion.dy)
                         < self.tolerance_px)
            motion = updated
            # Zhang (1994): the gate shrinks with the matches' typical distance, so points with
            # no counterpart (scene entering the view) stop pulling once the fit has locked on.
            gate_px = min(gate_px, max(self.min_gate_px,
                                       self.gate_factor * float(np.median(distances[keep]))))
            if converged:
                break
        final_distances, _, _ = self._matches(motion, points, self.inlier_px)
        return motion, {"n_correspondences": int(keep.size), "iterations": iteration,
                        "converged": converged,
                        "residual_px": float(np.sqrt(np.mean(distances[keep] ** 2))),
                        "gate_px": gate_px,
                        "inlier_fraction": float(np.mean(np.isfinite(final_distances))),
                        "start_angle_deg": start.angle_deg}

    def _point_to_line_step(self, motion: Motion, in_reference: np.ndarray,
                            nearest: np.ndarray) -> Motion:
        """``motion`` updated by one linearised point-to-line least-squares step (Low 2004, in
        2-D; the equations are in the module docstring) on current points, taken into the
        reference by the inverse of ``motion`` (``in_reference``), matched to the reference
        edge points of index ``nearest``."""
        normals = self._reference_normals[nearest]
        lever = in_reference - self._centre
        # The rotation's column in pixels per lever_scale radians, so that lstsq's rank cut-off
        # weighs the three unknowns alike; a direction the edges do not pin down (all edges
        # parallel) then gets no step rather than an arbitrary one (minimum-norm solution).
        lever_scale = max(float(np.sqrt(np.mean(np.sum(lever * lever, axis=1)))), 1.0)
        design = np.column_stack([
            (normals[:, 0] * lever[:, 1] - normals[:, 1] * lever[:, 0]) / lever_scale,
            normals])
        target = -np.sum(normals * (in_reference - self._reference_points[nearest]), axis=1)
        scaled_angle, step_dx, step_dy = np.linalg.lstsq(design, target, rcond=None)[0]
        # The step S (angle d, shift s) acts in the reference after the inverse of the motion M
        # (angle a, shift t): the new inverse is S o M^-1, so the new motion is M o S^-1, whose
        # angle is a - d and whose shift is t - R(a - d) s (all rotations about the centre).
        angle = math.radians(motion.angle_deg) - scaled_angle / lever_scale
        shift = (np.array([motion.dx, motion.dy])
                 - rotation_matrix(angle) @ np.array([step_dx, step_dy]))
        return Motion(math.degrees(angle), float(shift[0]), float(shift[1]))


def edge_normals(image: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Unit normals (N x 2, x y) of the edges of ``image`` at its edge pixels ``points``.

    The direction of the image gradient (3 x 3 ``cv2.Sobel``, the aperture ``cv2.Canny`` uses by
    default), which is across a depth step. A pixel of zero gradient (none of Canny's edge
    pixels at a positive low threshold) gets the zero vector, so it adds no equation.
    """
    columns, rows = points[:, 0].astype(np.intp), points[:, 1].astype(np.intp)
    gradient = np.column_stack([cv2.Sobel(image, cv2.CV_32F, 1, 0, ksize=3)[rows, columns],
                                cv2.Sobel(image, cv2.CV_32F, 0, 1, ksize=3)[rows, columns]])
    gradient = gradient.astype(np.float64)
    norm = np.linalg.norm(gradient, axis=1, keepdims=True)
    return gradient / np.maximum(norm, np.finfo(np.float64).tiny)

