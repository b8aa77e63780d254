"""The regression gate's comparison, exit codes and baseline file (the CI runs it for real)."""

from __future__ import annotations

import csv
import dataclasses
import json

import pytest

import sim.harness.gate as gate

TRUTH_FIGURES = {"angle_mean_deg": 1.5, "dx_mean_px": -4.0, "dy_mean_px": 2.0,
                 "failed_frames": 0}
BASE = {"ci_a": {"t2fuzzy": {"rotation_mean_deg": 0.40, "x_mean_px": 0.60, "y_mean_px": 0.40,
                             "rotation_bias_deg": -0.10, "x_bias_px": 0.20, "y_bias_px": 0.0,
                             "failed_frames": 3, "large_error_frames": 1},
                 gate.TRUTH: TRUTH_FIGURES}}


def _with(entry="t2fuzzy", **changes):
    figures = dict(BASE["ci_a"][entry], **changes)
    return {"ci_a": {**BASE["ci_a"], entry: figures}}


def _verdicts(current):
    return {(row["method"], row["metric"]): row["verdict"] for row in gate.compare(current, BASE)}


def test_same_figures_pass():
    rows = gate.compare(BASE, BASE)
    assert len(rows) == 12 and {row["verdict"] for row in rows} == {gate.WITHIN}


@pytest.mark.parametrize("metric, worse, better", [
    ("rotation_mean_deg", 0.40 + 1, 0.40 - 1), ("x_mean_px", 0.60 + 1, 0.60 - 1),
    ("failed_frames", 3 + 1, 3 - 1), ("large_error_frames", 1 + 1, 1 - 1),
    ("x_bias_px", 0.20 + 1, 0.20 - 1),          # further from 0, or nearer
    ("rotation_bias_deg", -0.10 - 1, -0.10 + 1),
])
def test_a_figure_moved_beyond_its_tolerance_fails_either_way(metric, worse, better):
    tolerance = gate.METHOD_TOLERANCES[metric]
    for step, expected in ((worse, gate.WORSE), (better, gate.BETTER)):
        base = BASE["ci_a"]["t2fuzzy"][metric]
        within = base + (step - base) * tolerance * 0.99  # the step scaled inside the tolerance
        assert _verdicts(_with(**{metric: within}))[("t2fuzzy", metric)] == gate.WITHIN
        # A count of frames has tolerance 0: one frame more or fewer is beyond it.
        beyond = base + (step - base) * (tolerance * 1.01 if tolerance else 1.0)
        assert _verdicts(_with(**{metric: beyond}))[("t2fuzzy", metric)] == expected


def test_a_bias_that_crosses_zero_is_judged_by_its_size():
    assert _verdicts(_with(x_bias_px=-0.24))[("t2fuzzy", "x_bias_px")] == gate.WORSE
    assert _verdicts(_with(x_bias_px=0.12))[("t2fuzzy", "x_bias_px")] == gate.BETTER


def test_a_bias_that_only_changed_sign_is_a_change_not_an_improvement():
    assert _verdicts(_with(x_bias_px=-0.20))[("t2fuzzy", "x_bias_px")] == gate.MOVED


def test_a_moved_ground_truth_fails_without_a_direction():
    for metric in ("dy_mean_px", "failed_frames"):
        moved = TRUTH_FIGURES[metric] + 3 * gate.TRUTH_TOLERANCES[metric]
        assert _verdicts(_with(gate.TRUTH, **{metric: moved}))[(gate.TRUTH, metric)] == gate.MOVED


def test_the_gate_sees_a_constant_offset_that_lowers_a_mean_absolute_error():
    # Errors leaning one way: an offset the other way lowers the mean absolute error.
    errors = [-0.6, -0.5, -0.7, -0.4]
    offset = [error + 0.4 for error in errors]
    means = [sum(abs(e) for e in values) / 4 for values in (errors, offset)]
    biases = [sum(values) / 4 for values in (errors, offset)]
    assert means[1] < means[0]
    current = _with(x_mean_px=means[1], x_bias_px=biases[1])
    baseline = _with(x_mean_px=means[0], x_bias_px=biases[0])
    verdicts = {(row["method"], row["metric"]): row["verdict"]
                for row in gate.compare(current, baseline)}
    assert verdicts[("t2fuzzy", "x_mean_px")] != gate.WORSE
    assert verdicts[("t2fuzzy", "x_bias_px")] == gate.BETTER  # nearer 0, and it fails the gate


def test_a_lost_estimate_or_scenario_is_a_regression():
    assert any(row["verdict"] == gate.NO_VALUE
               for row in gate.compare(_with(y_mean_px=float("nan")), BASE))
    assert gate.compare({}, BASE)[0]["verdict"] == gate.NOT_RUN


