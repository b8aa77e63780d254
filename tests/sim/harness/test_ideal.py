"""The ideal experiment: trajectories, image loading and the accuracy it measures."""

from __future__ import annotations

import csv
import json
import math
import os
import shutil
import signal
import subprocess
import sys
import time
import warnings
import zlib

import cv2
import numpy as np
import pytest

from scenarios import SCENARIOS_DIR
from sim.harness.cli import main
from sim.harness.ground_truth import GroundTruth
from sim.harness.ideal import (IdealConfig, load_image, load_trajectory, paper_cycle, run_ideal,
                               trajectory_from_run)
from sim.harness.interrupts import Interrupted
from sim.harness.runner import STAGING_FOLDER, RecordConfig, record
from sim.harness.validation import FileValueError
from stabilizer import depth_to_disparity
from stabilizer.motion import Motion, transform_points
from stabilizer.testing import make_depth_scene


def _frames_csv(path, rows: str, method_column: bool = False):
    """A trajectory frames.csv of ``rows`` (frame_index,truth_status,angle,dx,dy[,method])."""
    header = "frame_index,truth_status,true_angle_deg,true_dx_px,true_dy_px"
    path.write_text(header + (",method" if method_column else "") + "\n" + rows)
    return path


def test_paper_cycle_has_the_papers_magnitudes():
    motions = np.array([m.as_tuple() for m in paper_cycle(60)])
    angle, dx, dy = motions.T
    assert angle.max() == pytest.approx(12.0, abs=0.05) and angle.min() == pytest.approx(-12.0, abs=0.05)
    assert dx.max() == pytest.approx(40.0, abs=0.1) and dx.min() == pytest.approx(-40.0, abs=0.1)
    assert dy.min() == pytest.approx(2.0, abs=0.05) and dy.max() == pytest.approx(32.0, abs=0.05)

    def peaks(values):
        return int(np.sum((values > np.roll(values, 1)) & (values >= np.roll(values, -1))))

    # The camera bobs once per step, twice per cycle; it turns and sways once per cycle.
    assert (peaks(angle), peaks(dx), peaks(dy)) == (1, 1, 2)
    # The phases of the module docstring's formulas: x leads the rotation by pi / 3, y is
    # lowest at the cycle's start.
    np.testing.assert_allclose(motions[[0, 15]], [[0.0, 40.0 * math.sin(math.pi / 3), 2.0],
                                                  [12.0, 40.0 * math.cos(math.pi / 3), 32.0]],
                               atol=1e-12)


def test_unknown_trajectory_is_a_clear_error(tmp_path):
    with pytest.raises(ValueError, match="unknown trajectory 'zigzag'; accepted: 'paper_cycle'"):
        load_trajectory("zigzag")
    with pytest.raises(ValueError, match=r"trajectory \S*frames.csv: no such file; accepted: "
                                         r"'paper_cycle' or the path"):
        load_trajectory(str(tmp_path / "frames.csv"))


def test_run_ideal_replays_a_walking_runs_truth(tmp_path):
    np.save(tmp_path / "depth.npy", make_depth_scene(7))
    first = run_ideal(IdealConfig(str(tmp_path / "depth.npy"), str(tmp_path / "a"),
                                  methods=("t2fuzzy",), n_frames=6))
    motions = trajectory_from_run(tmp_path / "a" / "frames.csv")
    np.testing.assert_allclose([m.as_tuple() for m in motions],
                               [m.as_tuple() for m in paper_cycle(6)], rtol=0, atol=1e-12)
    replay = run_ideal(IdealConfig(str(tmp_path / "depth.npy"), str(tmp_path / "b"),
                                   trajectory=str(tmp_path / "a" / "frames.csv"),
                                   methods=("t2fuzzy",)))
    errors = lambda metrics: metrics["summary"]["run"]["t2fuzzy"]["errors"]  # noqa: E731
    assert errors(replay) == errors(first)


