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
    assert gate.compare({}, BASE)[0]["verdict"] == "REGRESSED (not run)"


def test_run_gate_exit_codes_and_baseline_update(tmp_path, monkeypatch, capsys):
    path = tmp_path / "baseline.json"
    with pytest.raises(ValueError, match="--update-baseline"):
        gate.run_gate(path)
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
