"""examples/estimates_file: a program that reads a sequence by its documented format alone writes
estimates that score as the same estimator does as a plugin."""

from __future__ import annotations

import csv
import importlib.util
import math
import os
import shutil
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest

from sim.harness.runner import RecordConfig, record

ROOT = Path(__file__).resolve().parents[2]
PROGRAM = ROOT / "examples" / "estimates_file" / "orb_estimates.py"
SCENARIO = ROOT / "scenarios" / "ci" / "ci_corridor.toml"
PLUGIN = "egostab_orb:OrbEstimator"
N_FRAMES = 12
BLANK_FRAME = 5  # made a frame without a measurement: a failure row of the file
#: Runs the program with egostab's packages unimportable: it may use the format's documentation,
#: numpy and OpenCV only.
WITHOUT_EGOSTAB = ("import runpy, sys; sys.modules.update(sim=None, stabilizer=None); "
                   "sys.argv = sys.argv[1:]; runpy.run_path(sys.argv[0], run_name='__main__')")


def _program(*args) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-c", WITHOUT_EGOSTAB, str(PROGRAM), *map(str, args)],
                          capture_output=True, text=True, timeout=120)


@pytest.fixture(scope="module")
def sequence(tmp_path_factory) -> Path:
    """A short recorded walk, one of whose frames measures nothing."""
    sequence = tmp_path_factory.mktemp("estimates_file") / "sequence"
    record(RecordConfig(scenario=str(SCENARIO), out_dir=str(sequence), max_frames=N_FRAMES))
    blank = sequence / "depth" / f"{BLANK_FRAME:06d}.png"
    cv2.imwrite(str(blank), np.zeros_like(cv2.imread(str(blank), cv2.IMREAD_UNCHANGED)))
    return sequence


@pytest.fixture(scope="module")
def scored(sequence) -> list[dict]:
    """frames.csv of one `egostab score` of the plugin and of the program's estimates file."""
    root = sequence.parent
    written = _program(sequence, root / "orb.csv")
    assert written.returncode == 0, written.stderr
    env = {**os.environ, "PYTHONPATH": str(ROOT / "examples" / "plugin"), "OMP_NUM_THREADS": "1"}
    scoring = subprocess.run(
        [sys.executable, "-m", "sim.harness.cli", "score", str(sequence), "--methods", PLUGIN,
         "--estimates", f"orb={root / 'orb.csv'}", "--check-estimates", "--no-record",
         "--quiet", "--out", str(root / "scored")],
        cwd=ROOT, env=env, capture_output=True, text=True, timeout=300)
    assert scoring.returncode == 0, scoring.stdout + scoring.stderr
    with open(root / "scored" / "frames.csv", newline="", encoding="utf-8") as handle:
        return list(csv.DictReader(handle))


def test_the_file_scores_as_the_plugin_does(scored):
    plugin = [row for row in scored if row["method"] == PLUGIN]
    from_file = [row for row in scored if row["method"] == "orb"]
    assert len(plugin) == len(from_file) == N_FRAMES
    assert [row["status"] for row in from_file] == [row["status"] for row in plugin]
    assert from_file[BLANK_FRAME]["status"] == "too_few_keypoints"
    assert sum(row["status"] == "ok" for row in from_file) >= N_FRAMES // 2
    for ours, theirs in zip(from_file, plugin):
        # The same images and matches; the Motion convention written out by hand agrees with
        # stabilizer.motion to rounding.
        for key in ("est_angle_deg", "est_dx_px", "est_dy_px", "err_angle_deg", "err_dx_px",
                    "err_dy_px", "epe_px"):
            a, b = float(ours[key]), float(theirs[key])
            assert (math.isnan(a) and math.isnan(b)) or abs(a - b) < 1e-9, (ours["frame_index"],
                                                                             key, a, b)


@pytest.mark.parametrize("header", [None, '{"format": "egostab-sequence/9"}', '[1, 2]'])
def test_a_folder_that_is_not_a_sequence_is_refused_in_one_line(tmp_path, header):
    if header is not None:
        (tmp_path / "sequence.json").write_text(header)
    refused = _program(tmp_path, tmp_path / "orb.csv")
    assert refused.returncode == 2 and refused.stdout == ""
    assert len(refused.stderr.splitlines()) == 1
    assert "is not a readable sequence folder" in refused.stderr
    assert "accepted: a sequence folder written by `egostab record`" in refused.stderr
    assert not (tmp_path / "orb.csv").exists()


def test_an_estimates_file_that_cannot_be_written_is_refused_in_one_line(sequence, tmp_path):
    refused = _program(sequence, tmp_path / "missing" / "orb.csv")
    assert refused.returncode == 2 and len(refused.stderr.splitlines()) == 1
    assert "cannot write" in refused.stderr and "No such file or directory" in refused.stderr


def test_a_missing_frame_image_is_refused_and_leaves_no_file(sequence, tmp_path):
    copy = Path(shutil.copytree(sequence, tmp_path / "sequence"))
    (copy / "depth" / "000007.png").unlink()
    refused = _program(copy, tmp_path / "orb.csv")
    assert refused.returncode == 2 and len(refused.stderr.splitlines()) == 1
    assert "000007.png is missing" in refused.stderr
    assert list(tmp_path.glob("orb.csv*")) == []


def test_an_interrupted_program_leaves_no_file(sequence, tmp_path, monkeypatch, capsys):
    spec = importlib.util.spec_from_file_location("orb_estimates", PROGRAM)
    program = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(program)
    calls = []

    def interrupted(self, reference, current, shape):
        calls.append(1)
        if len(calls) == 3:
            raise KeyboardInterrupt
        return "too_few_matches", ()

    monkeypatch.setattr(program.Orb, "motion", interrupted)
    assert program.main([str(sequence), str(tmp_path / "orb.csv")]) == 130
    assert "interrupted; no estimates file written" in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []
