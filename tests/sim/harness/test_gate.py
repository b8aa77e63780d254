"""The regression gate's comparison, exit codes and baseline file (the CI runs it for real)."""

from __future__ import annotations

import json

import pytest

import sim.harness.gate as gate

BASE = {"ci_a": {"t2fuzzy": {"rotation_mean_deg": 0.40, "x_mean_px": 0.60, "y_mean_px": 0.40,
                             "failure_rate": 0.0}}}


def _with(**changes):
    figures = dict(BASE["ci_a"]["t2fuzzy"], **changes)
    return {"ci_a": {"t2fuzzy": figures}}


def test_same_figures_pass():
    rows = gate.compare(BASE, BASE)
    assert len(rows) == 4 and {row["verdict"] for row in rows} == {"ok"}


def test_within_tolerance_passes_and_beyond_fails():
    limit = 0.40 * (1 + gate.REL_TOLERANCE) + gate.ABS_TOLERANCE["rotation_mean_deg"]
    assert all(row["verdict"] == "ok"
               for row in gate.compare(_with(rotation_mean_deg=limit - 1e-6), BASE))
    verdicts = {row["metric"]: row["verdict"]
                for row in gate.compare(_with(rotation_mean_deg=limit + 1e-6), BASE)}
    assert verdicts["rotation_mean_deg"] == "REGRESSED"


def test_improvement_is_reported_not_failed():
    verdicts = {row["metric"]: row["verdict"] for row in gate.compare(_with(x_mean_px=0.2), BASE)}
    assert verdicts["x_mean_px"] == "improved"


def test_a_lost_estimate_or_scenario_is_a_regression():
    assert any(row["verdict"] == "REGRESSED (no value)"
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
    monkeypatch.setattr(gate, "expected_coverage", lambda: {"ci_a": ("t2fuzzy",)})
    monkeypatch.setattr(gate, "run_ci_scenarios", lambda out_dir: BASE)
    assert gate.run_gate(path, update=True) == 0
    document = json.loads(path.read_text())
    assert document["format"] == gate.BASELINE_FORMAT and document["scenarios"] == BASE
    assert gate.run_gate(path) == 0
    assert "gate passed" in capsys.readouterr().out
    monkeypatch.setattr(gate, "run_ci_scenarios", lambda out_dir: _with(failure_rate=0.5))
    assert gate.run_gate(path) == 1
    out = capsys.readouterr().out
    assert "REGRESSION" in out and "failure_rate" in out


def test_an_incomplete_run_cannot_be_gated():
    metrics = {"status": "fell", "scenario": {"name": "ci_a"}, "run": {"message": "fell at 1 s"},
               "summary": {"run": {}}}
    with pytest.raises(ValueError, match="did not complete"):
        gate.gate_metrics(metrics)


def _must_not_run(out_dir):
    raise AssertionError("the CI scenarios ran before the baseline was checked")


@pytest.mark.parametrize("text, message", [
    ("", "not valid JSON"),
    ('{"format": "egostab-baseline/1", "scenarios": {"ci_a"', "not valid JSON"),
    ("[]", "not a baseline of format"),
    ('{"format": "egostab-baseline/1"}', "'scenarios' must be a non-empty object"),
    ('{"format": "egostab-baseline/1", "scenarios": {}}', "'scenarios' must be a non-empty"),
    ('{"format": "egostab-baseline/1", "scenarios": {"ci_a": {}}}', "scenarios.ci_a must be"),
    ('{"format": "egostab-baseline/1", "scenarios": {"ci_a": {"t2fuzzy": {"x_mean_px": 1}}}}',
     "must hold exactly the metrics"),
])
def test_a_malformed_baseline_is_refused_by_name_before_anything_runs(tmp_path, monkeypatch,
                                                                       text, message):
    path = tmp_path / "baseline.json"
    path.write_text(text)
    monkeypatch.setattr(gate, "run_ci_scenarios", _must_not_run)
    with pytest.raises(ValueError, match=message) as raised:
        gate.run_gate(path)
    assert str(path) in str(raised.value)


def test_a_value_of_the_wrong_type_is_named(tmp_path, monkeypatch):
    path = tmp_path / "baseline.json"
    figures = dict(BASE["ci_a"]["t2fuzzy"], y_mean_px="0.4")
    path.write_text(json.dumps({"format": gate.BASELINE_FORMAT,
                                "scenarios": {"ci_a": {"t2fuzzy": figures}}}))
    monkeypatch.setattr(gate, "run_ci_scenarios", _must_not_run)
    with pytest.raises(ValueError, match=r"scenarios\.ci_a\.t2fuzzy\.y_mean_px is '0.4'"):
        gate.run_gate(path)


@pytest.mark.parametrize("expected, problem", [
    ({"ci_a": ("t2fuzzy",), "ci_b": ("t2fuzzy",)}, "lacks scenario ci_b"),
    ({"ci_b": ("t2fuzzy",)}, "has scenario ci_a"),
    ({"ci_a": ("t2fuzzy", "ecc")}, "lacks method ecc of scenario ci_a"),
    ({"ci_a": ("ecc",)}, "has method t2fuzzy of scenario ci_a"),
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
