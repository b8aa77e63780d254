"""Stage 2 of Kang, Zhang & Park (2009), section II-B: interval type-2 fuzzy c-means
segmentation of the disparity image into objects.

Each gray level gets an interval of memberships to every cluster, from two fuzzifiers m1 < m2
(the paper's eqs. (1)-(3)); the cluster centres are the type-reduced, defuzzified centroids of
those intervals (eqs. (4)-(5)); each level takes the cluster it belongs to most, and a
morphological clean-up removes the noise from the label image.

IT2-FCM after Hwang & Rhee (IEEE TFS 2007), the paper's equations (2)-(5), with the standard
details of docs/method.md, section 2:

- type-1 memberships for a fuzzifier m: u_j(x_i) = 1 / sum_k (d_ij / d_ik)^(2/(m-1)), with
  d_ij = |x_i - v_j| (a level that sits on a centre belongs to it fully);
- upper / lower membership = the larger / smaller of the memberships for m1 and m2 (eq. (2));
- each centre is the type-reduced interval [v_L, v_R] of the centroid sum w_i x_i / sum w_i over
  weights w_i in [lower_i^m, upper_i^m], m = (m1 + m2) / 2 (eq. (4), Karnik-Mendel), and the crisp
  centre is (v_L + v_R) / 2 (eq. (5));
- iterate until the largest centre change is below ``tol`` gray levels or ``max_iter``;
- hard label of a level: the cluster with the largest mean of upper and lower membership.

Why on the histogram: every pixel of one gray level has the same memberships, so clustering the
distinct valid levels with their pixel counts as multiplicities (the counts multiply the weights
in every sum) is exactly the per-pixel algorithm at a fraction of the cost; a test checks this
against the per-pixel form.

Karnik-Mendel, vectorised: the KM iteration converges to the switch point k at which the centroid
with lower weights up to k and upper weights after it is largest (v_R), and with upper weights up
to k and lower after it is smallest (v_L) (Mendel, "Uncertain rule-based fuzzy systems", 2001).
Evaluating every switch point at once with cumulative sums gives the same v_L, v_R without the
sequential loop; a test checks it against the iterative KM.

Clean-up (paper: "Morphological technology is needed to deal with the noise data"): an opening
then a closing of each label's mask with a ``morph_size`` square (OpenCV), restricted to valid
pixels; labels with fewer than ``min_area`` pixels left are dropped.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from stabilizer.histogram_seeds import N_LEVELS
from stabilizer.inputs import MAX_ITERATIONS, MAX_KERNEL_SIDE

#: Label masks filtered in one OpenCV call, as the channels of one image: an image holds at most
#: 128 channels in OpenCV 5 (``CV_CN_MAX``), fewer than the 255 labels a label image can hold.
MASKS_PER_CALL = 128


@dataclass(frozen=True)
class FuzzyClusters:
    """Result of IT2-FCM on a histogram.

    Attributes
    ----------
    centres : (C,) ndarray of float
        Crisp centres (v_L + v_R) / 2 (eq. (5)), ascending gray levels.
    intervals : (C, 2) ndarray of float
        Type-reduced centre intervals [v_L, v_R] (eq. (4)).
    level_labels : (256,) ndarray of uint8
        Lookup table gray level -> hard label 1..C; level 0 (invalid) -> 0 (for ``cv2.LUT``).
    iterations : int
        Number of centre updates made.
    converged : bool
        Whether the largest centre change fell below the tolerance.
    """

    centres: np.ndarray
    intervals: np.ndarray
    level_labels: np.ndarray
    iterations: int
    converged: bool


def _distance_ratios(x: np.ndarray, centres: np.ndarray) -> np.ndarray:
    """d_min(x_i) / d_ji in [0, 1], shape (C, len(x)); a point on a centre has 1 there, 0 else.

    Raising this ratio to 2/(m-1) and normalising over the clusters gives the FCM memberships
    without the overflow of d^(-2/(m-1)) near a centre. Clusters are rows so that every sum
    over the data runs along contiguous memory.
    """
    distance = np.abs(centres[:, None] - x[None, :])
    nearest = distance.min(axis=0)
    if nearest.min() > 0.0:  # the usual case: no point sits exactly on a centre
        return nearest / distance
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = nearest / distance
    on_centre = nearest == 0.0
    ratio[:, on_centre] = distance[:, on_centre] == 0.0
    return ratio


def _normalised_power(ratio: np.ndarray, m: float, out: np.ndarray | None = None) -> np.ndarray:
    powered = np.power(ratio, 2.0 / (m - 1.0), out=out)
    powered /= powered.sum(axis=0)
    return powered


def type1_memberships(x: np.ndarray, centres: np.ndarray, m: float) -> np.ndarray:
    """FCM memberships u_j(x_i) = 1 / sum_k (d_ij / d_ik)^(2/(m-1)).

    A point at zero distance from one or more centres belongs to those centres equally.

    Parameters
    ----------
    x : (N,) ndarray of float
        Data values (gray levels).
    centres : (C,) ndarray of float
        Cluster centres.
    m : float
        Fuzzifier, > 1.

    Returns
    -------
    (C, N) ndarray of float
        Memberships; each column sums to 1.

    References
    ----------
    .. [1] T.-K. Kang, H. Zhang and G.-T. Park, MED 2009, eq. (2) (either branch).
    """
    return _normalised_power(_distance_ratios(x, centres), m)


def _membership_bounds(x: np.ndarray, centres: np.ndarray, m1: float, m2: float,
                       out: np.ndarray) -> np.ndarray:
    """Lower and upper memberships (eq. 2) written to ``out[0]`` and ``out[1]``, shape (C, N)
    each; ``out[2]`` (same shape) is scratch space. Few, in-place array operations: the data
    are at most 255 levels, so the cost is the number of numpy calls."""
    ratio = _distance_ratios(x, centres)
    u1 = _normalised_power(ratio, m1, out[0])
    u2 = _normalised_power(ratio, m2, out[2])
    np.maximum(u1, u2, out=out[1])
    np.minimum(u1, u2, out=out[0])
    return out


def interval_memberships(x: np.ndarray, centres: np.ndarray, m1: float,
                         m2: float) -> tuple[np.ndarray, np.ndarray]:
    """Upper and lower memberships: the larger and the smaller of the m1 and m2 memberships.

    Parameters
    ----------
    x : (N,) ndarray of float
        Data values (gray levels).
    centres : (C,) ndarray of float
        Cluster centres.
    m1, m2 : float
        The two fuzzifiers, 1 < m1 < m2.

    Returns
    -------
    upper, lower : (C, N) ndarray of float
        The primary membership interval [lower, upper] of every value in every cluster.

    References
    ----------
    .. [1] T.-K. Kang, H. Zhang and G.-T. Park, MED 2009, eq. (2).
    .. [2] C. Hwang and F. C.-H. Rhee, "Uncertain fuzzy clustering: interval type-2 fuzzy
           approach to C-means", IEEE Trans. Fuzzy Systems 15(1), 107-120, 2007.
    """
    bounds = _membership_bounds(x, centres, m1, m2, np.empty((3, centres.size, x.size)))
    return bounds[1], bounds[0]


def karnik_mendel(x: np.ndarray, lower_w: np.ndarray,
                  upper_w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Type-reduced centroid interval [v_L, v_R] for every row of the weights.

    Parameters
    ----------
    x : (N,) ndarray of float
        Ascending data values.
    lower_w, upper_w : (C, N) ndarray of float
        Weight bounds (multiplicities already folded in).

    Returns
    -------
    v_left, v_right : (C,) ndarray of float
        v_R is the largest centroid over all switch points k (lower weights for x_1..x_k, upper
        after); v_L the smallest (upper, then lower).

    References
    ----------
    .. [1] T.-K. Kang, H. Zhang and G.-T. Park, MED 2009, eq. (4).
    .. [2] J. M. Mendel, "Uncertain rule-based fuzzy logic systems", Prentice Hall, 2001
           (the Karnik-Mendel procedure).
    """
    c, n = lower_w.shape
    weights = np.empty((4, c, n))
    weights[0], weights[1] = lower_w, upper_w
    np.multiply(weights[:2], x, out=weights[2:])
    with np.errstate(invalid="ignore", divide="ignore"):
        return _km_interval(weights, np.zeros((4, c, n + 1)))


