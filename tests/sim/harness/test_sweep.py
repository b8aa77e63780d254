"""Sweeps: file validation, expansion, resumable parallel runs (spawn pool and Ray), tables.

The runs here use ``fake_run``: a cheap, picklable stand-in for ``sim.harness.runner.run`` that writes a
run folder with the real writer (``sim.harness.report.write_run_outputs``) from made-up frame records
whose errors grow with the noise level, so aggregation reads the real metrics.json layout.
"""

from __future__ import annotations

import csv
import json
import math
import os
import signal
import time
from pathlib import Path

import pytest

from sim.harness.cpu_paths import CPU_PATH_VARIABLES, cpu_paths_in_effect
from sim.harness.report import METRICS_JSON, read_metrics, write_run_outputs
from sim.harness.runner import RunConfig
from sim.harness.scenario import SCENARIOS_DIR
from sim.harness.scoring import FrameRecord, summarize
from sim.harness.sweep import (COLUMNS, DEFAULT_NOISE_KEY, ERROR_COLUMNS, RunOutcome,
                               SweepError, completed_metrics, default_sweep_dir, expand_sweep,
                               load_sweep, plan_sweep, run_sweep, sweep_from_dict,
                               table_markdown)
from sim.harness.sweep import execute as sweep_execute
from sim.harness.sweep.plan import planned_scenario
from sim.harness.threads import THREAD_VARIABLES

EXAMPLE_SWEEP = SCENARIOS_DIR / "sweeps" / "noise_sweep.toml"
METHODS = ("t2fuzzy", "sift")
#: Per-method error slope of the fake runs: |error| = slope * noise level + seed / 100.
SLOPES = {"t2fuzzy": 1.0, "sift": 2.0}
CALLS_LOG = "fake_calls.txt"
INTERVAL_LOG = "fake_interval.txt"
#: Set by a test in the parent process; a spawned (not forked) worker sees this default.
PARENT_MARK = "module default"


def small_spec(**changes):
    raw = {"name": "tiny", "scenarios": ["corridor_straight", "lab_clutter"], "seeds": [0, 1],
           "noise_levels": [0.5, 2.0], "methods": list(METHODS), "max_frames": 3}
    return sweep_from_dict({**raw, **changes}, source="tiny.toml")


def fake_run(config: RunConfig) -> dict:
    """Stand-in for sim.harness.runner.run: 3 frames per method, errors from the noise level;
    the time it started and ended goes to INTERVAL_LOG."""
    started = time.time()
    run_dir = Path(config.out_dir)
    run_dir.mkdir(parents=True, exist_ok=True)
    with open(run_dir / CALLS_LOG, "a", encoding="utf-8") as log:
        log.write(f"{os.getpid()}\n")
    noise = config.overrides[DEFAULT_NOISE_KEY]
    records = []
    for frame in range(3):
        for method in config.methods:
            error = SLOPES[method] * noise + config.seed / 100
            failed = method == "sift" and frame == 0
            records.append(FrameRecord(
                frame, frame / 30, 0, 0, method, "too_few_matches" if failed else "ok", 1.5,
                *((math.nan,) * 3 if failed else (error, error, error)), 0.0, 0.0, 0.0, "ok",
                0.1, 100, *((math.nan,) * 3 if failed else (error, error, error))))
    # The scenario and max_frames as run() writes them: resuming compares them with the plan.
    write_run_outputs(run_dir, scenario=planned_scenario(config)[1],
                      records=records, summary=summarize(records),
                      meta={"seed": config.seed, "max_frames": config.max_frames,
                            "parent_mark": PARENT_MARK, "ctrl_c": _ctrl_c_heard(),
                            "threads": _threads(),
                            "cpu_paths": cpu_paths_in_effect(_environment_at_start())},
                      status="complete", plots=False)
    (run_dir / INTERVAL_LOG).write_text(f"{started} {time.time()}")
    return read_metrics(run_dir)


def _ctrl_c_heard() -> bool:
    """Whether Ctrl-C raises KeyboardInterrupt here: handled so, and not blocked."""
    return (signal.getsignal(signal.SIGINT) is signal.default_int_handler
            and signal.SIGINT not in signal.pthread_sigmask(signal.SIG_BLOCK, []))


def _environment_at_start() -> dict[str, str]:
    """This process's environment as it started (numpy and OpenCV read it as they load; the
    process may have set more since: importing ``sim`` pins the CPU paths)."""
    entries = Path("/proc/self/environ").read_bytes().split(b"\0")
    return dict(entry.decode().split("=", 1) for entry in entries if b"=" in entry)


