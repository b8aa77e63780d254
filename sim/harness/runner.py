"""Run one walking scenario end to end: simulate, render, estimate, score, write.

``run(RunConfig) -> metrics`` is a pure, picklable entry point: it builds the world, the robot
and the renderer inside the calling process, so a process pool (spawn), Ray or Dask can run
many of them (docs/design.md, "Parallel runs").

One frame of the loop (docs/design.md, "Data flow of one run"): the robot walks under physics,
control period by control period, following the scenario's commands; at the SR4000's exposure
times the sensor renders; the finished Frame is scored against its reference frame (chosen by
the scenario's reference policy) by the ground truth and by every method; the recorder logs it.
A fall, an interrupt (Ctrl-C) or an error ends the run cleanly: the files written describe
every finished frame and say how the run ended.
"""

from __future__ import annotations

import math
import os
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Mapping

from sim.harness.interrupts import interrupt_reason, stop_signals_interrupt
from sim.harness.methods import Estimator, method_factory
from stabilizer import compensate
from stabilizer.motion import Motion

#: Statuses a run can end with (metrics.json "status").
COMPLETE, FELL, INTERRUPTED, ERROR = "complete", "fell", "interrupted", "error"
#: The status of a run folder until its final write (at checkpoints, or after a second interrupt).
INCOMPLETE = "incomplete"
#: Name of the recording in a run folder.
RECORDING_RRD = "recording.rrd"
#: Frames between checkpoints of frames.csv / metrics.json during a run.
CHECKPOINT_FRAMES = 150


@dataclass(frozen=True)
class RunConfig:
    """What to run and where to write it.

    Attributes:
        scenario: path of a scenario TOML file, or the name of a shipped one (scenarios/).
        out_dir: run folder; created; files inside are replaced atomically.
        methods: methods to score; None = the scenario's list.
        record: write ``recording.rrd`` (rerun) beside the metrics, if the scenario's
            ``[recording] enabled`` also allows it.
        max_frames: stop after this many frames (None = the scenario's duration).
        seed: overrides the scenario's seed when given.
        overrides: dotted scenario keys -> values applied before validation, for sweeps
            (for example ``{"sensor.noise_scale": 2.0}``).
        progress: show a progress bar.
    """

    scenario: str
    out_dir: str
    methods: tuple[str, ...] | None = None
    record: bool = True
    max_frames: int | None = None
    seed: int | None = None
    overrides: Mapping[str, Any] = field(default_factory=dict)
    progress: bool = False


def scenario_name(scenario: str | os.PathLike) -> str:
    """The run's name for a scenario given by name or path (its file stem)."""
    return Path(scenario).stem


class _ReferenceTracker:
    """Holds the current reference frame and its analysed estimators, per the policy.

    Policies (docs/design.md): ``cycle_start`` = the first frame of each gait cycle; ``previous``
    = the frame before; ``first`` = the run's first frame. The methods are resolved once, here
    (sim.harness.methods: built-in, entry point or import path).
    """

    def __init__(self, policy: str, methods: tuple[str, ...]):
        self.policy = policy
        self.methods = methods
        self.factories = {method: method_factory(method) for method in methods}
        self.frame = None
        self.cycle = None
        self.stabilizers: dict[str, Estimator] = {}
        self.analysis_ms: dict[str, list[float]] = {method: [] for method in methods}

    def _needs_new(self, cycle: int) -> bool:
        return (self.frame is None or self.policy == "previous"
                or (self.policy == "cycle_start" and cycle != self.cycle))

    def reference_for(self, frame, cycle: int, previous_frame):
        """The reference of ``frame``; analysed once per reference change."""
        if self._needs_new(cycle):
            reference = frame if (self.policy != "previous" or previous_frame is None) \
                else previous_frame
            self.frame, self.cycle = reference, cycle
            self.stabilizers = {}
            for method in self.methods:
                start = time.perf_counter()
                self.stabilizers[method] = self.factories[method](reference.disparity8)
                self.analysis_ms[method].append(1e3 * (time.perf_counter() - start))
        return self.frame


def build_robot(scene_name: str, scene_seed: int = 0, gait="default", seed: int = 0,
                scene_params: Mapping[str, Any] | None = None):
    """Scene ``scene_name`` with the humanoid standing at its start, ready to walk.

    ``gait`` is a GaitParams or a preset name; ``seed`` perturbs the initial joint angles;
    ``scene_params`` are the scene's keyword parameters (docs/scenes.md).
    """
    from sim.world.scenes import build_scene
    from sim.world.walking import RobotSimulation
    from sim.world.assembly import assemble, compile_world

    scene = build_scene(scene_name, scene_seed, **(scene_params or {}))
    model = compile_world(assemble(scene.arena, scene.start_xy, scene.start_yaw_deg))
    return RobotSimulation(model, gait=gait, seed=seed)


