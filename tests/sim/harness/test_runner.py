"""The runner end to end on short real runs: outputs, determinism, policies and faults."""

from __future__ import annotations

import csv
import json
from types import SimpleNamespace

import numpy as np
import pytest

import sim.harness.report
import sim.harness.runner
from scenarios import SCENARIOS_DIR
from sim.harness.runner import ReferencePolicy, RunConfig, frame_count, run, walk_until
from sim.world.sensor.sr4000 import SR4000
from sim.world.walking import RobotSimulation
from tests.sim.harness import plugin_methods

CI_CORRIDOR = str(SCENARIOS_DIR / "ci" / "ci_corridor.toml")
METHODS = ("t2fuzzy", "ecc")


def _rows(run_dir):
    with open(run_dir / "frames.csv", newline="", encoding="utf-8") as handle:
        return list(csv.DictReader(handle))


def _short_run(tmp_path, name="run", record=False, **kwargs):
    """12 frames of the CI corridor walk (its recording is off unless ``record``)."""
    config = dict(scenario=CI_CORRIDOR, out_dir=str(tmp_path / name), methods=METHODS,
                  record=record, max_frames=12,
                  overrides={"recording.enabled": True} if record else {})
    config.update(kwargs)
    return run(RunConfig(**config)), tmp_path / name


def test_the_robot_walks_to_the_control_step_nearest_each_exposure():
    """Steps of 10 ms, each under the command in force when it starts."""
    class Robot:
        control_period_s = 0.01

        def __init__(self):
            self.steps, self.time = 0, 0.0
            self.commanded = []

        def command(self, speed, yaw_rate):
            self.commanded.append((self.steps, speed, yaw_rate))

        def step(self):
            self.steps += 1
            self.time = self.steps * self.control_period_s

    class Scenario:
        @staticmethod
        def command_at(time_s):
            return SimpleNamespace(speed=0.1 if time_s >= 0.02 else 0.0, yaw_rate=0.0)

    robot = Robot()
    for exposure_s, steps in ((0.034, 3), (0.036, 4), (0.04, 4), (0.0449, 4), (0.0451, 5)):
        walk_until(Scenario, robot, exposure_s)
        assert robot.steps == steps, exposure_s
    assert robot.commanded == [(0, 0.0, 0.0), (1, 0.0, 0.0), (2, 0.1, 0.0), (3, 0.1, 0.0),
                               (4, 0.1, 0.0)]


def test_a_run_has_the_frames_of_its_duration_at_most_max_frames():
    scenario = SimpleNamespace(duration_s=2.01, sensor=SimpleNamespace(fps=30.0))
    assert [frame_count(scenario, most) for most in (None, 1, 60, 100)] == [60, 1, 60, 60]
    for most in (0, -1):
        with pytest.raises(ValueError, match="max_frames must be >= 1 or None"):
            frame_count(scenario, most)


def test_run_writes_every_output_and_they_agree(tmp_path):
    metrics, run_dir = _short_run(tmp_path, record=True)
    assert metrics["status"] == "complete"
    assert (run_dir / "failures.jsonl").is_file()
    for name in ("frames.csv", "metrics.json", "summary.md", "recording.rrd",
                 "error_histograms.png", "estimates_t2fuzzy.png", "estimates_ecc.png"):
        assert (run_dir / name).stat().st_size > 0, name
    assert not list(run_dir.glob(".*.tmp")), "temporary files left behind"
    rows = _rows(run_dir)
    assert len(rows) == 12 * len(METHODS)
    assert {row["method"] for row in rows} == set(METHODS)
    on_disk = json.loads((run_dir / "metrics.json").read_text())
    assert on_disk["status"] == "complete" and on_disk["run"]["frames_done"] == 12
    assert on_disk["scenario"]["name"] == "ci_corridor"
    assert "Rotation displacement" in (run_dir / "summary.md").read_text()
    assert "`recording.rrd`" in (run_dir / "summary.md").read_text()  # listed, to open
    # The truth of the reference frame itself is the identity.
    first = next(row for row in rows if row["frame_index"] == "0")
    assert first["reference_index"] == "0"
    assert abs(float(first["true_angle_deg"])) < 1e-9 and abs(float(first["true_dx_px"])) < 1e-9


def test_a_run_told_not_to_record_does_not_whatever_the_scenario_allows(tmp_path):
    _, run_dir = _short_run(tmp_path, methods=("ecc",), max_frames=3,
                            overrides={"recording.enabled": True})
    assert not (run_dir / "recording.rrd").exists()
    assert "`recording.rrd`" not in (run_dir / "summary.md").read_text()


