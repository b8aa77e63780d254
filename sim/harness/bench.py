"""Every speed figure of the project, measured side by side: the one place for speed code.

``egostab bench`` (:func:`run_benchmarks`) measures, in one run on this machine: stabilizer
ms/frame per method on synthetic scenes and on frames of a simulated walk, with each method's
ratio to the paper's; the walking physics' real-time factor (no rendering); the SR4000 render +
ToF frames/s; and the real-time factor of the whole pipeline on the default scenario. ``--out``
writes them as Markdown with the machine they came from (results/bench.md). The component
timings (:func:`ground_truth_ms`, :func:`scoring_ms`, :func:`recording_ms`) are here for
profiling one stage at a time, and :func:`t2fuzzy_corpus_benchmark` times the paper's method
against SIFT on a varied synthetic corpus and on the walking frames of every scene
(``python -m sim.harness.bench t2fuzzy-corpus``); :func:`t2fuzzy_stage_shares` shows which of its
stages takes that time (``python -m sim.harness.bench t2fuzzy-stages``).

Stabilizer figures: milliseconds per frame at the SR4000's 176 x 144. For each method and each
of ``n_scenes`` synthetic depth scenes, ``Stabilizer(reference, method)`` is built once (the
reference analysed once, as over a gait cycle) and ``estimate(current)`` is timed on that
scene's share of ``n_frames`` frames (the reference moved by random rigid motions within +-15
deg and +-40 px); several scenes, because the work of the paper's method depends on the scene
(cluster count, convergence). One thread: OpenCV's and the BLAS/OpenMP pools are set to 1
before anything is imported that starts them. The figure is the median over frames, so a rare
slow frame (page fault, scheduler) does not move it.

Run: ``python -m sim.harness.bench`` for the stabilizers alone (options: ``--frames N``,
``--seed S``, ``--methods a,b``), ``egostab bench`` for everything.
"""

from __future__ import annotations

from sim.harness.threads import limit_threads

limit_threads()  # before numpy and OpenCV load: the figures are for one core

import dataclasses
import functools
import math
import os
import sys
import tempfile
import time
from collections.abc import Sequence
from pathlib import Path

import mujoco
import numpy as np
from scipy.spatial.transform import Rotation

import stabilizer
from sim.harness.ground_truth import GroundTruth, ground_truth
from sim.harness.methods import method_factory
from sim.harness.recording import RunRecorder
from scenarios import DEFAULT_SCENARIO
from sim.harness.scoring import RAW_STREAM, FrameRecord, ItfAccumulator, summarize
from sim.world.assembly import assemble, compile_world
from sim.world.camera import SR4000_INTRINSICS, Frame
from sim.world.scenes import build_scene
from sim.world.sensor.sr4000 import SR4000, add_probe_camera
from sim.world.sensor.tof_model import TOF_PRESETS
from sim.world.walking import RobotSimulation
from stabilizer.inputs import depth_to_disparity
from stabilizer.motion import Motion, apply_motion

SHAPE = (144, 176)
#: The method every other method's time is compared with.
BASELINE = "t2fuzzy"


def _scenes(n_frames: int, n_scenes: int, seed: int) -> list[tuple[np.ndarray, list]]:
    """``n_scenes`` uint8 disparity references, each with its share of ``n_frames`` moved
    copies (rounded down, at least one)."""
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


def time_method(method: str, scenes: list[tuple[np.ndarray, list]],
                clock=time.perf_counter, checked: bool = True) -> float:
    """Median milliseconds of ``estimate(frame)`` over frames, the reference analysed once per
    scene (``Stabilizer(reference, method)`` for a built-in; sim.harness.methods). ``clock``:
    wall-clock time by default; ``time.process_time`` counts only this process's CPU time.
    ``checked=False`` times a built-in method without the trust check every estimate of a run
    goes through (``Stabilizer(..., verification=None)``): the method's own cost."""
    return float(np.median(frame_ms(method, scenes, clock, checked)))


def frame_ms(method: str, scenes: list[tuple[np.ndarray, list]],
             clock=time.perf_counter, checked: bool = True) -> list[float]:
    """Milliseconds of each ``estimate(frame)`` of :func:`time_method`, in frame order."""
    factory = method_factory(method)
    if not checked:
        factory = functools.partial(factory, verification=None)
    times = []
    for reference, frames in scenes:
        tracker = factory(reference)
        # Warm up caches and lazy imports on the reference itself: the check keeps its
        # measurements of the last frame, which a timed frame must not find.
        tracker.estimate(reference)
        for frame in frames:
            start = clock()
            tracker.estimate(frame)
            times.append(1e3 * (clock() - start))
    return times


