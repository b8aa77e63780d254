"""Unpushed walks that change their command abruptly: is a disturbance detected, does the robot stand?

    python benchmarks/abrupt_commands.py                          # 18 walks, about 10 s
    python benchmarks/abrupt_commands.py --com-feedback-after-push --lateral-sway 0  # the controller before

Each walk, with each gait preset and seed: stand 1 s, walk 10 s at the top speed, 5 s walking and
turning at the top rates, then 5 s of one of three changes (turning in place the same way,
turning in place the other way, walking on and turning the other way), then 2 s stopped. One line
per walk: when the step adjustment first detected a disturbance (there is no push), how many steps
it adjusted, and whether the robot fell. docs/walking.md ("Push detection") quotes the result.
"""

from __future__ import annotations

import itertools
import sys
from multiprocessing import Pool

GAITS = ("default", "paper_like")
#: The third phase of each walk: (forward speed, yaw rate) as fractions of the gait's top rates.
CHANGES = {"the same turn in place": (0.0, 1.0), "the other turn in place": (0.0, -1.0),
           "walking, the other turn": (1.0, -1.0)}


def walk(gait: str, change: str, seed: int, com_feedback: bool | str,
         lateral_sway_m: float | None) -> str:
    """One walk; when a disturbance was detected, the steps adjusted, and a fall if any."""
    from dataclasses import replace

    from sim.world.assembly import assemble, compile_world
    from sim.world.walking import GAIT_PRESETS, RobotSimulation

    params = GAIT_PRESETS[gait] if lateral_sway_m is None else replace(
        GAIT_PRESETS[gait], lateral_sway_m=lateral_sway_m)
    robot = RobotSimulation(compile_world(assemble()), gait=params, seed=seed,
                            com_feedback=com_feedback)
    speed, yaw_rate = robot.gait.max_forward_speed_mps, robot.gait.max_yaw_rate_dps
    speed_share, yaw_share = CHANGES[change]
    robot.run(1.0)
    for command, seconds in (((speed, 0.0), 10.0), ((speed, yaw_rate), 5.0),
                             ((speed_share * speed, yaw_share * yaw_rate), 5.0), ((0.0, 0.0), 2.0)):
        robot.command(*command)
        robot.run(seconds)
    stepper = robot.controller.step_adjustment
    detected = ("no disturbance" if stepper.disturbed_at_s is None
                else f"disturbance at {stepper.disturbed_at_s:.2f} s")
    fell = "stands" if robot.fall is None else f"fell at {robot.fall.time_s:.1f} s"
    steps = stepper.adjusted_steps
    return f"{detected}, {steps} step{'' if steps == 1 else 's'} adjusted, {fell}"


def _walk(args) -> str:
    gait, change, seed, *controller = args
    return f"{gait:>10}  {change:<24} seed {seed}: {walk(gait, change, seed, *controller)}"


def main(argv: list[str] | None = None) -> int:
    from sim.command_line import (MAX_SEED, POSITIVE_INTEGER, OneLineParser, integer_option,
                                  number_option)
    from sim.world.walking.gait import SOLE_HALF_WIDTH_M

    parser = OneLineParser(prog="abrupt_commands.py", description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=integer_option(0, MAX_SEED), nargs="+", default=[0, 1, 2])
    parser.add_argument("--com-feedback-after-push", action="store_true",
                        help="the CoM feedback only once a push is detected (RobotSimulation "
                             "com_feedback='after_push', the controller before)")
    parser.add_argument("--lateral-sway", type=number_option(-SOLE_HALF_WIDTH_M,
                                                             SOLE_HALF_WIDTH_M),
                        default=None, metavar="M",
                        help="the gaits' lateral_sway_m instead of the presets' (0 with "
                             "--com-feedback-after-push: the controller before)")
    parser.add_argument("--workers", type=POSITIVE_INTEGER, default=2)
    args = parser.parse_args(argv)
    com_feedback = "after_push" if args.com_feedback_after_push else True
    jobs = list(itertools.product(GAITS, CHANGES, args.seeds, [com_feedback],
                                  [args.lateral_sway]))
    with Pool(args.workers) as pool:
        for line in pool.imap(_walk, jobs):
            print(line, flush=True)
    return 0


if __name__ == "__main__":
    from sim.command_line import script_status

    sys.exit(script_status(main))
