"""Stage 1 of Kang, Zhang & Park (2009), section II-B: the number of clusters and their seeds.

The segmentation (stage 2, :mod:`stabilizer.it2fcm`) needs to know how many objects a disparity
image holds and where to start their centres. The paper reads both off the gray-level histogram:

"The number of peaks in the histogram of an image, which is bigger than the regular ratio for the
whole pixel number of an image in a domain interval of 20, is set as the number of cluster seeds.
... the ratio was set at 2%."

Resolution (docs/method.md, section 1): the histogram of the *valid* pixels (gray levels 1..255;
0 = no measurement never counts) is summed over bins of ``bin_width`` levels (1-20, 21-40, ...).
A peak is a bin that is a local maximum (>= both neighbours; a plateau of equal bins counts once)
holding more than ``min_ratio`` of the valid pixels. Each peak gives one seed: the bin's centre
of mass (the count-weighted mean level inside it), which lies in the bin as its centre does but
starts the clustering closer to the cluster. At least two seeds are returned when the image has
two distinct valid levels (the second one is the valid level farthest from the first seed).
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

#: Gray levels of a uint8 disparity-like image; level 0 is "no measurement".
N_LEVELS = 256


@dataclass(frozen=True)
class ClusterSeeds:
    """Result of stage 1.

    Attributes
    ----------
    seeds : (C,) ndarray of float
        Ascending gray-level seeds, one per cluster (empty if there is no valid pixel).
    level_counts : (256,) ndarray of float
        Histogram of the valid pixels (``level_counts[0]`` is 0).
    """

    seeds: np.ndarray
    level_counts: np.ndarray

    @property
    def n_clusters(self) -> int:
        return int(self.seeds.size)


def valid_level_histogram(image: np.ndarray) -> np.ndarray:
    """Counts of gray levels 0..255 with level 0 (invalid pixels) zeroed.

    Parameters
    ----------
    image : (H, W) uint8 ndarray
        Disparity-like image, 0 = no measurement.

    Returns
    -------
    (256,) ndarray of float
        The histogram of the valid pixels.
    """
    _check_disparity(image)
    counts = cv2.calcHist([image], [0], None, [N_LEVELS], [0, N_LEVELS]).ravel().astype(np.float64)
    counts[0] = 0.0
    return counts


def _check_disparity(image: np.ndarray) -> None:
    if not isinstance(image, np.ndarray) or image.ndim != 2 or image.dtype != np.uint8:
        raise ValueError(f"image must be a 2-D uint8 disparity-like array (0 = invalid); got "
                         f"{getattr(image, 'dtype', type(image).__name__)} of shape "
                         f"{np.shape(image)}")


class HistogramSeeds:
    """Cluster count and seeds from the histogram peaks of a disparity-like image.

    Parameters
    ----------
    bin_width : int, optional
        Width of the histogram bins in gray levels. Default 20, the paper's "domain interval
        of 20".
    min_ratio : float, optional
        A peak bin must hold more than this fraction of the valid pixels. Default 0.02, the
        paper's "ratio was set at 2%".

    References
    ----------
    .. [1] T.-K. Kang, H. Zhang and G.-T. Park, "Stereo-vision based motion stabilization of a
           humanoid robot for the environment recognition by type-2 fuzzy logic", MED 2009,
           section II-B (the text after eq. (5)).
    """

    def __init__(self, bin_width: int = 20, min_ratio: float = 0.02):
        if not (1 <= int(bin_width) <= 255):
            raise ValueError(f"bin_width must be an integer in 1..255; got {bin_width}")
        if not (0.0 <= min_ratio < 1.0):
            raise ValueError(f"min_ratio must be in [0, 1); got {min_ratio}")
        self.bin_width = int(bin_width)
        self.min_ratio = float(min_ratio)
        levels = np.arange(1, N_LEVELS)
        self._bin_of_level = (levels - 1) // self.bin_width  # level 1..255 -> bin index
        self._n_bins = int(self._bin_of_level[-1]) + 1

    def __call__(self, image: np.ndarray) -> ClusterSeeds:
        """Seeds of a disparity-like image.

        Parameters
        ----------
        image : (H, W) uint8 ndarray
            Disparity-like image, 0 = no measurement.

        Returns
        -------
        ClusterSeeds
        """
        return self.from_counts(valid_level_histogram(image))

    def from_counts(self, level_counts: np.ndarray) -> ClusterSeeds:
        """Seeds from a histogram of valid levels.

        Parameters
        ----------
        level_counts : (256,) ndarray
            Pixel count of every gray level; ``level_counts[0]`` (invalid) is ignored.

        Returns
        -------
        ClusterSeeds
        """
        if np.shape(level_counts) != (N_LEVELS,):
            raise ValueError(f"level_counts must be a histogram of {N_LEVELS} gray levels; got "
                             f"shape {np.shape(level_counts)}")
        counts = level_counts[1:]
        total = counts.sum()
        if total <= 0:
            return ClusterSeeds(np.empty(0), level_counts)
        levels = np.arange(1, N_LEVELS, dtype=np.float64)
        bin_counts = np.bincount(self._bin_of_level, weights=counts, minlength=self._n_bins)
        bin_mass = np.bincount(self._bin_of_level, weights=counts * levels,
                               minlength=self._n_bins)
        run_starts, is_peak = self._peak_runs(bin_counts, total)
        # A peak's seed: centre of mass of its bins (a plateau of equal bins counts once).
        run_counts = np.add.reduceat(bin_counts, run_starts)
        run_mass = np.add.reduceat(bin_mass, run_starts)
        seeds = list(run_mass[is_peak] / run_counts[is_peak])
        present = levels[counts > 0]
        if len(seeds) == 0:  # no bin clears the ratio: one seed at the densest bin
            densest = int(np.argmax(bin_counts))
            seeds = [bin_mass[densest] / bin_counts[densest]]
        if len(seeds) == 1 and present.size >= 2:
            seeds.append(present[np.argmax(np.abs(present - seeds[0]))])
        return ClusterSeeds(np.sort(np.asarray(seeds, dtype=np.float64)), level_counts)

    def _peak_runs(self, bin_counts: np.ndarray, total: float) -> tuple[np.ndarray, np.ndarray]:
        """First bin of each run of equal counts, and whether that run is a peak above ratio."""
        run_starts = np.concatenate(([0], np.flatnonzero(np.diff(bin_counts) != 0) + 1))
        runs = np.concatenate(([-1.0], bin_counts[run_starts], [-1.0]))
        is_peak = (runs[1:-1] > runs[:-2]) & (runs[1:-1] > runs[2:])
        return run_starts, is_peak & (runs[1:-1] > self.min_ratio * total)