def scenario_robot(scenario):
    """The robot of a loaded scenario: its scene and scene parameters, gait and seed."""
    return build_robot(scenario.scene, scenario.scene_seed, scenario.gait.params(),
                       scenario.seed, scenario.scene_params)


def open_sensor(scenario, robot):
    """The scenario's SR4000 on the robot's head (a context manager: it holds a renderer)."""
    from sim.world.sensor.sr4000 import SR4000

    return SR4000(robot.model, robot.camera_name, scenario.sensor.tof_params(),
                  fps=scenario.sensor.fps, seed=scenario.seed)


def walk_frames(scenario, robot, sensor, n_frames: int):
    """Walk the robot under the scenario's commands; yield each SR4000 frame when finished.

    Physics advances control period by control period; the sensor renders at its exposure
    times (the control step nearest each), so frames come at the sensor's frame rate.
    """
    for index in range(n_frames):
        for exposure_time in sensor.exposure_times(index):
            walk_until(scenario, robot, exposure_time)
            sensor.expose(robot.data)
        yield sensor.read_frame(index)


def walk_until(scenario, robot, time_s: float) -> None:
    """Step the robot under the scenario's commands to the control step nearest ``time_s``."""
    while robot.time + 0.5 * robot.control_period_s < time_s:
        command = scenario.command_at(robot.time)
        robot.command(command.speed, command.yaw_rate)
        robot.step()


def timed_estimate(stabilizer: Estimator, current) -> tuple[Motion, float]:
    """The estimate of ``current`` and the milliseconds it took; an exception becomes a status."""
    start = time.perf_counter()
    try:
        motion = stabilizer.estimate(current)
    except Exception as error:  # a method's bug must not take the other methods' run down
        motion = Motion.failed(f"exception:{type(error).__name__}", message=str(error))
    return motion, 1e3 * (time.perf_counter() - start)


def run(config: RunConfig) -> dict:
    """Run the scenario of ``config``; return the metrics dict also written to metrics.json.

    The run's status is "complete", "fell" (the robot fell: frames up to the fall are
    scored), "interrupted" (Ctrl-C, SIGTERM or SIGHUP; the message says which) or "error" (an
    exception, re-raised after the files of the finished frames are written). Until the final
    write, metrics.json says "incomplete" (written at the start and at every checkpoint); it is
    written last, so a second interrupt during the final write leaves the folder saying so.
    """
    # Imports here keep `import sim.harness.runner` light for process pools that only pickle configs.
    from sim.harness.scenario import load_scenario

    overrides = dict(config.overrides)
    if config.seed is not None:
        overrides["seed"] = config.seed
    scenario = load_scenario(config.scenario, overrides)
    methods = tuple(config.methods or scenario.evaluation.methods)
    if config.max_frames is not None and config.max_frames < 1:
        raise ValueError(f"max_frames must be >= 1 or None; got {config.max_frames}")
    out_dir = Path(config.out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)

    state = _RunState(scenario, methods, out_dir, config.max_frames,
                      record=config.record and scenario.recording.enabled)
    with stop_signals_interrupt():
        state.start()
        progress = _progress_bar(state.n_frames, scenario.name, config.progress)
        try:
            with open_sensor(scenario, state.robot) as sensor:
                for frame in walk_frames(scenario, state.robot, sensor, state.n_frames):
                    state.score_frame(frame)
                    progress.update(1)
                    if state.robot.fall is not None:
                        state.end_with_fall()
                        break
                    if (frame.index + 1) % CHECKPOINT_FRAMES == 0:
                        state.write(final=False)
        except KeyboardInterrupt as interrupt:
            state.status, state.message = INTERRUPTED, interrupt_reason(interrupt)
        except Exception as error:
            state.status, state.message = ERROR, f"{type(error).__name__}: {error}"
            raise
        finally:
            progress.close()
            metrics = state.finish()
    return metrics