def _threads() -> list[int]:
    """This process's OpenCV threads and its BLAS libraries' largest thread count."""
    import cv2
    import threadpoolctl

    blas = [pool["num_threads"] for pool in threadpoolctl.threadpool_info()
            if pool["user_api"] == "blas"]
    return [cv2.getNumThreads(), max(blas)]


def failing_run(config: RunConfig) -> dict:
    """Like fake_run, but the runs of seed 1 raise, with a message of two lines (the tables
    give the first)."""
    if config.seed == 1:
        raise RuntimeError(f"simulated crash in {Path(config.out_dir).name}\n"
                           f"a second line, as of a traceback")
    return fake_run(config)


def crashing_run(config: RunConfig) -> dict:
    """Like fake_run, but the run of seed 1 at noise 2.0 ends its process, as a crash in native
    code would."""
    if config.seed == 1 and config.overrides[DEFAULT_NOISE_KEY] == 2.0:
        os._exit(70)
    return fake_run(config)


def interrupting_run(config: RunConfig) -> dict:
    """Like fake_run, but the run of lab_clutter at noise 0.5 interrupts the sweep (a Ctrl-C of
    its parent) and goes on for a second."""
    if "lab_clutter" in config.scenario and config.overrides[DEFAULT_NOISE_KEY] == 0.5:
        os.kill(os.getppid(), signal.SIGINT)
        time.sleep(1.0)
    return fake_run(config)


def calls(run_dir) -> int:
    path = Path(run_dir) / CALLS_LOG
    return len(path.read_text().splitlines()) if path.exists() else 0


def read_csv(path: Path) -> list[dict]:
    with open(path, newline="", encoding="utf-8") as handle:
        return list(csv.DictReader(handle))


# ----------------------------------------------------------------------------- expansion
def test_expansion_is_the_full_product_in_file_order(tmp_path):
    spec = small_spec()
    configs = expand_sweep(spec, tmp_path)
    assert len(configs) == spec.n_runs == 8
    names = [Path(config.out_dir).name for config in configs]
    assert names[:3] == ["corridor_straight__seed0__noise0.5",
                         "corridor_straight__seed0__noise2.0",
                         "corridor_straight__seed1__noise0.5"]
    assert names[-1] == "lab_clutter__seed1__noise2.0"
    assert len(set(names)) == len(names)
    first = configs[0]
    assert Path(first.out_dir).parent == tmp_path / "runs"
    assert (first.scenario, first.seed, first.methods, first.max_frames, first.record) == (
        "corridor_straight", 0, METHODS, 3, False)
    assert dict(first.overrides) == {DEFAULT_NOISE_KEY: 0.5}
    assert expand_sweep(small_spec(), tmp_path) == configs  # deterministic


def test_expansion_applies_the_noise_key_and_shared_overrides(tmp_path):
    spec = small_spec(noise_key="sensor.fps", noise_levels=[10, 20],
                      overrides={"evaluation.reference": "previous"})
    overrides = [dict(config.overrides) for config in expand_sweep(spec, tmp_path)]
    assert overrides[:2] == [{"evaluation.reference": "previous", "sensor.fps": 10.0},
                             {"evaluation.reference": "previous", "sensor.fps": 20.0}]


def test_integer_keys_are_swept_with_the_integers_written(tmp_path):
    spec = small_spec(noise_key="scene_seed", noise_levels=[2, 9007199254740993],
                      scenarios=["corridor_straight"], seeds=[0])
    configs = expand_sweep(spec, tmp_path)
    assert [config.overrides["scene_seed"] for config in configs] == [2, 9007199254740993]
    assert all(type(config.overrides["scene_seed"]) is int for config in configs)
    # Named as before for a level a float holds; a larger integer is named exactly.
    assert [Path(config.out_dir).name for config in configs] == [
        "corridor_straight__seed0__noise2.0", "corridor_straight__seed0__noise9007199254740993"]


def test_the_sweep_table_writes_noise_levels_as_given_rates_in_percent_and_errors_rounded():
    errors = dict(zip(ERROR_COLUMNS.values(), (0.1234, 1.5, math.nan)))
    row = {"run": "r0", "scenario": "corridor", "seed": 3, "noise_level": 0.015,
           "run_status": "complete", "method": "ecc", "frames": 300, **errors,
           "failure_rate": 0.125, "ms_per_frame": 4.567}
    unscored = {**{column: "" for column in COLUMNS}, "run": "r1", "scenario": "corridor",
                "seed": 4, "noise_level": 2.0, "run_status": "failed"}
    lines = table_markdown([row, unscored]).splitlines()
    assert len(lines) == 4 and lines[0].startswith("| Run | Scenario | Seed | Noise |")
    assert lines[2] == "| r0 | corridor | 3 | 0.015 | complete | ecc | 300 | 0.12 | 1.50 | n/a " \
                       "| 12.5% | 4.57 |"
    assert lines[3] == "| r1 | corridor | 4 | 2 | failed |  |  |  |  |  |  |  |"