def test_each_failed_estimate_keeps_its_diagnostics_in_failures_jsonl(tmp_path):
    helpers = "tests.sim.harness.plugin_methods"
    methods = ("ecc", f"{helpers}:raising", f"{helpers}:fixed_tuple",
               f"{helpers}:unwritable_failure")
    folders = [_short_run(tmp_path, f"w{workers}", methods=methods, max_frames=3,
                          workers=workers)[1] for workers in (1, 2)]
    lines = (folders[0] / "failures.jsonl").read_text().splitlines()
    assert (folders[1] / "failures.jsonl").read_text().splitlines() == lines
    failures = [json.loads(line) for line in lines]
    failed_rows = [(int(row["frame_index"]), row["method"], row["status"])
                   for row in _rows(folders[0]) if row["status"] != "ok"]
    assert [(f["frame_index"], f["method"], f["status"]) for f in failures] == failed_rows
    raised = [f for f in failures if f["method"] == methods[1]]
    assert len(raised) == 3 and all(
        f["status"] == "exception:ValueError"
        and f["diagnostics"]["message"] == "this method always fails" for f in raised)
    # The reference frame scored against itself: the fixed motion is not the identity.
    rejected = next(f for f in failures if f["method"] == methods[2])
    assert rejected["frame_index"] == 0 and rejected["status"] == "unverified"
    assert rejected["diagnostics"]["unverified_motion"] == list(plugin_methods.FIXED)
    # Text UTF-8 cannot take is written escaped, an integer JSON cannot take is named.
    unwritable = [f for f in failures if f["method"] == methods[3]]
    assert len(unwritable) == 3 and {f["status"] for f in unwritable} == {"bad\\ud800name"}
    assert unwritable[0]["diagnostics"] == {"path": "\\udcff.png", "count": 3,
                                            "dropped_diagnostics": ["big"]}
    listed = json.loads((folders[0] / "metrics.json").read_text())["files"]
    assert listed["failed estimates' diagnostics"] == "failures.jsonl"


def test_same_scenario_and_seed_give_identical_results(tmp_path):
    _, first = _short_run(tmp_path, "first")
    _, second = _short_run(tmp_path, "second")
    strip = lambda rows: [{k: v for k, v in row.items() if k != "ms"} for row in rows]  # noqa: E731
    assert strip(_rows(first)) == strip(_rows(second))
    _, third = _short_run(tmp_path, "other_seed", seed=1)
    assert strip(_rows(third)) != strip(_rows(first))


@pytest.mark.parametrize("policy", ["previous", "first"])
def test_reference_policies(tmp_path, policy):
    _, run_dir = _short_run(tmp_path, policy, methods=("ecc",),
                            overrides={"evaluation.reference": policy})
    references = [int(row["reference_index"]) for row in _rows(run_dir)]
    if policy == "first":
        assert set(references) == {0}
    else:
        assert references == [0] + list(range(11))


def test_interrupt_ends_cleanly_with_complete_files(tmp_path, interrupt_ground_truth):
    interrupt_ground_truth(6)
    metrics, run_dir = _short_run(tmp_path, record=True)
    assert metrics["status"] == "interrupted"
    assert "interrupted" in metrics["run"]["message"]
    assert len(_rows(run_dir)) == 5 * len(METHODS)
    assert json.loads((run_dir / "metrics.json").read_text())["status"] == "interrupted"
    assert (run_dir / "recording.rrd").stat().st_size > 0
    assert not list(run_dir.glob(".*.tmp"))


def test_a_second_interrupt_during_the_final_write_leaves_the_folder_saying_incomplete(
        tmp_path, monkeypatch, interrupt_ground_truth):
    real_write = sim.harness.report.write_run_outputs

    def interrupted_again_in_the_final_write(run_dir, **kwargs):
        if kwargs["plots"]:
            raise KeyboardInterrupt
        return real_write(run_dir, **kwargs)

    interrupt_ground_truth(4)
    monkeypatch.setattr(sim.harness.report, "write_run_outputs",
                        interrupted_again_in_the_final_write)
    with pytest.raises(KeyboardInterrupt):
        _short_run(tmp_path, record=True)
    run_dir = tmp_path / "run"
    assert json.loads((run_dir / "metrics.json").read_text())["status"] == "incomplete"
    assert (run_dir / "recording.rrd").stat().st_size > 0
    assert not list(run_dir.glob(".*.tmp"))


@pytest.mark.parametrize("interval_s, checkpoints", [(0.0, list(range(1, 13))), (1e9, [])])
def test_checkpoints_are_written_every_checkpoint_seconds(tmp_path, monkeypatch, interval_s,
                                                          checkpoints):
    """A checkpoint after each frame that ends CHECKPOINT_S or more after the last write (the
    start's); none in a run shorter than that."""
    written = []
    real_write = sim.harness.report.write_run_outputs

    def spy(run_dir, **kwargs):
        written.append((kwargs["status"], len(kwargs["records"]), kwargs["plots"]))
        return real_write(run_dir, **kwargs)

    monkeypatch.setattr(sim.harness.runner, "CHECKPOINT_S", interval_s)
    monkeypatch.setattr(sim.harness.report, "write_run_outputs", spy)
    metrics, _ = _short_run(tmp_path, methods=("ecc",))
    assert written == ([("incomplete", 0, False)]
                       + [("incomplete", frames, False) for frames in checkpoints]
                       + [("complete", 12, True)])
    assert metrics["run"]["frames_done"] == 12


