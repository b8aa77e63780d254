"""Speed benchmark of the stabilizers: milliseconds per frame at the SR4000's 176 x 144.

For each method and each of ``n_scenes`` synthetic depth scenes, ``Stabilizer(reference,
method)`` is built once (the reference analysed once, as over a gait cycle) and
``estimate(current)`` is timed on that scene's share of ``n_frames`` frames (the reference moved
by random rigid motions within +-15 deg and +-40 px); several scenes, because the work of the
paper's method depends on the scene (cluster count, convergence). One thread: OpenCV's and
the BLAS/OpenMP pools are set to 1 before anything is imported that starts them. The figure is
the median over frames, so a rare slow frame (page fault, scheduler) does not move it.

Run: ``python -m sim.bench`` (options: ``--frames N``, ``--seed S``, ``--methods a,b``).
"""

from __future__ import annotations

import os

for _variable in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_variable, "1")

import argparse
import time

import cv2
import numpy as np

import stabilizer
from stabilizer.motion import apply_motion

SHAPE = (144, 176)
#: The method every other method's time is compared with.
BASELINE = "t2fuzzy"


def _scenes(n_frames: int, n_scenes: int, seed: int) -> list[tuple[np.ndarray, list]]:
    """``n_scenes`` uint8 disparity references, each with its share of moved copies."""
    # The scene generator lives with the tests; the same one the accuracy tests use.
    from tests.synthetic import make_depth_scene, random_motion

    rng = np.random.default_rng(seed)
    per_scene = max(1, n_frames // n_scenes)
    scenes = []
    for index in range(n_scenes):
        reference = stabilizer.depth_to_disparity(make_depth_scene(seed + index, SHAPE))
        scenes.append((reference, [apply_motion(reference, random_motion(rng))
                                   for _ in range(per_scene)]))
    return scenes


def time_method(method: str, scenes: list[tuple[np.ndarray, list]]) -> float:
    """Median milliseconds of ``Stabilizer(reference, method).estimate(frame)`` over frames."""
    times = []
    for reference, frames in scenes:
        tracker = stabilizer.Stabilizer(reference, method)
        tracker.estimate(frames[0])  # warm up caches and lazy imports
        for frame in frames:
            start = time.perf_counter()
            tracker.estimate(frame)
            times.append(time.perf_counter() - start)
    return 1e3 * float(np.median(times))


def stabilizer_benchmark(methods: list[str] | None = None, n_frames: int = 200,
                         seed: int = 0, n_scenes: int = 10) -> dict[str, float]:
    """Median ms per frame of each method (NaN for a method whose module is not available).

    Prints one line per method with its time and its ratio to t2fuzzy.
    """
    cv2.setNumThreads(1)
    methods = list(stabilizer.available_methods() if methods is None else methods)
    scenes = _scenes(n_frames, n_scenes, seed)
    results: dict[str, float] = {}
    for method in methods:
        try:
            results[method] = time_method(method, scenes)
        except ImportError as error:  # a method whose module is not written yet
            results[method] = float("nan")
            print(f"{method:>16}: not available ({error})")
    baseline = results.get(BASELINE, float("nan"))
    print(f"ms per frame at {SHAPE[1]}x{SHAPE[0]}, median of {n_frames} frames of {n_scenes} "
          "scenes, one thread:")
    for method, ms in results.items():
        if np.isfinite(ms):
            print(f"{method:>16}: {ms:8.3f} ms   ({ms / baseline:6.2f} x {BASELINE})")
    return results


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=200, help="frames timed per method")
    parser.add_argument("--seed", type=int, default=0, help="scene and motion seed")
    parser.add_argument("--scenes", type=int, default=10, help="distinct scenes")
    parser.add_argument("--methods", default=None,
                        help="comma-separated methods (default: all available)")
    args = parser.parse_args(argv)
    methods = None if args.methods is None else args.methods.split(",")
    stabilizer_benchmark(methods, args.frames, args.seed, args.scenes)


if __name__ == "__main__":
    main()