def test_example_sweep_file_loads():
    spec = load_sweep(EXAMPLE_SWEEP)
    assert spec.name == "noise_sweep" and spec.noise_key == DEFAULT_NOISE_KEY
    assert spec.n_runs == len(spec.scenarios) * len(spec.seeds) * len(spec.noise_levels) > 1
    assert default_sweep_dir(spec) == Path("results", "sweeps", "noise_sweep")
    assert default_sweep_dir(spec, "elsewhere") == Path("elsewhere", "sweeps", "noise_sweep")


def test_relative_scenario_paths_are_taken_from_the_sweep_files_folder(tmp_path):
    (tmp_path / "mine").mkdir()
    (tmp_path / "mine" / "walk.toml").write_text(
        (SCENARIOS_DIR / "corridor_straight.toml").read_text())
    sweep_file = tmp_path / "mine" / "my sweep.toml"
    sweep_file.write_text('scenarios = ["walk.toml"]\nseeds = [3]\nnoise_levels = [1]\n')
    spec = load_sweep(sweep_file)
    assert spec.name == "my_sweep"
    assert spec.scenarios == (str((tmp_path / "mine" / "walk.toml").resolve()),)
    assert [Path(c.out_dir).name for c in expand_sweep(spec, tmp_path)] == [
        "walk__seed3__noise1.0"]


# ----------------------------------------------------------------------------- validation
@pytest.mark.parametrize("changes, key, allowed", [
    ({"seeds": [0], "sedes": [1]}, "sedes", "keys name"),
    ({"scenarios": None}, "scenarios", "non-empty list"),
    ({"scenarios": []}, "scenarios", "non-empty list"),
    ({"scenarios": ["no_such_scenario"]}, "scenarios[0]", "shipped scenario names"),
    ({"scenarios": ["corridor_straight", "corridor_straight"]}, "scenarios[1]", "distinct"),
    ({"seeds": []}, "seeds", "integers from 0 to 2**63 - 1"),
    ({"seeds": [0, -1]}, "seeds[1]", "integers from 0 to 2**63 - 1"),
    ({"seeds": [True]}, "seeds[0]", "integers from 0 to 2**63 - 1"),
    ({"seeds": [1, 1]}, "seeds[1]", "distinct"),
    ({"seeds": [1.5]}, "seeds[0]", "integers from 0 to 2**63 - 1"),
    ({"seeds": [0, 2**63]}, "seeds[1]", "integers from 0 to 2**63 - 1"),
    ({"noise_levels": ["high"]}, "noise_levels[0]", "finite numbers"),
    ({"noise_levels": [float("nan")]}, "noise_levels[0]", "finite numbers"),
    ({"noise_levels": [1, 1.0]}, "noise_levels[1]", "distinct"),
    # A value the sweep sets is refused as the scenario refuses it, under the sweep's key.
    ({"noise_levels": [1.0, 200.0]}, "noise_levels[1]", "0 to 100 (multiplies the preset's"),
    ({"noise_key": "sensor..noise"}, "noise_key", "dotted scenario key"),
    ({"noise_key": "sensor.nosie_scale"}, "noise_levels[0]", "keys preset, fps, noise_scale"),
    ({"methods": ["surf"]}, "methods[0]", "t2fuzzy"),
    ({"methods": []}, "methods", "t2fuzzy"),
    ({"max_frames": 0}, "max_frames", "integer >= 1"),
    ({"max_frames": 2.5}, "max_frames", "integer >= 1"),
    ({"record": "yes"}, "record", "true or false"),
    ({"name": "a/b"}, "name", "letters, digits"),
    ({"name": ".."}, "name", "not only dots"),  # results/sweeps/.. is results/ itself
    ({"overrides": {"seed": 3}}, "overrides", "not seed"),
    ({"overrides": {"sensor.noise_scale": 3}}, "overrides", "not the noise key"),
    # Within the noise key, or holding it: the level would replace it unseen.
    ({"overrides": {"sensor.noise_scale.x": 1}}, "overrides", "not the noise key"),
    ({"overrides": {"seed.x": 1}}, "overrides", "not seed"),
    ({"overrides": {"sensor": 1}}, "overrides", "not the noise key"),
    ({"overrides": {"sensor.fsp": 3}}, "overrides: sensor.fsp", "keys preset, fps, noise_scale"),
    ({"overrides": {"gait.overrides.step_period_s": -0.5}}, "overrides: gait.overrides",
     "valid GaitParams values"),
    # Refused by another key of the scenario, but only with the override: the override's fault.
    ({"overrides": {"duration_s": 1.0}, "scenarios": ["push_recovery"]}, "overrides",
     "every scenario"),
    ({"overrides": []}, "overrides", "a table"),
    ({"overrides": {"sensor": {"fps": 20.0}}}, "overrides", "single values"),
])
def test_invalid_sweeps_name_the_file_the_key_and_what_is_allowed(changes, key, allowed):
    with pytest.raises(SweepError) as info:
        small_spec(**changes)
    message = str(info.value)
    assert isinstance(info.value, ValueError)
    assert message.startswith(f"tiny.toml: {key}: "), message
    assert allowed in message.split("; allowed: ")[-1], message


def test_a_sweep_may_walk_one_frame_a_run():
    assert small_spec(max_frames=1).max_frames == 1


def test_an_unknown_scenario_name_is_refused_with_the_shipped_ones():
    with pytest.raises(SweepError) as info:
        small_spec(scenarios=["no_such_scenario"])
    assert "(shipped: corridor_straight, " in str(info.value)


def test_missing_required_key_and_bad_toml_are_named(tmp_path):
    with pytest.raises(SweepError, match=r"<dict>: noise_levels: missing"):
        sweep_from_dict({"scenarios": ["corridor_straight"], "seeds": [0]})
    broken = tmp_path / "broken.toml"
    broken.write_text("scenarios = [\n")
    with pytest.raises(SweepError, match="broken.toml: \\(file\\): not valid TOML"):
        load_sweep(broken)
    with pytest.raises(FileNotFoundError, match="no sweep file"):
        load_sweep(tmp_path / "absent.toml")
    with pytest.raises(FileNotFoundError, match="is a folder, not a sweep file"):
        load_sweep(tmp_path)


def test_two_scenario_files_with_one_name_are_refused(tmp_path):
    for folder in ("a", "b"):
        (tmp_path / folder).mkdir()
        (tmp_path / folder / "walk.toml").write_text(
            (SCENARIOS_DIR / "corridor_straight.toml").read_text())
    spec = sweep_from_dict({"scenarios": ["a/walk.toml", "b/walk.toml"], "seeds": [0],
                            "noise_levels": [1]}, base_dir=tmp_path)
    with pytest.raises(SweepError, match="share the name"):
        expand_sweep(spec, tmp_path)


def test_bad_backend_and_workers_are_refused(tmp_path):
    with pytest.raises(ValueError, match="accepted: local, ray"):
        run_sweep(small_spec(), tmp_path, backend="dask", run_fn=fake_run)
    with pytest.raises(ValueError, match=r"workers \S+: accepted: an integer from 1 to \d+"):
        run_sweep(small_spec(), tmp_path, workers=0, run_fn=fake_run)
    for workers in (0, 1.5, True):  # on Ray too, before anything is imported or written
        with pytest.raises(ValueError, match="workers must be an integer >= 1"):
            run_sweep(small_spec(), tmp_path / "ray", backend="ray", workers=workers,
                      run_fn=fake_run)
    assert not (tmp_path / "ray").exists()


@pytest.mark.parametrize("workers, n_runs, expected", [(None, 4, 1), (3, 4, 3), (4, 2, 2)])
def test_local_runs_at_a_time_default_to_the_usable_cores_and_never_exceed_the_runs(
        monkeypatch, workers, n_runs, expected):
    monkeypatch.setattr(os, "sched_getaffinity", lambda pid: {0}, raising=False)
    pools = []
    monkeypatch.setattr(sweep_execute, "_run_pool",
                        lambda pending, run_fn, processes, broken: pools.append(processes) or [])
    list(sweep_execute._run_local(["run"] * n_runs, fake_run, workers, None))
    assert pools == [expected]


def test_a_file_where_the_runs_folder_goes_is_refused_before_any_run(tmp_path):
    (tmp_path / "runs").write_text("not a folder")
    with pytest.raises(ValueError, match=r"runs: is a file where run \S+ keeps a folder; "
                                         r"accepted: a folder there, or nothing"):
        run_sweep(small_spec(), tmp_path, workers=1, run_fn=_never_run)
    run = plan_sweep(small_spec(), tmp_path)[1]
    (tmp_path / "runs").unlink()
    Path(run.config.out_dir).parent.mkdir()
    Path(run.config.out_dir).write_text("not a folder")
    with pytest.raises(ValueError, match=f"{run.name}: is a file where run {run.name} keeps"):
        run_sweep(small_spec(), tmp_path, workers=1, run_fn=_never_run)
    assert sorted(path.name for path in tmp_path.iterdir()) == ["runs"]  # no table written


def _never_run(config: RunConfig) -> dict:
    raise AssertionError("a run started")


def test_missing_ray_names_the_extra(tmp_path, monkeypatch):
    monkeypatch.setitem(__import__("sys").modules, "ray", None)  # import ray -> ImportError
    with pytest.raises(ImportError, match=r'pip install -e "\.\[cluster\]"'):
        run_sweep(small_spec(seeds=[0], noise_levels=[1.0]), tmp_path, backend="ray",
                  run_fn=fake_run)
    assert not any(tmp_path.iterdir())  # nothing written


# ----------------------------------------------------------------------------- running
@pytest.mark.parametrize("status, done", [("complete", True), ("fell", True),
                                          ("interrupted", False), ("error", False)])
def test_only_complete_or_fallen_runs_count_as_done(tmp_path, status, done):
    config = expand_sweep(small_spec(seeds=[0], noise_levels=[1.0]), tmp_path)[0]
    assert completed_metrics(config.out_dir) is None  # no metrics.json yet
    fake_run(config)
    metrics = Path(config.out_dir) / METRICS_JSON
    metrics.write_text(metrics.read_text().replace('"status": "complete"',
                                                   f'"status": "{status}"'))
    assert (completed_metrics(config.out_dir) is not None) == done
    metrics.write_text(metrics.read_text()[:40])  # a torn or foreign file: run again
    assert completed_metrics(config.out_dir) is None


def test_a_finished_run_counts_as_done_only_for_the_methods_it_scored(tmp_path):
    config = expand_sweep(small_spec(seeds=[0], noise_levels=[1.0]), tmp_path)[0]
    fake_run(config)
    assert completed_metrics(config.out_dir, config.methods) is not None
    assert completed_metrics(config.out_dir, config.methods[:1]) is not None
    assert completed_metrics(config.out_dir, (*config.methods, "ecc")) is None  # added later
    (Path(config.out_dir) / "frames.csv").unlink()  # a folder that lost its table: run again
    assert completed_metrics(config.out_dir, config.methods) is None


def test_a_run_whose_metrics_lack_a_methods_figures_is_not_done_for_it(tmp_path):
    spec = small_spec(scenarios=["corridor_straight"], seeds=[0], noise_levels=[1.0])
    run_sweep(spec, tmp_path, workers=1, run_fn=fake_run)
    run_dir = Path(plan_sweep(spec, tmp_path)[0].config.out_dir)
    document = read_metrics(run_dir)
    del document["summary"]["run"]["sift"]  # summary.methods still lists it
    (run_dir / METRICS_JSON).write_text(json.dumps(document))
    assert completed_metrics(run_dir, ("t2fuzzy",)) is not None
    assert completed_metrics(run_dir, METHODS) is None
    resumed = run_sweep(spec, tmp_path, workers=1, run_fn=fake_run)
    assert not resumed.outcomes[0].skipped and calls(run_dir) == 2  # sift is scored again
    assert [row["method"] for row in read_csv(tmp_path / "sweep.csv")] == list(METHODS)


def test_an_interrupted_rescore_keeps_every_run_finished_before_in_the_tables(tmp_path,
                                                                             monkeypatch):
    """A method added to the file, then an interrupt: the runs not scored anew yet keep their
    finished files (a run over a finished one replaces it only once finished), and the tables
    keep them too, with the runs finished anew before the interrupt."""
    first = small_spec(methods=["t2fuzzy"])
    run_sweep(first, tmp_path, workers=2, run_fn=fake_run)
    before = read_csv(tmp_path / "sweep.csv")
    assert len(before) == 8
    finished_anew = []

    def interrupted_after(pending, run_fn, workers, ray_address):
        for sweep_run in pending[:len(finished_anew)]:
            yield RunOutcome(sweep_run, fake_run(sweep_run.config))
        # A run interrupted with its metrics back: its folder still holds the finished run.
        yield RunOutcome(pending[len(finished_anew)],
                         {**read_metrics(pending[len(finished_anew)].config.out_dir),
                          "status": "interrupted"})
        raise KeyboardInterrupt

    monkeypatch.setattr(sweep_execute, "_run_local", interrupted_after)
    with pytest.raises(KeyboardInterrupt):  # stopped at once
        run_sweep(small_spec(), tmp_path, workers=2, run_fn=fake_run)
    assert read_csv(tmp_path / "sweep.csv") == before
    assert "8 planned, 8 finished (8 already complete before this call)" in (
        tmp_path / "sweep.md").read_text()

    finished_anew.append(1)
    with pytest.raises(KeyboardInterrupt):  # stopped after one run scored sift too
        run_sweep(small_spec(), tmp_path, workers=2, run_fn=fake_run)
    rows = read_csv(tmp_path / "sweep.csv")
    assert [row["method"] for row in rows[:2]] == list(METHODS)
    assert rows[0]["run"] == rows[1]["run"] == before[0]["run"] and rows[2:] == before[1:]

    def finished_unreported(pending, run_fn, workers, ray_address):
        # A run that finished while the interrupt cancelled it (a Ray task): no result came
        # back, its files are there, written in this call.
        time.sleep(0.05)  # past the coarse clock of file times
        fake_run(pending[0].config)
        raise KeyboardInterrupt
        yield

    monkeypatch.setattr(sweep_execute, "_run_local", finished_unreported)
    with pytest.raises(KeyboardInterrupt):
        run_sweep(small_spec(), tmp_path, workers=2, run_fn=fake_run)
    assert "8 planned, 8 finished (7 already complete before this call)" in (
        tmp_path / "sweep.md").read_text()
    assert [row["method"] for row in read_csv(tmp_path / "sweep.csv")[:4]] == [*METHODS] * 2


def check_table(out_dir: Path, spec, expected_status: dict[str, str]) -> list[dict]:
    """sweep.csv/md and one PNG per scenario exist; rows match what fake_run wrote."""
    rows = read_csv(out_dir / "sweep.csv")
    assert tuple(rows[0]) == COLUMNS
    assert (out_dir / "sweep.md").read_text().count("\n| ") == len(rows) + 1
    for scenario in ("corridor_straight", "lab_clutter"):
        png = out_dir / f"error_vs_noise__{scenario}.png"
        assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    for row in rows:
        assert row["run_status"] == expected_status[row["run"]], row
        if row["run_status"] != "complete":
            continue
        noise, seed = float(row["noise_level"]), int(row["seed"])
        expected = SLOPES[row["method"]] * noise + seed / 100
        for column in ERROR_COLUMNS.values():
            assert float(row[column]) == pytest.approx(expected)
        assert float(row["failure_rate"]) == pytest.approx(1 / 3 if row["method"] == "sift"
                                                           else 0.0)
        assert float(row["ms_per_frame"]) == 1.5
    return rows


def test_local_pool_runs_everything_then_resumes_only_the_unfinished(tmp_path):
    spec = small_spec()
    plan = plan_sweep(spec, tmp_path)
    result = run_sweep(spec, tmp_path, workers=2, run_fn=fake_run)
    assert not result.failed and not any(outcome.skipped for outcome in result.outcomes)
    assert [calls(r.config.out_dir) for r in plan] == [1] * 8
    rows = check_table(tmp_path, spec, {r.name: "complete" for r in plan})
    assert len(rows) == 8 * len(METHODS)
    assert [row["run"] for row in rows[::2]] == [r.name for r in plan]  # plan order

    again = run_sweep(spec, tmp_path, workers=2, run_fn=fake_run)
    assert all(outcome.skipped for outcome in again.outcomes)
    assert [calls(r.config.out_dir) for r in plan] == [1] * 8

    interrupted, lost = Path(plan[1].config.out_dir), Path(plan[6].config.out_dir)
    metrics = interrupted / METRICS_JSON
    metrics.write_text(metrics.read_text().replace('"status": "complete"',
                                                   '"status": "interrupted"'))
    (lost / METRICS_JSON).unlink()
    resumed = run_sweep(spec, tmp_path, workers=2, run_fn=fake_run)
    assert [outcome.run.name for outcome in resumed.outcomes if not outcome.skipped] == [
        plan[1].name, plan[6].name]
    assert [calls(r.config.out_dir) for r in plan] == [1, 2, 1, 1, 1, 1, 2, 1]
    check_table(tmp_path, spec, {r.name: "complete" for r in plan})


@pytest.mark.parametrize("sweep_hears_ctrl_c", [True, False])
def test_local_pool_starts_workers_with_spawn(tmp_path, monkeypatch, sweep_hears_ctrl_c):
    monkeypatch.setattr(__import__(__name__, fromlist=["_"]), "PARENT_MARK", "set in parent")
    # As started from a terminal, or in the background (`&`, nohup: Ctrl-C ignored).
    previous = signal.signal(signal.SIGINT, signal.default_int_handler if sweep_hears_ctrl_c
                             else signal.SIG_IGN)
    try:
        result = run_sweep(small_spec(seeds=[0], noise_levels=[1.0]), tmp_path, workers=2,
                           run_fn=fake_run)
    finally:
        signal.signal(signal.SIGINT, previous)
    for outcome in result.outcomes:
        assert outcome.metrics["run"]["parent_mark"] == "module default"  # not inherited
        assert outcome.metrics["run"]["threads"] == [1, 1]  # one thread per process
        # Started deaf to Ctrl-C (no traceback of theirs while they import), they hear it
        # when they run if the sweep does: an interrupted sweep's runs end with complete files.
        assert outcome.metrics["run"]["ctrl_c"] is sweep_hears_ctrl_c
        assert calls(outcome.run.config.out_dir) == 1
        pid = int((Path(outcome.run.config.out_dir) / CALLS_LOG).read_text())
        assert pid != os.getpid()


def test_a_failing_run_is_reported_and_the_others_finish(tmp_path):
    spec = small_spec()
    result = run_sweep(spec, tmp_path, workers=2, run_fn=failing_run)
    failed = {outcome.run.name for outcome in result.failed}
    assert failed == {r.name for r in plan_sweep(spec, tmp_path) if r.seed == 1}
    assert all("RuntimeError: simulated crash" in o.error for o in result.failed)
    expected = {r.name: ("complete" if r.seed == 0 else
                         f"error: RuntimeError: simulated crash in {r.name}")
                for r in plan_sweep(spec, tmp_path)}
    rows = check_table(tmp_path, spec, expected)
    assert len(rows) == 4 * len(METHODS) + 4  # failed runs: one row each, no methods
    assert "4 failed" in result.markdown


def test_a_run_that_ends_its_worker_process_fails_alone(tmp_path):
    # Its crash breaks the pool, and with it every run under way or queued there: those run
    # again one at a time, so only the crashing run ends with the error.
    spec = small_spec()
    result = run_sweep(spec, tmp_path, workers=2, run_fn=crashing_run)
    crashed = {r.name for r in plan_sweep(spec, tmp_path)
               if r.seed == 1 and r.config.overrides[DEFAULT_NOISE_KEY] == 2.0}
    assert {outcome.run.name for outcome in result.failed} == crashed
    assert all("BrokenProcessPool" in outcome.error for outcome in result.failed)
    assert sum(outcome.status == "complete" for outcome in result.outcomes) == 8 - len(crashed)


def test_an_interrupted_sweep_starts_no_queued_run(tmp_path):
    # The pool hands its worker one more queued run than it can cancel: that one must not
    # start once the sweep is stopping. The run under way ends with its files.
    spec = small_spec(seeds=[0], noise_levels=[0.5, 2.0])
    plan = plan_sweep(spec, tmp_path)
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        with pytest.raises(KeyboardInterrupt):
            run_sweep(spec, tmp_path, workers=1, run_fn=interrupting_run)
    finally:
        signal.signal(signal.SIGINT, previous)
    assert [r.name for r in plan if calls(r.config.out_dir)] == [
        "corridor_straight__seed0__noise0.5", "corridor_straight__seed0__noise2.0",
        "lab_clutter__seed0__noise0.5"]
    check_table(tmp_path, spec, {r.name: "complete" for r in plan})


def test_a_ray_task_can_be_cancelled_when_the_sweep_ignores_ctrl_c():
    # Started in the background (`&`, nohup, a batch job), the sweep ignores Ctrl-C and so do
    # Ray's workers; a cancel, a Ctrl-C of the worker, then never stopped the run.
    from sim.harness.sweep.execute import _run_as_ray_task

    previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        handler = _run_as_ray_task(lambda config: signal.getsignal(signal.SIGINT), None)
    finally:
        signal.signal(signal.SIGINT, previous)
    assert handler is signal.default_int_handler


def test_ray_backend_on_a_local_instance(tmp_path, monkeypatch):
    ray = pytest.importorskip("ray")
    spec = small_spec(seeds=[0, 1], noise_levels=[1.0])
    # Ray started by the caller, its workers with neither the single-thread environment nor
    # the CPU paths (as on a cluster's nodes, started by `ray start`).
    pins = cpu_paths_in_effect()
    for name in (*THREAD_VARIABLES, *CPU_PATH_VARIABLES):
        monkeypatch.delenv(name, raising=False)
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
    for name, value in pins.items():
        monkeypatch.setenv(name, value)
    try:
        result = run_sweep(spec, tmp_path, backend="ray", run_fn=failing_run)
        assert {o.run.name for o in result.failed} == {
            "corridor_straight__seed1__noise1.0", "lab_clutter__seed1__noise1.0"}
        resumed = run_sweep(spec, tmp_path, backend="ray", workers=1, run_fn=fake_run)
    finally:
        ray.shutdown()
    assert not resumed.failed
    # --workers 1: one run at a time.
    first, second = sorted(tuple(map(float, (Path(o.run.config.out_dir) / INTERVAL_LOG)
                                     .read_text().split()))
                           for o in resumed.outcomes if not o.skipped)
    assert first[1] <= second[0]
    assert {tuple(o.metrics["run"]["threads"]) for o in resumed.outcomes} == {(1, 1)}
    assert all(o.metrics["run"]["cpu_paths"] == pins for o in resumed.outcomes)
    assert sorted(o.run.name for o in resumed.outcomes if not o.skipped) == sorted(
        o.run.name for o in result.failed)
    plan = plan_sweep(spec, tmp_path)
    assert [calls(r.config.out_dir) for r in plan] == [1, 1, 1, 1]
    check_table(tmp_path, spec, {r.name: "complete" for r in plan})


def test_runs_made_by_another_version_of_the_sweep_file_run_again(tmp_path):
    run_sweep(small_spec(), tmp_path, workers=1, run_fn=fake_run)
    assert all(o.skipped for o in run_sweep(small_spec(), tmp_path, workers=1,
                                            run_fn=fake_run).outcomes)
    for changed in (small_spec(max_frames=4),
                    small_spec(overrides={"sensor.overrides.phase_wrapping": False})):
        assert not any(o.skipped for o in run_sweep(changed, tmp_path, workers=1,
                                                    run_fn=fake_run).outcomes)


def test_a_folder_in_use_by_another_sweep_or_suite_is_refused(tmp_path, capsys):
    from sim.atomic import LOCK_FILE, folder_in_use
    from sim.harness.cli import main

    with folder_in_use(tmp_path):
        assert main(["sweep", str(EXAMPLE_SWEEP), "--out", str(tmp_path)]) == 2
        err = capsys.readouterr().err.strip()
        assert "in use by another egostab command" in err and "\n" not in err
        assert not (tmp_path / "runs").exists()
    assert not (tmp_path / LOCK_FILE).exists()


def test_a_sweep_that_stops_on_an_error_ends_its_own_workers_and_no_other_process(
        tmp_path, monkeypatch):
    # It ended every child process of the caller (multiprocessing.active_children()).
    import multiprocessing

    bystander = multiprocessing.get_context("spawn").Process(target=time.sleep, args=(60,))
    bystander.start()

    def failing_consumer(outcomes, total, progress, label):
        for _ in outcomes:
            raise RuntimeError("the consumer failed")
        yield

    monkeypatch.setattr(sweep_execute, "_with_progress", failing_consumer)
    try:
        with pytest.raises(RuntimeError, match="the consumer failed"):
            run_sweep(small_spec(), tmp_path, workers=2, run_fn=fake_run)
        assert bystander.is_alive()
    finally:
        bystander.terminate()
        bystander.join()
    assert multiprocessing.active_children() == []


def test_a_second_stop_during_the_pools_shutdown_still_waits_for_its_workers():
    # timeout and batch systems signal the process, then its group: the second stop landed in
    # the shutdown, which then never told the workers to end, and the exit waited for them
    # forever (CPython issue 83386).
    class Pool:
        calls = []

        def shutdown(self, wait, cancel_futures):
            signal.raise_signal(signal.SIGTERM)
            time.sleep(0.05)  # a Python handler runs between bytecodes: here, were it not held
            self.calls.append((wait, cancel_futures))

    with sweep_execute.stop_signals_interrupt():
        with pytest.raises(sweep_execute.Interrupted, match="SIGTERM"):  # after the shutdown
            sweep_execute._shut_down(Pool())
    assert Pool.calls == [(True, True)]
