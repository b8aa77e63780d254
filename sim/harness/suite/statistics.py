"""How sure a suite's figures are: bootstrap intervals of means over sequences.

The samples are per-sequence figures (a method's mean absolute error or failure rate over one
sequence). Frames within a sequence are strongly correlated, so frames are never resampled:
only whole sequences are. The interval of a mean is scipy's BCa bootstrap at 95%; when BCa
cannot be computed (all samples equal, or too few distinct values for its acceleration) the
percentile bootstrap is used, and the interval says which one it is. Two methods are compared
on the same sequences by bootstrapping their per-sequence differences (a paired comparison):
the difference is clear when its interval excludes 0. The resampling generator has a fixed
seed, so the same samples give the same intervals bit for bit.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Sequence
from dataclasses import asdict, dataclass

import numpy as np
from scipy import stats

CONFIDENCE_LEVEL = 0.95
#: Seed of the resampling generator (fixed: tables are reproducible).
BOOTSTRAP_SEED = 0
N_RESAMPLES = 9999
BCA, PERCENTILE = "BCa", "percentile"


@dataclass(frozen=True)
class Interval:
    """The mean of ``n`` samples and its bootstrap interval (NaN bounds with fewer than 2).

    ``method`` is "BCa" or "percentile" (the fallback), or "" when there is no interval.
    """

    mean: float
    low: float
    high: float
    n: int
    method: str

    def excludes_zero(self) -> bool:
        """True when the interval lies wholly above or wholly below 0."""
        return self.low > 0 or self.high < 0  # False for NaN bounds

    def to_dict(self) -> dict:
        return asdict(self)


def mean_interval(samples: Sequence[float], seed: int = BOOTSTRAP_SEED) -> Interval:
    """The mean of the finite ``samples`` and its 95% bootstrap interval.

    Samples that are not finite (NaN, infinite) are left out (``n`` counts those kept). BCa is
    tried first; if it gives no finite bounds (degenerate samples), the percentile interval is
    returned instead.
    """
    values = np.asarray(samples, dtype=float)
    values = values[np.isfinite(values)]
    if values.size == 0:
        return Interval(math.nan, math.nan, math.nan, 0, "")
    mean = float(values.mean())
    if values.size < 2:
        return Interval(mean, math.nan, math.nan, 1, "")
    if values.min() == values.max():  # every resample has this mean: BCa is degenerate
        return Interval(float(values[0]), float(values[0]), float(values[0]), int(values.size),
                        PERCENTILE)
    for method in (BCA, PERCENTILE):
        with warnings.catch_warnings():  # a degenerate BCa warns and gives NaN: handled below
            warnings.simplefilter("ignore")
            result = stats.bootstrap((values,), np.mean, confidence_level=CONFIDENCE_LEVEL,
                                     n_resamples=N_RESAMPLES, method=method,
                                     rng=np.random.default_rng(seed))
        low, high = (float(bound) for bound in result.confidence_interval)
        if math.isfinite(low) and math.isfinite(high):
            return Interval(mean, low, high, int(values.size), method)
    return Interval(mean, math.nan, math.nan, int(values.size), "")


def paired_difference(first: Sequence[float], second: Sequence[float],
                      seed: int = BOOTSTRAP_SEED) -> Interval:
    """The mean of ``first[i] - second[i]`` and its interval, over the pairs both have.

    ``first`` and ``second`` are the same sequences' figures in the same order; a pair with a
    NaN on either side is left out.
    """
    first, second = np.asarray(first, dtype=float), np.asarray(second, dtype=float)
    if first.shape != second.shape:
        raise ValueError(f"paired samples must have the same length; got {first.size} and "
                         f"{second.size}")
    return mean_interval(first - second, seed)