def test_a_baseline_that_lacks_or_keeps_a_method_fails():
    both = {"ci_a": {**BASE["ci_a"], "sift": BASE["ci_a"]["t2fuzzy"]}}
    new_method = {row["verdict"] for row in gate.compare(both, BASE) if row["method"] == "sift"}
    assert new_method == {gate.NOT_IN_BASELINE}
    dropped = [row for row in gate.compare(BASE, both) if row["method"] == "sift"]
    assert [row["verdict"] for row in dropped] == [gate.NOT_RUN]


def test_run_gate_exit_codes_and_baseline_update(tmp_path, monkeypatch, capsys):
    path = tmp_path / "baseline.json"
    with pytest.raises(ValueError, match="--update-baseline"):
        gate.run_gate(path)
    monkeypatch.setattr(gate, "expected_coverage", lambda: {"ci_a": ("t2fuzzy", gate.TRUTH)})
    monkeypatch.setattr(gate, "run_ci_scenarios", lambda out_dir: (BASE, {}))
    assert gate.run_gate(path, update=True) == 0
    document = json.loads(path.read_text())
    assert document["format"] == gate.BASELINE_FORMAT and document["scenarios"] == BASE
    assert gate.run_gate(path) == 0
    assert "gate passed" in capsys.readouterr().out
    monkeypatch.setattr(gate, "run_ci_scenarios", lambda out_dir: (_with(failed_frames=9), {}))
    assert gate.run_gate(path) == 1
    out = capsys.readouterr().out
    assert "gate failed: 1 figure(s)" in out
    assert "| failed_frames | 3.0000 | 9.0000 | +6.0000 |" in out
    monkeypatch.setattr(gate, "run_ci_scenarios", lambda out_dir: (_with(failed_frames=0), {}))
    assert gate.run_gate(path) == 1
    assert "(0 worse, 1 better" in capsys.readouterr().out


def test_a_failed_gate_counts_its_moved_figures_by_direction(tmp_path, monkeypatch, capsys):
    path = tmp_path / "baseline.json"
    monkeypatch.setattr(gate, "expected_coverage", lambda: {"ci_a": ("t2fuzzy", gate.TRUTH)})
    monkeypatch.setattr(gate, "run_ci_scenarios", lambda out_dir: (BASE, {}))
    assert gate.run_gate(path, update=True) == 0
    current = _with(failed_frames=9, x_mean_px=0.0)  # one worse, one better
    current["ci_a"][gate.TRUTH] = dict(TRUTH_FIGURES, dy_mean_px=5.0)  # moved, no direction
    monkeypatch.setattr(gate, "run_ci_scenarios", lambda out_dir: (current, {}))
    assert gate.run_gate(path) == 1
    assert "3 figure(s) moved" in (out := capsys.readouterr().out)
    assert "(1 worse, 1 better, 1 changed without a better way" in out


def test_an_incomplete_run_cannot_be_gated():
    metrics = {"status": "fell", "scenario": {"name": "ci_a"}, "run": {"message": "fell at 1 s"},
               "summary": {"run": {}}}
    with pytest.raises(gate.RunNotComplete, match=r"^fell \(fell at 1 s\)$"):
        gate.gate_metrics(metrics, [])


def test_a_ci_run_that_falls_fails_the_gate_as_a_regression_not_as_bad_input(tmp_path,
                                                                            monkeypatch,
                                                                            capsys):
    path = tmp_path / "baseline.json"
    monkeypatch.setattr(gate, "expected_coverage", lambda: {"ci_a": ("t2fuzzy", gate.TRUTH)})
    monkeypatch.setattr(gate, "run_ci_scenarios", lambda out_dir: (BASE, {}))
    assert gate.run_gate(path, update=True) == 0
    written = path.read_bytes()
    fell = "fell (the robot fell at 0.41 s (torso_tilt))"
    monkeypatch.setattr(gate, "run_ci_scenarios", lambda out_dir: ({}, {"ci_a": fell}))
    assert gate.run_gate(path) == 1
    out = capsys.readouterr().out
    assert out.rstrip().endswith(f"gate failed: CI run(s) did not complete: ci_a {fell}")
    assert gate.NOT_RUN in out
    assert gate.run_gate(path, update=True) == 1
    assert capsys.readouterr().out.strip() == (
        f"baseline not written: CI run(s) did not complete: ci_a {fell}")
    assert path.read_bytes() == written


@pytest.mark.parametrize("message, signal_name", [
    ("interrupted by SIGTERM", "SIGTERM"), ("interrupted by the user (Ctrl-C)", None)])