def simulated_scenes(scenario: str = DEFAULT_SCENARIO, n_frames: int = 150,
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
                         label: str | None = None, checked: bool = True) -> dict[str, float]:
    """Median ms per frame of each method (NaN for a method whose module is not available).

    Synthetic scenes by default; pass ``scenes`` (e.g. :func:`simulated_scenes`) to time other
    frames. Prints one line per method with its time and its ratio to t2fuzzy. ``checked``:
    see :func:`time_method`.
    """
    methods = list(stabilizer.available_methods() if methods is None else methods)
    if scenes is None:
        scenes = _scenes(n_frames, n_scenes, seed)
        per_scene = len(scenes[0][1])
        label = label or (f"{n_scenes} synthetic scene{'s' if n_scenes > 1 else ''}, "
                          f"{per_scene} frame{'s' if per_scene > 1 else ''} each")
    n_timed = sum(len(frames) for _, frames in scenes)
    results: dict[str, float] = {}
    for method in methods:
        try:
            results[method] = time_method(method, scenes, checked=checked)
        except ImportError as error:  # a method whose module is not written yet
            results[method] = float("nan")
            print(f"{method:>16}: not available ({error})")
    baseline = results.get(BASELINE, float("nan"))
    print(f"ms per frame at {SHAPE[1]}x{SHAPE[0]}, median of {n_timed} frames "
          f"({label or 'given scenes'}), one thread, trust check {'on' if checked else 'off'}:")
    for method, ms in results.items():
        if np.isfinite(ms):
            ratio = f"   ({ms / baseline:6.2f} x {BASELINE})" if np.isfinite(baseline) else ""
            print(f"{method:>16}: {ms:8.3f} ms{ratio}")
    return results


#: The shipped scenario whose walk gives each scene's frames in :func:`t2fuzzy_corpus_benchmark`.
WALK_SCENARIOS = {"corridor": "corridor_straight", "office": "office_turn", "lab": "lab_clutter",
                  "hall": "paper_like_gait"}
#: Issue 13's targets for t2fuzzy with a cached reference: ms/frame on the synthetic corpus,
#: times faster than SIFT there, and ms/frame on the walking frames of every scene.
T2FUZZY_TARGET_MS, SIFT_TARGET_RATIO, WALK_TARGET_MS = 2.0, 4.0, 3.0


def t2fuzzy_corpus_benchmark(n_scenes: int = 4, frames_per_scene: int = 10,
                             walk_frames: int = 80, seed: int = 0) -> dict[str, dict]:
    """t2fuzzy against SIFT on every generator of the varied synthetic corpus, and t2fuzzy on
    the walking frames of every scene; prints a table and returns the figures.

    Synthetic: for each generator of :data:`stabilizer.testing.CORPUS_GENERATORS`,
    ``n_scenes`` scenes (seeds ``seed``, ``seed + 1``, ...) with ``frames_per_scene`` moved
    frames each (:func:`stabilizer.testing.corpus_frames`). Walking: ``walk_frames`` frames of
    the scene's walk in :data:`WALK_SCENARIOS`, after the standing start, grouped by gait cycle
    (:func:`simulated_scenes`; 0: no walk). Each figure is the median ms per frame with the
    reference analysed once per scene or cycle (:func:`time_method`), one thread, on the wall
    clock and in process CPU time (which other jobs sharing the machine disturb less); and,
    on the wall clock, without the trust check every estimate of a run goes through (the
    methods' own cost; ``_own``), ``t2fuzzy_paper`` (the paper's stages without the
    refinements) too.

    Returns:
        {"synthetic": {generator or "all generators": {"t2fuzzy", "sift", "t2fuzzy_cpu",
         "sift_cpu", "t2fuzzy_own", "t2fuzzy_paper_own", "sift_own"}}, "walking": {scene:
         {"t2fuzzy", "t2fuzzy_cpu", "t2fuzzy_own", "t2fuzzy_paper_own"}}}, milliseconds.
    """
    from sim.harness.scenario import load_scenario
    from stabilizer.testing import CORPUS_GENERATORS, corpus_frames

    def timed(method, scenes):
        return {method: frame_ms(method, scenes),
                f"{method}_cpu": frame_ms(method, scenes, time.process_time)}

    def own(methods, scenes):
        return {f"{method}_own": frame_ms(method, scenes, checked=False) for method in methods}

    def medians(times):
        return {key: float(np.median(values)) for key, values in times.items()}

    print(f"t2fuzzy and sift, median ms per frame at {SHAPE[1]}x{SHAPE[0]}, one thread, "
          f"reference analysed once; wall clock (process CPU time); {_load()}")
    print(f"synthetic corpus: {n_scenes} scenes x {frames_per_scene} frames per generator, "
          f"motions within +-15 deg, +-40 px (targets: t2fuzzy <= {T2FUZZY_TARGET_MS} ms, "
          f">= {SIFT_TARGET_RATIO}x faster than sift)")
    figures: dict[str, dict] = {"synthetic": {}, "walking": {}}
    every_frame: dict[str, list] = {}
    for generator in (*CORPUS_GENERATORS, "all generators"):
        if generator in CORPUS_GENERATORS:
            scenes = [corpus_frames(generator, seed + index, frames_per_scene)[:2]
                      for index in range(n_scenes)]
            times = {**timed("t2fuzzy", scenes), **timed("sift", scenes),
                     **own(("t2fuzzy", "t2fuzzy_paper", "sift"), scenes)}
            for key, values in times.items():
                every_frame.setdefault(key, []).extend(values)
        else:  # the medians over every frame of the corpus
            times = every_frame
        ms = figures["synthetic"][generator] = medians(times)
        print(f"{generator:>16}: t2fuzzy {ms['t2fuzzy']:6.2f} ({ms['t2fuzzy_cpu']:5.2f}) ms   "
              f"sift {ms['sift']:6.2f} ({ms['sift_cpu']:5.2f}) ms   sift / t2fuzzy "
              f"{ms['sift'] / ms['t2fuzzy']:5.2f} ({ms['sift_cpu'] / ms['t2fuzzy_cpu']:5.2f})")
        print(f"{'':>16}  without the check: t2fuzzy {ms['t2fuzzy_own']:6.2f} ms   "
              f"t2fuzzy_paper {ms['t2fuzzy_paper_own']:5.2f} ms   sift {ms['sift_own']:5.2f} ms   "
              f"sift / t2fuzzy {ms['sift_own'] / ms['t2fuzzy_own']:5.2f}")
    if walk_frames > 0:
        print(f"simulated walks: {walk_frames} frames per scene (target: t2fuzzy <= "
              f"{WALK_TARGET_MS} ms)")
    for scene, scenario in WALK_SCENARIOS.items() if walk_frames > 0 else ():
        if load_scenario(scenario).scene != scene:
            raise ValueError(f"scenario {scenario!r} no longer walks the {scene} scene")
        scenes = simulated_scenes(scenario, walk_frames)
        ms = figures["walking"][scene] = medians({**timed("t2fuzzy", scenes),
                                                  **own(("t2fuzzy", "t2fuzzy_paper"), scenes)})
        print(f"{scene:>16}: t2fuzzy {ms['t2fuzzy']:6.2f} ({ms['t2fuzzy_cpu']:5.2f}) ms   "
              f"({scenario}); without the check: t2fuzzy {ms['t2fuzzy_own']:5.2f} ms   "
              f"t2fuzzy_paper {ms['t2fuzzy_paper_own']:5.2f} ms")
    print(_load())
    return figures


