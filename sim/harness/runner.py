"""Run one walking scenario end to end: simulate, render, estimate, score, write.

``run(RunConfig) -> metrics`` is a pure, picklable entry point: it builds the world, the robot
and the renderer inside the calling process, so a process pool (spawn), Ray or Dask can run
many of them (docs/design.md, "Parallel runs").

One frame of the loop (docs/design.md, "Data flow of one run"): the robot walks under physics,
control period by control period, following the scenario's commands; at the SR4000's exposure
times the sensor renders; the finished Frame is scored against its reference frame (chosen by
the scenario's reference policy) by the ground truth and by every method; the recorder logs it.
Every frame passes through the sequence encoding first (sim.harness.sequence), and ``run`` and
``egostab score`` (sim.harness.score) share one scoring loop, ``score_frames``, fed by a frame
source: the simulation here, a sequence folder there. ``record`` writes the simulation's
frames as a sequence folder instead of scoring them.
A fall, an interrupt (Ctrl-C) or an error ends the run cleanly: the files written describe
every finished frame and say how the run ended.
"""

from __future__ import annotations

import functools
import math
import os
import shutil
import time
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Mapping

import numpy as np

from sim.harness.interrupts import (interrupt_reason, stop_signals_interrupt, stops_held,
                                    stops_the_job)
from sim.harness.methods import Estimator, check_methods, exception_text, method_factory
from sim.harness.threads import worker_count
from stabilizer import compensate
from stabilizer.motion import Motion

#: Statuses a run can end with (metrics.json "status").
COMPLETE, FELL, INTERRUPTED, ERROR = "complete", "fell", "interrupted", "error"
#: The status of a run folder until its final write (at checkpoints, or where the process was
#: killed outright).
INCOMPLETE = "incomplete"
#: Name of the recording in a run folder.
RECORDING_RRD = "recording.rrd"
#: Least wall-clock seconds between checkpoints of frames.csv / metrics.json during a run: an
#: interruption the process cannot answer (a kill, a power cut) loses at most about this much
#: work, and a fast run (re-scoring a sequence) spends no time on checkpoints.
CHECKPOINT_S = 10.0


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
        workers: processes that run the methods, each frame's estimates started as soon as
            it is rendered (``sim.harness.pipeline``); 1 = this process; None = one per method
            and core when more than one method runs, else 1 (with one method, the simulation,
            rendering and scoring in the main process are as much work as the estimates, and
            workers made such runs slower: docs/design.md, "Threads and processes").
    """

    scenario: str
    out_dir: str
    methods: tuple[str, ...] | None = None
    record: bool = True
    max_frames: int | None = None
    seed: int | None = None
    overrides: Mapping[str, Any] = field(default_factory=dict)
    progress: bool = False
    workers: int | None = 1

    def __post_init__(self):
        check_not_a_sequence(self.out_dir)


def check_not_a_sequence(out_dir: str | os.PathLike, kind: str = "run") -> None:
    """Refuse an output folder (of a ``kind``: run, sweep, suite, gate) that holds a recorded
    sequence: its files would mix with the sequence's (``score`` refuses any folder inside the
    sequence it scores)."""
    from sim.harness.sequence import holds_sequence

    if holds_sequence(out_dir):
        raise ValueError(f"--out {out_dir}: holds a recorded sequence; accepted: a folder of "
                         f"its own for the {kind}")


def check_not_a_run(out_dir: str | os.PathLike, kind: str = "sequence") -> None:
    """Refuse an output folder (of a ``kind``: sequence, sweep, suite, gate) that holds a run's
    metrics.json: its files would mix with the run's, as :func:`check_not_a_sequence` refuses
    the other way round."""
    from sim.harness.report import METRICS_JSON

    if (Path(out_dir) / METRICS_JSON).is_file():
        raise ValueError(f"--out {out_dir}: holds a run (its {METRICS_JSON}); accepted: a folder "
                         f"of its own for the {kind}")


def check_folder_of_its_own(out_dir: str | os.PathLike, kind: str) -> None:
    """Refuse the output folder of a ``kind`` of job that writes runs in sub-folders (sweep,
    suite, gate) when it holds a recorded sequence or a run, or cannot be a folder
    (:func:`~sim.atomic.check_output_path`)."""
    from sim.atomic import check_output_path

    check_output_path(out_dir)
    check_not_a_sequence(out_dir, kind)
    check_not_a_run(out_dir, kind)


def scenario_name(scenario: str | os.PathLike) -> str:
    """The run's name for a scenario given by name or path (its file stem)."""
    return Path(scenario).stem


