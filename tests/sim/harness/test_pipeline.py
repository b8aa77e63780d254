"""`egostab run --workers N` (sim.harness.pipeline): the estimates made ahead in worker processes
give the figures and the recording of one process; an interrupt still leaves complete files and
no worker behind."""

from __future__ import annotations

import json
import multiprocessing
import subprocess
import sys
from pathlib import Path

import pytest

from sim.harness.methods import MethodError
from sim.harness.runner import RunConfig, run
from tests.sim.harness.test_recording import _rows_per_entity
from tests.sim.harness.test_score import CI_CORRIDOR, _rows, _same_rows, _same_summary, _summary

METHODS = ("t2fuzzy", "ecc")
N_FRAMES = 12


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    root = tmp_path_factory.mktemp("pipeline")
    for workers in (1, 2):
        run(RunConfig(scenario=CI_CORRIDOR, out_dir=str(root / f"w{workers}"), methods=METHODS,
                      max_frames=N_FRAMES, workers=workers,
                      overrides={"recording.enabled": True, "recording.frame_stride": 1}))
    return root


def test_two_workers_give_the_figures_of_one(runs):
    _same_rows(_rows(runs / "w1"), _rows(runs / "w2"))
    _same_summary(_summary(runs / "w1"), _summary(runs / "w2"))
    metrics = json.loads((runs / "w2" / "metrics.json").read_text())
    assert metrics["status"] == "complete" and metrics["run"]["frames_done"] == N_FRAMES
    assert metrics["run"]["workers"] == 2
    assert sorted(path.name for path in (runs / "w1").glob("*.png")) == \
        sorted(path.name for path in (runs / "w2").glob("*.png"))


def test_two_workers_record_what_one_process_records(runs):
    # The segmentation of the paper's method comes back from the workers with the estimates.
    one, two = (_rows_per_entity(runs / name / "recording.rrd") for name in ("w1", "w2"))
    assert one == two
    assert any("segmentation" in entity or "labels" in entity for entity in two)


def test_an_interrupted_run_with_workers_leaves_complete_files_and_no_worker(
        tmp_path, interrupt_ground_truth):
    interrupt_ground_truth(6)
    metrics = run(RunConfig(scenario=CI_CORRIDOR, out_dir=str(tmp_path), methods=METHODS,
                            max_frames=N_FRAMES, workers=2, record=False))
    assert metrics["status"] == "interrupted"
    assert len(_rows(tmp_path)) == 5 * len(METHODS)
    assert json.loads((tmp_path / "metrics.json").read_text())["status"] == "interrupted"
    assert not list(tmp_path.glob(".*.tmp"))
    assert multiprocessing.active_children() == []


def test_a_method_that_cannot_be_loaded_is_refused_before_any_work(tmp_path):
    with pytest.raises(MethodError, match="nosuch"):
        run(RunConfig(scenario=CI_CORRIDOR, out_dir=str(tmp_path / "run"), methods=("nosuch",),
                      workers=2))
    assert not (tmp_path / "run").exists()


def test_by_default_a_run_of_one_method_estimates_in_its_own_process(tmp_path):
    metrics = run(RunConfig(scenario=CI_CORRIDOR, out_dir=str(tmp_path / "run"),
                            methods=("t2fuzzy",), max_frames=2, record=False, workers=None))
    assert metrics["run"]["workers"] == 1


@pytest.mark.parametrize("cores", [1, 3])
def test_by_default_a_run_of_several_methods_uses_a_worker_per_method_and_core(
        tmp_path, monkeypatch, cores):
    import os

    monkeypatch.setattr(os, "sched_getaffinity", lambda pid: set(range(cores)), raising=False)
    metrics = run(RunConfig(scenario=CI_CORRIDOR, out_dir=str(tmp_path / "run"),
                            methods=METHODS, max_frames=2, record=False, workers=None))
    assert metrics["run"]["workers"] == min(cores, len(METHODS))


@pytest.mark.parametrize("workers", [0, -1, True, 1.5])
def test_a_bad_worker_count_is_refused_before_any_work(tmp_path, workers):
    with pytest.raises(ValueError, match=r"workers \S+: accepted: an integer from 1 to \d+"):
        run(RunConfig(scenario=CI_CORRIDOR, out_dir=str(tmp_path / "run"), workers=workers))
    assert not (tmp_path / "run").exists()


def test_a_method_that_ends_its_worker_process_ends_the_run_with_an_error_not_a_hang(tmp_path):
    out = tmp_path / "out"
    done = subprocess.run(
        [sys.executable, "-m", "sim.harness.cli", "run", CI_CORRIDOR, "--methods",
         "tests.sim.harness.plugin_methods:ends_its_process,ecc", "--workers", "2",
         "--max-frames", str(N_FRAMES), "--no-record", "--quiet", "--out", str(out)],
        cwd=Path(__file__).resolve().parents[3], capture_output=True, text=True, timeout=240)
    assert done.returncode == 1, done.stderr
    assert done.stderr.splitlines()[-1].startswith(
        "egostab run: error: a worker process died while estimating")
    assert json.loads((out / "metrics.json").read_text())["status"] == "error"