def t2fuzzy_stage_shares(walk_frames: int = 80) -> dict[str, dict[str, tuple[float, float]]]:
    """Where ``t2fuzzy``'s time goes on the walking frames of every scene; prints a table.

    The frames are those :func:`t2fuzzy_corpus_benchmark` times (``walk_frames`` per scene of
    :data:`WALK_SCENARIOS`, reference analysed once per gait cycle, the trust check on), run
    under ``cProfile``. Each row is a function of the pipeline: how often it ran per estimate
    (the estimate of each reference itself included) and the share of the time spent in it,
    callees included, of the whole: the estimates and each reference's analysis before them
    (stages 1-5 of the reference run there). The stages do not call one another, so their
    shares add up with "the rest" (what runs outside them) to the whole; the parts run within
    the stages.
    ``cProfile`` adds a cost per Python call, so rows of many small calls read somewhat high:
    a map of where to look, not a timing (:func:`time_method` is).

    Returns:
        {scene: {row: (calls per estimate, share of the whole)}}, also "the rest";
        "estimate" is (1.0, ms of the whole per estimate under the profiler).
    """
    import cProfile
    import pstats

    from stabilizer.api import Stabilizer
    from stabilizer.t2fuzzy import T2FuzzyEstimator
    from stabilizer.t2fuzzy_refinements import RotationSearch
    from stabilizer.verification import Verifier

    # Disjoint: each runs from the estimate or the check, not from another of these.
    stages = {
        "stages 1-5 (segmentation, wavelets, ellipses, threshold)": T2FuzzyEstimator.analyse,
        "stage 6, the rotation and shift search": RotationSearch.__call__,
        "stage 6, a disagreement resolved": RotationSearch.resolve_disagreement,
        "the trust check's measurements of the frame": Verifier.measure,
        "the trust check of the estimate": Verifier.check,
        "the second look at a doubted estimate": T2FuzzyEstimator.second_look,
    }
    # Parts of the stages above (a part may run in several of them).
    parts = {
        "climb on the large template": RotationSearch.refine_on_large_template,
        "climb on the whole overlap, half resolution": RotationSearch._climb_whole_overlap,
        "climb on the whole overlap, full resolution": RotationSearch.climb_on_overlap,
        "rival motion search": Verifier._rival_candidate,
        "ECC at full resolution": Verifier.full_resolution_optimum,
    }

    def key(function):
        code = function.__code__
        return code.co_filename, code.co_firstlineno, code.co_name

    figures: dict[str, dict[str, tuple[float, float]]] = {}
    print(f"t2fuzzy's stages on walking frames under cProfile (one thread; calls per estimate "
          f"and share of the time, the references' analyses included; indented: parts of the "
          f"stages; {_load()})")
    for scene, scenario in WALK_SCENARIOS.items():
        scenes = simulated_scenes(scenario, walk_frames)
        profile = cProfile.Profile()
        profile.enable()
        frame_ms("t2fuzzy", scenes)
        profile.disable()
        timings = pstats.Stats(profile).stats
        n_frames = sum(len(frames) for _, frames in scenes)
        n_estimates = n_frames + len(scenes)  # frame_ms also estimates each reference
        calls = timings[key(Stabilizer.estimate)][1]
        if calls != n_estimates:
            raise RuntimeError(f"{scene}: {calls} estimates profiled, {n_estimates} expected")
        # The whole: the estimates and each reference's analysis, which runs before them.
        whole_s = timings[key(frame_ms)][3]
        row = figures[scene] = {"estimate": (1.0, 1e3 * whole_s / n_estimates)}
        print(f"{scene} ({scenario}): {n_frames} frames, {row['estimate'][1]:.2f} ms an "
              f"estimate under the profiler")
        for stage, function in (*stages.items(), *parts.items()):
            _, calls, _, stage_s, _ = timings.get(key(function), (0, 0, 0.0, 0.0, None))
            row[stage] = (calls / n_estimates, stage_s / whole_s)
            indent = "    " if stage in parts else "  "
            print(f"{indent}{stage:<{60 - len(indent)}} {calls / n_estimates:5.2f} "
                  f"{100 * row[stage][1]:5.1f}%")
        row["the rest"] = (1.0, 1.0 - sum(row[stage][1] for stage in stages))
        print(f"  {'the rest (outside these stages, the references set-up too)':<58} {'':5} "
              f"{100 * row['the rest'][1]:5.1f}%")
    return figures