def test_an_ideal_runs_end_point_error_is_measured_on_every_other_measured_pixel(tmp_path):
    """The walking truth's sample: the reference's measured pixels of even row and column,
    those the true motion keeps in view; the truth itself is exact (its own error 0)."""
    depth = make_depth_scene(7)
    depth[20:60, 30:90] = 0.0  # unmeasured
    np.save(tmp_path / "depth.npy", depth)
    run_ideal(IdealConfig(str(tmp_path / "depth.npy"), str(tmp_path / "out"), methods=("ecc",),
                          n_frames=4))
    reference = load_image(str(tmp_path / "depth.npy"))
    assert not reference[20:60, 30:90].any()
    rows, cols = np.nonzero(reference[::2, ::2])
    source = np.stack([2 * cols, 2 * rows], axis=1).astype(np.float64)
    height, width = reference.shape
    with open(tmp_path / "out" / "frames.csv", newline="", encoding="utf-8") as handle:
        scored = list(csv.DictReader(handle))
    assert len(scored) == 4 and all(row["status"] == "ok" for row in scored)
    for row in scored:
        truth, estimate = (Motion(*(float(row[f"{kind}_{key}"]) for key in
                                    ("angle_deg", "dx_px", "dy_px"))) for kind in ("true", "est"))
        target = transform_points(truth, source, reference.shape)
        kept = ((target[:, 0] >= -0.5) & (target[:, 0] < width - 0.5)
                & (target[:, 1] >= -0.5) & (target[:, 1] < height - 0.5))
        distances = np.hypot(*(transform_points(estimate, source[kept], reference.shape)
                               - target[kept]).T)
        assert float(row["epe_px"]) == pytest.approx(distances.mean(), rel=1e-4, abs=1e-5)
        assert float(row["truth_epe_px"]) == 0.0


def test_a_trajectory_saved_again_by_a_spreadsheet_replays_the_same(tmp_path):
    np.save(tmp_path / "depth.npy", make_depth_scene(7))
    run_ideal(IdealConfig(str(tmp_path / "depth.npy"), str(tmp_path / "a"), methods=("ecc",),
                          n_frames=4))
    text = (tmp_path / "a" / "frames.csv").read_text()
    (tmp_path / "saved.csv").write_bytes(text.replace("\n", "\r\n").encode("utf-8-sig"))
    assert trajectory_from_run(tmp_path / "saved.csv") == \
        trajectory_from_run(tmp_path / "a" / "frames.csv")
    (tmp_path / "cut.csv").write_text(text.replace("true_dx_px", "dx_true"))
    with pytest.raises(FileValueError, match="cut.csv: header: lacks column"):
        trajectory_from_run(tmp_path / "cut.csv")


def test_paper_method_is_accurate_in_the_ideal_case(tmp_path):
    """Table I's setting on a synthetic disparity image: sub-pixel, sub-half-degree errors."""
    np.save(tmp_path / "scene.npy", make_depth_scene(11))
    metrics = run_ideal(IdealConfig(str(tmp_path / "scene.npy"), str(tmp_path / "out"),
                                    methods=("t2fuzzy",), n_frames=30))
    score = metrics["summary"]["run"]["t2fuzzy"]
    assert score["failure_rate"] <= 0.05
    assert score["errors"]["rotation"]["mean"] < 0.5
    assert score["errors"]["x"]["mean"] < 0.5 and score["errors"]["y"]["mean"] < 0.5
    with open(tmp_path / "out" / "frames.csv", newline="") as handle:
        rows = list(csv.DictReader(handle))
    assert [int(row["frame_index"]) for row in rows] == list(range(30))
    # The frames lie on the time axis of a 30-fps camera.
    assert [float(row["time_s"]) for row in rows] == pytest.approx(np.arange(30) / 30.0)


def test_frames_csv_without_truth_is_rejected(tmp_path):
    path = _frames_csv(tmp_path / "frames.csv", "0,no_overlap,nan,nan,nan\n")
    with pytest.raises(ValueError, match="no frame with a ground truth"):
        trajectory_from_run(path)


@pytest.mark.parametrize("value", ["nan", "inf", "-inf", "", "two"])
def test_a_truth_that_is_not_finite_is_refused_by_line_and_column(tmp_path, value):
    path = _frames_csv(tmp_path / "frames.csv", f"0,ok,0,0,0\n1,ok,0,{value},0\n")
    with pytest.raises(FileValueError, match=f"frames.csv:3: true_dx_px: is '{value}'; allowed: "
                                             "a finite number where truth_status is 'ok'"):
        trajectory_from_run(path)


