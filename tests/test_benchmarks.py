"""The scripts of benchmarks/ compute what the ``egostab`` command does: numpy and OpenCV load
on the SIMD paths its runs pin (sim/harness/cpu_paths.py), or not before the harness does. And
ok_but_off.py, which docs/suites.md quotes, finds and checks again what it says it does (the
tuning script's own tests are in tests/sim/harness/test_suite.py)."""

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from sim.harness.cpu_paths import CPU_PATH_VARIABLES, pinned_paths
from sim.harness.threads import THREAD_VARIABLES

ROOT = Path(__file__).resolve().parents[1]
SCRIPTS = sorted((ROOT / "benchmarks").glob("*.py"))

# Import the script as its command line does (not its main), then say which libraries are
# loaded and on which paths.
PROBE = """
import importlib.util, json, os, sys
spec = importlib.util.spec_from_file_location("script", sys.argv[1])
spec.loader.exec_module(importlib.util.module_from_spec(spec))
loaded = [name for name in ("numpy", "cv2") if name in sys.modules]
print(json.dumps({"loaded": loaded,
                  "paths": {name: os.environ.get(name) for name in json.loads(sys.argv[2])},
                  "opencv_threads": sys.modules["cv2"].getNumThreads() if "cv2" in loaded else None}))
"""


@pytest.mark.skipif(not pinned_paths(), reason="below x86-64-v3 or off Linux x86-64: no pin")
@pytest.mark.parametrize("script", SCRIPTS, ids=[script.name for script in SCRIPTS])
def test_a_benchmark_loads_numpy_and_opencv_only_on_the_pinned_paths(script):
    # They loaded them first and ran on the machine's own paths: on a machine with AVX-512
    # their figures then differed from egostab's (one t2fuzzy frame in 15,120 of `rivals`).
    environment = {name: value for name, value in os.environ.items()
                   if name not in CPU_PATH_VARIABLES}
    done = subprocess.run([sys.executable, "-c", PROBE, str(script),
                           json.dumps(list(CPU_PATH_VARIABLES))], capture_output=True,
                          text=True, timeout=120, cwd=ROOT, env=environment)
    assert done.returncode == 0, done.stderr
    found = json.loads(done.stdout)
    if found["loaded"]:
        assert {name: value for name, value in found["paths"].items() if value} \
            == pinned_paths()


@pytest.mark.parametrize("script", SCRIPTS, ids=[script.name for script in SCRIPTS])
def test_a_benchmark_that_loads_opencv_runs_it_and_blas_on_one_thread(script):
    # As egostab's estimates run: their figures (timings, process CPU time) are for one core.
    environment = {name: value for name, value in os.environ.items()
                   if name not in THREAD_VARIABLES}
    done = subprocess.run([sys.executable, "-c", PROBE, str(script), json.dumps(THREAD_VARIABLES)],
                          capture_output=True, text=True, timeout=120, cwd=ROOT, env=environment)
    assert done.returncode == 0, done.stderr
    found = json.loads(done.stdout)
    if "cv2" in found["loaded"]:
        assert found["opencv_threads"] == 1
        assert set(found["paths"].values()) == {"1"}