def test_a_stopped_run_stops_the_gate_as_a_stop_not_as_bad_input(message, signal_name):
    metrics = {"status": "interrupted", "scenario": {"name": "ci_a"},
               "run": {"message": message}, "summary": {"run": {}}}
    with pytest.raises(KeyboardInterrupt) as stop:  # the CLI: one line, exit status 130
        gate.gate_metrics(metrics, [])
    assert getattr(stop.value, "signal_name", None) == signal_name


def test_the_figures_of_a_run_come_from_its_metrics_and_frames():
    def row(frame, status, est, true, truth_status="ok"):
        return {"frame_index": str(frame), "method": "ecc", "status": status,
                "truth_status": truth_status,
                **{f"est_{k}": str(v) for k, v in zip(("angle_deg", "dx_px", "dy_px"), est)},
                **{f"true_{k}": str(v) for k, v in zip(("angle_deg", "dx_px", "dy_px"), true)}}

    rows = [row(0, "ok", (179.0, 1.0, 2.0), (-179.0, 0.5, 2.5)),   # 2 degrees, wrapped
            row(1, "ok", (1.0, -1.0, 0.0), (0.0, -0.5, 0.5)),
            row(2, "lost_track", ("nan",) * 3, (0.0, 0.0, 1.0)),
            row(3, "ok", (0.0, 0.0, 0.0), ("nan",) * 3, truth_status="no_overlap")]
    errors = {axis: {"mean": 0.1} for axis in ("rotation", "x", "y")}
    metrics = {"status": "complete", "summary": {"run": {"ecc": {"errors": errors,
                                                                 "n_failed": 1,
                                                                 "n_large_errors": 0}}}}
    figures = gate.gate_metrics(metrics, rows)
    assert figures["ecc"] == pytest.approx({
        "rotation_mean_deg": 0.1, "x_mean_px": 0.1, "y_mean_px": 0.1,
        "rotation_bias_deg": -0.5, "x_bias_px": 0.0, "y_bias_px": -0.5, "failed_frames": 1,
        "large_error_frames": 0})
    assert figures[gate.TRUTH] == pytest.approx({
        "angle_mean_deg": -179.0 / 3, "dx_mean_px": 0.0, "dy_mean_px": 4.0 / 3,
        "failed_frames": 1})


def _must_not_run(out_dir):
    raise AssertionError("the CI scenarios ran before the baseline was checked")


@pytest.mark.parametrize("text, message", [
    ("", "not valid JSON"),
    ('{"format": "egostab-baseline/3", "scenarios": {"ci_a"', "not valid JSON"),
    ("[]", "not a baseline of format"),
    ('{"format": "egostab-baseline/3"}', "'scenarios' must be a non-empty object"),
    ('{"format": "egostab-baseline/3", "scenarios": {}}', "'scenarios' must be a non-empty"),
    ('{"format": "egostab-baseline/3", "scenarios": {"ci_a": {}}}', "scenarios.ci_a must be"),
    ('{"format": "egostab-baseline/3", "scenarios": {"ci_a": {"t2fuzzy": {"x_mean_px": 1}}}}',
     "must hold exactly the figures"),
    ('{"format": "egostab-baseline/2", "scenarios": {"ci_a": {}}}', "--update-baseline"),
])
def test_a_malformed_baseline_is_refused_by_name_before_anything_runs(tmp_path, monkeypatch,
                                                                       text, message):
    path = tmp_path / "baseline.json"
    path.write_text(text)
    monkeypatch.setattr(gate, "run_ci_scenarios", _must_not_run)
    with pytest.raises(ValueError, match=message) as raised:
        gate.run_gate(path)
    assert str(path) in str(raised.value)


@pytest.mark.parametrize("value, shown", [
    ("0.4", "'0.4'"), (10**400, "1" + "0" * 39 + "..."), (float("inf"), "inf")])
def test_a_value_of_the_wrong_type_is_named(tmp_path, monkeypatch, value, shown):
    # A number beyond the float range passed and crashed the comparison after the runs.
    path = tmp_path / "baseline.json"
    figures = dict(BASE["ci_a"]["t2fuzzy"], y_mean_px=value)
    path.write_text(json.dumps({"format": gate.BASELINE_FORMAT,
                                "scenarios": {"ci_a": {"t2fuzzy": figures}}}))
    monkeypatch.setattr(gate, "run_ci_scenarios", _must_not_run)
    with pytest.raises(ValueError) as raised:
        gate.run_gate(path)
    assert f"scenarios.ci_a.t2fuzzy.y_mean_px is {shown}; accepted: a number" in str(
        raised.value)


