"""The ideal experiment: trajectories, image loading and the accuracy it measures."""

from __future__ import annotations

import csv

import numpy as np
import pytest

from sim.harness.ideal import IdealConfig, load_trajectory, paper_cycle, run_ideal, trajectory_from_run
from sim.harness.validation import FileValueError
from stabilizer import depth_to_disparity
from stabilizer.testing import make_depth_scene


def test_paper_cycle_has_the_papers_magnitudes():
    motions = np.array([m.as_tuple() for m in paper_cycle(60)])
    angle, dx, dy = motions.T
    assert angle.max() == pytest.approx(12.0, abs=0.05) and angle.min() == pytest.approx(-12.0, abs=0.05)
    assert dx.max() == pytest.approx(40.0, abs=0.1) and dx.min() == pytest.approx(-40.0, abs=0.1)
    assert dy.min() == pytest.approx(2.0, abs=0.05) and dy.max() == pytest.approx(32.0, abs=0.05)


def test_unknown_trajectory_is_a_clear_error():
    with pytest.raises(ValueError, match="paper_cycle"):
        load_trajectory("zigzag")


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
        assert sum(1 for _ in csv.DictReader(handle)) == 30


def test_frames_csv_without_truth_is_rejected(tmp_path):
    path = tmp_path / "frames.csv"
    path.write_text("frame_index,truth_status,true_angle_deg,true_dx_px,true_dy_px\n"
                    "0,no_overlap,nan,nan,nan\n")
    with pytest.raises(ValueError, match="no frame with a ground truth"):
        trajectory_from_run(path)


@pytest.mark.parametrize("value", ["nan", "inf", "-inf"])
def test_a_truth_that_is_not_finite_is_refused_by_line(tmp_path, value):
    path = tmp_path / "frames.csv"
    path.write_text("frame_index,truth_status,true_angle_deg,true_dx_px,true_dy_px\n"
                    f"0,ok,0,0,0\n1,ok,0,{value},0\n")
    with pytest.raises(FileValueError, match="frames.csv:3: row: .*not a finite number"):
        trajectory_from_run(path)


def test_disparity_png_round_trip_is_exact(tmp_path):
    import cv2

    from sim.harness.ideal import load_image

    image = depth_to_disparity(make_depth_scene(3))
    cv2.imwrite(str(tmp_path / "d.png"), image)
    assert np.array_equal(load_image(str(tmp_path / "d.png")), image)


@pytest.mark.parametrize("data", [b"\x89PNG\r\n\x1a\nnot a header", b"not an image at all"])
def test_an_unreadable_image_is_refused_in_one_line(tmp_path, capfd, data):
    from sim.harness.cli import main

    path = tmp_path / "broken.png"
    path.write_bytes(data)
    assert main(["ideal", str(path), "--methods", "ecc", "--out", str(tmp_path / "out")]) == 2
    # Read at the file descriptor: OpenCV logs a broken PNG header there, not to sys.stderr.
    err = capfd.readouterr().err.strip()
    assert "broken.png" in err and "an unreadable file" in err and "\n" not in err, err


def test_an_image_larger_than_opencv_decodes_is_refused_in_one_line(tmp_path, capfd):
    import zlib

    from sim.harness.cli import main

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
    from sim.harness.cli import main

    with pytest.raises(SystemExit) as exit_info:
        main(["ideal", "corridor", *argv, "--out", str(tmp_path / "out")])
    assert exit_info.value.code == 2 and words in capsys.readouterr().err