def build_robot(scene_name: str, scene_seed: int = 0, gait="default", seed: int = 0,
                scene_params: Mapping[str, Any] | None = None, floor=None):
    """Scene ``scene_name`` with the humanoid standing at its start, ready to walk.

    ``gait`` is a GaitParams or a preset name; ``seed`` perturbs the initial joint angles;
    ``scene_params`` are the scene's keyword parameters and ``floor`` its floor (a
    sim.world.scenes.Floor; None: flat) (docs/scenes.md).
    """
    from sim.world.scenes import build_scene
    from sim.world.walking import RobotSimulation
    from sim.world.assembly import assemble, compile_world

    scene = build_scene(scene_name, scene_seed, floor, **(scene_params or {}))
    model = compile_world(assemble(scene.arena, scene.start_xy, scene.start_yaw_deg))
    return RobotSimulation(model, gait=gait, seed=seed)


def scenario_robot(scenario):
    """The robot of a loaded scenario: its scene, scene parameters and floor, gait and seed,
    with the scenario's pushes scheduled."""
    robot = build_robot(scenario.scene, scenario.scene_seed, scenario.gait.params(),
                        scenario.seed, scenario.scene_params, scenario.floor.floor())
    for push in scenario.pushes:
        robot.schedule_push(push.t, push.impulse_ns, push.duration_s)
    return robot


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
    # A method's bug, or a plugin's sys.exit() or own BaseException (a KeyboardInterrupt too
    # where the user cannot have pressed Ctrl-C), must not take the other methods' run down.
    except BaseException as error:
        if stops_the_job(error):
            raise
        motion = Motion.failed(f"exception:{type(error).__name__}",
                               message=exception_text(error))
    return motion, 1e3 * (time.perf_counter() - start)


@dataclass(frozen=True)
class SourceFrame:
    """One frame as the scorer gets it: decoded as a sequence stores it, with its gait cycle,
    the robot's torso position (for the recording), from the simulator the stored images and
    every body's pose (``xpos``, ``xquat``) as the frame was read, and its ground truth when
    the source computed it (None: the scorer computes it)."""

    frame: Any
    gait_cycle: int
    robot_position: Any
    encoded: Any = None
    truth: Any = None
    body_poses: Any = None


class SimulatedFrames:
    """Frames of a walking simulation, each passed through the sequence encoding.

    A context manager (it holds the renderer); iterate inside it. ``fall`` is the robot's fall
    once it happened (checked after each frame), ``sim_time_s`` the simulated time so far,
    ``intrinsics`` the camera's pinhole.
    """

    def __init__(self, scenario, n_frames: int):
        self.scenario, self.n_frames = scenario, n_frames
        self.robot = scenario_robot(scenario)
        self.sensor = None

    def __enter__(self) -> "SimulatedFrames":
        self.sensor = open_sensor(self.scenario, self.robot).__enter__()
        return self

    def __exit__(self, *exc_info) -> None:
        self.sensor.__exit__(*exc_info)

    @property
    def intrinsics(self):
        return self.sensor.intrinsics

    @property
    def fall(self):
        return self.robot.fall

    @property
    def sim_time_s(self) -> float:
        return self.robot.time

    def __iter__(self):
        from sim.harness.sequence import decoded_frame, encode_frame

        no_surface_m, unit_m = self.sensor.tof.no_surface_depth_m, self.depth_unit_m
        for frame in walk_frames(self.scenario, self.robot, self.sensor, self.n_frames):
            encoded = encode_frame(frame, no_surface_m, unit_m)
            data = self.robot.data
            yield SourceFrame(
                decoded_frame(frame.index, frame.time_s, frame.cam_pos, frame.cam_mat, encoded,
                              unit_m),
                self.robot.gait_cycle, self.robot.torso_pose()[0], encoded,
                body_poses=(data.xpos.copy(), data.xquat.copy()))

    @property
    def depth_unit_m(self) -> float:
        """Metres per unit of the stored reported depth: the finest that holds the farthest
        depth this sensor can report (its range limit, its unambiguous range when it wraps,
        at most the render's no-surface depth)."""
        from sim.harness.sequence import reported_depth_unit_m

        params = self.sensor.tof.params
        farthest = min(params.max_range_m, self.sensor.tof.no_surface_depth_m,
                       params.unambiguous_range_m if params.phase_wrapping else math.inf)
        return reported_depth_unit_m(farthest)