def test_a_baseline_whose_tolerances_were_edited_is_refused(tmp_path, monkeypatch):
    # They are the gate's: an edit in the baseline was silently ignored.
    path = tmp_path / "baseline.json"
    monkeypatch.setattr(gate, "expected_coverage", lambda: {"ci_a": ("t2fuzzy", gate.TRUTH)})
    monkeypatch.setattr(gate, "run_ci_scenarios", lambda out_dir: (BASE, {}))
    assert gate.run_gate(path, update=True) == 0
    document = json.loads(path.read_text())
    document["tolerances"]["methods"]["x_mean_px"] = 1.0
    path.write_text(json.dumps(document))
    monkeypatch.setattr(gate, "run_ci_scenarios", _must_not_run)
    with pytest.raises(ValueError, match="'tolerances' are not the ones the gate applies"):
        gate.run_gate(path)


def test_a_number_json_cannot_read_is_named_as_not_valid_json(tmp_path, monkeypatch):
    path = tmp_path / "baseline.json"
    path.write_text('{"format": "egostab-baseline/3", "scenarios": {"ci_a": ' + "9" * 5000 + "}}")
    monkeypatch.setattr(gate, "run_ci_scenarios", _must_not_run)
    with pytest.raises(ValueError, match="not valid JSON"):
        gate.run_gate(path)


@pytest.mark.parametrize("expected, problem", [
    ({"ci_a": ("t2fuzzy", gate.TRUTH), "ci_b": ("t2fuzzy", gate.TRUTH)}, "lacks scenario ci_b"),
    ({"ci_b": ("t2fuzzy", gate.TRUTH)}, "has scenario ci_a"),
    ({"ci_a": ("t2fuzzy", "ecc", gate.TRUTH)}, "lacks method ecc of scenario ci_a"),
    ({"ci_a": ("ecc", gate.TRUTH)}, "has method t2fuzzy of scenario ci_a"),
])
def test_a_baseline_that_does_not_cover_the_ci_set_fails_before_running(tmp_path, monkeypatch,
                                                                          expected, problem):
    path = tmp_path / "baseline.json"
    gate.write_baseline(path, BASE)
    monkeypatch.setattr(gate, "expected_coverage", lambda: expected)
    monkeypatch.setattr(gate, "run_ci_scenarios", _must_not_run)
    with pytest.raises(ValueError, match=problem):
        gate.run_gate(path)


def test_the_shipped_baseline_covers_the_ci_set_exactly():
    path = gate.SCENARIOS_DIR.parent / "results" / "baseline.json"
    gate.check_coverage(gate.read_baseline(path), gate.expected_coverage(), path)


def test_a_constant_offset_of_one_method_fails_the_gate(tmp_path, monkeypatch):
    # The whole path of a run's figures (metrics.json and frames.csv) on a real CI walk.
    import stabilizer.t2fuzzy
    from sim.harness.runner import RunConfig, run

    def figures(out):
        metrics = run(RunConfig(scenario=str(gate.CI_SCENARIOS_DIR / "ci_corridor.toml"),
                                out_dir=str(out), methods=("t2fuzzy",), record=False,
                                max_frames=60, workers=1, progress=False))
        with open(out / "frames.csv", newline="", encoding="utf-8") as handle:
            return {"ci_corridor": gate.gate_metrics(metrics, list(csv.DictReader(handle)))}

    clean = figures(tmp_path / "clean")
    estimate = stabilizer.t2fuzzy.T2FuzzyEstimator.estimate

    def offset(self, current):
        motion = estimate(self, current)
        return dataclasses.replace(motion, dx=motion.dx + 0.3) if motion.ok else motion

    monkeypatch.setattr(stabilizer.t2fuzzy.T2FuzzyEstimator, "estimate", offset)
    rows = gate.compare(figures(tmp_path / "offset"), clean)
    moved = {row["metric"]: row for row in rows if row["verdict"] != gate.WITHIN}
    assert "x_bias_px" in moved and moved["x_bias_px"]["current"] - moved["x_bias_px"][
        "baseline"] == pytest.approx(0.3, abs=0.05)
    assert not any(row["method"] == gate.TRUTH for row in moved.values())


def test_a_refused_gate_leaves_no_new_folder_and_names_a_folder_given_as_baseline(
        tmp_path, monkeypatch, capsys):
    from sim.harness.cli import main

    monkeypatch.setattr(gate, "run_ci_scenarios", _must_not_run)
    monkeypatch.chdir(tmp_path)
    (tmp_path / "a_file").write_text("")
    assert main(["gate", "--update-baseline", "--baseline", "new/b.json", "--out", "a_file"]) == 2
    assert "--out a_file: exists and is not a folder" in capsys.readouterr().err
    assert not (tmp_path / "new").exists()
    (tmp_path / "a_folder").mkdir()
    assert main(["gate", "--baseline", "a_folder"]) == 2
    assert "is a folder" in capsys.readouterr().err
    with pytest.raises(SystemExit) as exited:  # an unset shell variable: not the folder "."
        main(["gate", "--baseline", ""])
    assert exited.value.code == 2 and "an empty one" in capsys.readouterr().err
