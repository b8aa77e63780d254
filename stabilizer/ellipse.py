"""Stage 4 of Kang, Zhang & Park (2009), section II-C: the orientation of each point set from
its direct least-squares ellipse.

"A numerically stable direct least-square method fitting an ellipse [3] to a set of data points
was used to calculate the rotation angle": every wavelet point set of every object (stage 3) is
fitted with an ellipse, and the change of its major-axis angle between the reference and the
current frame is one estimate of the rotation (:func:`axis_angle_difference`).

The fit (Fitzgibbon, Pilu & Fisher 1999) is the conic a x^2 + b xy + c y^2 + d x + e y + f = 0
that minimises the algebraic distance under the constraint 4ac - b^2 = 1, solved in the
numerically stable form of Halir & Flusser (1998), the paper's reference [3]: the design matrix
is split into its quadratic part D1 = [x^2, xy, y^2] and linear part D2 = [x, y, 1]; with
S1 = D1'D1, S2 = D1'D2, S3 = D2'D2 and T = -S3^-1 S2', the quadratic coefficients are the
eigenvector of C1^-1 (S1 + S2 T) with 4ac - b^2 > 0, and the linear ones are T times it. Points
are centred and scaled per set first.

Every point set of a frame is fitted at once: the scatter matrices are sums of monomials up to
degree four, accumulated per set, and the 3 x 3 eigenproblems are solved as one stacked call.
Tests check the result against ``cv2.fitEllipseDirect`` and scikit-image.

Angles follow the image frame (x right, y down): the angle of the major axis is measured from +x
toward +y, in [0, 180) degrees, as ``cv2.ellipse`` draws it. An axis has no sign, so an angle
is only defined modulo 180 degrees; nearly circular fits carry no angle at all
(docs/method.md, section 4).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from stabilizer.motion import wrap_angle_deg

#: Exponents (p, q) of x^p y^q in [D1 | D2] = [x^2, xy, y^2, x, y, 1].
_MONOMIALS = ((2, 0), (1, 1), (0, 2), (1, 0), (0, 1), (0, 0))
#: The moments x^p y^q (p + q <= 4) that the scatter matrices of those monomials need, and
#: where each entry of the 6 x 6 scatter matrix [D1 | D2]' [D1 | D2] finds its moment.
_MOMENTS = tuple((p, q) for p in range(5) for q in range(5 - p))
_SCATTER_INDEX = np.array([[_MOMENTS.index((pr + pc, qr + qc)) for pc, qc in _MONOMIALS]
                           for pr, qr in _MONOMIALS])
_MOMENT_ROWS = tuple(slice(_MOMENTS.index((p, 0)), _MOMENTS.index((p, 4 - p)) + 1)
                     for p in range(5))
#: C1^-1 M is M with rows reversed and scaled by these (C1 = [[0, 0, 2], [0, -1, 0], [2, 0, 0]]).
_C1_INVERSE_ROWS = np.array([[0.5], [-1.0], [0.5]])
#: Fewer points than this cannot pin down a conic (5 unknowns) with any redundancy.
MIN_POINTS = 6


@dataclass(frozen=True)
class EllipseFits:
    """Per-set results of :func:`fit_ellipses`; entries of sets with ``valid`` False are NaN.

    Attributes
    ----------
    valid : (n_sets,) ndarray of bool
        The set had at least :data:`MIN_POINTS` points and its best conic is a real ellipse.
    oriented : (n_sets,) ndarray of bool
        Valid and elongated enough (axis ratio >= ``min_axis_ratio``) to carry an angle.
    angle_deg : (n_sets,) ndarray of float
        Angle of the major axis from +x toward +y, in [0, 180).
    centre_x, centre_y, half_major, half_minor : (n_sets,) ndarray of float
        The ellipse in image pixels.
    n_points : (n_sets,) ndarray of int
        Points in each set.
    """

    valid: np.ndarray
    oriented: np.ndarray
    angle_deg: np.ndarray
    centre_x: np.ndarray
    centre_y: np.ndarray
    half_major: np.ndarray
    half_minor: np.ndarray
    n_points: np.ndarray

    def as_tuples(self, mask: np.ndarray | None = None) -> list[tuple[float, ...]]:
        """(cx, cy, half_major, half_minor, angle_deg) of the valid fits (optionally masked)."""
        keep = self.valid if mask is None else self.valid & mask
        table = np.column_stack((self.centre_x, self.centre_y, self.half_major,
                                 self.half_minor, self.angle_deg))[keep]
        return [tuple(row) for row in table.tolist()]


def fit_ellipses(x: np.ndarray, y: np.ndarray, set_id: np.ndarray, n_sets: int,
                 min_axis_ratio: float = 1.05, weight: np.ndarray | None = None) -> EllipseFits:
    """Direct least-squares ellipse of every point set, all sets at once.

    Parameters
    ----------
    x, y : (P,) ndarray of float or int
        Point coordinates in image pixels (finite).
    set_id : (P,) ndarray of int
        Set index of each point, in [0, n_sets).
    n_sets : int
        Number of sets (>= 0); sets without points come out invalid.
    min_axis_ratio : float, optional
        Fits whose major / minor half-axis ratio is below this are too round to orient
        (``oriented`` False). Default 1.05 (the paper gives none; docs/method.md, section 4).
    weight : (P,) ndarray of float, optional
        Non-negative weight of each point in the least-squares sum; default 1 for every point.

    Returns
    -------
    EllipseFits
        Per-set arrays of length ``n_sets``.

    References
    ----------
    .. [1] T.-K. Kang, H. Zhang and G.-T. Park, "Stereo-vision based motion stabilization of a
           humanoid robot for the environment recognition by type-2 fuzzy logic", MED 2009,
           section II-C.
    .. [2] A. Fitzgibbon, M. Pilu and R. B. Fisher, "Direct least square fitting of ellipses",
           IEEE Trans. PAMI 21(5), 476-480, 1999.
    .. [3] R. Halir and J. Flusser, "Numerically stable direct least squares fitting of
           ellipses", WSCG 1998.
    """
    x, y = np.asarray(x), np.asarray(y)
    set_id = np.asarray(set_id)
    if x.ndim != 1 or x.shape != y.shape or x.shape != set_id.shape:
        raise ValueError(f"x, y and set_id must be 1-D arrays of one length; got shapes "
                         f"{x.shape}, {y.shape} and {set_id.shape}")
    if x.dtype.kind not in "iuf" or y.dtype.kind not in "iuf":
        raise ValueError(f"x and y must be real-valued (integer or float) arrays; got dtypes "
                         f"{x.dtype} and {y.dtype}")
    if not (np.isfinite(x).all() and np.isfinite(y).all()):
        raise ValueError("x and y must be finite; got NaN or infinite coordinates")
    if isinstance(n_sets, bool) or not isinstance(n_sets, (int, np.integer)) or n_sets < 0:
        raise ValueError(f"n_sets must be an integer >= 0; got {n_sets!r}")
    if not np.issubdtype(set_id.dtype, np.integer):
        raise ValueError(f"set_id must be an integer array; got dtype {set_id.dtype}")
    if set_id.size and (set_id.min() < 0 or set_id.max() >= n_sets):
        raise ValueError(f"set_id must lie in [0, n_sets) = [0, {n_sets}); got values from "
                         f"{set_id.min()} to {set_id.max()}")
    if not min_axis_ratio >= 1.0:
        raise ValueError(f"min_axis_ratio must be >= 1 (major / minor); got {min_axis_ratio}")
    if weight is not None:
        weight = np.asarray(weight, dtype=np.float64)
        if weight.shape != x.shape:
            raise ValueError(f"weight must have the shape of x, {x.shape}; got {weight.shape}")
        if not (np.isfinite(weight).all() and (weight >= 0).all()):
            raise ValueError("weight must be finite and non-negative")
    set_id = set_id.astype(np.intp, copy=False)
    weight = np.ones(len(x)) if weight is None else weight
    # Sorted by set, every per-set sum is one np.add.reduceat over contiguous runs.
    order = np.argsort(set_id, kind="stable")
    set_id, x, y, weight = set_id[order], x[order], y[order], weight[order]
    n_points = np.bincount(set_id, minlength=n_sets)
    present = np.flatnonzero(n_points)
    starts = np.searchsorted(set_id, present)

    def per_set(rows: np.ndarray) -> np.ndarray:
        """Sums of each row over each set's points, shape (rows, n_sets); 0 for empty sets."""
        sums = np.zeros((rows.shape[0], n_sets))
        if present.size:
            sums[:, present] = np.add.reduceat(rows, starts, axis=1)
        return sums

    # One work table for all per-point rows, filled in place (a fresh array per row costs
    # measurably more: cache misses on a frame's thousands of points). It holds the weighted
    # coordinates, then the powers of u and v and the products x^p y^q (weight folded in
    # first: numpy is slow to broadcast it in) whose per-set sums give the scatter matrices
    # S1 = D1'D1, S2 = D1'D2, S3 = D2'D2 as blocks of one table.
    work = np.empty((len(_MOMENTS) + 10, len(x)))
    work[0] = weight
    np.multiply(weight, x, out=work[1])
    np.multiply(weight, y, out=work[2])
    total, sum_x, sum_y = per_set(work[:3])
    safe_total = np.where(total > 0, total, 1.0)
    mean_x, mean_y = sum_x / safe_total, sum_y / safe_total
    u = x - mean_x[set_id]
    v = y - mean_y[set_id]
    squares = np.multiply(u, u, out=work[3])
    squares += np.multiply(v, v, out=work[4])
    spread = np.sqrt(per_set(np.multiply(weight, squares, out=work[3:4]))[0] / safe_total / 2)
    spread = np.where(spread > 0, spread, 1.0)
    u /= spread[set_id]
    v /= spread[set_id]
    weighted_u, powers_v = _powers(u, work[:5]), _powers(v, work[5:10])
    np.multiply(weighted_u, weight, out=weighted_u)
    products = work[10:]
    for p, rows in enumerate(_MOMENT_ROWS):  # the rows x^p y^q, q = 0 .. 4 - p
        np.multiply(weighted_u[p], powers_v[:rows.stop - rows.start], out=products[rows])
    moments = per_set(products)
    scatter = np.moveaxis(moments[_SCATTER_INDEX], -1, 0)
    s1, s2, s3 = scatter[:, :3, :3], scatter[:, :3, 3:], scatter[:, 3:, 3:]

    solvable = (n_points >= MIN_POINTS) & (np.abs(np.linalg.det(s3)) > 1e-9 * safe_total ** 3)
    unsolvable = ~solvable
    any_unsolvable = bool(unsolvable.any())
    if any_unsolvable:  # harmless identity systems, discarded below
        s3[unsolvable] = np.eye(3)
    t = -np.linalg.solve(s3, np.swapaxes(s2, 1, 2))
    m = s1 + s2 @ t
    # C1^-1 M with C1 = [[0, 0, 2], [0, -1, 0], [2, 0, 0]] (the constraint 4ac - b^2).
    reduced = m[:, ::-1] * _C1_INVERSE_ROWS
    if any_unsolvable:
        reduced[unsolvable] = np.eye(3)
    _, vectors = np.linalg.eig(reduced)
    vectors = vectors.real
    constraint = 4.0 * vectors[:, 0] * vectors[:, 2] - vectors[:, 1] ** 2
    pick = np.argmax(constraint, axis=1)
    every_set = np.arange(n_sets)
    quadratic = vectors[every_set, :, pick]
    linear = (t @ quadratic[:, :, None])[:, :, 0]
    is_ellipse = solvable & (constraint[every_set, pick] > 0)
    return _ellipse_geometry(quadratic, linear, is_ellipse, mean_x, mean_y, spread, n_points,
                             min_axis_ratio)


