"""ICP's two error metrics side by side: point-to-point and point-to-line (docs/peers.md, ICP).

    python benchmarks/icp_error_metrics.py        # about a minute

Two measurements, both metrics in one process, one thread:

- identical frames: the 60 ICP cases of the randomized property test
  (tests/stabilizer/test_robustness.py, 64-240 px) and 60 frames of the same generator at
  64 x 64, each estimated against itself; how many are ``"ok"`` within 1 deg and 1 px, before
  and after the trust check;
- moved frames: :func:`stabilizer.testing.corpus_frames`, every generator, seeds 0-9, 10 frames
  each, no trust check: mean absolute angle and shift errors of the ``"ok"`` estimates, how
  many are accurate (1 deg, 2 px) and how many are ``"ok"`` yet off by more than 5 deg or
  10 px, and the median ms per frame (the two metrics alternating frame by frame).
"""

from __future__ import annotations

import math
import sys
import time
from pathlib import Path

# First: importing sim puts numpy and OpenCV on the SIMD paths of egostab's runs, and
# limit_threads gives them one thread each, as where egostab estimates, before they load.
from sim.harness.threads import limit_threads

limit_threads()

import cv2
import numpy as np

METRICS = ("point_to_point", "point_to_line")


def identical_frames() -> None:
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "stabilizer"))
    import test_robustness as properties

    from stabilizer.peers.icp import IcpEstimator
    from stabilizer.verification import VerificationParams, Verifier

    for label, side in (("property test cases, 64-240 px", None), ("same generator, 64 x 64", 64)):
        for metric in METRICS:
            rng = properties.method_rng("icp", 1)
            raw = checked = 0
            for _ in range(60):
                shape = properties.property_shape(rng, "icp") if side is None else (side, side)
                frame = properties.property_scene(rng, shape)
                motion = IcpEstimator(frame, error_metric=metric).estimate(frame.copy())
                if motion.ok:
                    motion_checked = Verifier(frame, VerificationParams())(frame.copy(), motion)
                    near_zero = abs(motion.angle_deg) <= 1 and math.hypot(motion.dx,
                                                                          motion.dy) <= 1
                    raw += near_zero
                    checked += near_zero and motion_checked.ok
            print(f"identical frames, {label}, {metric}: ok within 1 deg / 1 px {raw}/60, "
                  f"after the trust check {checked}/60")


def moved_frames() -> None:
    from stabilizer.motion import wrap_angle_deg
    from stabilizer.peers.icp import IcpEstimator
    from stabilizer.testing import CORPUS_GENERATORS, corpus_frames

    errors = {metric: [] for metric in METRICS}
    failures = {metric: 0 for metric in METRICS}
    times = {metric: [] for metric in METRICS}
    for generator in CORPUS_GENERATORS:
        for seed in range(10):
            reference, frames, truths = corpus_frames(generator, seed, 10)
            estimators = {metric: IcpEstimator(reference, error_metric=metric)
                          for metric in METRICS}
            for frame, truth in zip(frames, truths):
                for metric in METRICS:
                    start = time.perf_counter()
                    motion = estimators[metric].estimate(frame)
                    times[metric].append(1e3 * (time.perf_counter() - start))
                    if not motion.ok:
                        failures[metric] += 1
                        continue
                    errors[metric].append((
                        abs(float(wrap_angle_deg(motion.angle_deg - truth.angle_deg))),
                        math.hypot(motion.dx - truth.dx, motion.dy - truth.dy)))
    for metric in METRICS:
        angle, shift = np.array(errors[metric]).T
        accurate = int(np.sum((angle <= 1) & (shift <= 2)))
        large = int(np.sum((angle > 5) | (shift > 10)))
        print(f"corpus_frames, {metric}: mean abs angle / shift error {angle.mean():.3f} deg / "
              f"{shift.mean():.3f} px, accurate {accurate}/{len(times[metric])}, failures "
              f"{failures[metric]}, ok yet > 5 deg or 10 px {large}, median "
              f"{np.median(times[metric]):.2f} ms/frame")


def main(argv: list[str] | None = None) -> int:
    from sim.command_line import OneLineParser

    # No options: an argument given is refused rather than ignored.
    OneLineParser(prog="icp_error_metrics.py",
                  description=__doc__.splitlines()[0]).parse_args(argv)
    cv2.setNumThreads(1)
    identical_frames()
    moved_frames()
    return 0


if __name__ == "__main__":
    from sim.command_line import script_status

    sys.exit(script_status(main))
