"""Push recovery of the walking humanoid: push trials and the largest impulse survived.

A trial: the robot stands 1 s, walks straight ahead at ``speed_mps``, is pushed on the torso
(``RobotSimulation.schedule_push``, 0.1 s) once the gait is steady, and walks on for
``after_s``. It survives when no FallEvent is recorded; it has recovered its commanded path
when, over the last gait cycle, its heading is within ``HEADING_TOLERANCE_DEG`` of the start
heading and its torso's mean lateral offset from the straight line it was commanded to walk is
within ``LATERAL_TOLERANCE_M``.

The seed draws the initial joint perturbation (RobotSimulation) and the push's phase within a
gait cycle, so several seeds push at several moments of the step.

Run ``python -m sim.world.walking.push_recovery [--gaits ...] [--seeds N]
[--no-step-adjustment] [--no-com-feedback | --com-feedback-after-push] [--lateral-sway M]
[--no-counterbalance]`` to print the table of docs/walking.md, "Push recovery": per gait and
direction the largest impulse survived (bisection), for the worst and the best seed.
"""

from __future__ import annotations

import math
import sys
from dataclasses import dataclass, replace

import mujoco
import numpy as np

from sim.command_line import POSITIVE_INTEGER, OneLineParser, number_option, script_status
from sim.world.walking.gait import GAIT_PRESETS, SOLE_HALF_WIDTH_M, GaitParams
from sim.world.walking.simulation import RobotSimulation
from sim.world.assembly import assemble, compile_world

#: Largest heading error (deg) and mean lateral offset (m) over the last gait cycle of a trial
#: that still count as back on the commanded path.
HEADING_TOLERANCE_DEG = 10.0
LATERAL_TOLERANCE_M = 0.05
#: Push directions of the table, degrees counter-clockwise from the walking direction.
DIRECTIONS_DEG = {"forward": 0.0, "left": 90.0, "backward": 180.0, "right": 270.0,
                  "forward-left": 45.0, "backward-left": 135.0, "backward-right": 225.0,
                  "forward-right": 315.0}
PUSH_DURATION_S = 0.1
STAND_S = 1.0
#: Walking time before the earliest push: the gait is steady after the first two steps.
WALK_BEFORE_PUSH_S = 2.4


@dataclass(frozen=True)
class PushTrial:
    """Outcome of one push trial (angles in degrees, distances in metres)."""

    fell: bool
    push_start_s: float
    heading_error_deg: float
    lateral_offset_m: float

    @property
    def recovered(self) -> bool:
        return (not self.fell and abs(self.heading_error_deg) <= HEADING_TOLERANCE_DEG
                and abs(self.lateral_offset_m) <= LATERAL_TOLERANCE_M)


def push_trial(model: mujoco.MjModel, gait: GaitParams | str, impulse_ns: float,
               direction_deg: float, seed: int = 0, speed_mps: float = 0.1,
               after_s: float = 4.0, step_adjustment: bool = True,
               com_feedback: bool | str = True, counterbalance: bool = True) -> PushTrial:
    """Push the walking robot horizontally by ``impulse_ns`` towards ``direction_deg``
    (counter-clockwise from its walking direction) and walk on for ``after_s``; the switches
    are RobotSimulation's."""
    sim = RobotSimulation(model, gait=gait, seed=seed, step_adjustment=step_adjustment,
                          com_feedback=com_feedback, counterbalance=counterbalance)
    start_xy, start_yaw = sim.torso_pose()[0][:2], sim.torso_pose()[1]
    cycle_s = 2.0 * sim.gait.step_period_s
    phase_s = float(np.random.default_rng(seed).uniform(0.0, cycle_s))
    push_start_s = STAND_S + WALK_BEFORE_PUSH_S + phase_s
    angle = start_yaw + math.radians(direction_deg)
    sim.schedule_push(push_start_s, (impulse_ns * math.cos(angle), impulse_ns * math.sin(angle), 0.0),
                      PUSH_DURATION_S)
    sim.run(STAND_S)
    sim.command(forward_speed_mps=speed_mps)
    end_s = push_start_s + PUSH_DURATION_S + after_s
    walk_direction = np.array([math.cos(start_yaw), math.sin(start_yaw)])
    lateral = []
    while sim.time < end_s - 1e-9 and sim.fall is None:
        sim.step()
        if sim.time > end_s - cycle_s:
            offset = sim.torso_pose()[0][:2] - start_xy
            lateral.append(walk_direction[0] * offset[1] - walk_direction[1] * offset[0])
    heading_error = math.degrees(math.remainder(sim.torso_pose()[1] - start_yaw, 2 * math.pi))
    return PushTrial(sim.fall is not None, push_start_s, heading_error,
                     float(np.mean(lateral)) if lateral else math.nan)


