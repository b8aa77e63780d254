"""The "ok is trustworthy" properties of every method over other seeds than the tests'.

``tests/stabilizer/test_robustness.py`` checks them on 60 fixed cases per method and property;
this counts the cases that break them over as many more as asked, with a seed of the caller's:

    python benchmarks/trust_properties.py --cases 150 --seed 77

Per method: ``"ok"`` on unrelated frames (scenes of only 2-3 objects, with or without a shared
floor, sides 64-240: harder than the test's four-object scenes, docs/method.md, section 11), on
identical frames an ``"ok"`` more than 1 degree or 1 px from no motion, and on a frame moved by a
known motion (within +-15 degrees and 40 px or a fifth of the smaller side) an ``"ok"`` more
than 4 degrees or 6 px from it; and, for what the check costs, the known motions found (an
``"ok"`` within those limits).
"""

from __future__ import annotations

import math
import sys

# First: importing sim puts numpy and OpenCV on the SIMD paths of egostab's runs, and
# limit_threads gives them one thread each, as where egostab estimates, before they load.
from sim.harness.threads import limit_threads

limit_threads()

import cv2
import numpy as np


def main(argv: list[str] | None = None) -> int:
    from stabilizer import Motion, apply_motion, available_methods, estimate
    from stabilizer.api import _estimator_class
    from stabilizer.inputs import depth_to_disparity
    from stabilizer.motion import wrap_angle_deg
    from stabilizer.testing import make_depth_scene, random_motion

    from sim.command_line import MAX_SEED, POSITIVE_INTEGER, OneLineParser, integer_option

    parser = OneLineParser(prog="trust_properties.py", description=__doc__.splitlines()[0])
    parser.add_argument("--cases", type=POSITIVE_INTEGER, default=150,
                        help="cases per method and property")
    parser.add_argument("--seed", type=integer_option(0, MAX_SEED), default=77)
    methods = available_methods()
    parser.add_argument("--methods", nargs="+", choices=methods, default=methods,
                        help="methods to check (default: every built-in one; each draws the "
                             "same cases whichever others are checked)")
    args = parser.parse_args(argv)
    cv2.setNumThreads(1)

    def shape(rng, method: str, smallest: int = 0) -> tuple[int, int]:
        low = max(_estimator_class(method).min_side(), smallest)
        return int(rng.integers(low, 241)), int(rng.integers(low, 241))

    def scene(rng, size, n_objects: int, floor: bool) -> np.ndarray:
        return depth_to_disparity(make_depth_scene(int(rng.integers(2**31)), size,
                                                   n_objects=n_objects, floor=floor))

    def off(motion: Motion, truth: Motion, max_deg: float, max_px: float) -> bool:
        return motion.ok and (
            abs(float(wrap_angle_deg(motion.angle_deg - truth.angle_deg))) > max_deg
            or math.hypot(motion.dx - truth.dx, motion.dy - truth.dy) > max_px)

    for method in args.methods:
        rng = np.random.default_rng([args.seed, methods.index(method)])
        unrelated = identical = known = found = 0
        for _ in range(args.cases):
            size = shape(rng, method, 64)
            n_objects, floor = int(rng.integers(2, 4)), bool(rng.integers(2))
            reference = scene(rng, size, n_objects, floor)
            unrelated += estimate(reference, scene(rng, size, n_objects, floor), method).ok
        for _ in range(args.cases):
            frame = scene(rng, shape(rng, method), int(rng.integers(2, 7)), bool(rng.integers(2)))
            identical += off(estimate(frame, frame.copy(), method), Motion(0.0, 0.0, 0.0),
                             1.0, 1.0)
        for _ in range(args.cases):
            size = shape(rng, method)
            reference = scene(rng, size, int(rng.integers(2, 7)), bool(rng.integers(2)))
            truth = random_motion(rng, 15.0, min(40.0, 0.2 * min(size)))
            motion = estimate(reference, apply_motion(reference, truth), method)
            missed = off(motion, truth, 4.0, 6.0)
            known += missed
            found += motion.ok and not missed
        print(f"{method}: of {args.cases} cases each, ok on unrelated frames {unrelated}, "
              f"invented on identical frames {identical}, off a known motion {known}, "
              f"known motions found {found}", flush=True)
    return 0


if __name__ == "__main__":
    from sim.command_line import script_status

    sys.exit(script_status(main))
