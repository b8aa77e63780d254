"""Speed benchmarks: stabilizers, physics, rendering and the whole pipeline, side by side.

``egostab bench`` (``run_benchmarks``) prints, measured in one run on this machine:
stabilizer ms/frame per method on synthetic scenes and on frames of a simulated walk, with
each method's ratio to the paper's; the walking physics' real-time factor (no rendering); the
SR4000 render + ToF frames/s; and the real-time factor of the whole pipeline on the default
scenario. ``--out`` writes them as Markdown with the machine they came from
(results/bench.md).

Stabilizer figures: milliseconds per frame at the SR4000's 176 x 144.

For each method and each of ``n_scenes`` synthetic depth scenes, ``Stabilizer(reference,
method)`` is built once (the reference analysed once, as over a gait cycle) and
``estimate(current)`` is timed on that scene's share of ``n_frames`` frames (the reference moved
by random rigid motions within +-15 deg and +-40 px); several scenes, because the work of the
paper's method depends on the scene (cluster count, convergence). One thread: OpenCV's and
the BLAS/OpenMP pools are set to 1 before anything is imported that starts them. The figure is
the median over frames, so a rare slow frame (page fault, scheduler) does not move it.

Run: ``python -m sim.harness.bench`` for the stabilizers alone (options: ``--frames N``, ``--seed S``,
``--methods a,b``), ``egostab bench`` for everything.
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
    # The same scene generator as the accuracy tests.
    from stabilizer.testing import make_depth_scene, random_motion

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


def simulated_scenes(scenario: str = "corridor_straight", n_frames: int = 150,
                     skip_s: float = 1.5) -> list[tuple[np.ndarray, list]]:
    """Frames of a simulated walk grouped by gait cycle: (first frame, the cycle's frames).

    The first ``skip_s`` seconds (standing, before the first step) are left out.
    """
    from sim.harness.runner import open_sensor, scenario_robot, walk_frames
    from sim.harness.scenario import load_scenario

    loaded = load_scenario(scenario)
    robot = scenario_robot(loaded)
    n_skip = int(skip_s * loaded.sensor.fps)
    cycles: dict[int, list[np.ndarray]] = {}
    with open_sensor(loaded, robot) as sensor:
        for frame in walk_frames(loaded, robot, sensor, n_skip + n_frames):
            if frame.index >= n_skip:
                cycles.setdefault(robot.gait_cycle, []).append(frame.disparity8)
    return [(frames[0], frames[1:]) for frames in cycles.values() if len(frames) > 1]


def stabilizer_benchmark(methods: list[str] | None = None, n_frames: int = 200,
                         seed: int = 0, n_scenes: int = 10,
                         scenes: list[tuple[np.ndarray, list]] | None = None,
                         label: str | None = None) -> dict[str, float]:
    """Median ms per frame of each method (NaN for a method whose module is not available).

    Synthetic scenes by default; pass ``scenes`` (e.g. :func:`simulated_scenes`) to time other
    frames. Prints one line per method with its time and its ratio to t2fuzzy.
    """
    cv2.setNumThreads(1)
    methods = list(stabilizer.available_methods() if methods is None else methods)
    if scenes is None:
        scenes = _scenes(n_frames, n_scenes, seed)
        label = label or f"{n_frames} frames of {n_scenes} synthetic scenes"
    n_timed = sum(len(frames) for _, frames in scenes)
    results: dict[str, float] = {}
    for method in methods:
        try:
            results[method] = time_method(method, scenes)
        except ImportError as error:  # a method whose module is not written yet
            results[method] = float("nan")
            print(f"{method:>16}: not available ({error})")
    baseline = results.get(BASELINE, float("nan"))
    print(f"ms per frame at {SHAPE[1]}x{SHAPE[0]}, median of {n_timed} frames "
          f"({label or 'given scenes'}), one thread:")
    for method, ms in results.items():
        if np.isfinite(ms):
            print(f"{method:>16}: {ms:8.3f} ms   ({ms / baseline:6.2f} x {BASELINE})")
    return results


def _machine() -> str:
    import platform

    cpu = platform.processor() or "unknown CPU"
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as handle:
            cpu = next(line.split(":", 1)[1].strip() for line in handle
                       if line.startswith("model name"))
    except (OSError, StopIteration):
        pass
    return f"{cpu}, {os.cpu_count()} cores, {platform.platform()}, Python {platform.python_version()}"


def run_benchmarks(quick: bool = False, out_path=None) -> dict:
    """Every speed figure of the project, measured side by side; optionally as Markdown."""
    import tempfile
    from pathlib import Path

    from sim.harness.atomic import write_text_atomic
    from sim.harness.cli import DEFAULT_SCENARIO
    from sim.harness.runner import RunConfig, run
    from sim.world.sensor.sr4000 import benchmark_fps
    from sim.world.walking import benchmark_realtime_factor

    n_frames = 60 if quick else 200
    synthetic = stabilizer_benchmark(n_frames=n_frames)
    walk = stabilizer_benchmark(scenes=simulated_scenes(DEFAULT_SCENARIO, n_frames // 2 if quick
                                                        else 150),
                                label=f"a simulated walk, scenario {DEFAULT_SCENARIO}")
    physics_rtf = benchmark_realtime_factor(5.0 if quick else 20.0)
    print(f"walking physics + control, no rendering: {physics_rtf:.1f}x real time")
    render_fps = benchmark_fps(100 if quick else 300)
    pipeline_frames = 45 if quick else 150
    with tempfile.TemporaryDirectory() as scratch:
        metrics = run(RunConfig(DEFAULT_SCENARIO, scratch, record=True,
                                max_frames=pipeline_frames))
    pipeline_rtf = metrics["run"]["realtime_factor"]
    print(f"whole pipeline, {DEFAULT_SCENARIO}, {pipeline_frames} frames, "
          f"{len(metrics['run']['methods'])} methods, recording on: {pipeline_rtf:.2f}x real time")
    figures = {"machine": _machine(), "date": time.strftime("%Y-%m-%d"),
               "stabilizer_ms_synthetic": synthetic, "stabilizer_ms_simulated": walk,
               "physics_realtime_factor": physics_rtf, "render_tof_fps": render_fps,
               "pipeline_realtime_factor": pipeline_rtf, "quick": quick}
    if out_path is not None:
        write_text_atomic(Path(out_path), bench_markdown(figures))
    return figures


def bench_markdown(figures: dict) -> str:
    """results/bench.md: the figures and the machine they came from."""
    lines = [f"# Benchmarks ({figures['date']})", "",
             f"Machine: {figures['machine']}.", "",
             "Measured by `egostab bench" + (" --quick" if figures["quick"] else "")
             + " --out results/bench.md`; stabilizers on one thread.", "",
             "| Method | ms/frame, synthetic scenes | x t2fuzzy | ms/frame, simulated walk | "
             "x t2fuzzy |", "|---|---|---|---|---|"]
    synthetic, walk = figures["stabilizer_ms_synthetic"], figures["stabilizer_ms_simulated"]
    for method, ms in synthetic.items():
        lines.append(f"| {method} | {ms:.2f} | {ms / synthetic[BASELINE]:.2f} | "
                     f"{walk[method]:.2f} | {walk[method] / walk[BASELINE]:.2f} |")
    lines += ["", "| Figure | Value |", "|---|---|",
              f"| walking physics + control, no rendering | "
              f"{figures['physics_realtime_factor']:.1f}x real time |",
              f"| SR4000 render + ToF, motion blur off | {figures['render_tof_fps']:.0f} frames/s |",
              f"| whole pipeline, default scenario, every method, recording on | "
              f"{figures['pipeline_realtime_factor']:.2f}x real time |", ""]
    return "\n".join(lines)


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