class _RunState:
    """What one run has done so far, and its files.

    It holds the robot, the scored records, the ITF streams, the reference tracker, the
    recorder and how the run is ending (``status``, ``message``); ``meta`` becomes
    metrics.json's "run" section. ``start`` starts the wall clock and the recording,
    ``score_frame`` scores one frame, ``write`` writes the run folder (a cheap checkpoint while
    running, or the final files with plots and recording), ``finish`` closes the recording and
    writes the final files with how the run ended and its timing.
    """

    def __init__(self, scenario, methods: tuple[str, ...], out_dir: Path,
                 max_frames: int | None, record: bool):
        from sim.harness.scoring import ItfAccumulator

        self.scenario, self.methods, self.out_dir = scenario, methods, out_dir
        self.robot = scenario_robot(scenario)
        self.recording_path = out_dir / RECORDING_RRD if record else None
        self.scenario_dict = scenario.to_dict()
        self.meta: dict[str, Any] = {
            "seed": scenario.seed, "methods": list(methods),
            "reference_policy": scenario.evaluation.reference, "scene": scenario.scene,
            "scene_seed": scenario.scene_seed, "fps": scenario.sensor.fps,
            "max_frames": max_frames,
        }
        self.records: list = []
        self.itf = ItfAccumulator()
        self.tracker = _ReferenceTracker(scenario.evaluation.reference, methods)
        self.n_frames = int(math.floor(scenario.duration_s * scenario.sensor.fps))
        if max_frames is not None:
            self.n_frames = min(self.n_frames, max_frames)
        self.status, self.message = COMPLETE, ""
        self.previous_frame = None
        self.recorder = None
        self.wall_start = math.nan

    def start(self) -> None:
        """Start the wall clock and, if the run is recorded, the rerun recording; mark the
        folder incomplete until the final write."""
        self.write(final=False)
        self.wall_start = time.perf_counter()
        if self.recording_path is not None:
            from sim.harness.recording import RunRecorder

            self.recorder = RunRecorder(
                self.recording_path, self.methods,
                properties={"scenario": self.scenario_dict, "seed": self.scenario.seed},
                frame_stride=self.scenario.recording.frame_stride,
                recording_id=f"{self.scenario.name}-seed{self.scenario.seed}")

    def score_frame(self, frame) -> None:
        """Score ``frame`` against its reference with the truth and every method; log it."""
        from sim.harness.ground_truth import ground_truth
        from sim.harness.scoring import RAW_STREAM, FrameRecord

        cycle = self.robot.gait_cycle
        reference = self.tracker.reference_for(frame, cycle, self.previous_frame)
        truth = ground_truth(reference, frame, reference_depth_m=reference.true_depth_m,
                             current_depth_m=frame.true_depth_m)
        estimates, compensated = {}, {}
        for method in self.methods:
            motion, ms = timed_estimate(self.tracker.stabilizers[method], frame.disparity8)
            estimates[method] = motion
            compensated[method] = compensate(frame.disparity8, motion)
            self.records.append(FrameRecord.score(
                frame_index=frame.index, time_s=frame.time_s, gait_cycle=cycle,
                reference_index=reference.index, method=method, estimate=motion, truth=truth,
                ms=ms))
            self.itf.add(method, compensated[method], gait_cycle=cycle,
                         reference_index=reference.index)
        self.itf.add(RAW_STREAM, frame.disparity8, gait_cycle=cycle,
                     reference_index=reference.index)
        if self.recorder is not None:
            self.recorder.log_frame(frame, estimates=estimates, truth=truth,
                                    compensated=compensated,
                                    robot_position=self.robot.torso_pose()[0])
        self.previous_frame = frame

    def end_with_fall(self) -> None:
        """Mark the run as ended by the robot's fall."""
        fall = self.robot.fall
        self.status = FELL
        self.message = f"the robot fell at {fall.time_s:.2f} s ({fall.reason})"
        self.meta["fall"] = {"time_s": fall.time_s, "reason": fall.reason}

    def write(self, final: bool) -> dict:
        """Write the run folder; return metrics.json's content.

        A checkpoint (``final=False``) has the status "incomplete" and no plots; the final
        write has the run's status, the plots and the recording's listing.
        """
        from sim.harness.report import write_run_outputs
        from sim.harness.scoring import summarize

        self.meta["frames_done"] = len(self.records) // max(len(self.methods), 1)
        files = write_run_outputs(
            self.out_dir, scenario=self.scenario_dict, records=self.records,
            summary=summarize(self.records, self.itf), meta=self.meta,
            status=self.status if final else INCOMPLETE, plots=final,
            recording=self.recording_path if final else None)
        return files.metrics

    def finish(self) -> dict:
        """Close the recording; add how the run ended and its timing to ``meta``; write the
        final files and return metrics.json's content."""
        if self.recorder is not None:
            if self.message:
                self.recorder.log_event(self.message, level="WARN")
            self.recorder.close()
        wall_s = time.perf_counter() - self.wall_start
        self.meta.update({
            "message": self.message, "sim_time_s": self.robot.time, "wall_time_s": wall_s,
            "realtime_factor": self.robot.time / wall_s if wall_s > 0 else math.nan,
            "reference_analysis_ms": {m: (sum(v) / len(v) if v else math.nan)
                                      for m, v in self.tracker.analysis_ms.items()},
        })
        return self.write(final=True)


def _progress_bar(total: int, name: str, enabled: bool):
    from tqdm import tqdm

    return tqdm(total=total, desc=name, unit="frame", disable=not enabled, leave=False)