class PrefetchedFrames:
    """A frame source run ahead in its own thread, so the next frames are simulated and
    rendered while this thread estimates and scores the current one.

    MuJoCo's physics and renderer, numpy and OpenCV release the GIL in their heavy calls, so
    the two threads share both cores. The source (its renderer's OpenGL context included) is
    entered, iterated and closed in the producing thread only. Frames come in order, each
    with the source's ``fall`` and ``sim_time_s`` as they were when it was made, so the
    results are those of the source alone; the producer stops after a fall. At most
    ``ahead`` frames wait.
    """

    _END = object()

    def __init__(self, source, ahead: int = 4):
        import queue
        import threading

        self.source, self.n_frames = source, source.n_frames
        self._frames: queue.Queue = queue.Queue(maxsize=ahead)
        self._opened: queue.Queue = queue.Queue(maxsize=1)
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._produce, name="frames", daemon=True)
        self.intrinsics = None
        self.fall = None
        self.sim_time_s = 0.0

    def _put(self, item) -> bool:
        """Queue ``item`` unless asked to stop first; whether it was queued."""
        import queue

        while not self._stop.is_set():
            try:
                self._frames.put(item, timeout=0.05)
                return True
            except queue.Full:
                continue
        return False

    def _produce(self) -> None:
        try:
            with self.source:
                self._opened.put(self.source.intrinsics)
                for item in self.source:
                    if not self._put((item, self.source.fall, self.source.sim_time_s)) \
                            or self.source.fall is not None:
                        break
                end_time_s = self.source.sim_time_s
            self._put((self._END, None, end_time_s))
        except BaseException as error:  # handed to the consuming thread, which re-raises it
            if self._opened.empty():
                self._opened.put(error)
            self._put((error, None, None))

    def __enter__(self) -> "PrefetchedFrames":
        self._thread.start()
        try:
            opened = self._opened.get()
        except BaseException:  # interrupted while the source opens
            self.__exit__()
            raise
        if isinstance(opened, BaseException):
            self._thread.join()
            raise opened
        self.intrinsics = opened
        return self

    def __exit__(self, *exc_info) -> None:
        self._stop.set()
        self._thread.join()

    def __iter__(self):
        while True:
            item, fall, sim_time_s = self._frames.get()
            if item is self._END:
                self.sim_time_s = sim_time_s
                return
            if isinstance(item, BaseException):
                raise item
            self.fall, self.sim_time_s = fall, sim_time_s
            yield item


class ReferencePolicy:
    """Chooses each frame's reference (docs/design.md): ``cycle_start`` = the first frame of
    each gait cycle; ``previous`` = the frame before; ``first`` = the first frame."""

    def __init__(self, policy: str):
        self.policy = policy
        self.frame = self.cycle = self.previous = None

    def reference_for(self, frame, cycle: int):
        """The reference of ``frame`` (frames come in order)."""
        if (self.frame is None or self.policy == "previous"
                or (self.policy == "cycle_start" and cycle != self.cycle)):
            self.frame = frame if (self.policy != "previous" or self.previous is None) \
                else self.previous
            self.cycle = cycle
        self.previous = frame
        return self.frame


def frame_truth(reference, frame, intrinsics):
    """The ground truth of ``frame`` against ``reference`` from their exact depth."""
    from sim.harness.ground_truth import ground_truth

    return ground_truth(reference, frame, intrinsics, reference_depth_m=reference.true_depth_m,
                        current_depth_m=frame.true_depth_m)


@dataclass(frozen=True)
class Estimate:
    """One method's result for one frame: the motion, the milliseconds it took (NaN when
    unknown) and the frame compensated by it."""

    motion: Motion
    ms: float
    compensated: Any

    def without_images(self) -> "Estimate":
        """The estimate with its motion's diagnostic arrays (segmentations, subbands) left
        out: a recording shows them, nothing else reads them, and a worker process's estimate
        costs less to send back without them."""
        kept = {key: value for key, value in self.motion.diagnostics.items()
                if not isinstance(value, np.ndarray)}
        return replace(self, motion=replace(self.motion, diagnostics=kept))


