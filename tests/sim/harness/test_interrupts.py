"""SIGTERM and SIGHUP end a job like Ctrl-C: complete files, status "interrupted" and why."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time

import pytest

from scenarios import SCENARIOS_DIR
from sim.harness.interrupts import Interrupted, interrupt_reason, stop_signals_interrupt

CI_CORRIDOR = str(SCENARIOS_DIR / "ci" / "ci_corridor.toml")


def test_a_stop_signal_raises_interrupted_inside_the_block_only():
    previous = signal.getsignal(signal.SIGTERM)
    with stop_signals_interrupt():
        assert interrupt_reason(KeyboardInterrupt()) == "interrupted by the user (Ctrl-C)"
        with pytest.raises(Interrupted) as raised:
            os.kill(os.getpid(), signal.SIGTERM)
            time.sleep(1)  # the handler runs before this returns
    assert isinstance(raised.value, KeyboardInterrupt)
    assert interrupt_reason(raised.value) == "interrupted by SIGTERM"
    assert signal.getsignal(signal.SIGTERM) is previous


def test_a_signal_raised_again_by_a_library_is_still_named():
    # MuJoCo's model compiler re-raises an interrupt in its callbacks with a message of its own,
    # or as a plain KeyboardInterrupt.
    with stop_signals_interrupt():
        with pytest.raises(Interrupted):
            os.kill(os.getpid(), signal.SIGHUP)
            time.sleep(1)
        for again in (Interrupted("Line 47: error while parsing element <default>: SIGHUP"),
                      KeyboardInterrupt()):
            assert interrupt_reason(again) == "interrupted by SIGHUP"


def _wait_for(predicate, timeout_s: float) -> None:
    deadline = time.monotonic() + timeout_s
    while not predicate():
        if time.monotonic() > deadline:
            raise AssertionError("timed out")
        time.sleep(0.1)


@pytest.mark.parametrize("stop", [signal.SIGTERM, signal.SIGHUP])
def test_a_run_stopped_by_a_signal_leaves_complete_files(tmp_path, stop):
    run_dir = tmp_path / "run"
    process = subprocess.Popen(
        [sys.executable, "-m", "sim.harness.cli", "run", "corridor_straight", "--out",
         str(run_dir), "--methods", "ecc", "--quiet"],  # recorded: recording.rrd is written
        env={**os.environ, "OMP_NUM_THREADS": "1"}, stdout=subprocess.PIPE,
        stderr=subprocess.PIPE)
    try:
        _wait_for(lambda: (run_dir / "metrics.json").exists(), 120)  # the run has started
        time.sleep(1.0)
        process.send_signal(stop)
        out, err = process.communicate(timeout=120)
    finally:
        process.kill()
    metrics = json.loads((run_dir / "metrics.json").read_text())
    assert metrics["status"] == "interrupted", err.decode()
    assert metrics["run"]["message"] == f"interrupted by {stop.name}"
    assert process.returncode == 130
    frames = (run_dir / "frames.csv").read_text().splitlines()
    assert len(frames) == 1 + metrics["run"]["frames_done"]
    assert (run_dir / "summary.md").exists() and (run_dir / "recording.rrd").stat().st_size
    assert not list(run_dir.glob(".*.tmp"))


def test_a_sweep_stopped_by_sigterm_stops_its_runs_with_complete_files(tmp_path):
    sweep_file = tmp_path / "two.toml"
    sweep_file.write_text(f"""name = "two"
scenarios = ["{CI_CORRIDOR}"]
seeds = [0, 1]
noise_levels = [1.0]
methods = ["ecc"]
""")
    out = tmp_path / "sweep"
    process = subprocess.Popen(
        [sys.executable, "-m", "sim.harness.cli", "sweep", str(sweep_file), "--out", str(out),
         "--workers", "2"], env={**os.environ, "OMP_NUM_THREADS": "1"},
        stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    try:
        _wait_for(lambda: len(list(out.glob("runs/*/metrics.json"))) == 2, 180)
        time.sleep(1.0)
        process.send_signal(signal.SIGTERM)
        out_text, err = process.communicate(timeout=180)
    finally:
        process.kill()
    assert process.returncode == 130, err.decode()
    assert "interrupted by SIGTERM" in err.decode()
    statuses = [json.loads(path.read_text())["status"]
                for path in out.glob("runs/*/metrics.json")]
    assert statuses and set(statuses) <= {"interrupted", "complete"}, statuses
    assert "interrupted" in statuses
    assert (out / "sweep.md").exists()
    assert not list(out.rglob(".*.tmp"))


def test_a_run_stopped_while_its_recording_opens_ends_interrupted(tmp_path, monkeypatch):
    """The stop comes after metrics.json says "incomplete" and before the first frame, while
    the rerun recording is being set up: the run still ends "interrupted", with no recording
    listed and no temporary file left."""
    from sim.harness.recording import RunRecorder
    from sim.harness.report import RECORDING_NOTE
    from sim.harness.runner import RunConfig, run

    def stopped(self, properties):
        raise Interrupted("SIGTERM")

    monkeypatch.setattr(RunRecorder, "_log_static", stopped)
    run_dir = tmp_path / "run"
    metrics = run(RunConfig(CI_CORRIDOR, str(run_dir), max_frames=2, methods=("ecc",),
                            overrides={"recording.enabled": True}))
    assert metrics["status"] == "interrupted"
    assert metrics["run"]["message"] == "interrupted by SIGTERM"
    assert json.loads((run_dir / "metrics.json").read_text())["status"] == "interrupted"
    assert not (run_dir / "recording.rrd").exists()
    assert RECORDING_NOTE not in (run_dir / "summary.md").read_text()
    assert not list(run_dir.glob(".*.tmp"))
