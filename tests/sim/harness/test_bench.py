"""sim.harness.bench (the corpus benchmark's synthetic part: the walks render; the stage shares; its
options) and the options of the benchmarks/ scripts."""

from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from sim.harness import bench
from stabilizer.testing import CORPUS_GENERATORS


def test_corpus_benchmark_times_both_methods_on_every_generator(capsys):
    figures = bench.t2fuzzy_corpus_benchmark(n_scenes=1, frames_per_scene=2, walk_frames=0)
    assert set(figures["synthetic"]) == {*CORPUS_GENERATORS, "all generators"}
    assert figures["walking"] == {}
    for generator, ms in figures["synthetic"].items():
        assert set(ms) == {"t2fuzzy", "sift", "t2fuzzy_cpu", "sift_cpu", "t2fuzzy_own",
                           "t2fuzzy_paper_own", "sift_own"}
        assert all(np.isfinite(value) and 0 < value < 1e4 for value in ms.values()), generator
    printed = capsys.readouterr().out
    assert "sift / t2fuzzy" in printed and "load average" in printed
    assert all(f"{generator}: t2fuzzy" in printed for generator in figures["synthetic"])
    assert printed.count("without the check: t2fuzzy") == len(figures["synthetic"])


def test_the_corpus_benchmark_times_the_methods_with_and_without_the_check(monkeypatch, capsys):
    # Each timing tagged with what was timed: method, clock and whether the check ran.
    def tagged(method, scenes, clock=bench.time.perf_counter, checked=True):
        cpu = clock is bench.time.process_time
        return [{"t2fuzzy": 2.0, "t2fuzzy_paper": 3.0, "sift": 4.0}[method]
                + 10.0 * cpu + 100.0 * checked]

    monkeypatch.setattr(bench, "frame_ms", tagged)
    monkeypatch.setattr(bench, "simulated_scenes", lambda scenario, n: [])
    figures = bench.t2fuzzy_corpus_benchmark(n_scenes=1, frames_per_scene=1, walk_frames=1)
    for ms in [*figures["synthetic"].values(), *figures["walking"].values()]:
        assert ms["t2fuzzy"] == 102.0 and ms["t2fuzzy_cpu"] == 112.0
        assert ms["t2fuzzy_own"] == 2.0 and ms["t2fuzzy_paper_own"] == 3.0
    for ms in figures["synthetic"].values():
        assert ms["sift"] == 104.0 and ms["sift_cpu"] == 114.0 and ms["sift_own"] == 4.0
    printed = capsys.readouterr().out
    assert printed.count("sift / t2fuzzy  1.02 ( 1.02)") == len(figures["synthetic"])
    assert printed.count("sift / t2fuzzy  2.00") == len(figures["synthetic"])
    markdown = bench.bench_markdown({
        "date": "d", "machine": "m", "load": "l", "quick": False,
        "stabilizer_ms_synthetic": {"t2fuzzy": 4.0, "sift": 6.0},
        "stabilizer_ms_simulated": {"t2fuzzy": 5.0, "sift": 2.5},
        "stabilizer_ms_synthetic_unchecked": {"t2fuzzy": 2.0, "sift": 3.0},
        "stabilizer_ms_simulated_unchecked": {"t2fuzzy": 2.5, "sift": 1.5},
        "physics_realtime_factor": 50.0, "render_tof_fps": 160.0,
        "pipeline_realtime_factor": {"every method": 1.25},
        "record_realtime_factor": 2.5, "sequence_mb": 47.0,
        "rescore_t2fuzzy_realtime_factor": 3.5, "rescore_t2fuzzy_cpu_realtime_factor": 3.25,
        "rescore_t2fuzzy_unchecked_realtime_factor": 6.25, "score_workers1_s": 30.0,
        "score_workers2_s": 15.0, "t2fuzzy_corpus": figures})
    # Each ratio is to t2fuzzy (the first table) or of SIFT to t2fuzzy (the corpus).
    assert "| t2fuzzy | 4.00 | 2.00 | 1.00 | 5.00 | 2.50 | 1.00 |" in markdown
    assert "| sift | 6.00 | 3.00 | 1.50 | 2.50 | 1.50 | 0.50 |" in markdown
    assert "| `egostab run` of the default scenario, every method | 1.25x real time |" in markdown
    assert "| walking physics + control, no rendering | 50.0x real time |" in markdown
    assert "a sequence of 47 MB" in markdown and "| 3.5x real time |" in markdown
    assert ("(`egostab score --no-check`), faster of two runs alternating with the checked "
            "ones | 6.2x real time |") in markdown
    assert "| 2.00x faster (30.0 s / 15.0 s) |" in markdown
    assert "| clutter | 102.00 (112.00) | 104.00 (114.00) | 1.02 | 2.00 | 3.00 | 4.00 | 2.00 |" \
        in markdown
    assert "| walking, corridor | 102.00 (112.00) | | | 2.00 | 3.00 | | |" in markdown