class MethodEstimation:
    """A method's estimates in this process, analysing each reference once; through the trust
    check (``stabilizer.verification``) unless ``checked`` is False, then as the method reports
    them."""

    def __init__(self, method: str, checked: bool = True):
        self.factory = method_factory(method)
        if not checked:
            self.factory = functools.partial(self.factory, verification=None)
        self.reference_index = None
        self.stabilizer: Estimator | None = None
        self.analysis_ms: list[float] = []

    def estimate(self, reference, frame) -> Estimate:
        if reference.index != self.reference_index:
            start = time.perf_counter()
            self.stabilizer = self.factory(reference.disparity8)
            self.analysis_ms.append(1e3 * (time.perf_counter() - start))
            self.reference_index = reference.index
        motion, ms = timed_estimate(self.stabilizer, frame.disparity8)
        return Estimate(motion, ms, compensate(frame.disparity8, motion))


def run(config: RunConfig) -> dict:
    """Run the scenario of ``config``; return the metrics dict also written to metrics.json.

    Every frame goes through the sequence encoding before it is scored (sim.harness.sequence),
    so ``egostab score`` of a recorded sequence gives the same figures. The run's status is
    "complete", "fell" (the robot fell: frames up to the fall are scored), "interrupted"
    (Ctrl-C, SIGTERM or SIGHUP; the message says which) or "error" (an exception, re-raised
    after the files of the finished frames are written). Until the final write, metrics.json
    says "incomplete" (written at the start and at every checkpoint); a stop during the final
    write is held until the write is done, then ends the job (raised from here).
    """
    scenario = _configured_scenario(config.scenario, config.seed, config.overrides)
    methods = tuple(config.methods or scenario.evaluation.methods)
    check_methods(methods)
    workers = worker_count(config.workers, len(methods) if len(methods) > 1 else 1)
    source = SimulatedFrames(scenario, frame_count(scenario, config.max_frames))
    scoring = Scoring(scenario, methods, Path(config.out_dir),
                      record=config.record and scenario.recording.enabled,
                      meta={"max_frames": config.max_frames, "workers": workers},
                      world_model=source.robot.model)
    if workers == 1:
        estimations = {method: MethodEstimation(method) for method in methods}
        return score_frames(PrefetchedFrames(source), scoring, estimations, config.progress)
    from sim.harness.pipeline import PipelinedFrames
    from sim.harness.threads import single_thread_pool

    with single_thread_pool(workers) as pool:
        frames = PipelinedFrames(PrefetchedFrames(source), methods, pool, workers,
                                 scenario.evaluation.reference,
                                 keep_images=scoring.recording_path is not None)
        scoring.plot_pool = pool
        return score_frames(frames, scoring, frames.estimations, config.progress)


def _configured_scenario(scenario: str, seed: int | None, overrides: Mapping[str, Any]):
    # Imported here to keep `import sim.harness.runner` light for pools that pickle configs.
    from sim.harness.scenario import load_scenario

    overrides = dict(overrides)
    if seed is not None:
        overrides["seed"] = seed
    return load_scenario(scenario, overrides)


def frame_count(scenario, max_frames: int | None) -> int:
    """Frames of the scenario's duration at its frame rate, at most ``max_frames``."""
    if max_frames is not None and max_frames < 1:
        raise ValueError(f"max_frames must be >= 1 or None; got {max_frames}")
    n_frames = int(math.floor(scenario.duration_s * scenario.sensor.fps))
    return n_frames if max_frames is None else min(n_frames, max_frames)


