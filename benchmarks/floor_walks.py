"""Walks on the roughest floor a scene accepts: does the robot stay up for 20 s?

    python benchmarks/floor_walks.py                      # 32 walks, about a minute
    python benchmarks/floor_walks.py --seconds 8 --seeds 0

Each walk: the corridor scene on a floor sloped by 3 degrees with 5 mm bumps
(:class:`sim.world.scenes.floor.Floor`), rising towards 0, 90, 180 or 270 degrees from the
robot's walking direction (uphill, across rising to its left, downhill, across rising to its
right); the robot stands 1 s, then walks straight at 0.1 m/s, with each gait preset. One line per
walk: whether and when it fell. docs/scenes.md and docs/walking.md (Known limits) quote the
result.
"""

from __future__ import annotations

import itertools
import sys
from multiprocessing import Pool

DIRECTIONS_DEG = (0.0, 90.0, 180.0, 270.0)
GAITS = ("default", "paper_like")


def walk(gait: str, direction_deg: float, seed: int, seconds: float) -> str:
    """One walk; "stands" or "fell at T s" (T from the start of the simulation)."""
    from sim.world.assembly import assemble, compile_world
    from sim.world.scenes import build_scene
    from sim.world.scenes.floor import Floor
    from sim.world.walking import RobotSimulation

    scene = build_scene("corridor", seed, floor=Floor(3.0, direction_deg, 0.005))
    robot = RobotSimulation(compile_world(assemble(scene.arena, scene.start_xy,
                                                   scene.start_yaw_deg)), gait=gait, seed=seed)
    robot.run(1.0)
    robot.command(0.1, 0.0)
    robot.run(seconds)
    return "stands" if robot.fall is None else f"fell at {robot.fall.time_s:.1f} s"


def _walk(args) -> str:
    gait, direction, seed, seconds = args
    return f"{gait:>10}  rising towards {direction:5.0f} deg  seed {seed}: " \
           f"{walk(gait, direction, seed, seconds)}"


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
    with Pool(args.workers) as pool:
        for line in pool.imap(_walk, jobs):
            print(line, flush=True)
    return 0


if __name__ == "__main__":
    from sim.command_line import script_status

    sys.exit(script_status(main))