@pytest.mark.parametrize("value", ["1.5", "", "one"])
def test_a_frame_index_that_is_not_a_whole_number_is_refused_by_line(tmp_path, value):
    path = _frames_csv(tmp_path / "frames.csv", f"0,ok,0,0,0\n{value},ok,0,1,0\n")
    with pytest.raises(FileValueError, match=f"frames.csv:3: frame_index: is '{value}'.*whole"):
        trajectory_from_run(path)


def test_disparity_png_round_trip_is_exact(tmp_path):
    image = depth_to_disparity(make_depth_scene(3))
    cv2.imwrite(str(tmp_path / "d.png"), image)
    assert np.array_equal(load_image(str(tmp_path / "d.png")), image)


@pytest.mark.parametrize("data", [b"\x89PNG\r\n\x1a\nnot a header", b"not an image at all",
                                  b"\x89PNG\r\n\x1a\n\x00\x00\x00\x0dIHDR" + bytes(9)])  # cut at 25
def test_an_unreadable_image_is_refused_in_one_line(tmp_path, capfd, data):
    path = tmp_path / "broken.png"
    path.write_bytes(data)
    assert main(["ideal", str(path), "--methods", "ecc", "--out", str(tmp_path / "out")]) == 2
    # Read at the file descriptor: OpenCV logs a broken PNG header there, not to sys.stderr.
    err = capfd.readouterr().err.strip()
    assert "broken.png" in err and "an unreadable file" in err and "\n" not in err, err


def test_an_image_larger_than_opencv_decodes_is_refused_in_one_line(tmp_path, capfd):
    def chunk(kind, data):
        body = kind + data
        return len(data).to_bytes(4, "big") + body + zlib.crc32(body).to_bytes(4, "big")

    # A valid 40000 x 40000 grey PNG header over almost no data (1.6e9 pixels claimed).
    header = (40000).to_bytes(4, "big") * 2 + bytes([8, 0, 0, 0, 0])
    path = tmp_path / "huge.png"
    path.write_bytes(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", header)
                     + chunk(b"IDAT", zlib.compress(b"\x00" * 64)) + chunk(b"IEND", b""))
    assert main(["ideal", str(path), "--methods", "ecc", "--out", str(tmp_path / "out")]) == 2
    err = capfd.readouterr().err.strip()
    assert "huge.png" in err and "\n" not in err, err


@pytest.mark.parametrize("argv, words", [
    (["--frames", "1000000000000"], "an integer from 2 to 10000"),
    (["--methods", "all,ecc"], "'all' alone"),
])
def test_ideal_options_out_of_range_are_refused(tmp_path, capsys, argv, words):
    with pytest.raises(SystemExit) as exit_info:
        main(["ideal", "corridor", *argv, "--out", str(tmp_path / "out")])
    assert exit_info.value.code == 2 and words in capsys.readouterr().err


# ------------------------------------------------------------------ interrupted experiments
def _wait_for(predicate, timeout_s: float) -> None:
    deadline = time.monotonic() + timeout_s
    while not predicate():
        if time.monotonic() > deadline:
            raise AssertionError("timed out")
        time.sleep(0.05)


def _ideal_stopped_by_sigterm(tmp_path, out_dir, started):
    """``egostab ideal`` of a long cycle into ``out_dir``, sent SIGTERM once ``started()``;
    its exit status and stderr."""
    np.save(tmp_path / "depth.npy", make_depth_scene(7))
    process = subprocess.Popen(
        [sys.executable, "-m", "sim.harness.cli", "ideal", str(tmp_path / "depth.npy"),
         "--methods", "ecc", "--frames", "10000", "--out", str(out_dir)],
        env={**os.environ, "OMP_NUM_THREADS": "1"}, stdout=subprocess.PIPE,
        stderr=subprocess.PIPE)
    try:
        _wait_for(started, 120)
        time.sleep(1.0)  # some frames are done
        process.send_signal(signal.SIGTERM)
        _, err = process.communicate(timeout=120)
    finally:
        process.kill()
    return process.returncode, err.decode()


def test_an_ideal_stopped_by_sigterm_leaves_complete_files_saying_so(tmp_path):
    out_dir = tmp_path / "out"
    status, err = _ideal_stopped_by_sigterm(tmp_path, out_dir,
                                            lambda: (out_dir / "metrics.json").exists())
    assert status == 130, err
    assert err.strip().splitlines()[-1] == "egostab ideal: interrupted by SIGTERM"
    metrics = json.loads((out_dir / "metrics.json").read_text())
    assert metrics["status"] == "interrupted"
    assert metrics["run"]["message"] == "interrupted by SIGTERM"
    done = metrics["run"]["frames_done"]
    assert 0 < done < 10000 and metrics["summary"]["n_frames"] == done
    assert len((out_dir / "frames.csv").read_text().splitlines()) == 1 + done
    assert (out_dir / "summary.md").exists() and (out_dir / "estimates_ecc.png").exists()
    assert not list(out_dir.glob(".*"))  # no temporary file, no staging folder


def test_an_ideal_stopped_by_sigterm_over_a_finished_one_leaves_it_as_it_was(tmp_path):
    np.save(tmp_path / "depth.npy", make_depth_scene(7))
    out_dir = tmp_path / "out"
    run_ideal(IdealConfig(str(tmp_path / "depth.npy"), str(out_dir), methods=("ecc", "t2fuzzy"),
                          n_frames=4))
    before = {path.name: path.read_bytes() for path in out_dir.iterdir()}
    status, err = _ideal_stopped_by_sigterm(
        tmp_path, out_dir, lambda: (out_dir / STAGING_FOLDER / "metrics.json").exists())
    assert status == 130, err
    assert err.strip().splitlines()[-1] == "egostab ideal: interrupted by SIGTERM"
    assert {path.name: path.read_bytes() for path in out_dir.iterdir()} == before


def test_an_interrupted_ideal_keeps_the_frames_it_finished(tmp_path, monkeypatch):
    """In process: the stop comes in the third frame; two frames, every method's, are kept."""
    real, calls = GroundTruth.exact, []

    def interrupting(*args, **kwargs):
        calls.append(1)
        if len(calls) == 3:
            raise Interrupted("SIGTERM")
        return real(*args, **kwargs)

    monkeypatch.setattr(GroundTruth, "exact", staticmethod(interrupting))
    np.save(tmp_path / "depth.npy", make_depth_scene(7))
    metrics = run_ideal(IdealConfig(str(tmp_path / "depth.npy"), str(tmp_path / "out"),
                                    methods=("ecc", "t2fuzzy"), n_frames=6))
    assert metrics["status"] == "interrupted"
    assert metrics["run"]["message"] == "interrupted by SIGTERM"
    assert metrics["run"]["frames_done"] == 2
    assert json.loads((tmp_path / "out" / "metrics.json").read_text()) == metrics
    with open(tmp_path / "out" / "frames.csv", newline="") as handle:
        assert len(list(csv.DictReader(handle))) == 2 * 2


def test_a_stop_during_the_final_write_is_held_until_the_files_are_complete(tmp_path,
                                                                          monkeypatch):
    """A stop arriving as a finished experiment writes its files (a sweep's SIGTERM reached a
    run there and left it "incomplete"): the files say "complete", then the stop ends the job."""
    import sim.harness.report as report

    real = report.write_run_outputs

    def stopped_while_writing(*args, **kwargs):
        if kwargs["status"] != "incomplete":  # the final write
            signal.raise_signal(signal.SIGTERM)
            time.sleep(0.05)  # a Python handler runs between bytecodes: here, were it not held
        return real(*args, **kwargs)

    monkeypatch.setattr(report, "write_run_outputs", stopped_while_writing)
    np.save(tmp_path / "depth.npy", make_depth_scene(7))
    with pytest.raises(Interrupted, match="SIGTERM"):
        run_ideal(IdealConfig(str(tmp_path / "depth.npy"), str(tmp_path / "out"),
                              methods=("ecc",), n_frames=3))
    metrics = json.loads((tmp_path / "out" / "metrics.json").read_text())
    assert (metrics["status"], metrics["run"]["frames_done"]) == ("complete", 3)
    assert (tmp_path / "out" / "summary.md").is_file()


# ------------------------------------------------------------- trajectories and their bounds
@pytest.mark.parametrize("row, column, allowed", [
    ("1,ok,0,1e308,0", "true_dx_px", "at most 176 px either way (the image's width"),
    ("1,ok,0,-1e6,0", "true_dx_px", "at most 176 px either way (the image's width"),
    ("1,ok,0,0,145", "true_dy_px", "at most 144 px either way (the image's height"),
    ("1,ok,1e300,0,0", "true_angle_deg", "at most 180 deg either way"),
])
def test_an_ideal_trajectory_beyond_its_bounds_is_refused_by_line(tmp_path, capfd, row, column,
                                                                  allowed):
    np.save(tmp_path / "depth.npy", make_depth_scene(7))  # 176 x 144 pixels
    path = _frames_csv(tmp_path / "frames.csv", f"0,ok,0,0,0\n{row}\n")
    assert main(["ideal", str(tmp_path / "depth.npy"), "--trajectory", str(path),
                 "--methods", "ecc", "--out", str(tmp_path / "out")]) == 2
    err = capfd.readouterr().err.strip()
    assert f"frames.csv:3: {column}: is " in err and allowed in err and "\n" not in err, err
    assert not (tmp_path / "out").exists()


def test_an_ideal_trajectory_within_its_bounds_is_replayed(tmp_path):
    np.save(tmp_path / "depth.npy", make_depth_scene(7))
    path = _frames_csv(tmp_path / "frames.csv", "0,ok,-180,176,-144\n1,ok,3,-4,5\n")
    metrics = run_ideal(IdealConfig(str(tmp_path / "depth.npy"), str(tmp_path / "out"),
                                    trajectory=str(path), methods=("ecc",)))
    assert metrics["status"] == "complete" and metrics["summary"]["n_frames"] == 2
    # failures.jsonl lists the frames whose estimate failed (frame 0 left the image), only.
    with open(tmp_path / "out" / "frames.csv", newline="") as handle:
        failed = [int(row["frame_index"]) for row in csv.DictReader(handle)
                  if row["status"] != "ok"]
    listed = [json.loads(line)["frame_index"] for line in
              (tmp_path / "out" / "failures.jsonl").read_text().splitlines()]
    assert listed == failed and 0 in failed and len(failed) < 2
    # Without an image, the bound is the longest side any image may have.
    assert trajectory_from_run(_frames_csv(tmp_path / "far.csv", "0,ok,0,100000,0\n"))


@pytest.mark.parametrize("status", ["OK", " ok", "Ok", "failed"])
def test_an_ideal_truth_status_not_written_by_a_run_is_refused(tmp_path, status):
    path = _frames_csv(tmp_path / "frames.csv", f"0,ok,0,0,0\n1,{status},1,2,3\n")
    with pytest.raises(FileValueError, match=r"frames.csv:3: truth_status: is .*'ok' or "
                                             r"'no_overlap'"):
        trajectory_from_run(path)


@pytest.mark.parametrize("last_row, cells", [("2,ok,1", 3), ("2,ok,1,2,3,4", 6)])
def test_an_ideal_trajectory_line_cut_short_or_run_on_is_refused(tmp_path, last_row, cells):
    path = _frames_csv(tmp_path / "frames.csv", f"0,ok,0,0,0\n1,ok,1,2,3\n{last_row}")
    with pytest.raises(FileValueError, match=rf"frames.csv:4: row: has {cells} cells \(a line "
                                             r"cut short or run on\?\); allowed: one per column of the "
                                             r"header, 5"):
        trajectory_from_run(path)


def test_an_ideal_trajectory_skips_frames_without_truth_only(tmp_path):
    path = _frames_csv(tmp_path / "frames.csv", "0,ok,0,0,0\n1,no_overlap,nan,nan,nan\n"
                                                "2,ok,1,2,3\n")
    assert [m.as_tuple() for m in trajectory_from_run(path)] == [(0, 0, 0), (1, 2, 3)]


def test_an_ideal_trajectory_is_replayed_in_frame_order_whatever_the_rows_order(tmp_path):
    path = _frames_csv(tmp_path / "frames.csv", "2,ok,1,2,3\n0,ok,0,0,0\n1,ok,4,5,6\n")
    assert [m.as_tuple() for m in trajectory_from_run(path)] == [(0, 0, 0), (4, 5, 6),
                                                                 (1, 2, 3)]


