"""SIGTERM and SIGHUP end a job like Ctrl-C: complete files, status "interrupted" and why;
before and after the job, the egostab process ends on them at once with the same one line."""

from __future__ import annotations

import json
import multiprocessing
import os
import signal
import subprocess
import sys
import threading
import time
import tomllib
from concurrent.futures import ProcessPoolExecutor

import pytest

from scenarios import SCENARIOS_DIR, SUITES_DIR
from sim.harness.interrupts import (Interrupted, children_start_deaf_to_ctrl_c,
                                    interrupt_reason, signal_handlers_kept, stop_signals_interrupt,
                                    stops_held)

CI_CORRIDOR = str(SCENARIOS_DIR / "ci" / "ci_corridor.toml")


@pytest.fixture(autouse=True)
def hangups_not_ignored():
    """SIGHUP at its default for each test and the jobs it starts: under nohup the tests
    inherit it ignored, and a job keeps an ignored SIGHUP ignored (as it should), so the
    tests of SIGHUP ending a job would see nothing."""
    previous = signal.signal(signal.SIGHUP, signal.SIG_DFL)
    yield
    signal.signal(signal.SIGHUP, previous)


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


def test_an_ignored_stop_signal_stays_ignored_inside_the_block():
    # nohup ignores SIGHUP so that a job outlives its terminal.
    previous = signal.signal(signal.SIGHUP, signal.SIG_IGN)
    try:
        with stop_signals_interrupt():
            assert signal.getsignal(signal.SIGHUP) is signal.SIG_IGN
            os.kill(os.getpid(), signal.SIGHUP)
            time.sleep(0.2)  # nothing is raised
        assert signal.getsignal(signal.SIGHUP) is signal.SIG_IGN
    finally:
        signal.signal(signal.SIGHUP, previous)


def test_a_handler_installed_within_the_kept_block_is_undone():
    # As ray.init installs a SIGTERM handler that exits without the runs' "interrupted" files.
    with stop_signals_interrupt():
        ours = signal.getsignal(signal.SIGTERM)
        with signal_handlers_kept():
            signal.signal(signal.SIGTERM, lambda signum, frame: None)  # as ray.init does
        assert signal.getsignal(signal.SIGTERM) is ours


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


def test_a_stop_within_a_held_block_ends_the_job_after_it():
    reached = []
    with stop_signals_interrupt():
        with pytest.raises(Interrupted, match="SIGHUP"):
            with stops_held():
                signal.raise_signal(signal.SIGHUP)
                time.sleep(0.05)
                reached.append("end of the block")
        assert reached == ["end of the block"]
        assert signal.getsignal(signal.SIGHUP) is not signal.SIG_IGN  # the job's handler again


def test_a_stop_held_through_a_final_write_says_the_files_are_complete():
    # It ended the command as any stop does, yet the files said "complete": the line must not
    # have the user discard a finished result.
    with stop_signals_interrupt():
        for final_write in (True, False):
            with pytest.raises(Interrupted) as raised:
                with stops_held(final_write=final_write):
                    signal.raise_signal(signal.SIGTERM)
            reason = interrupt_reason(raised.value)
            assert reason.startswith("interrupted by SIGTERM")
            assert ("during its final write, which it finished (its files are complete"
                    in reason) is final_write


@pytest.fixture
def hears_ctrl_c():
    """This process hears Ctrl-C, as from a terminal (a test run in the background ignores it)."""
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    yield
    signal.signal(signal.SIGINT, previous)


def test_processes_started_within_the_block_ignore_ctrl_c_from_their_start(hears_ctrl_c):
    # A worker still importing its modules printed a traceback of its own on Ctrl-C. A pool
    # without an initializer shows the state a worker starts in.
    context = multiprocessing.get_context("spawn")
    with children_start_deaf_to_ctrl_c():
        deaf = ProcessPoolExecutor(1, mp_context=context)
        handler = deaf.submit(signal.getsignal, signal.SIGINT)
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler  # this process's again
    with deaf, ProcessPoolExecutor(1, mp_context=context) as usual:
        assert handler.result() == signal.SIG_IGN
        assert usual.submit(signal.getsignal, signal.SIGINT).result() \
            is signal.default_int_handler


def test_a_ctrl_c_within_the_block_reaches_this_process_after_it(hears_ctrl_c):
    reached = []
    with pytest.raises(KeyboardInterrupt):
        with children_start_deaf_to_ctrl_c():
            signal.pthread_kill(threading.main_thread().ident, signal.SIGINT)
            time.sleep(0.1)
            reached.append("end of the block")
    assert reached == ["end of the block"]
    assert signal.SIGINT not in signal.pthread_sigmask(signal.SIG_BLOCK, [])


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
        # and its recording is open (on a busy machine that may take more than a second)
        _wait_for(lambda: list(run_dir.glob(".recording.rrd.*.tmp")), 120)
        time.sleep(1.0)
        process.send_signal(stop)
        out, err = process.communicate(timeout=120)
    finally:
        process.kill()
    metrics = json.loads((run_dir / "metrics.json").read_text())
    # How the process ended says where a stop went astray (a stop signal's default action
    # leaves the status incomplete and nothing on stderr).
    assert metrics["status"] == "interrupted", (process.returncode, err.decode()[-2000:],
                                                out.decode()[-500:])
    assert metrics["run"]["message"] == f"interrupted by {stop.name}"
    assert process.returncode == 130
    # One line on stderr says so (the results' tables go to stdout).
    assert err.decode().strip().splitlines()[-1] == f"egostab run: interrupted by {stop.name}"
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