def _km_interval(weights: np.ndarray, running: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`karnik_mendel` from the stacked [lower, upper, lower * x, upper * x] weights,
    shape (4, C, N); ``running`` is a (4, C, N + 1) buffer whose first column is zero."""
    # Running sums with a leading zero column: column k holds the sums over the first k points.
    np.cumsum(weights, axis=2, out=running[:, :, 1:])
    # [lower - upper, lower*x - upper*x] over the first k points; adding the upper totals gives
    # "lower for the first k, upper after" and subtracting from the lower totals the reverse
    # (rows: [sum of weights, sum of weights * x]).
    switched = running[0::2] - running[1::2]
    right = running[1::2, :, -1:] + switched
    left = running[0::2, :, -1:] - switched
    return (np.fmin.reduce(left[1] / left[0], axis=1),
            np.fmax.reduce(right[1] / right[0], axis=1))


class _CentreUpdate:
    """One IT2-FCM centre update (eqs. (2)-(5)) on fixed data, with every buffer allocated once.

    The same element-wise operations, in the same order, as :func:`interval_memberships`
    followed by :func:`karnik_mendel` on the weights [lower^m, upper^m] times the counts, so the
    result is the same to the last bit; the data are at most 255 levels, so the cost is the
    number of numpy calls, which the stacked buffers keep small (the two fuzzifiers' memberships
    are normalised in one call, both KM bounds divided in one).
    """

    def __init__(self, x: np.ndarray, counts: np.ndarray, n_clusters: int, m1: float,
                 m2: float, m: float):
        self.x, self.counts, self.m = x, counts, m
        self.exponents = (2.0 / (m1 - 1.0), 2.0 / (m2 - 1.0))
        shape = (n_clusters, x.size)
        self.ratio = np.empty(shape)
        self.powered = np.empty((2,) + shape)  # the memberships for m1 and for m2
        # [lower, upper, lower * x, upper * x] weights, their running sums with a leading zero
        # column, and the KM sums [left, right] x [sum of weights, sum of weights * x].
        self.weights = np.empty((4,) + shape)
        self.running = np.zeros((4, n_clusters, x.size + 1))
        self.weight_rows = self.weights.reshape(-1, x.size)
        self.running_rows = self.running.reshape(-1, x.size + 1)[:, 1:]
        self.switched = np.empty((2, n_clusters, x.size + 1))
        self.km_sums = np.empty((2, 2, n_clusters, x.size + 1))

    def __call__(self, centres: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """[v_L, v_R] of every cluster for the memberships to ``centres``."""
        ratio = self.ratio
        np.subtract(centres[:, None], self.x, out=ratio)
        distance = np.abs(ratio, out=ratio)
        nearest = distance.min(axis=0)
        # Levels are integers: only an integer centre can have a level at distance zero.
        if any(centre.is_integer() for centre in centres.tolist()) and not nearest.min() > 0.0:
            ratio[...] = _distance_ratios(self.x, centres)
        else:
            np.divide(nearest, distance, out=ratio)
        powered = self.powered
        for exponent, out in zip(self.exponents, powered):
            np.power(ratio, exponent, out=out)
        powered /= powered.sum(axis=1)[:, None]
        weights = self.weights
        np.maximum(powered[0], powered[1], out=weights[1])
        np.minimum(powered[0], powered[1], out=weights[0])
        bounds = weights[:2]
        np.power(bounds, self.m, out=bounds)
        bounds *= self.counts
        np.multiply(bounds, self.x, out=weights[2:])
        # As _km_interval: np.cumsum's running sums (one accumulate over a 2-D view costs
        # less), and both quotients in one call.
        running = self.running
        np.add.accumulate(self.weight_rows, axis=1, out=self.running_rows)
        switched = np.subtract(running[0::2], running[1::2], out=self.switched)
        sums = self.km_sums
        np.subtract(running[0::2, :, -1:], switched, out=sums[0])
        np.add(running[1::2, :, -1:], switched, out=sums[1])
        centroids = sums[:, 1] / sums[:, 0]
        return np.fmin.reduce(centroids[0], axis=1), np.fmax.reduce(centroids[1], axis=1)


class IT2FCM:
    """Interval type-2 fuzzy c-means on the weighted histogram of valid gray levels.

    Parameters
    ----------
    m1, m2 : float, optional
        The two fuzzifiers, 1 < m1 < m2 (eqs. (2)-(3)). The paper gives no values; defaults 2
        and 5, a common choice (docs/method.md, section 2; section 10 measures alternatives).
    tol : float, optional
        Stop when no centre moves more than this many gray levels. Default 0.01.
    max_iter : int, optional
        Cap on the number of centre updates, at most 1000
        (:data:`~stabilizer.inputs.MAX_ITERATIONS`). Default 100.

    References
    ----------
    .. [1] T.-K. Kang, H. Zhang and G.-T. Park, "Stereo-vision based motion stabilization of a
           humanoid robot for the environment recognition by type-2 fuzzy logic", MED 2009,
           section II-B, eqs. (1)-(5).
    .. [2] C. Hwang and F. C.-H. Rhee, "Uncertain fuzzy clustering: interval type-2 fuzzy
           approach to C-means", IEEE Trans. Fuzzy Systems 15(1), 107-120, 2007.
    """

    def __init__(self, m1: float = 2.0, m2: float = 5.0, tol: float = 1e-2,
                 max_iter: int = 100):
        if not (1.0 < m1 < m2):
            raise ValueError(f"fuzzifiers must satisfy 1 < m1 < m2; got m1={m1}, m2={m2}")
        if tol <= 0 or not 1 <= max_iter <= MAX_ITERATIONS:
            raise ValueError(f"need tol > 0 and max_iter from 1 to {MAX_ITERATIONS}; "
                             f"got tol={tol}, max_iter={max_iter}")
        self.m1, self.m2 = float(m1), float(m2)
        self.m = (self.m1 + self.m2) / 2.0
        self.tol = float(tol)
        self.max_iter = int(max_iter)

    def fit(self, level_counts: np.ndarray, seeds: np.ndarray) -> FuzzyClusters:
        """Cluster the valid levels (counts as weights) starting from ``seeds``.

        Parameters
        ----------
        level_counts : (256,) ndarray
            Histogram of the valid pixels (level 0 ignored).
        seeds : (C,) array_like of float
            Initial centres, at least one (stage 1, :mod:`stabilizer.histogram_seeds`).

        Returns
        -------
        FuzzyClusters
        """
        if np.shape(level_counts) != (N_LEVELS,):
            raise ValueError(f"level_counts must be a histogram of {N_LEVELS} gray levels; got "
                             f"shape {np.shape(level_counts)}")
        if np.ndim(seeds) != 1 or np.size(seeds) == 0:
            raise ValueError(f"seeds must be a non-empty 1-D array of gray levels; got shape "
                             f"{np.shape(seeds)}")
        present = np.flatnonzero(level_counts[1:] > 0) + 1
        if present.size == 0:
            raise ValueError("level_counts has no valid pixel (every count of levels 1-255 is "
                             "0); a histogram of at least one valid level is needed")
        x = present.astype(np.float64)
        centres = np.sort(np.asarray(seeds, dtype=np.float64))
        update = _CentreUpdate(x, level_counts[present], centres.size, self.m1, self.m2, self.m)
        v_left = v_right = centres
        converged = False
        iterations = 0
        with np.errstate(invalid="ignore", divide="ignore"):
            while iterations < self.max_iter and not converged:
                v_left, v_right = update(centres)
                new_centres = (v_left + v_right) / 2.0
                # C is small: every change in plain floats (the same doubles as numpy's; a NaN
                # change is not converged, as np.max(...) < tol would say).
                converged = all(abs(new - old) < self.tol for new, old in
                                zip(new_centres.tolist(), centres.tolist()))
                centres = new_centres
                iterations += 1
        return FuzzyClusters(centres, np.column_stack((v_left, v_right)),
                             self._level_labels(centres), iterations, converged)

    def _level_labels(self, centres: np.ndarray) -> np.ndarray:
        """Lookup table level -> 1 + argmax_j of the mean of upper and lower membership."""
        levels = np.arange(N_LEVELS, dtype=np.float64)
        upper, lower = interval_memberships(levels, centres, self.m1, self.m2)
        table = (np.argmax(upper + lower, axis=0) + 1).astype(np.uint8)
        table[0] = 0
        return table


class LabelCleaner:
    """Morphological clean-up of a hard label image (opening, then closing, per label).

    Parameters
    ----------
    morph_size : int, optional
        Side of the square structuring element in pixels (odd, from 1 to 255,
        :data:`~stabilizer.inputs.MAX_KERNEL_SIDE`; 1 disables). The paper uses morphology
        without giving a size; default 3.
    min_area : int, optional
        Labels with fewer pixels than this after clean-up are removed (set to 0). Default 30.

    References
    ----------
    .. [1] T.-K. Kang, H. Zhang and G.-T. Park, MED 2009, section II-B and Fig. 4:
           "Morphological technology is needed to deal with the noise data".
    """

    def __init__(self, morph_size: int = 3, min_area: int = 30):
        if not 1 <= int(morph_size) <= MAX_KERNEL_SIDE or int(morph_size) % 2 == 0:
            raise ValueError(f"morph_size must be an odd integer from 1 to {MAX_KERNEL_SIDE}; "
                             f"got {morph_size}")
        if min_area < 0:
            raise ValueError(f"min_area must be >= 0; got {min_area}")
        self.kernel = cv2.getStructuringElement(cv2.MORPH_RECT, (int(morph_size),) * 2)
        self.min_area = int(min_area)

    def __call__(self, labels: np.ndarray, n_labels: int) -> np.ndarray:
        """Cleaned uint8 label image; 0 (invalid / unlabelled) stays 0, labels keep their ids.

        A pixel keeps its label if its label's cleaned mask holds it; a pixel its own label
        lost (noise) takes the first other label whose closing covers it, else 0. The label
        masks are filtered as the channels of one image, :data:`MASKS_PER_CALL` at a time.

        Parameters
        ----------
        labels : (H, W) ndarray of int
            Hard labels 0..``n_labels`` (0 = invalid or unlabelled).
        n_labels : int
            Number of labels, 1..255.

        Returns
        -------
        (H, W) ndarray of uint8
        """
        return self.with_areas(labels, n_labels)[0]

    def with_areas(self, labels: np.ndarray, n_labels: int) -> tuple[np.ndarray, np.ndarray]:
        """The cleaned label image (see :meth:`__call__`) and the pixel count of each label
        1..``n_labels`` in it (0 for a dropped label)."""
        if not 1 <= n_labels <= 255:
            raise ValueError(f"n_labels must be in 1..255 (uint8 labels); got {n_labels}")
        small = labels.astype(np.uint8, copy=False)  # C <= 255; byte-wide work is faster
        planes = [(small == label).view(np.uint8) for label in range(1, n_labels + 1)]
        masks = np.concatenate([self._opened_and_closed(planes[start:start + MASKS_PER_CALL])
                                for start in range(0, n_labels, MASKS_PER_CALL)], axis=2)
        kept = np.zeros_like(small)  # 1 where a pixel's own label's cleaned mask holds it
        for label, before in enumerate(planes):
            kept |= before & masks[:, :, label]
        cleaned = small * kept
        # The few pixels their own label lost: the first label whose mask covers them, or 0.
        lost = np.flatnonzero(cleaned != small)
        covering = masks.reshape(-1, n_labels)[lost]
        first = covering.argmax(axis=1)
        cleaned.ravel()[lost] = (first + 1) * covering[np.arange(lost.size), first]
        areas = cv2.calcHist([cleaned], [0], None, [n_labels + 1], [0, n_labels + 1]).ravel()
        dropped = areas < self.min_area
        dropped[0] = False
        if not dropped.any():
            return cleaned, areas[1:]
        keep = np.arange(256, dtype=np.uint8)
        keep[:n_labels + 1][dropped] = 0
        areas[dropped] = 0
        return cv2.LUT(cleaned, keep), areas[1:]

    def _opened_and_closed(self, planes: list[np.ndarray]) -> np.ndarray:
        """The masks ``planes`` (H x W uint8 each) opened, then closed, as the channels of one
        (H, W, len(planes)) image, filtered in one call each."""
        masks = cv2.merge(planes) if len(planes) > 1 else planes[0]
        masks = cv2.morphologyEx(masks, cv2.MORPH_OPEN, self.kernel)
        masks = cv2.morphologyEx(masks, cv2.MORPH_CLOSE, self.kernel)
        return masks.reshape(*masks.shape[:2], -1)