@pytest.mark.parametrize("rows, method_column, words", [
    ("0,ok,0,0,0\n0,ok,0,0,0\n", False, "frame_index: 0 repeats line 2;"),
    ("0,ok,0,0,0,ecc\n0,ok,0,0,0,t2fuzzy\n1,ok,1,1,1,ecc\n1,ok,1,1,1,ecc\n", True,
     "frames.csv:5: frame_index: 1 repeats line 4 for method 'ecc'"),
    ("0,ok,0,0,0,ecc\n0,ok,0,1,0,t2fuzzy\n", True, "frame 0's truth differs from line 2's"),
])
def test_an_ideal_trajectory_with_a_repeated_frame_is_refused(tmp_path, rows, method_column,
                                                              words):
    path = _frames_csv(tmp_path / "frames.csv", rows, method_column)
    with pytest.raises(FileValueError) as error:
        trajectory_from_run(path)
    assert words in str(error.value)


def test_an_ideal_run_frames_csv_with_one_row_per_method_is_one_frame_each(tmp_path):
    path = _frames_csv(tmp_path / "frames.csv", "0,ok,0,0,0,ecc\n0,ok,0,0,0,t2fuzzy\n"
                                                "1,ok,1,2,3,ecc\n1,ok,1,2,3,t2fuzzy\n", True)
    assert len(trajectory_from_run(path)) == 2