def test_ok_but_off_checks_again_the_frames_a_suite_lists(tmp_path):
    """benchmarks/ok_but_off.py on a suite whose estimates file is the truth but for one frame
    turned 8 degrees and still called ok: that frame, and only it, is listed; the check fails
    the estimate and passes the truth on the sensor's depth and on the exact depth."""
    import csv
    import importlib.util

    from sim.harness.cli import main

    suite = tmp_path / "one.toml"
    suite.write_text(f'name = "one"\nmethods = ["ecc"]\nmax_frames = 30\nrecord = false\n'
                     f'[overrides]\n"recording.enabled" = false\n[[sequences]]\n'
                     f'scenario = "{ROOT / "scenarios" / "ci" / "ci_corridor.toml"}"\n'
                     f'scene_seeds = [0]\n', encoding="utf-8")
    out = tmp_path / "out"
    assert main(["suite", str(suite), "--workers", "1", "--out", str(out)]) == 0
    (run,) = (out / "runs").iterdir()
    estimates = tmp_path / "mine"
    estimates.mkdir()
    with open(run / "sequence" / "truth.csv", newline="") as truth, \
            open(estimates / f"{run.name}.csv", "w", encoding="utf-8") as written:
        written.write("frame,angle_deg,dx,dy,status\n")
        for row in csv.DictReader(truth):
            turned = float(row["angle_deg"]) + (8.0 if row["frame"] == "20" else 0.0)
            written.write(f"{row['frame']},{turned},{row['dx']},{row['dy']},ok\n")
    assert main(["suite", str(suite), "--workers", "1", "--out", str(out), "--estimates",
                 f"mine={estimates}/{{sequence}}.csv"]) == 0

    spec = importlib.util.spec_from_file_location("ok_but_off", ROOT / "benchmarks" /
                                                  "ok_but_off.py")
    script = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(script)
    (found,) = script.looked_at(out)
    assert (found["method"], found["frame"]) == ("mine", 20)
    assert found["rotation_deg"] == pytest.approx(8.0)
    for depth in ("sensor", "exact"):
        assert found[depth]["estimate"] != "ok" and found[depth]["truth"] == "ok"
        assert found[depth]["optimum_off_truth_deg"] < 1.0
    assert "| mine | " in script.table([found])

    # The picture: reference, current, then the overlays; the one at the truth lines the frames
    # up (gray), the one at the estimate turned 8 degrees does not (magenta and green apart).
    import cv2
    import numpy as np

    from sim.harness.sequence import load_sequence

    (path,) = script.write_pictures([found], out, tmp_path / "figures")
    image = cv2.imread(str(path))
    rows, columns = load_sequence(run / "sequence").frame(20).disparity8.shape
    assert image.shape == (3 * rows, 4 * 3 * columns, 3)
    width = 3 * columns
    at_estimate, at_truth = (image[40:, k * width:(k + 1) * width].astype(int) for k in (2, 3))
    both = [(panel[..., 1] > 0) & (panel[..., 2] > 0) for panel in (at_estimate, at_truth)]
    apart = [float(np.abs(panel[..., 1] - panel[..., 2])[shown].mean())
             for panel, shown in zip((at_estimate, at_truth), both)]
    assert apart[1] < 0.5 * apart[0], apart


def test_rejected_estimates_sorts_the_checks_rejections_into_accurate_and_off(tmp_path):
    """benchmarks/rejected_estimates.py, which docs/suites.md quotes, on a run folder made by
    hand: a rejected estimate 0.5 deg and 1.5 px off counts as accurate, one 6 deg off as far
    off; a frame whose truth failed, a failure of another status and, with --where-ok, a frame
    the other method did not call ok are left out."""
    import importlib.util

    spec = importlib.util.spec_from_file_location("rejected_estimates",
                                                  ROOT / "benchmarks" / "rejected_estimates.py")
    script = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(script)
    run = tmp_path / "run"
    run.mkdir()
    truth = {0: "ok", 1: "ok", 2: "ok", 3: "failed", 4: "ok"}
    ecc_status = {0: "ok", 1: "ok", 2: "ok", 3: "ok", 4: "unverified"}
    lines = ["frame_index,method,status,true_angle_deg,true_dx_px,true_dy_px,truth_status"]
    for frame, truth_status in truth.items():
        lines.append(f"{frame},t2fuzzy,unverified,1.0,10.0,-5.0,{truth_status}")
        lines.append(f"{frame},ecc,{ecc_status[frame]},1.0,10.0,-5.0,{truth_status}")
    (run / "frames.csv").write_text("\n".join(lines) + "\n", encoding="utf-8")
    failures = [(0, "unverified", [1.5, 11.5, -5.0], "ambiguous"),  # accurate
                (1, "unverified", [7.0, 10.0, -5.0], "correlation"),  # 6 deg off
                (2, "rotation_unconverged", [30.0, 0.0, 0.0], None),
                (3, "unverified", [1.0, 10.0, -5.0], "depth"),  # its truth failed
                (4, "unverified", [1.0, 13.0, -5.0], "parallax")]  # 3 px off; ECC not ok
    (run / "failures.jsonl").write_text("".join(
        json.dumps({"frame_index": frame, "method": "t2fuzzy", "status": status,
                    "diagnostics": {"unverified_motion": motion, "verify_failed": test}}) + "\n"
        for frame, status, motion, test in failures), encoding="utf-8")
    every = script.rejected(script.run_folders([run]))["t2fuzzy"]
    assert (every["rejected"], every["accurate"], every["far_off"]) == (3, 1, 1)
    assert every["accurate_by_test"] == {"ambiguous": 1}
    assert every["median_rotation_deg"] == pytest.approx(0.5)  # of 0.5, 6 and 0 deg
    assert every["median_shift_px"] == pytest.approx(1.5)  # of 1.5, 0 and 3 px
    where_ecc_ok = script.rejected([run], where_ok="ecc")["t2fuzzy"]
    assert (where_ecc_ok["rejected"], where_ecc_ok["accurate"]) == (2, 1)