def test_a_pushed_robot_falls_and_the_run_says_so(tmp_path, monkeypatch):
    real_step = RobotSimulation.step

    def shove(self):  # a real push: 40 N sideways on the torso from 0.3 s on
        if self.time > 0.3:
            torso = self.model.body("humanoid/torso").id
            self.data.xfrc_applied[torso, 1] = 40.0
        real_step(self)

    monkeypatch.setattr(RobotSimulation, "step", shove)
    metrics, run_dir = _short_run(tmp_path, methods=("ecc",), max_frames=90)
    assert metrics["status"] == "fell"
    assert metrics["run"]["fall"]["reason"]
    assert "fell" in metrics["run"]["message"]
    frames_done = metrics["run"]["frames_done"]
    assert 0 < frames_done < 90
    assert len(_rows(run_dir)) == frames_done


def test_sensor_dropouts_are_reported_not_fatal(tmp_path, monkeypatch):
    real_read = SR4000.read_frame

    def drop_every_third(self, index):
        frame = real_read(self, index)
        if index % 3 == 2:
            blank = np.zeros_like(frame.disparity8)
            frame = type(frame)(frame.index, frame.time_s, np.zeros_like(frame.depth_m),
                                np.zeros_like(frame.valid), blank, frame.cam_pos,
                                frame.cam_mat, frame.true_depth_m)
        return frame

    monkeypatch.setattr(SR4000, "read_frame", drop_every_third)
    metrics, run_dir = _short_run(tmp_path)
    assert metrics["status"] == "complete"
    rows = _rows(run_dir)
    dropped = [row for row in rows if int(row["frame_index"]) % 3 == 2]
    assert dropped and all(row["status"] != "ok" for row in dropped)
    assert not any(row["status"].startswith("exception") for row in rows)
    for method in METHODS:
        assert metrics["summary"]["run"][method]["n_failed"] >= len(dropped) // len(METHODS)



@pytest.mark.parametrize("name", [path.stem for path in sorted(SCENARIOS_DIR.glob("*.toml"))])
def test_robot_walks_each_shipped_scenario_without_touching_anything(name):
    """The whole command timeline under physics (no rendering): no fall and no body other
    than the feet touching the scene (a wall, a desk, a stair), which FallDetector reports;
    without a push, no disturbance detected either (the walk follows its plan)."""
    from sim.harness.runner import scenario_robot, walk_until
    from sim.harness.scenario import load_scenario

    scenario = load_scenario(name)
    robot = scenario_robot(scenario)
    start = robot.torso_pose()[0]
    walk_until(scenario, robot, scenario.duration_s)  # a fall is recorded, never raised
    assert robot.fall is None, robot.fall
    assert np.linalg.norm(robot.torso_pose()[0][:2] - start[:2]) > 1.0  # it really walked
    # Pushed, the robot catches itself with a step (the pushes are large enough for one).
    detected = robot.controller.step_adjustment.disturbed_at_s
    assert (detected is None) == (not scenario.pushes), detected


def test_scene_params_of_a_scenario_shape_the_walked_scene():
    from sim.harness.runner import scenario_robot
    from sim.harness.scenario import load_scenario

    default = scenario_robot(load_scenario(CI_CORRIDOR))
    wide = scenario_robot(load_scenario(CI_CORRIDOR,
                                        {"scene_params.half_width_m": [1.2, 1.2]}))

    def walls_at_1_2_m(model):  # the corridor's side walls run at y = +-half_width_m
        return sum(abs(abs(model.body(i).pos[1]) - 1.2) < 1e-9 for i in range(model.nbody)
                   if model.body(i).name.startswith("wall"))

    assert walls_at_1_2_m(wide.model) >= 2 and walls_at_1_2_m(default.model) == 0


@pytest.mark.parametrize("policy, references", [
    ("cycle_start", [0, 0, 0, 3, 3, 3, 3, 7, 7, 7]),
    ("previous", [0, 0, 1, 2, 3, 4, 5, 6, 7, 8]),
    ("first", [0] * 10)])
def test_each_policy_gives_the_references_docs_design_names(policy, references):
    cycles = [0, 0, 0, 1, 1, 1, 1, 2, 2, 2]
    chooser = ReferencePolicy(policy)
    assert [chooser.reference_for(frame, cycle) for frame, cycle in enumerate(cycles)] == references