def test_ideal_frames_with_a_trajectory_file_is_refused(tmp_path, capsys):
    np.save(tmp_path / "depth.npy", make_depth_scene(7))
    path = _frames_csv(tmp_path / "frames.csv", "0,ok,0,0,0\n1,ok,1,2,3\n")
    assert main(["ideal", str(tmp_path / "depth.npy"), "--trajectory", str(path),
                 "--frames", "5", "--methods", "ecc", "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err.strip()
    assert "--frames 5 with the trajectory" in err and "'paper_cycle' only" in err, err
    assert "\n" not in err and not (tmp_path / "out").exists()
    with pytest.raises(ValueError, match="--frames 5"):
        load_trajectory(str(path), 5)


# ------------------------------------------------------------------------------ images
def test_an_ideal_sequence_frame_is_read_in_the_sequences_depth_unit(tmp_path, capsys):
    sequence = tmp_path / "sequence"
    record(RecordConfig(str(SCENARIOS_DIR / "ci" / "ci_corridor.toml"), str(sequence),
                        max_frames=1))
    header = json.loads((sequence / "sequence.json").read_text())
    for sub, key in (("depth", "depth_unit_m"), ("exact", "exact_depth_unit_m")):
        png = sequence / sub / "000000.png"
        units = cv2.imread(str(png), cv2.IMREAD_UNCHANGED)
        assert units.dtype == np.uint16
        expected = depth_to_disparity(np.where(units > 0, units * header[key], np.nan))
        assert np.count_nonzero(expected) > units.size // 2
        assert np.array_equal(load_image(str(png)), expected), sub
        # The same PNG outside its sequence: millimetres unless told its unit.
        alone = tmp_path / f"{sub}.png"
        shutil.copy(png, alone)
        assert not np.array_equal(load_image(str(alone)), expected)
        assert np.array_equal(load_image(str(alone), depth_unit_mm=header[key] * 1000),
                              expected)
    assert header["depth_unit_m"] == 1e-4  # the SR4000's reported depth: 0.1 mm
    assert main(["ideal", str(sequence / "depth" / "000000.png"), "--methods", "ecc",
                 "--frames", "2", "--out", str(tmp_path / "out")]) == 0
    run = json.loads((tmp_path / "out" / "metrics.json").read_text())["run"]
    assert run["depth_unit_mm"] == pytest.approx(0.1)
    assert main(["ideal", str(tmp_path / "depth.png"), "--depth-unit-mm", "0.1",
                 "--methods", "ecc", "--frames", "2", "--out", str(tmp_path / "o2")]) == 0
    assert json.loads((tmp_path / "o2" / "metrics.json").read_text())["run"][
        "depth_unit_mm"] == 0.1
    # A header whose unit is not the format's is refused, naming it and what is allowed.
    (sequence / "sequence.json").write_text(json.dumps(
        {**{k: v for k, v in header.items() if k != "exact_depth_unit_m"}, "depth_unit_m": 0.5}))
    capsys.readouterr()
    for sub, problem in (("depth", "depth_unit_m: is 0.5"),
                         ("exact", "exact_depth_unit_m: is missing")):
        assert main(["ideal", str(sequence / sub / "000000.png"), "--methods", "ecc",
                     "--frames", "2", "--out", str(tmp_path / f"refused_{sub}")]) == 2
        err = capsys.readouterr().err.strip()
        assert f"{sequence / 'sequence.json'}: {problem}" in err and "\n" not in err, err
        assert "(metres per PNG unit)" in err and not (tmp_path / f"refused_{sub}").exists()


@pytest.mark.parametrize("value", ["0", "-1", "nan", "inf", "1e9", "mm"])
def test_an_ideal_depth_unit_out_of_range_is_refused(tmp_path, capsys, value):
    with pytest.raises(SystemExit) as exit_info:
        main(["ideal", "corridor", "--depth-unit-mm", value, "--out", str(tmp_path / "out")])
    err = capsys.readouterr().err.strip()
    assert exit_info.value.code == 2 and "a number greater than 0 and at most 1000" in err
    assert "\n" not in err


def test_an_ideal_depth_unit_for_an_image_without_one_is_refused(tmp_path, capsys):
    cv2.imwrite(str(tmp_path / "d.png"), depth_to_disparity(make_depth_scene(3)))
    np.save(tmp_path / "depth.npy", make_depth_scene(3))
    for image in ("d.png", "depth.npy"):
        assert main(["ideal", str(tmp_path / image), "--depth-unit-mm", "0.1",
                     "--out", str(tmp_path / "out")]) == 2
        err = capsys.readouterr().err.strip()
        assert "accepted: --depth-unit-mm with a 16-bit depth PNG only" in err, err
        assert "\n" not in err and not (tmp_path / "out").exists()


@pytest.mark.parametrize("suffix, kind", [(".jpg", "a JPEG image"), (".tiff", "a TIFF image"),
                                          (".png", "a JPEG image")])
def test_an_ideal_image_other_than_png_is_refused_in_one_line(tmp_path, capfd, suffix, kind):
    image = depth_to_disparity(make_depth_scene(3))
    path = tmp_path / f"scene{suffix}"
    if suffix == ".png":  # a JPEG named .png
        path.write_bytes(cv2.imencode(".jpg", image)[1].tobytes())
    else:
        assert cv2.imwrite(str(path), image)
    assert main(["ideal", str(path), "--methods", "ecc", "--out", str(tmp_path / "out")]) == 2
    err = capfd.readouterr().err.strip()
    assert f"got {kind}; accepted: a single-channel 8-bit (disparity) or 16-bit" in err, err
    assert "\n" not in err and not (tmp_path / "out").exists()


@pytest.mark.parametrize("mode, kind", [("P", "a palette (indexed-colour) PNG"),
                                        ("RGB", "an RGB PNG"), ("LA", "a grey + alpha PNG"),
                                        ("RGBA", "an RGBA PNG")])
def test_an_ideal_colour_png_is_refused_by_its_colour_type(tmp_path, capfd, mode, kind):
    image = pytest.importorskip("PIL.Image")
    disparity = depth_to_disparity(make_depth_scene(3))
    path = tmp_path / "scene.png"
    image.fromarray(disparity).convert(mode).save(path)
    assert main(["ideal", str(path), "--methods", "ecc", "--out", str(tmp_path / "out")]) == 2
    err = capfd.readouterr().err.strip()
    assert f"got {kind} (read as uint8 with shape (144, 176" in err, err
    assert "\n" not in err and not (tmp_path / "out").exists()


def test_an_ideal_complex_depth_array_is_refused_without_a_warning(tmp_path, capfd):
    np.save(tmp_path / "complex.npy", make_depth_scene(3).astype(np.complex128))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert main(["ideal", str(tmp_path / "complex.npy"), "--methods", "ecc",
                     "--out", str(tmp_path / "out")]) == 2
    err = capfd.readouterr().err.strip()
    assert "need a 2-D array of real depths in metres" in err and "complex128" in err, err
    assert "\n" not in err


def test_a_file_named_npy_that_is_not_one_is_named_so(tmp_path, capfd):
    # numpy took it for a pickle and suggested loading it unsafely.
    (tmp_path / "depth.npy").write_bytes(b"not numpy")
    assert main(["ideal", str(tmp_path / "depth.npy"), "--methods", "ecc",
                 "--out", str(tmp_path / "out")]) == 2
    err = capfd.readouterr().err.strip()
    assert "not a .npy file" in err and "pickle" not in err and "\n" not in err, err


def test_depths_all_beyond_the_far_limit_are_refused_as_a_wrong_unit(tmp_path, capfd):
    # Millimetres in a .npy, or a PNG in 0.1 mm read as 1 mm, ran "complete" with every frame
    # failed and nothing said.
    depth = make_depth_scene(3)
    assert np.nanmax(depth) < 6.5
    np.save(tmp_path / "mm.npy", depth * 1000.0)
    cv2.imwrite(str(tmp_path / "tenth_mm.png"), np.round(depth * 10_000).astype(np.uint16))
    for image, advice in (("mm.npy", "millimetres? accepted: depths in metres"),
                          ("tenth_mm.png", "another unit than 1 mm? accepted: --depth-unit-mm")):
        assert main(["ideal", str(tmp_path / image), "--methods", "ecc", "--frames", "2",
                     "--out", str(tmp_path / "out")]) == 2
        err = capfd.readouterr().err.strip()
        assert f"{image}: every depth lies beyond 10 m" in err and advice in err, err
        assert "\n" not in err and not (tmp_path / "out").exists()
    # In its own unit, and with no measured pixel at all (a degenerate scene), it runs.
    assert main(["ideal", str(tmp_path / "tenth_mm.png"), "--depth-unit-mm", "0.1", "--methods",
                 "ecc", "--frames", "2", "--out", str(tmp_path / "tenth")]) == 0
    np.save(tmp_path / "nothing.npy", np.full((64, 64), np.nan))
    assert main(["ideal", str(tmp_path / "nothing.npy"), "--methods", "ecc", "--frames", "2",
                 "--out", str(tmp_path / "nothing")]) == 0
    assert json.loads((tmp_path / "nothing" / "metrics.json").read_text())["status"] == "complete"


def test_an_ideal_image_longer_than_the_methods_take_is_resized_to_fit_them(tmp_path, capsys):
    np.save(tmp_path / "wide.npy", np.full((200, 5000), 2.0))  # fewer pixels than 1280 x 1024
    assert main(["ideal", str(tmp_path / "wide.npy"), "--methods", "ecc", "--frames", "2",
                 "--out", str(tmp_path / "refused")]) == 2
    err = capsys.readouterr().err.strip()
    assert "wide.npy: 5000 x 200 pixels is larger than" in err and "4096 on a side" in err, err
    run = run_ideal(IdealConfig(str(tmp_path / "wide.npy"), str(tmp_path / "out"),
                                methods=("ecc",), n_frames=2, resize=True))["run"]
    assert run["image_size"] == [4096, 163] and run["image_size_read"] == [5000, 200]


@pytest.mark.parametrize("shape, taken", [((1024, 1280), True), ((1024, 1281), False),
                                          ((1280, 1024), True), ((100, 4096), True),
                                          ((100, 4097), False), ((4097, 100), False)])
def test_an_ideal_image_at_the_size_limits_is_taken_as_it_is(tmp_path, shape, taken):
    np.save(tmp_path / "depth.npy", np.full(shape, 2.0))
    if taken:
        assert load_image(str(tmp_path / "depth.npy")).shape == shape
    else:
        with pytest.raises(ValueError, match="is larger than the ideal experiment accepts"):
            load_image(str(tmp_path / "depth.npy"))


def test_an_ideals_metrics_record_the_image_size_and_resize(tmp_path):
    image = np.kron(depth_to_disparity(make_depth_scene(3)), np.ones((10, 10), np.uint8))
    cv2.imwrite(str(tmp_path / "large.png"), image)  # 1760 x 1440 pixels
    metrics = run_ideal(IdealConfig(str(tmp_path / "large.png"), str(tmp_path / "out"),
                                    methods=("ecc",), n_frames=2, resize=True))
    run = metrics["run"]
    assert run["resize"] is True and run["image_size_read"] == [1760, 1440]
    width, height = run["image_size"]
    assert width * height <= 1280 * 1024 and width / height == pytest.approx(1760 / 1440, rel=0.01)
    assert run["depth_unit_mm"] is None
    np.save(tmp_path / "depth.npy", make_depth_scene(3))
    run = run_ideal(IdealConfig(str(tmp_path / "depth.npy"), str(tmp_path / "small"),
                                methods=("ecc",), n_frames=2))["run"]
    assert run["resize"] is False and run["image_size"] == run["image_size_read"] == [176, 144]