def score_frames(source, scoring: "Scoring", estimations: Mapping[str, Any],
                 progress: bool) -> dict:
    """The one scoring loop of ``run`` and ``score``: every frame of ``source`` (a context
    manager yielding SourceFrame, with ``fall``, ``sim_time_s`` and ``intrinsics``) is scored
    by ``estimations`` (method -> object with ``estimate(reference, frame) -> Estimate`` and
    ``analysis_ms``); returns metrics.json's content."""
    with stop_signals_interrupt():
        bar = _progress_bar(source.n_frames, scoring.scenario.name, progress)
        try:
            # Started inside the try: an interrupt while the recording opens ends the run too.
            scoring.start()
            last_write = time.perf_counter()
            with source:
                for item in source:
                    scoring.score_frame(item, estimations, source.intrinsics)
                    bar.update(1)
                    if source.fall is not None:
                        scoring.end_with_fall(source.fall)
                        break
                    if time.perf_counter() - last_write >= CHECKPOINT_S:
                        scoring.write(final=False)
                        last_write = time.perf_counter()
        except KeyboardInterrupt as interrupt:
            scoring.status, scoring.message = INTERRUPTED, interrupt_reason(interrupt)
        except BaseException as error:  # SystemExit too: the folder must not say "complete"
            scoring.status, scoring.message = ERROR, f"{type(error).__name__}: {error}"
            raise
        finally:
            with stops_held(final_write=True):  # a stop now ends the job after it, not within
                bar.close()
                metrics = scoring.finish(source.sim_time_s, estimations)
    return metrics


#: Where a run over a finished run is written until it finishes (:class:`Scoring`).
STAGING_FOLDER = ".egostab-rerun"


def _finished_run(run_dir: Path) -> bool:
    """Whether ``run_dir`` holds a run that finished ("complete" or "fell")."""
    from sim.harness.report import read_metrics

    try:
        return read_metrics(run_dir)["status"] in (COMPLETE, FELL)
    except ValueError:  # no metrics.json, or not a run's
        return False


def _listed_files(run_dir: Path) -> set[str]:
    """The names of the files the run in ``run_dir`` lists in its metrics.json as its own."""
    from sim.harness.report import read_metrics

    try:
        listed = read_metrics(run_dir).get("files") or {}
    except ValueError:
        return set()
    names = set()
    for value in listed.values():
        for name in ([value] if isinstance(value, str) else value):
            if isinstance(name, str) and Path(name).name == name:  # a file of the folder only
                names.add(name)
    return names


class Scoring:
    """What a run (or a score of a sequence) has done so far, and its run folder.

    It holds the scored records, the ITF streams, the reference policy, the recorder and how
    the run is ending (``status``, ``message``); ``meta`` becomes metrics.json's "run" section.
    ``start`` starts the wall clock and the recording, ``score_frame`` scores one frame,
    ``write`` writes the run folder (a cheap checkpoint while running, or the final files with
    plots and recording), ``finish`` closes the recording and writes the final files with how
    the run ended and its timing.
    """

    def __init__(self, scenario, methods: tuple[str, ...], out_dir: Path, record: bool,
                 meta: Mapping[str, Any], world_model=None):
        from sim.harness.scoring import ItfAccumulator

        self.scenario, self.methods = scenario, methods
        self.folder = RunFolder(out_dir)
        self.out_dir = self.folder.out_dir
        self.recording_path = self.out_dir / RECORDING_RRD if record else None
        self.scenario_dict = scenario.to_dict()
        self.meta: dict[str, Any] = {
            "seed": scenario.seed, "methods": list(methods),
            "reference_policy": scenario.evaluation.reference, "scene": scenario.scene,
            "scene_seed": scenario.scene_seed, "fps": scenario.sensor.fps, **meta,
        }
        self.records: list = []
        self.failures: list[dict] = []
        self.itf = ItfAccumulator()
        self.references = ReferencePolicy(scenario.evaluation.reference)
        self.status, self.message = COMPLETE, ""
        self.recorder = None
        self.world_model = world_model  # the recording's 3-D scene; None for a sequence
        self.plot_pool = None  # a process pool that draws the final plots (--workers)
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
                recording_id=f"{self.scenario.name}-seed{self.scenario.seed}",
                model=self.world_model)

    def score_frame(self, item: SourceFrame, estimations: Mapping[str, Any], intrinsics) -> None:
        """Score one frame against its reference with the truth and every method; log it."""
        from sim.harness.scoring import RAW_STREAM, FrameRecord, failure_entry

        frame, cycle = item.frame, item.gait_cycle
        reference = self.references.reference_for(frame, cycle)
        truth = item.truth if item.truth is not None else frame_truth(reference, frame, intrinsics)
        estimates = {method: estimations[method].estimate(reference, frame)
                     for method in self.methods}
        for method, estimate in estimates.items():
            self.records.append(FrameRecord.score(
                frame_index=frame.index, time_s=frame.time_s, gait_cycle=cycle,
                reference_index=reference.index, method=method, estimate=estimate.motion,
                truth=truth, ms=estimate.ms))
            if not estimate.motion.ok:
                self.failures.append(failure_entry(frame_index=frame.index, method=method,
                                                   estimate=estimate.motion))
            self.itf.add(method, estimate.compensated, gait_cycle=cycle,
                         reference_index=reference.index)
        self.itf.add(RAW_STREAM, frame.disparity8, gait_cycle=cycle,
                     reference_index=reference.index)
        if self.recorder is not None:
            self.recorder.log_frame(
                frame, estimates={m: e.motion for m, e in estimates.items()}, truth=truth,
                compensated={m: e.compensated for m, e in estimates.items()},
                robot_position=item.robot_position, body_poses=item.body_poses)

    def end_with_fall(self, fall) -> None:
        """Mark the run as ended by the robot's fall (anything with ``time_s`` and ``reason``)."""
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
            failures=self.failures, summary=summarize(self.records, self.itf), meta=self.meta,
            status=self.status if final else INCOMPLETE, plots=final,
            recording=self.recording_path if final and self.recorder is not None else None,
            # An interrupted run's pool may still hold estimation work: plots drawn here then.
            plot_pool=self.plot_pool if self.status in (COMPLETE, FELL) else None)
        return files.metrics

    def finish(self, sim_time_s: float, estimations: Mapping[str, Any]) -> dict:
        """Close the recording; add how the run ended and its timing to ``meta``; write the
        final files and return metrics.json's content."""
        if self.recorder is not None:
            if self.message:
                self.recorder.log_event(self.message, level="WARN")
            self.recorder.close()
        wall_s = time.perf_counter() - self.wall_start
        analysis_ms = {method: estimations[method].analysis_ms for method in self.methods}
        self.meta.update({
            "message": self.message, "sim_time_s": sim_time_s, "wall_time_s": wall_s,
            "realtime_factor": sim_time_s / wall_s if wall_s > 0 else math.nan,
            "reference_analysis_ms": {m: (sum(v) / len(v) if v else math.nan)
                                      for m, v in analysis_ms.items()},
        })
        try:
            return self.write(final=True)
        finally:
            self.folder.settle(finished=self.status in (COMPLETE, FELL))


