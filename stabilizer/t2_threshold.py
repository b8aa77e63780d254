"""Stage 5 of Kang, Zhang & Park (2009), section II-C: type-2 fuzzy thresholding of the angle
estimates.

Stage 4 gives one rotation estimate per pair of matching point sets, "including some noise
values which can occur in the case in which the object partially disappears". Two thresholds
found by type-2 fuzzy thresholding cut off the outliers on either side, and the rotation is the
mean of the estimates between them (Fig. 7).

Tizhoosh (Pattern Recognition 38, 2005), the paper's eq. (6): a type-1 membership function mu_T
is shifted over the data range; its footprint of uncertainty has upper mu_U = mu^(1/alpha) and
lower mu_L = mu^alpha, alpha in (1, 2], and the ultrafuzziness at position T is

    gamma(T) = (1 / N) * sum_g h(g) * (mu_U(g) - mu_L(g)),

with h the histogram of the data (here: angle estimates quantised to ``resolution_deg``).

The paper then takes "two peaks ... as thresholds that get rid of the left and right noise
values" and averages the angles between them (Fig. 7). Resolution used here (docs/method.md,
section 5, with the triangular membership it names): mu_T is a triangle of half-width
``bandwidth_deg`` centred at T. mu_U - mu_L vanishes where mu = 1 (at T) and where mu = 0, and
is largest where mu ~ 0.4, so for a group of agreeing estimates gamma has one peak on each side
of the group, about 0.6 bandwidths out. The lower threshold is the highest gamma peak at or
below the median estimate, the upper one the highest at or above it; the rotation is the mean
of the estimates between them. Fewer than ``min_values`` estimates, or none between the
thresholds, fall back to the median and say so.

gamma is computed as the histogram convolved with the sampled kernel mu_U - mu_L: the same sum,
without a loop over positions.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: Value of ``RobustAngle.fallback`` when the thresholds could not be used.
MEDIAN_FALLBACK = "median"
#: Widest membership function (degrees): the angle estimates of stage 4 are differences of
#: ellipse axes, within +-90 degrees, which a wider triangle spans whole.
MAX_BANDWIDTH_DEG = 90.0
#: Finest histogram step (degrees): the histogram and its convolution grow as 1 / step^2 (a step
#: of 1e-7 degrees ran for minutes); a hundredth of a degree is far below the estimates' spread.
MIN_RESOLUTION_DEG = 0.01


@dataclass(frozen=True)
class RobustAngle:
    """Result of the two-threshold filter.

    Attributes
    ----------
    value : float
        The mean of the inliers (or the median on fallback); NaN if there was no data.
    lower, upper : float
        The two thresholds (NaN on fallback).
    inliers : ndarray of bool
        Mask over the input values (all False on fallback).
    fallback : str or None
        None, or ``"median"`` when the median was used instead.
    """

    value: float
    lower: float
    upper: float
    inliers: np.ndarray
    fallback: str | None


class Type2FuzzyThreshold:
    """Two ultrafuzziness thresholds around the main group of values; mean of the inliers.

    Parameters
    ----------
    alpha : float, optional
        Exponent of the footprint of uncertainty, in (1, 2] (eq. (6)). Default 2.
    bandwidth_deg : float, optional
        Half-width of the triangular membership function in degrees, at most
        :data:`MAX_BANDWIDTH_DEG`. Default 1 (the paper gives none; docs/method.md, section 5).
    resolution_deg : float, optional
        Quantisation step of the histogram of values, at least :data:`MIN_RESOLUTION_DEG` and
        less than ``bandwidth_deg``. Default 0.1 (docs/method.md, section 5).
    min_values : int, optional
        Fewer values than this fall back to the median. Default 3.

    References
    ----------
    .. [1] T.-K. Kang, H. Zhang and G.-T. Park, "Stereo-vision based motion stabilization of a
           humanoid robot for the environment recognition by type-2 fuzzy logic", MED 2009,
           section II-C, eq. (6) and Fig. 7.
    .. [2] H. R. Tizhoosh, "Image thresholding using type II fuzzy sets", Pattern Recognition
           38(12), 2363-2372, 2005.
    """

    def __init__(self, alpha: float = 2.0, bandwidth_deg: float = 1.0,
                 resolution_deg: float = 0.1, min_values: int = 3):
        if not (1.0 < alpha <= 2.0):
            raise ValueError(f"alpha must be in (1, 2] (paper eq. 6); got {alpha}")
        if not (MAX_BANDWIDTH_DEG >= bandwidth_deg > resolution_deg >= MIN_RESOLUTION_DEG):
            raise ValueError(f"need {MAX_BANDWIDTH_DEG:g} >= bandwidth_deg > resolution_deg >= "
                             f"{MIN_RESOLUTION_DEG:g}; got {bandwidth_deg} and {resolution_deg}")
        if min_values < 1:
            raise ValueError(f"min_values must be >= 1; got {min_values}")
        self.alpha = float(alpha)
        self.bandwidth = float(bandwidth_deg)
        self.resolution = float(resolution_deg)
        self.min_values = int(min_values)
        self._half_taps = int(np.ceil(self.bandwidth / self.resolution))
        offsets = np.arange(-self._half_taps, self._half_taps + 1) * self.resolution
        membership = np.clip(1.0 - np.abs(offsets) / self.bandwidth, 0.0, 1.0)
        self._kernel = membership ** (1.0 / self.alpha) - membership ** self.alpha

    def ultrafuzziness(self, values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Ultrafuzziness gamma(T) of eq. (6) at every position T of the histogram of values.

        Parameters
        ----------
        values : (N,) array_like of float
            Finite angle estimates in degrees, at least one.

        Returns
        -------
        positions, gamma : ndarray of float
            Positions T (degrees), every ``resolution_deg`` over the range of ``values`` +- one
            bandwidth, and gamma(T).
        """
        values = np.asarray(values, dtype=np.float64)
        if values.size == 0 or not np.isfinite(values).all():
            raise ValueError(f"values must be finite and at least one; got {values.size} values")
        bins = np.rint(values / self.resolution).astype(np.int64)
        first = bins.min() - self._half_taps
        histogram = np.bincount(bins - first, minlength=int(bins.max() - first) + 1
                                + self._half_taps)
        gamma = np.convolve(histogram, self._kernel, mode="same") / bins.size
        positions = (first + np.arange(histogram.size)) * self.resolution
        return positions, gamma

    def __call__(self, values: np.ndarray) -> RobustAngle:
        """The robust rotation of the angle estimates ``values``.

        Parameters
        ----------
        values : (N,) array_like of float
            Angle estimates in degrees; non-finite entries are ignored and never inliers.

        Returns
        -------
        RobustAngle
        """
        values = np.asarray(values, dtype=np.float64)
        finite = np.isfinite(values)
        inliers = np.zeros(values.shape, bool)
        if not finite.any():
            return RobustAngle(np.nan, np.nan, np.nan, inliers, MEDIAN_FALLBACK)
        data = values[finite]
        median = _median(data)
        if data.size >= self.min_values:
            positions, gamma = self.ultrafuzziness(data)
            # Positions ascend: those at or below the median are a prefix, those at or above
            # it a suffix.
            below = int(np.searchsorted(positions, median, side="right"))
            above = int(np.searchsorted(positions, median, side="left"))
            lower = float(positions[np.argmax(gamma[:below])])
            upper = float(positions[above + np.argmax(gamma[above:])])
            inliers = finite & (values >= lower) & (values <= upper)
            if inliers.any():
                return RobustAngle(float(values[inliers].mean()), lower, upper, inliers, None)
        return RobustAngle(median, np.nan, np.nan, np.zeros(values.shape, bool),
                           MEDIAN_FALLBACK)


def _median(values: np.ndarray) -> float:
    """``np.median`` of a non-empty array, bit for bit (the mean of the two middle values of
    an even count), with less overhead on the few values here."""
    ordered = np.sort(values).tolist()
    middle = len(ordered) // 2
    if len(ordered) % 2:
        return ordered[middle]
    return (ordered[middle - 1] + ordered[middle]) / 2.0