def _powers(values: np.ndarray, out: np.ndarray) -> np.ndarray:
    """``out`` (5 rows) filled with values^0 .. values^4 (the squares reused)."""
    out[0] = 1.0
    out[1] = values
    np.multiply(values, values, out=out[2])
    np.multiply(out[2], values, out=out[3])
    np.multiply(out[2], out[2], out=out[4])
    return out


def _ellipse_geometry(quadratic, linear, is_ellipse, mean_x, mean_y, spread, n_points,
                      min_axis_ratio) -> EllipseFits:
    """Centre, half-axes and major-axis angle of conics fitted in normalised coordinates."""
    sign = np.where(quadratic[:, 0] + quadratic[:, 2] < 0, -1.0, 1.0)[:, None]
    a, b, c, d, e, f = (sign * np.hstack((quadratic, linear))).T
    with np.errstate(invalid="ignore", divide="ignore"):
        det = 4.0 * a * c - b * b
        x0 = (b * e - 2.0 * c * d) / det
        y0 = (b * d - 2.0 * a * e) / det
        f0 = f + (d * x0 + e * y0) / 2.0
        root = np.sqrt(((a - c) / 2.0) ** 2 + (b / 2.0) ** 2)
        small, large = (a + c) / 2.0 - root, (a + c) / 2.0 + root
        half_major = np.sqrt(-f0 / small) * spread
        half_minor = np.sqrt(-f0 / large) * spread
    valid = is_ellipse & (small > 0) & (f0 < 0) & np.isfinite(half_major)
    # Q = [[a, b/2], [b/2, c]]: its larger eigenvalue's axis is at atan2(b, a - c) / 2, the major
    # axis (smaller eigenvalue) is perpendicular to it.
    angle = np.mod(np.degrees(0.5 * np.arctan2(b, a - c)) + 90.0, 180.0)
    oriented = valid & (half_major >= min_axis_ratio * half_minor)
    geometry = np.where(valid, np.stack((angle, x0 * spread + mean_x, y0 * spread + mean_y,
                                         half_major, half_minor)), np.nan)
    return EllipseFits(valid, oriented, *geometry, n_points=n_points)


def axis_angle_difference(reference_deg: np.ndarray, current_deg: np.ndarray) -> np.ndarray:
    """Rotation (Motion convention, counter-clockwise as displayed) taking reference axes to
    current axes, wrapped to (-90, 90].

    In image coordinates (y down) a counter-clockwise rotation by theta lowers an axis angle
    measured from +x toward +y by theta, so theta = reference - current; axes are undirected,
    hence the 180-degree period.

    Parameters
    ----------
    reference_deg, current_deg : array_like of float
        Major-axis angles (degrees, as :attr:`EllipseFits.angle_deg`) of matching sets.

    Returns
    -------
    ndarray of float
        One rotation estimate (degrees) per pair, the inputs of stage 5.

    References
    ----------
    .. [1] T.-K. Kang, H. Zhang and G.-T. Park, MED 2009, section II-C and Fig. 6.
    """
    return wrap_angle_deg(np.asarray(reference_deg) - np.asarray(current_deg), period=180.0)