class RunFolder:
    """Where a run into ``final_dir`` writes until it ends, and how it leaves the folder.

    A run over a finished one ("complete" or "fell") is written beside it, in
    :data:`STAGING_FOLDER`, and replaces it only if it finishes too (:meth:`settle`): an
    interrupt or an error leaves the finished run as it was. A run over an unfinished one, or
    into a new folder, is written in place. Either way, once the new run has replaced the
    earlier one, the earlier run's own files (those its metrics.json lists) that the new one
    did not write go: its recording, the plots of methods no longer run would pass for the new
    run's. Other files in the folder stay. What a run killed outright (SIGKILL) left goes at the
    start: its staging folder and its half-written temporary files (``atomic_path``'s).
    """

    def __init__(self, final_dir: str | os.PathLike):
        from sim.atomic import remove_stale_temporaries

        self.final_dir = Path(final_dir)
        beside = _finished_run(self.final_dir)
        self.out_dir = self.final_dir / STAGING_FOLDER if beside else self.final_dir
        # Read before the new run's first write replaces its metrics.json.
        self._unfinished_files = set() if beside else _listed_files(self.final_dir)
        # A staging folder is removed when its run settles: one found now is a killed run's,
        # whose files would otherwise be moved in with the new run's.
        shutil.rmtree(self.final_dir / STAGING_FOLDER, ignore_errors=True)
        if self.final_dir.is_dir():
            remove_stale_temporaries(self.final_dir)
        self.out_dir.mkdir(parents=True, exist_ok=True)

    def settle(self, finished: bool) -> None:
        """End the run written in ``out_dir``: in place, remove the unfinished run's files it
        did not write; beside a finished run, replace that run's files when ``finished``
        (metrics.json last, each file atomically), and remove the staging folder."""
        from sim.harness.report import METRICS_JSON

        if self.out_dir == self.final_dir:
            self._remove_earlier(self._unfinished_files)
            return
        staged = self.out_dir / METRICS_JSON
        if finished and staged.is_file():
            previous = _listed_files(self.final_dir)
            for path in sorted(self.out_dir.iterdir()):
                if path.is_file() and path.name != METRICS_JSON:
                    os.replace(path, self.final_dir / path.name)
            os.replace(staged, self.final_dir / METRICS_JSON)
            self._remove_earlier(previous)
        shutil.rmtree(self.out_dir, ignore_errors=True)

    def _remove_earlier(self, earlier: set[str]) -> None:
        for name in earlier - _listed_files(self.final_dir):
            (self.final_dir / name).unlink(missing_ok=True)