def walking_realtime_factor(sim_seconds: float = 20.0, gait: str = "default",
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


def ground_truth_ms(n_frames: int = 500, stride: int = 2) -> float:
    """Milliseconds per ``ground_truth`` call on SR4000-sized frames; prints and returns it.

    The reference is a blocky random depth scene at 0.8-5 m; each current pose is turned and
    shifted a little (a walking head's motion), so most points stay in view.
    """
    rng = np.random.default_rng(0)
    shape = (SR4000_INTRINSICS.height, SR4000_INTRINSICS.width)
    depth = np.kron(rng.uniform(0.8, 5.0, (shape[0] // 8, shape[1] // 8)),
                    np.ones((8, 8))).astype(np.float32)
    base = np.array([[0.0, 0.0, -1.0], [-1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
    no_image = np.zeros(shape, np.uint8)

    def frame(index, cam_mat, cam_pos):
        return Frame(index, index / 30.0, depth, depth > 0, no_image, cam_pos, cam_mat)

    reference = frame(0, base, np.zeros(3))
    currents = [frame(i, base @ Rotation.from_euler("zyx", rng.uniform(-3, 3, 3),
                                                     degrees=True).as_matrix(),
                      rng.uniform(-0.03, 0.03, 3)) for i in range(1, n_frames + 1)]
    started = time.perf_counter()
    for current in currents:
        ground_truth(reference, current, stride=stride)
    ms = 1e3 * (time.perf_counter() - started) / n_frames
    print(f"ground_truth: {ms:.3f} ms/frame (stride {stride}, {n_frames} frames, 176 x 144)")
    return ms


def scoring_ms(n_frames: int = 1000, methods: tuple[str, ...] = ("t2fuzzy", "sift", "icp", "ecc",
                                                               "fourier_mellin")) -> float:
    """Milliseconds of scoring per frame (every method): records, ITF updates, the summary.

    Prints and returns the figure; the compensation warps themselves (the runner's
    ``stabilizer.compensate`` calls) are not included.
    """

    rng = np.random.default_rng(0)
    images = rng.integers(0, 256, (8, 144, 176), dtype=np.uint8)
    rows, cols = np.mgrid[0:SHAPE[0]:2, 0:SHAPE[1]:2]  # the ground truth's stride-2 sample
    truth = GroundTruth.exact(Motion(1.0, 2.0, 3.0), np.stack([cols.ravel(), rows.ravel()], 1),
                              SHAPE)
    estimate = Motion(1.1, 2.2, 2.9)
    itf = ItfAccumulator()
    records = []
    started = time.perf_counter()
    for index in range(n_frames):
        cycle, reference = index // 30, 30 * (index // 30)
        itf.add(RAW_STREAM, images[index % 8], gait_cycle=cycle, reference_index=reference)
        for method in methods:
            records.append(FrameRecord.score(
                frame_index=index, time_s=index / 30, gait_cycle=cycle,
                reference_index=reference, method=method, estimate=estimate, truth=truth, ms=2.0))
            itf.add(method, images[(index + 1) % 8], gait_cycle=cycle, reference_index=reference)
    summarize(records, itf)
    ms = 1e3 * (time.perf_counter() - started) / n_frames
    print(f"scoring: {ms:.3f} ms/frame ({len(methods)} methods, {n_frames} frames, 176 x 144)")
    return ms


def recording_ms(n_frames: int = 300, methods: Sequence[str] = ("t2fuzzy", "sift", "icp", "ecc",
                                                             "fourier_mellin")) -> float:
    """Milliseconds per ``log_frame`` with every entity logged; prints it and the file size.

    Synthetic SR4000-sized frames: noisy depth, its disparity image, a compensated frame per
    method, a 5-cluster segmentation with ellipses for the first method.
    """
    rng = np.random.default_rng(0)
    shape = (SR4000_INTRINSICS.height, SR4000_INTRINSICS.width)
    labels = np.kron(rng.integers(0, 6, (shape[0] // 16, shape[1] // 16)),
                     np.ones((16, 16), np.int32))
    ellipses = [(40.0 + 20 * i, 70.0, 15.0, 8.0, 30.0 * i) for i in range(5)]
    truth = GroundTruth(Motion(1.0, 2.0, 3.0), 0.5, 5000)
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "benchmark.rrd"
        elapsed = 0.0
        with RunRecorder(path, methods) as recorder:
            for index in range(n_frames):
                depth = rng.uniform(0.8, 5.0, shape).astype(np.float32)
                disparity = depth_to_disparity(depth)
                frame = Frame(index, index / 30.0, depth, depth > 0, disparity,
                              rng.normal(size=3), np.eye(3))
                estimates = {method: Motion(1.1, 2.1, 2.9) for method in methods}
                estimates[methods[0]] = Motion(1.1, 2.1, 2.9, diagnostics={
                    "labels": labels, "ellipses": ellipses})
                compensated = {method: disparity for method in methods}
                started = time.perf_counter()
                recorder.log_frame(frame, estimates=estimates, truth=truth,
                                   compensated=compensated)
                elapsed += time.perf_counter() - started
        size_kb = path.stat().st_size / 1024 / n_frames
    ms = 1e3 * elapsed / n_frames
    print(f"RunRecorder.log_frame: {ms:.2f} ms/frame, {size_kb:.0f} KB/frame "
          f"({len(methods)} methods, {n_frames} frames, random depth: worst case for size)")
    return ms


def render_fps(n_frames: int = 300, motion_blur: bool = False) -> float:
    """Frames/s of render + ToF model on a camera walking the corridor scene (one process).

    Prints and returns the figure. Motion blur off by default (one render per frame), as in the
    speed target (>= 150 frames/s at 176 x 144).
    """

    scene = build_scene("corridor", seed=0)
    probe = add_probe_camera(scene.arena, scene.start_xy, scene.start_yaw_deg)
    model = scene.compile()
    data = mujoco.MjData(model)
    params = TOF_PRESETS["sr4000"]
    if not motion_blur:
        params = dataclasses.replace(params, motion_blur_subframes=1)
    yaw = math.radians(scene.start_yaw_deg)
    velocity = 0.1 * np.array([math.cos(yaw), math.sin(yaw), 0.0])  # the robot's pace, m/s
    mocap = model.body(probe).mocapid[0]
    start = data.mocap_pos[mocap].copy()
    with SR4000(model, probe, params, seed=0) as sensor:
        started = time.perf_counter()
        for k in range(n_frames):
            for t in sensor.exposure_times(k):
                data.time = t
                data.mocap_pos[mocap] = start + velocity * t
                sensor.expose(data)
            sensor.read_frame(k)
        elapsed = time.perf_counter() - started
    fps = n_frames / elapsed
    print(f"SR4000 render + ToF: {fps:.1f} frames/s at 176x144 "
          f"({n_frames} frames, motion blur {'on' if motion_blur else 'off'})")
    return fps


def finished(document: dict) -> dict:
    """A timed job's metrics.json (``run``, ``score``) or sequence.json (``record``) content,
    when it ran to its end; the stop that cut it short, raised again, otherwise: ``run`` and
    ``record`` end on Ctrl-C or SIGTERM by returning, and the timing of a cut-short job is no
    figure to publish."""
    from sim.harness.interrupts import Interrupted
    from sim.harness.runner import INTERRUPTED

    status = document.get("status", document.get("ended"))
    if status == INTERRUPTED:
        message = document.get("message", document.get("run", {}).get("message", ""))
        raise Interrupted.named_in(message)
    return document


def rescoring(n_frames: int | None = None) -> dict[str, float]:
    """Recording the default scenario, and re-scoring the sequence: speed and parallelism.

    Records ``n_frames`` (None: the whole scenario) once (timed: ``egostab record``; the
    sequence's size on disk is reported too, at most 60 MB asked for the whole scenario), then
    times ``egostab score`` of ``t2fuzzy`` alone in this process, twice, alternating with the
    same without the trust check (``--no-check``: the method's own cost; as a multiple of real
    time: the sequence's simulated seconds per wall-clock second; each figure is the faster of
    its two runs, the first also pays the process's first imports of the report and plotting
    code, about 1 s), and of every method with one and with two worker processes, each twice,
    alternating (the ratio of the faster runs is the speed-up of ``--workers 2``; a shared
    machine's load drifts within minutes).
    """
    from sim.harness.runner import RecordConfig, record
    from sim.harness.score import ScoreConfig, score

    with tempfile.TemporaryDirectory() as scratch:
        sequence = Path(scratch) / "sequence"
        started = time.perf_counter()
        sim_time_s = finished(record(RecordConfig(DEFAULT_SCENARIO, str(sequence),
                                                  max_frames=n_frames)))["sim_time_s"]
        record_rtf = sim_time_s / (time.perf_counter() - started)
        sequence_mb = sum(path.stat().st_size for path in sequence.rglob("*")
                          if path.is_file()) / 1e6

        def seconds(name: str, clock=time.perf_counter, **options) -> float:
            started = clock()
            finished(score(ScoreConfig(str(sequence), str(Path(scratch) / name), record=False,
                                       **options)))
            return clock() - started

        t2fuzzy_runs = [(seconds(f"t2fuzzy{run}", methods=("t2fuzzy",)),
                         seconds(f"t2fuzzy_unchecked{run}", methods=("t2fuzzy",),
                                 trust_check=False)) for run in (1, 2)]
        (first, again), unchecked = zip(*t2fuzzy_runs)
        t2fuzzy_rtf = sim_time_s / min(first, again)
        unchecked_rtf = sim_time_s / min(unchecked)
        # Process CPU time: what the re-score costs this process, which other jobs on a shared
        # machine disturb less than the wall clock.
        cpu_rtf = sim_time_s / seconds("t2fuzzy_cpu", time.process_time, methods=("t2fuzzy",))
        runs = [(seconds(f"workers1_{run}", workers=1), seconds(f"workers2_{run}", workers=2))
                for run in range(2)]
        one, two = (min(times) for times in zip(*runs))
    print(f"egostab record {DEFAULT_SCENARIO} ({sim_time_s:.1f} s): {record_rtf:.2f}x real time, "
          f"{sequence_mb:.1f} MB")
    print(f"re-scoring t2fuzzy on a recorded {DEFAULT_SCENARIO} ({sim_time_s:.1f} s): "
          f"{t2fuzzy_rtf:.1f}x real time, one core (runs of {first:.2f} s and {again:.2f} s); "
          f"{cpu_rtf:.1f}x in process CPU time; without the trust check {unchecked_rtf:.1f}x "
          f"(runs of {unchecked[0]:.2f} s and {unchecked[1]:.2f} s)")
    print(f"score, every method: --workers 1 {one:.1f} s, --workers 2 {two:.1f} s "
          f"({one / two:.2f}x)")
    return {"record_realtime_factor": record_rtf, "sequence_mb": sequence_mb,
            "rescore_t2fuzzy_realtime_factor": t2fuzzy_rtf,
            "rescore_t2fuzzy_cpu_realtime_factor": cpu_rtf,
            "rescore_t2fuzzy_unchecked_realtime_factor": unchecked_rtf, "score_workers1_s": one,
            "score_workers2_s": two}


def _load() -> str:
    one, five, _ = os.getloadavg()
    return f"load average {one:.2f} (1 min), {five:.2f} (5 min)"


def _machine() -> str:
    import platform

    cpu = platform.processor() or "unknown CPU"
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as handle:
            cpu = next(line.split(":", 1)[1].strip() for line in handle
                       if line.startswith("model name"))
    except (OSError, StopIteration):
        pass
    return (f"{cpu}, {os.cpu_count()} cores, {platform.platform()}, "
            f"Python {platform.python_version()}")


def run_benchmarks(quick: bool = False, out_path=None) -> dict:
    """Every speed figure of the project, measured side by side; optionally as Markdown."""
    from sim.atomic import write_text_atomic
    from sim.harness.runner import RunConfig, run

    n_frames = 60 if quick else 200
    load_before = _load()
    synthetic, synthetic_unchecked = (stabilizer_benchmark(n_frames=n_frames, checked=checked)
                                      for checked in (True, False))
    walk_scenes = simulated_scenes(DEFAULT_SCENARIO, n_frames // 2 if quick else 150)
    walk, walk_unchecked = (stabilizer_benchmark(
        scenes=walk_scenes, label=f"a simulated walk, scenario {DEFAULT_SCENARIO}",
        checked=checked) for checked in (True, False))
    physics_rtf = walking_realtime_factor(5.0 if quick else 20.0)
    print(f"walking physics + control, no rendering: {physics_rtf:.1f}x real time")
    render_tof_fps = render_fps(100 if quick else 300)
    pipeline_frames = 45 if quick else None  # None: the scenario's whole duration
    pipeline_rtf = {}
    for label, methods, record, workers in (
            ("every method, recording on", None, True, None),
            ("every method, recording on", None, True, 1),
            ("t2fuzzy alone, no recording", ("t2fuzzy",), False, None)):
        with tempfile.TemporaryDirectory() as scratch:
            metrics = finished(run(RunConfig(DEFAULT_SCENARIO, scratch, methods=methods,
                                             record=record, max_frames=pipeline_frames,
                                             workers=workers)))
        used = metrics["run"]["workers"]
        label += (f", default workers (`--workers {used}` here)" if workers is None
                  else f", `--workers {workers}`")
        pipeline_rtf[label] = metrics["run"]["realtime_factor"]
        print(f"egostab run {DEFAULT_SCENARIO}, {metrics['run']['frames_done']} frames, {label}: "
              f"{pipeline_rtf[label]:.2f}x real time")
    sequences = rescoring(150 if quick else None)
    corpus = t2fuzzy_corpus_benchmark(n_scenes=2 if quick else 4,
                                      walk_frames=30 if quick else 80)
    figures = {"machine": _machine(), "date": time.strftime("%Y-%m-%d"),
               "load": f"before: {load_before}; after: {_load()}",
               "stabilizer_ms_synthetic": synthetic, "stabilizer_ms_simulated": walk,
               "stabilizer_ms_synthetic_unchecked": synthetic_unchecked,
               "stabilizer_ms_simulated_unchecked": walk_unchecked,
               "physics_realtime_factor": physics_rtf, "render_tof_fps": render_tof_fps,
               "pipeline_realtime_factor": pipeline_rtf, **sequences, "t2fuzzy_corpus": corpus,
               "quick": quick}
    if out_path is not None:
        write_text_atomic(Path(out_path), bench_markdown(figures))
    return figures


def bench_markdown(figures: dict) -> str:
    """results/bench.md: the figures and the machine they came from."""
    lines = [f"# Benchmarks ({figures['date']})", "",
             f"Machine: {figures['machine']}; {figures['load']}.", "",
             "Measured by `egostab bench" + (" --quick" if figures["quick"] else "")
             + " --out results/bench.md`; stabilizers on one thread; median ms per frame, "
             "with the trust check every estimate of a run goes through (without it: the "
             "method's own cost).", "",
             "| Method | synthetic scenes | without the check | x t2fuzzy | simulated walk | "
             "without the check | x t2fuzzy |", "|---|---|---|---|---|---|---|"]
    synthetic, walk = figures["stabilizer_ms_synthetic"], figures["stabilizer_ms_simulated"]
    synthetic_own = figures["stabilizer_ms_synthetic_unchecked"]
    walk_own = figures["stabilizer_ms_simulated_unchecked"]
    for method, ms in synthetic.items():
        lines.append(f"| {method} | {ms:.2f} | {synthetic_own[method]:.2f} | "
                     f"{ms / synthetic[BASELINE]:.2f} | {walk[method]:.2f} | "
                     f"{walk_own[method]:.2f} | {walk[method] / walk[BASELINE]:.2f} |")
    lines += ["", "| Figure | Value |", "|---|---|",
              f"| walking physics + control, no rendering | "
              f"{figures['physics_realtime_factor']:.1f}x real time |",
              f"| SR4000 render + ToF, motion blur off | {figures['render_tof_fps']:.0f} frames/s |",
              *(f"| `egostab run` of the default scenario, {label} | {rtf:.2f}x real time |"
                for label, rtf in figures["pipeline_realtime_factor"].items()),
              f"| `egostab record` of the default scenario | "
              f"{figures['record_realtime_factor']:.2f}x real time, a sequence of "
              f"{figures['sequence_mb']:.0f} MB |",
              "| re-scoring t2fuzzy alone on the recorded default scenario, one core, faster of "
              f"two runs | "
              f"{figures['rescore_t2fuzzy_realtime_factor']:.1f}x real time |",
              f"| the same, in process CPU time (a third run) | "
              f"{figures['rescore_t2fuzzy_cpu_realtime_factor']:.1f}x real time |",
              "| the same without the trust check (`egostab score --no-check`), faster of two "
              "runs alternating with the checked ones | "
              f"{figures['rescore_t2fuzzy_unchecked_realtime_factor']:.1f}x real time |",
              f"| `egostab score`, every method, `--workers 2` against `--workers 1`, faster of "
              f"two runs each | "
              f"{figures['score_workers1_s'] / figures['score_workers2_s']:.2f}x faster "
              f"({figures['score_workers1_s']:.1f} s / {figures['score_workers2_s']:.1f} s) |",
              "", "t2fuzzy against SIFT on the varied synthetic corpus "
              "(`python -m sim.harness.bench t2fuzzy-corpus`; "
              "stabilizer.testing.CORPUS_GENERATORS) and on walking frames of every scene; "
              "median ms per frame, wall clock (process CPU time); then without the trust "
              "check, wall clock, with the paper's stages alone (t2fuzzy_paper) beside them:",
              "", "| Frames | t2fuzzy ms | SIFT ms | SIFT / t2fuzzy | without the check: "
              "t2fuzzy ms | t2fuzzy_paper ms | SIFT ms | SIFT / t2fuzzy |",
              "|---|---|---|---|---|---|---|---|"]
    for generator, ms in figures["t2fuzzy_corpus"]["synthetic"].items():
        lines.append(f"| {generator} | {ms['t2fuzzy']:.2f} ({ms['t2fuzzy_cpu']:.2f}) | "
                     f"{ms['sift']:.2f} ({ms['sift_cpu']:.2f}) | "
                     f"{ms['sift'] / ms['t2fuzzy']:.2f} | {ms['t2fuzzy_own']:.2f} | "
                     f"{ms['t2fuzzy_paper_own']:.2f} | {ms['sift_own']:.2f} | "
                     f"{ms['sift_own'] / ms['t2fuzzy_own']:.2f} |")
    for scene, ms in figures["t2fuzzy_corpus"]["walking"].items():
        lines.append(f"| walking, {scene} | {ms['t2fuzzy']:.2f} ({ms['t2fuzzy_cpu']:.2f}) | | "
                     f"| {ms['t2fuzzy_own']:.2f} | {ms['t2fuzzy_paper_own']:.2f} | | |")
    lines.append("")
    return "\n".join(lines)


COMPONENTS = {
    "t2fuzzy-corpus": t2fuzzy_corpus_benchmark,
    "t2fuzzy-stages": t2fuzzy_stage_shares,
    "rescoring": lambda: rescoring(150),
    "ground-truth": lambda: (ground_truth_ms(stride=2), ground_truth_ms(stride=1)),
    "scoring": scoring_ms,
    "recording": recording_ms,
    "render": lambda: (render_fps(), render_fps(motion_blur=True)),
    "walking": lambda: print(f"walking physics + control, no rendering: "
                             f"{walking_realtime_factor():.1f}x real time (wall clock), "
                             f"{walking_realtime_factor(clock=time.process_time):.1f}x "
                             f"(process CPU time)"),
}


def main(argv: list[str] | None = None) -> None:
    from sim.command_line import MAX_SEED, POSITIVE_INTEGER, OneLineParser, integer_option
    from sim.harness.cli import method_list

    parser = OneLineParser(prog="python -m sim.harness.bench",
                           description=__doc__.splitlines()[0])
    parser.add_argument("component", nargs="?", default="stabilizers",
                        choices=("stabilizers", *COMPONENTS),
                        help="what to time (default: the stabilizers; the options below are "
                             "theirs)")
    parser.add_argument("--frames", type=POSITIVE_INTEGER, default=None,
                        help="frames timed per method, split evenly over the scenes (at least "
                             "one each; default 200)")
    parser.add_argument("--seed", type=integer_option(0, MAX_SEED), default=None,
                        help="scene and motion seed (default 0)")
    parser.add_argument("--scenes", type=POSITIVE_INTEGER, default=None,
                        help="distinct scenes (default 10)")
    parser.add_argument("--methods", type=method_list, default=None,
                        help="comma-separated methods, or all (default: all available)")
    args = parser.parse_args(argv)
    # Option -> stabilizer_benchmark's parameter; an option not given keeps its default.
    options = {"--frames": ("n_frames", args.frames), "--seed": ("seed", args.seed),
               "--scenes": ("n_scenes", args.scenes), "--methods": ("methods", args.methods)}
    given = {option: pair for option, pair in options.items() if pair[1] is not None}
    if args.component != "stabilizers":
        if given:
            parser.error(f"{next(iter(given))} with {args.component}: the options time the "
                         f"stabilizers only; accepted: {args.component} alone")
        COMPONENTS[args.component]()
        return
    stabilizer_benchmark(**dict(given.values()))


if __name__ == "__main__":
    from sim.command_line import script_status

    sys.exit(script_status(main))