def test_the_walking_scenarios_cover_every_scene():
    from sim.world.scenes import SCENES

    assert set(bench.WALK_SCENARIOS) == set(SCENES)


def test_walking_frames_are_grouped_by_gait_cycle_after_the_standing_start(monkeypatch):
    # A fake walk at the default scenario's 30 frames/s whose gait cycle changes every 10
    # frames: the first 1.5 s (45 frames) are left out, then 16 frames (45-60) are kept by
    # cycle; frame 60, alone in its cycle, is no pair to time.
    import contextlib

    import sim.harness.runner

    robot = SimpleNamespace(gait_cycle=0)
    walked = []

    def walk_frames(loaded, robot_, sensor, n_frames):
        walked.append(n_frames)
        for index in range(n_frames):
            robot.gait_cycle = index // 10
            yield SimpleNamespace(index=index, disparity8=index)

    monkeypatch.setattr(sim.harness.runner, "scenario_robot", lambda loaded: robot)
    monkeypatch.setattr(sim.harness.runner, "open_sensor",
                        lambda loaded, robot_: contextlib.nullcontext())
    monkeypatch.setattr(sim.harness.runner, "walk_frames", walk_frames)
    assert bench.simulated_scenes(n_frames=16, skip_s=1.5) == [
        (45, [46, 47, 48, 49]), (50, [51, 52, 53, 54, 55, 56, 57, 58, 59])]
    assert walked == [61]


def test_time_method_uses_the_clock_it_is_given():
    ticks = iter(range(1000))
    scenes = [(np.zeros((144, 176), np.uint8), [np.zeros((144, 176), np.uint8)] * 3)]
    # Each estimate spans one tick of this clock: 1 ms per frame whatever the work took.
    assert bench.time_method("t2fuzzy", scenes, clock=lambda: next(ticks) * 1e-3) == 1.0


class JobClock:
    """A clock that only the fake jobs move, each by its own duration (seconds)."""

    def __init__(self, durations):
        self.now, self.durations = 100.0, durations

    def __call__(self):
        return self.now

    def job(self, name):
        self.now += self.durations[name]


def test_rescoring_reports_the_sequences_seconds_per_second_of_its_jobs(monkeypatch, capsys):
    # A 10 s sequence of 2 MB recorded in 4 s; t2fuzzy re-scored in 5 s, then 4 s, then 8 s
    # of CPU, and without the trust check in 2.5 and 2 s; every method with one worker in 30
    # and 28 s, with two in 15 and 16 s.
    import sim.harness.runner
    import sim.harness.score

    clock = JobClock({"record": 4.0, "t2fuzzy1": 5.0, "t2fuzzy2": 4.0, "t2fuzzy_cpu": 8.0,
                      "t2fuzzy_unchecked1": 2.5, "t2fuzzy_unchecked2": 2.0,
                      "workers1_0": 30.0, "workers2_0": 15.0, "workers1_1": 28.0,
                      "workers2_1": 16.0})

    def record(config):
        clock.job("record")
        Path(config.out_dir).mkdir(parents=True)
        (Path(config.out_dir) / "frames.bin").write_bytes(bytes(2_000_000))
        return {"ended": "complete", "sim_time_s": 10.0}

    def score(config):
        # Only the runs named unchecked leave the trust check out.
        assert config.trust_check == ("unchecked" not in Path(config.out_dir).name)
        clock.job(Path(config.out_dir).name)
        return {"status": "complete"}

    monkeypatch.setattr(sim.harness.runner, "record", record)
    monkeypatch.setattr(sim.harness.score, "score", score)
    monkeypatch.setattr(bench, "time", SimpleNamespace(perf_counter=clock, process_time=clock))
    assert bench.rescoring(2) == pytest.approx({
        "record_realtime_factor": 2.5, "sequence_mb": 2.0,
        "rescore_t2fuzzy_realtime_factor": 2.5, "rescore_t2fuzzy_cpu_realtime_factor": 1.25,
        "rescore_t2fuzzy_unchecked_realtime_factor": 5.0, "score_workers1_s": 28.0,
        "score_workers2_s": 15.0})
    assert "--workers 1 28.0 s, --workers 2 15.0 s (1.87x)" in capsys.readouterr().out


def test_the_physics_and_render_rates_are_per_second_of_their_clock(monkeypatch):
    ticks = iter([10.0, 14.0])
    assert bench.walking_realtime_factor(0.2, clock=lambda: next(ticks)) == pytest.approx(0.05)
    with pytest.raises(ValueError, match="sim_seconds must be > 0"):
        bench.walking_realtime_factor(0.0)
    ticks = iter([10.0, 10.5])
    monkeypatch.setattr(bench, "time", SimpleNamespace(perf_counter=lambda: next(ticks)))
    assert bench.render_fps(2) == pytest.approx(4.0)


def test_a_timed_job_cut_short_stops_the_benchmark_with_its_signal(monkeypatch):
    # run and record end on Ctrl-C or SIGTERM by returning: the benchmark went on and
    # published the cut-short job's timing.
    import sim.harness.runner
    from sim.harness.interrupts import Interrupted

    def recorded_until_sigterm(config):
        return {"ended": "interrupted", "message": "interrupted by SIGTERM", "sim_time_s": 0.9}

    monkeypatch.setattr(sim.harness.runner, "record", recorded_until_sigterm)
    with pytest.raises(Interrupted) as stop:
        bench.rescoring(2)
    assert stop.value.signal_name == "SIGTERM"
    assert bench.finished({"status": "fell", "run": {"message": "the robot fell"}})
    with pytest.raises(KeyboardInterrupt):
        bench.finished({"status": "interrupted",
                        "run": {"message": "interrupted by the user (Ctrl-C)"}})


def test_stage_shares_split_the_estimate_into_its_stages(monkeypatch, capsys):
    from stabilizer.testing import corpus_frames

    # Synthetic frames for every scene: the shares' bookkeeping, not the walks' rendering.
    reference, frames = corpus_frames("clutter", 3, 4)[:2]
    monkeypatch.setattr(bench, "simulated_scenes", lambda scenario, n: [(reference, frames)])
    figures = bench.t2fuzzy_stage_shares(walk_frames=4)
    assert set(figures) == set(bench.WALK_SCENARIOS)
    for scene, row in figures.items():
        calls, ms = row.pop("estimate")
        assert calls == 1.0 and 0 < ms < 1e4
        rest = row.pop("the rest")[1]
        stages = [share for stage, (_, share) in row.items() if not stage.startswith("climb")
                  and stage not in ("rival motion search", "ECC at full resolution")]
        assert len(stages) == 6 and all(0.0 <= share <= 1.0 for share in stages), scene
        # Every frame is analysed, searched and checked: most of the time is in the stages.
        assert row["stages 1-5 (segmentation, wavelets, ellipses, threshold)"][0] >= 1.0
        assert row["the trust check of the estimate"][0] >= 1.0
        assert row["the trust check's measurements of the frame"][0] > 0.0
        assert 0.0 <= rest < 0.5 and abs(sum(stages) + rest - 1.0) < 1e-9
    printed = capsys.readouterr().out
    assert "load average" in printed and "the trust check of the estimate" in printed


