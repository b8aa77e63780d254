"""Walks on the roughest floor a scene accepts: does the robot stay up for 20 s?

    python benchmarks/floor_walks.py                      # 32 walks, about a minute
    python benchmarks/floor_walks.py --seconds 8 --seeds 0

Each walk: the corridor scene on a floor sloped by 3 degrees with 5 mm bumps
(:class:`sim.world.scenes.floor.Floor`), rising towards 0, 90, 180 or 270 degrees from the
robot's walking direction (uphill, across rising to its left, downhill, across rising to its
right); the robot stands 1 s, then walks straight at 0.1 m/s, with each gait preset. One line per
walk: whether and when it fell, and how far the controller's floor estimate points off the
slope's direction (the median over the walk's last 10 s, sampled every 0.5 s); then the median
and the worst of those over the walks that stand. docs/scenes.md and docs/walking.md (Sloped
floors, Known limits) quote the result.
"""

from __future__ import annotations

import itertools
import math
import statistics
import sys
from multiprocessing import Pool

DIRECTIONS_DEG = (0.0, 90.0, 180.0, 270.0)
GAITS = ("default", "paper_like")


#: The floor estimate's direction is sampled this often over the walk's last WINDOW_S.
SAMPLE_S, WINDOW_S = 0.5, 10.0


def walk(gait: str, direction_deg: float, seed: int, seconds: float) -> tuple[str, float]:
    """One walk: "stands" or "fell at T s" (T from the start of the simulation), and the
    median of how far the floor estimate points off the slope's direction over its last
    ``WINDOW_S``, degrees (NaN after a fall, or while the estimate is level)."""
    from sim.world.assembly import assemble, compile_world
    from sim.world.scenes import build_scene
    from sim.world.scenes.floor import Floor
    from sim.world.walking import RobotSimulation

    scene = build_scene("corridor", seed, floor=Floor(3.0, direction_deg, 0.005))
    robot = RobotSimulation(compile_world(assemble(scene.arena, scene.start_xy,
                                                   scene.start_yaw_deg)), gait=gait, seed=seed)
    robot.run(1.0)
    robot.command(0.1, 0.0)
    samples = int(seconds // SAMPLE_S)
    robot.run(seconds - samples * SAMPLE_S)
    off_deg = []
    for sample in range(samples):
        robot.run(SAMPLE_S)
        gradient = robot.controller.floor.estimate
        if (samples - sample) * SAMPLE_S <= WINDOW_S and gradient != (0.0, 0.0):
            off_deg.append(abs(math.degrees(math.remainder(
                math.atan2(gradient[1], gradient[0]) - math.radians(direction_deg),
                2 * math.pi))))
    if robot.fall is not None:
        return f"fell at {robot.fall.time_s:.1f} s", math.nan
    return "stands", statistics.median(off_deg) if off_deg else math.nan


def _walk(args) -> tuple[str, float]:
    gait, direction, seed, seconds = args
    outcome, off_deg = walk(gait, direction, seed, seconds)
    return (f"{gait:>10}  rising towards {direction:5.0f} deg  seed {seed}: {outcome}, floor "
            f"estimate {off_deg:.1f} deg off the slope's direction", off_deg)


def main(argv: list[str] | None = None) -> int:
    from sim.command_line import (MAX_SEED, POSITIVE_INTEGER, OneLineParser, integer_option,
                                  number_option)

    parser = OneLineParser(prog="floor_walks.py", description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=number_option(0.0, 3600.0), default=20.0,
                        help="walking time per walk")
    parser.add_argument("--seeds", type=integer_option(0, MAX_SEED), nargs="+",
                        default=[0, 1, 2, 3])
    parser.add_argument("--workers", type=POSITIVE_INTEGER, default=2)
    args = parser.parse_args(argv)
    jobs = list(itertools.product(GAITS, DIRECTIONS_DEG, args.seeds, [args.seconds]))
    offs = []
    with Pool(args.workers) as pool:
        for line, off_deg in pool.imap(_walk, jobs):
            print(line, flush=True)
            offs.append(off_deg)
    measured = [(off, job) for off, job in zip(offs, jobs)
                if not math.isnan(off)]  # NaN: fell, or level
    if measured:
        worst, (gait, direction, seed, _) = max(measured)
        median = statistics.median(off for off, _ in measured)
        print(f"floor estimate off the slope's direction over {len(measured)} walks: median "
              f"{median:.1f} deg, worst {worst:.1f} deg ({gait}, rising towards "
              f"{direction:.0f} deg, seed {seed})")
    return 0


if __name__ == "__main__":
    from sim.command_line import script_status

    sys.exit(script_status(main))