def _egostab_process(argv: list[str], hook: str) -> subprocess.Popen:
    """``egostab argv`` as its console script runs it, after the Python code ``hook``. Ctrl-C
    is Python's KeyboardInterrupt in it, as in a terminal (this test may run with it ignored)."""
    code = (f"import atexit, importlib.abc, pathlib, signal, sys, time\n"
            f"signal.signal(signal.SIGINT, signal.default_int_handler)\n{hook}\n"
            f"sys.argv = ['egostab', *{argv!r}]\n"
            f"from sim.harness.cli import console\nconsole()\n")
    return subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE)


def _stopped_at(marker, process: subprocess.Popen, stop: signal.Signals) -> tuple[str, str]:
    """Send ``stop`` once ``marker`` exists; the process's stdout and stderr."""
    try:
        _wait_for(marker.exists, 120)
        process.send_signal(stop)
        out, err = process.communicate(timeout=120)
    finally:
        process.kill()
    return out.decode(), err.decode()


def _reason(stop: signal.Signals) -> str:
    return ("interrupted by the user (Ctrl-C)" if stop == signal.SIGINT
            else f"interrupted by {stop.name}")


def test_the_console_script_is_the_process_entry_point():
    scripts = tomllib.loads((SCENARIOS_DIR.parent / "pyproject.toml").read_text())["project"]
    assert scripts["scripts"]["egostab"] == "sim.harness.cli:console"


@pytest.mark.parametrize("stop", [signal.SIGINT, signal.SIGTERM])
def test_a_stop_during_the_imports_is_one_line_and_status_130(tmp_path, stop):
    """egostab's imports take a second; the child stalls in its first import of numpy (which
    comes after the console script's own import of the CLI) until the signal comes."""
    marker, out_dir = tmp_path / "importing", tmp_path / "suite"
    hook = (f"class StallAtNumpy(importlib.abc.MetaPathFinder):\n"
            f"    def find_spec(self, name, path, target=None):\n"
            f"        if name == 'numpy':\n"
            f"            pathlib.Path({str(marker)!r}).touch()\n"
            f"            time.sleep(120)\n"
            f"sys.meta_path.insert(0, StallAtNumpy())")
    process = _egostab_process(["suite", str(SUITES_DIR / "ci_suite.toml"), "--out",
                                str(out_dir)], hook)
    out, err = _stopped_at(marker, process, stop)
    assert (process.returncode, err, out) == (130, f"egostab: {_reason(stop)}\n", "")
    assert not out_dir.exists()


@pytest.mark.parametrize("stop", [signal.SIGINT, signal.SIGTERM, signal.SIGHUP])
def test_a_stop_while_exiting_is_one_line_after_the_complete_output(tmp_path, stop):
    """The stop comes after the command printed everything, while Python cleans up (here an
    atexit callback registered during the command that stalls); without the fix SIGTERM and
    SIGHUP killed the process silently there (143, 129)."""
    marker = tmp_path / "exiting"
    hook = (f"def stall():\n"
            f"    pathlib.Path({str(marker)!r}).touch()\n"
            f"    time.sleep(120)\n"
            f"class StallAtExit(importlib.abc.MetaPathFinder):\n"
            f"    def find_spec(self, name, path, target=None):\n"
            f"        if name == 'numpy':\n"
            f"            sys.meta_path.remove(self)\n"
            f"            atexit.register(stall)\n"
            f"sys.meta_path.insert(0, StallAtExit())")
    listing, _ = _egostab_process(["list"], "").communicate(timeout=120)
    process = _egostab_process(["list"], hook)
    out, err = _stopped_at(marker, process, stop)
    assert process.returncode == 130
    assert err == f"egostab list: {_reason(stop)}, while exiting (its files are complete)\n"
    assert out == listing.decode()


def test_an_unstopped_process_ends_as_python_ends_it(tmp_path):
    """Every exit callback runs, also one registered before egostab starts (a sitecustomize,
    coverage's), and the modules are torn down: a file a plugin left open is written out."""
    early, left_open = tmp_path / "early_callback", tmp_path / "left_open.txt"
    hook = (f"atexit.register(pathlib.Path({str(early)!r}).touch)\n"
            f"sys.modules['left_open'] = open({str(left_open)!r}, 'w')\n"
            f"sys.modules['left_open'].write('buffered')")
    process = _egostab_process(["list"], hook)
    out, err = process.communicate(timeout=120)
    assert (process.returncode, err) == (0, b"") and out.count(b"\n") >= 5
    assert early.exists() and left_open.read_text() == "buffered"


@pytest.mark.skipif(not os.path.exists("/dev/full"), reason="needs Linux's /dev/full")
def test_output_that_cannot_be_written_is_an_error_not_a_success():
    # Buffered output (a file, not a terminal) is written at the end, after the command.
    environment = {key: value for key, value in os.environ.items()
                   if key != "PYTHONUNBUFFERED"}
    with open("/dev/full", "w") as full:
        done = subprocess.run([sys.executable, "-m", "sim.harness.cli", "list"], stdout=full,
                              stderr=subprocess.PIPE, text=True, env=environment, timeout=120)
    assert done.returncode == 2
    assert done.stderr == ("egostab list: error: its output could not be written: No space "
                           "left on device\n")