@pytest.mark.parametrize("argv, named", [
    (["--frames", "0"], "--frames: '0': accepted: an integer >= 1"),
    (["--scenes", "0"], "--scenes: '0': accepted: an integer >= 1"),
    (["--seed", "-1"], "--seed: '-1': accepted: an integer from 0"),
    (["--methods", "no_such_method"], "method 'no_such_method': unknown"),
    (["t2fuzzy-stages", "--frames", "3"], "--frames with t2fuzzy-stages: the options time the "
                                           "stabilizers only; accepted: t2fuzzy-stages alone"),
    (["rescoring", "--methods", "icp"], "--methods with rescoring"),
])
def test_bad_options_are_refused_in_one_line(argv, named, capsys):
    # --scenes 0 divided by zero, --methods of an unknown method ended in a traceback, and a
    # component's run ignored the stabilizers' options.
    with pytest.raises(SystemExit) as stop:
        bench.main(argv)
    err = capsys.readouterr().err.strip().splitlines()
    assert stop.value.code == 2 and len(err) == 1 and named in err[0], err


def test_the_stabilizer_timing_reports_the_frames_it_timed(capsys):
    # 3 frames over 2 scenes time 1 frame of each: the line said "3 frames of 2 scenes".
    figures = bench.stabilizer_benchmark(["icp"], n_frames=3, n_scenes=2)
    printed = capsys.readouterr().out
    assert "median of 2 frames (2 synthetic scenes, 1 frame each)" in printed, printed
    # Without t2fuzzy timed there is no ratio to it (it printed "nan x t2fuzzy").
    assert np.isfinite(figures["icp"]) and "nan" not in printed


@pytest.mark.parametrize("script, argv, named", [
    ("trust_properties.py", ["--cases", "0"], "--cases: '0': accepted: an integer >= 1"),
    ("trust_properties.py", ["--seed", "-3"], "--seed: '-3': accepted: an integer from 0"),
    ("floor_walks.py", ["--workers", "0"], "--workers: '0': accepted: an integer >= 1"),
    ("abrupt_commands.py", ["--seeds", "-1"], "--seeds: '-1': accepted: an integer from 0"),
    ("icp_error_metrics.py", ["--cases", "3"], "unrecognized arguments: --cases 3"),
    ("t2fuzzy_failures.py", ["summary", "x", "--refinements", "no_such=1"],
     "--refinements no_such: no such setting"),
    ("t2fuzzy_failures.py", ["margins", "x", "--stride", "0"], "--stride: '0'"),
    ("t2fuzzy_failures.py", ["grid-reach", "x", "--stride", "0"], "--stride: '0'"),
    ("t2fuzzy_failures.py", ["switch", "x", "--stride", "0"], "--stride: '0'"),
    ("t2fuzzy_failures.py", ["switch", "x", "--param", "min_correlation"],
     "--param: invalid choice: 'min_correlation'"),
    ("t2fuzzy_failures.py",
     ["margins", "x", "--param", "strong_edge_ridge", "--values", "0", "2"],
     "--values 2: strong_edge_ridge is a switch; accepted: 0 and 1"),
    ("t2fuzzy_failures.py", ["check-time", "x", "--param", "no_such", "--values", "1"],
     "--param no_such: no such setting of the check; accepted: min_correlation"),
    ("ok_but_off.py", ["no_such_folder", "--figures", "/dev/null"],
     "--figures /dev/null: exists and is not a folder"),
    ("ok_but_off.py", ["no_such_folder"], "no_such_folder: no suite.json"),
    ("t2fuzzy_failures.py", ["figures", "no_such_folder"],
     "no_such_folder/hall_de_2001: no sequence; accepted: the folder `record` wrote"),
])
def test_the_benchmark_scripts_refuse_bad_options_in_one_line(script, argv, named):
    # --cases 0 ran nothing and printed zeros, --seed -3, --workers 0 and figures without its
    # sequences ended in tracebacks, icp_error_metrics.py ignored its arguments.
    import subprocess
    import sys
    from pathlib import Path

    path = Path(__file__).resolve().parents[3] / "benchmarks" / script
    done = subprocess.run([sys.executable, str(path), *argv], capture_output=True, text=True,
                          timeout=120)
    assert done.returncode == 2 and done.stderr.count("\n") == 1, done.stderr
    assert named in done.stderr and done.stdout == ""