@dataclass(frozen=True)
class RecordConfig:
    """What to record and where: the scenario (name or path), the sequence folder, and as for
    RunConfig ``max_frames``, ``seed``, ``overrides`` and ``progress``."""

    scenario: str
    out_dir: str
    max_frames: int | None = None
    seed: int | None = None
    overrides: Mapping[str, Any] = field(default_factory=dict)
    progress: bool = False


def record(config: RecordConfig) -> dict:
    """Simulate the scenario once and write its sequence folder; return sequence.json's content.

    The recording ends "complete", "fell" (the frames up to the fall are kept) or "interrupted"
    (Ctrl-C, SIGTERM or SIGHUP); an error leaves sequence.json saying "incomplete" and is
    re-raised.
    """
    from sim.harness.provenance import provenance
    from sim.harness.sequence import (EXACT_DEPTH_UNIT_M, RecordedFall, SequenceWriter,
                                      TruthRow, check_recording_folder)

    check_not_a_run(config.out_dir)  # before simulating anything
    check_recording_folder(config.out_dir)
    scenario = _configured_scenario(config.scenario, config.seed, config.overrides)
    source = SimulatedFrames(scenario, frame_count(scenario, config.max_frames))
    references = ReferencePolicy(scenario.evaluation.reference)
    scenario_dict = {k: v for k, v in scenario.to_dict().items() if k != "source"}
    ended, message, fall, writer = COMPLETE, "", None, None
    with stop_signals_interrupt():
        bar = _progress_bar(source.n_frames, scenario.name, config.progress)
        try:
            with source:
                intrinsics = source.intrinsics
                writer = SequenceWriter(config.out_dir, {
                    "scenario": scenario_dict, "seed": scenario.seed, "fps": scenario.sensor.fps,
                    "intrinsics": {"fx": float(intrinsics.fx), "fy": float(intrinsics.fy),
                                   "cx": float(intrinsics.cx), "cy": float(intrinsics.cy),
                                   "width": int(intrinsics.width),
                                   "height": int(intrinsics.height)},
                    "depth_unit_m": source.depth_unit_m,
                    "exact_depth_unit_m": EXACT_DEPTH_UNIT_M,
                    "reference_policy": scenario.evaluation.reference,
                    "provenance": provenance()})
                writer.start()
                for item in source:
                    frame = item.frame
                    reference = references.reference_for(frame, item.gait_cycle)
                    truth = frame_truth(reference, frame, intrinsics)
                    writer.add(item.encoded, TruthRow(
                        frame.index, frame.time_s, reference.index, item.gait_cycle,
                        *truth.motion.as_tuple(), truth.motion.status, truth.residual_rms_px,
                        truth.n_points, tuple(frame.cam_pos.tolist()),
                        tuple(tuple(row) for row in frame.cam_mat.tolist()),
                        tuple(np.asarray(item.robot_position, dtype=float).tolist())))
                    bar.update(1)
                    if source.fall is not None:
                        ended = FELL
                        fall = RecordedFall(source.fall.time_s, source.fall.reason)
                        message = f"the robot fell at {fall.time_s:.2f} s ({fall.reason})"
                        break
        except KeyboardInterrupt as interrupt:
            ended, message = INTERRUPTED, interrupt_reason(interrupt)
        finally:
            bar.close()
        if writer is None or not writer.started:  # the folder is as it was: nothing to keep
            raise KeyboardInterrupt(message)
        try:
            return writer.close(ended, message, fall, sim_time_s=source.sim_time_s)
        except KeyboardInterrupt as interrupt:
            # A stop during the final write: the frames written still form a sequence.
            return writer.close(INTERRUPTED, interrupt_reason(interrupt), fall,
                                sim_time_s=source.sim_time_s)


def _progress_bar(total: int, name: str, enabled: bool):
    from tqdm import tqdm

    return tqdm(total=total, desc=name, unit="frame", disable=not enabled, leave=False)