def largest_survived_impulse(model: mujoco.MjModel, gait: GaitParams | str, direction_deg: float,
                             seed: int = 0, upper_ns: float = 8.0, resolution_ns: float = 0.125,
                             **trial_kwargs) -> float:
    """Largest impulse (N s, to ``resolution_ns``) survived with this seed, by bisection on
    [0, ``upper_ns``]; survival is assumed monotonic in the impulse."""
    for name, value in (("upper_ns", upper_ns), ("resolution_ns", resolution_ns)):
        if isinstance(value, bool) or not (isinstance(value, (int, float))
                                           and math.isfinite(value) and value > 0.0):
            raise ValueError(f"{name} {value!r}: accepted: a finite number of N s above 0")

    def survives(impulse):
        return not push_trial(model, gait, impulse, direction_deg, seed, **trial_kwargs).fell
    if survives(upper_ns):
        return upper_ns
    low, high = 0.0, upper_ns
    # Each trial halves the interval: a fixed count of them, until it is no wider than the
    # resolution.
    for _ in range(max(0, math.ceil(math.log2(upper_ns / resolution_ns)))):
        middle = (low + high) / 2.0
        low, high = (middle, high) if survives(middle) else (low, middle)
    return low


def main(argv: list[str] | None = None) -> None:
    parser = OneLineParser(prog="python -m sim.world.walking.push_recovery",
                           description="Largest push survived while walking, per gait and "
                                       "direction: worst and best seed (bisection).")
    parser.add_argument("--gaits", nargs="+", default=["default", "paper_like"],
                        choices=sorted(GAIT_PRESETS))
    parser.add_argument("--directions", nargs="+", default=list(DIRECTIONS_DEG),
                        choices=list(DIRECTIONS_DEG))
    parser.add_argument("--seeds", type=POSITIVE_INTEGER, default=4, help="seeds 0 .. N-1")
    parser.add_argument("--speed", type=number_option(0.0, 1.0), default=0.1,
                        help="forward speed, m/s (clipped to the gait's top speed)")
    parser.add_argument("--no-step-adjustment", action="store_true",
                        help="plan the footsteps from the commands alone (the controller before "
                             "push recovery)")
    feedback = parser.add_mutually_exclusive_group()
    feedback.add_argument("--no-com-feedback", action="store_true",
                          help="no centre-of-mass feedback")
    feedback.add_argument("--com-feedback-after-push", action="store_true",
                          help="centre-of-mass feedback only once a push is detected (the "
                               "controller before it fed back from the start)")
    parser.add_argument("--lateral-sway", type=number_option(-SOLE_HALF_WIDTH_M,
                                                             SOLE_HALF_WIDTH_M),
                        default=None, metavar="M",
                        help="the gaits' lateral_sway_m instead of the presets' (0: the ZMP "
                             "reference at the sole's centre, as the controller before)")
    parser.add_argument("--no-counterbalance", action="store_true",
                        help="no counterbalance by the waist and the swing leg after a push "
                             "towards the support foot")
    args = parser.parse_args(argv)
    model = compile_world(assemble())
    options = dict(speed_mps=args.speed, step_adjustment=not args.no_step_adjustment,
                   com_feedback=("after_push" if args.com_feedback_after_push
                                 else not args.no_com_feedback),
                   counterbalance=not args.no_counterbalance)
    gaits = {gait: GAIT_PRESETS[gait] if args.lateral_sway is None else replace(
        GAIT_PRESETS[gait], lateral_sway_m=args.lateral_sway) for gait in args.gaits}
    print("| direction | " + " | ".join(f"`{g}`: worst / best seed (N s)" for g in args.gaits) + " |")
    print("|---|" + "---|" * len(args.gaits))
    for name in args.directions:
        cells = []
        for params in gaits.values():
            survived = [largest_survived_impulse(model, params, DIRECTIONS_DEG[name], seed,
                                                 **options)
                        for seed in range(args.seeds)]
            cells.append(f"{min(survived):.2f} / {max(survived):.2f}")
        print(f"| {name} | " + " | ".join(cells) + " |", flush=True)


if __name__ == "__main__":
    sys.exit(script_status(main))
