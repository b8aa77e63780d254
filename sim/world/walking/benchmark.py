"""Real-time factor of walking physics + control, without rendering, on one core."""

from __future__ import annotations

import argparse
import time

from sim.world.walking.simulation import RobotSimulation
from sim.world.assembly import assemble, compile_world


def benchmark_realtime_factor(sim_seconds: float = 20.0, gait: str = "default",
                              clock=time.perf_counter) -> float:
    """Simulated seconds per second of ``clock`` of the humanoid walking forward on a floor.

    Times ``RobotSimulation.run`` (controller + physics, a single thread) only, after building
    the world. ``clock`` is wall-clock time by default; ``time.process_time`` counts only this
    process's CPU time, which other jobs sharing the machine disturb less.
    """
    if sim_seconds <= 0:
        raise ValueError(f"sim_seconds must be > 0, got {sim_seconds!r}")
    sim = RobotSimulation(compile_world(assemble()), gait=gait)
    sim.command(forward_speed_mps=sim.gait.max_forward_speed_mps)
    start = clock()
    sim.run(sim_seconds)
    return sim_seconds / (clock() - start)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=benchmark_realtime_factor.__doc__)
    parser.add_argument("--seconds", type=float, default=20.0)
    parser.add_argument("--gait", default="default")
    args = parser.parse_args(argv)
    wall = benchmark_realtime_factor(args.seconds, args.gait)
    cpu = benchmark_realtime_factor(args.seconds, args.gait, clock=time.process_time)
    print(f"real-time factor ({args.gait}, {args.seconds:g} s simulated, no rendering, one "
          f"core): {wall:.1f}x wall clock, {cpu:.1f}x process CPU time")


if __name__ == "__main__":
    main()
