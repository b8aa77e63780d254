"""Sequence folders: what `egostab record` writes reads back exactly; bad folders are refused."""

from __future__ import annotations

import dataclasses
import json
import math
import shutil

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from scenarios import SCENARIOS_DIR
from sim.harness.runner import RecordConfig, SimulatedFrames, frame_truth, record
from sim.harness.scenario import load_scenario
from sim.harness.interrupts import Interrupted
from sim.harness.sequence import (EXACT_DEPTH_UNIT_M, FINE_DEPTH_UNIT_M, FORMAT, TRUTH_COLUMNS,
                                  UINT16_MAX, SequenceWriter, decoded_frame, encode_frame,
                                  load_sequence, remove_recording, reported_depth_unit_m)
from sim.harness.validation import FileValueError
from sim.world.camera import Frame
from tests.sim.harness.truth_files import set_truth_cell

CI_CORRIDOR = str(SCENARIOS_DIR / "ci" / "ci_corridor.toml")
N_FRAMES = 5


@pytest.fixture(scope="module")
def sequence_dir(tmp_path_factory):
    out = tmp_path_factory.mktemp("sequence") / "ci_corridor"
    record(RecordConfig(scenario=CI_CORRIDOR, out_dir=str(out), max_frames=N_FRAMES))
    return out


def test_a_recorded_sequence_reads_back_the_frames_and_truth_it_was_made_of(sequence_dir):
    sequence = load_sequence(sequence_dir)
    header = json.loads((sequence_dir / "sequence.json").read_text())
    assert header["format"] == FORMAT and header["ended"] == "complete"
    assert header["frames"] == sequence.n_frames == N_FRAMES
    assert header["intrinsics"]["width"] == 176 and header["provenance"]["versions"]["numpy"]
    with SimulatedFrames(load_scenario(CI_CORRIDOR), N_FRAMES) as source:
        simulated = list(source)
    for item in simulated:
        loaded = sequence.frame(item.frame.index)
        for name in ("depth_m", "valid", "disparity8", "cam_pos", "cam_mat", "true_depth_m"):
            np.testing.assert_array_equal(getattr(loaded, name), getattr(item.frame, name))
        assert loaded.time_s == item.frame.time_s
        row = sequence.rows[item.frame.index]
        assert row.gait_cycle == item.gait_cycle
        assert row.torso == tuple(item.robot_position.tolist())
        reference = sequence.frame(row.reference_frame)
        truth = frame_truth(reference, loaded, sequence.intrinsics)
        assert (row.angle_deg, row.dx, row.dy) == truth.motion.as_tuple()
        assert row.truth_points == truth.n_points
    lines = (sequence_dir / "groundtruth.txt").read_text().splitlines()
    assert lines[0].startswith("#") and len(lines) == N_FRAMES + 1
    quaternion = np.array([float(v) for v in lines[1].split()[4:]])
    assert len(lines[1].split()) == 8 and abs(np.linalg.norm(quaternion) - 1) < 1e-12
    # The TUM pose is the optical frame's (x right, y down, z forward): MuJoCo's camera (x
    # right, y up, looking along -z) turned half a turn about its x axis.
    optical = Rotation.from_quat(quaternion).as_matrix()
    camera = np.asarray(sequence.rows[0].cam_mat)
    np.testing.assert_allclose(optical, camera * [1.0, -1.0, -1.0], atol=1e-12)


def _small_frame(valid, exact):
    """A 2 x 3 frame 2 m deep everywhere it reports (``valid``), with exact depth ``exact``."""
    return Frame(index=0, time_s=0.0, depth_m=np.full((2, 3), 2.0, np.float32), valid=valid,
                 disparity8=np.zeros((2, 3), np.uint8), cam_pos=np.zeros(3), cam_mat=np.eye(3),
                 true_depth_m=exact)


def test_depths_a_sequence_cannot_hold_are_refused_and_no_surface_is_stored_as_0():
    exact = np.full((2, 3), 2.0, np.float32)
    exact[0, 0] = 50.0  # the render's no-surface depth (its far clip)
    frame = _small_frame(np.ones((2, 3), bool), exact)
    encoded = encode_frame(frame, no_surface_depth_m=50.0, depth_unit_m=FINE_DEPTH_UNIT_M)
    assert encoded.exact[0, 0] == 0 and np.all(encoded.exact.ravel()[1:] == 4000)
    assert np.all(encoded.depth == 20000)
    # The farthest depth the unit holds is stored; half a unit beyond it rounds past it.
    farthest = np.full((2, 3), UINT16_MAX * FINE_DEPTH_UNIT_M)
    assert np.all(encode_frame(dataclasses.replace(frame, depth_m=farthest), 50.0,
                               FINE_DEPTH_UNIT_M).depth == UINT16_MAX)
    beyond = dataclasses.replace(frame, depth_m=farthest + 0.6 * FINE_DEPTH_UNIT_M)
    with pytest.raises(ValueError, match=r"reported depth reaches 6.55 m"):
        encode_frame(beyond, 50.0, FINE_DEPTH_UNIT_M)
    far = dataclasses.replace(frame, depth_m=np.full((2, 3), 7.0, np.float32))
    with pytest.raises(ValueError, match=r"frame 0's reported depth reaches 7.00 m; a sequence "
                                         r"stores at most 6.5535 m"):
        encode_frame(far, no_surface_depth_m=50.0, depth_unit_m=FINE_DEPTH_UNIT_M)


def test_stored_depths_are_rounded_to_the_nearest_unit():
    # Half a unit at most from what was measured, each way: 2.00006 m is 20001 units of
    # 0.1 mm, 2.00004 m 20000; the exact depth in units of 0.5 mm likewise.
    depth = np.array([[2.00006, 2.00004, 1.99996], [3.0, 3.00024, 3.00026]], np.float32)
    frame = dataclasses.replace(_small_frame(np.ones((2, 3), bool), depth), depth_m=depth)
    encoded = encode_frame(frame, 50.0, FINE_DEPTH_UNIT_M)
    assert encoded.depth.tolist() == [[20001, 20000, 20000], [30000, 30002, 30003]]
    assert encoded.exact.tolist() == [[4000, 4000, 4000], [6000, 6000, 6001]]
    # The finest unit that holds the sensor's farthest report, up to the last one it holds.
    assert reported_depth_unit_m(UINT16_MAX * FINE_DEPTH_UNIT_M) == FINE_DEPTH_UNIT_M
    assert reported_depth_unit_m(6.554) == EXACT_DEPTH_UNIT_M


def test_a_frames_unmeasured_pixels_and_surfaces_read_back_unmeasured_and_absent():
    valid = np.ones((2, 3), bool)
    valid[1, 2] = False  # a pixel the sensor does not report (low amplitude, say)
    exact = np.full((2, 3), 2.0, np.float32)
    exact[0, 1] = 0.0  # no surface rendered there
    frame = _small_frame(valid, exact)
    decoded = decoded_frame(0, 0.0, frame.cam_pos, frame.cam_mat,
                            encode_frame(frame, 50.0, FINE_DEPTH_UNIT_M), FINE_DEPTH_UNIT_M)
    np.testing.assert_array_equal(decoded.valid, valid)
    assert decoded.depth_m[1, 2] == 0 and decoded.disparity8[1, 2] == 0
    assert decoded.true_depth_m[0, 1] == 0 and decoded.true_depth_m[0, 0] == 2.0


def _broken_copy(sequence_dir, tmp_path, damage):
    copy = tmp_path / "broken"
    shutil.copytree(sequence_dir, copy)
    damage(copy)
    return copy


def _set_json(key, value):
    def damage(folder):
        path = folder / "sequence.json"
        content = json.loads(path.read_text())
        content[key] = value
        path.write_text(json.dumps(content))
    return damage


def _drop_json(key):
    def damage(folder):
        path = folder / "sequence.json"
        content = json.loads(path.read_text())
        del content[key]
        path.write_text(json.dumps(content))
    return damage


def _edit_truth(edit):
    """A damage that rewrites truth.csv as the bytes ``edit`` makes of its text."""
    def damage(folder):
        path = folder / "truth.csv"
        path.write_bytes(edit(path.read_text()))
    return damage


def _folder_in_place_of(path):
    path.unlink()
    path.mkdir()


def test_a_truth_table_saved_with_a_byte_order_mark_reads_the_same(sequence_dir, tmp_path):
    copy = _broken_copy(sequence_dir, tmp_path,
                        _edit_truth(lambda text: text.encode("utf-8-sig")))
    assert load_sequence(copy).rows == load_sequence(sequence_dir).rows


def test_a_frame_without_a_truth_reads_back_as_one(sequence_dir, tmp_path):
    # The truth of a frame that shares too little with its reference is NaN, "no_overlap".
    def no_truth(text):
        for column, value in (("angle_deg", "nan"), ("dx", "nan"), ("dy", "nan"),
                              ("truth_residual_px", "nan"), ("truth_status", "no_overlap")):
            text = set_truth_cell(text, 2, column, value)
        return text.encode()

    row = load_sequence(_broken_copy(sequence_dir, tmp_path, _edit_truth(no_truth))).rows[2]
    assert row.truth_status == "no_overlap"
    assert all(math.isnan(value) for value in (row.angle_deg, row.dx, row.dy,
                                               row.truth_residual_px))


@pytest.mark.parametrize("damage, named", [
    (_set_json("format", "egostab-sequence/99"), "sequence.json"),
    (_set_json("ended", "incomplete"), "sequence.json"),
    (_set_json("frames", N_FRAMES + 1), "truth.csv"),
    (lambda folder: (folder / "depth" / "000003.png").unlink(), "000003.png"),
    (lambda folder: (folder / "truth.csv").write_text(",".join(TRUTH_COLUMNS[:5]) + "\n"),
     "truth.csv"),
    (lambda folder: (folder / "sequence.json").write_text("{not json"), "sequence.json"),
    (_edit_truth(lambda text: text.encode("utf-16")), "truth.csv: encoding"),
    (_edit_truth(lambda text: set_truth_cell(text, 2, "tx", "nan").encode()), "truth.csv:4: tx"),
    (_edit_truth(lambda text: set_truth_cell(text, 1, "time_s", "inf").encode()),
     "truth.csv:3: time_s"),
    (_set_json("frames", 4.5), "sequence.json: frames"),
    (_set_json("frames", True), "sequence.json: frames"),
    (_set_json("intrinsics", {"width": 176.0, "height": 144, "fx": 1, "fy": 1, "cx": 0,
                              "cy": 0}), "sequence.json: intrinsics.width"),
    (_set_json("intrinsics", {"width": 176, "height": 144, "fx": 0, "fy": 1, "cx": 0,
                              "cy": 0}), "sequence.json: intrinsics.fx"),
    (_set_json("intrinsics", {"width": 176, "height": 0, "fx": 1, "fy": 1, "cx": 0,
                              "cy": 0}), "sequence.json: intrinsics.height: is 0"),
    (_set_json("intrinsics", {"width": 176, "height": 144, "fx": 1, "fy": 1, "cx": 0}),
     "sequence.json: intrinsics.cy: is missing"),
    (_set_json("sim_time_s", "abc"), "sequence.json: sim_time_s"),
    (_set_json("fps", "30"), "sequence.json: fps: is '30'; allowed: a finite number > 0"),
    (_set_json("fps", 0), "sequence.json: fps: is 0"),
    (_set_json("fps", float("inf")), "sequence.json: fps: is inf"),
    (_drop_json("fps"), "sequence.json: fps: is missing"),
    (_set_json("message", 5), "sequence.json: message: is 5; allowed: text"),
    (lambda folder: _folder_in_place_of(folder / "truth.csv"), "truth.csv: file: cannot be read"),
    (lambda folder: _folder_in_place_of(folder / "sequence.json"),
     "sequence.json: file: cannot be read"),
    (_set_json("fall", "x"), "sequence.json: fall"),
    (_set_json("scenario", [1, 2]), "sequence.json: scenario"),
    (_set_json("depth_unit_m", "0.0001"), "sequence.json: depth_unit_m: is '0.0001'; allowed"),
    (_edit_truth(lambda text: set_truth_cell(text, 4, "reference_frame", "50").encode()),
     "truth.csv:6: reference_frame"),
    (_edit_truth(lambda text: set_truth_cell(text, 2, "reference_frame", "4").encode()),
     "truth.csv:4: reference_frame"),
])
def test_a_bad_sequence_is_refused_naming_the_file(sequence_dir, tmp_path, damage, named):
    with pytest.raises(FileValueError) as error:
        load_sequence(_broken_copy(sequence_dir, tmp_path, damage))
    message = str(error.value)
    assert named in message and "\n" not in message


def test_a_damaged_frame_image_is_refused_when_read(sequence_dir, tmp_path):
    import cv2

    def to_8_bit(folder):
        cv2.imwrite(str(folder / "exact" / "000002.png"), np.zeros((144, 176), np.uint8))

    sequence = load_sequence(_broken_copy(sequence_dir, tmp_path, to_8_bit))
    with pytest.raises(FileValueError, match="000002.png"):
        sequence.frame(2)


def test_a_cut_off_frame_image_is_refused_in_one_line(sequence_dir, tmp_path, capfd):
    from sim.harness.cli import main

    def cut_off(folder):
        image = folder / "depth" / "000003.png"
        data = image.read_bytes()
        image.write_bytes(data[:len(data) // 2])  # an interrupted copy

    broken = _broken_copy(sequence_dir, tmp_path, cut_off)
    assert main(["score", str(broken), "--methods", "ecc", "--out", str(tmp_path / "out"),
                 "--no-record", "--quiet"]) == 2
    # Read at the file descriptor: libpng writes its own complaints there, not to sys.stderr.
    err = capfd.readouterr().err.strip()
    assert "000003.png" in err and "16-bit grey PNG" in err and "\n" not in err, err


def test_an_interrupted_recording_is_a_complete_shorter_sequence(tmp_path,
                                                                  interrupt_ground_truth):
    interrupt_ground_truth(4)
    header = record(RecordConfig(scenario=CI_CORRIDOR, out_dir=str(tmp_path / "seq"),
                                 max_frames=N_FRAMES))
    assert header["ended"] == "interrupted" and "interrupted" in header["message"]
    sequence = load_sequence(tmp_path / "seq")
    assert sequence.n_frames == 3 and sequence.ended == "interrupted"
    assert not list((tmp_path / "seq").rglob(".*.tmp"))


def test_a_stop_between_a_frames_two_images_leaves_no_image_of_a_frame_not_held(tmp_path,
                                                                                 monkeypatch):
    import sim.harness.sequence

    real, written = sim.harness.sequence.atomic_path, []

    def stop_before_frame_3s_exact_image(path):  # its depth image is written already
        written.append(path)
        if len(written) == 8:
            raise KeyboardInterrupt
        return real(path)

    monkeypatch.setattr(sim.harness.sequence, "atomic_path", stop_before_frame_3s_exact_image)
    header = record(RecordConfig(scenario=CI_CORRIDOR, out_dir=str(tmp_path / "seq"),
                                 max_frames=N_FRAMES))
    assert header["ended"] == "interrupted" and header["frames"] == 3
    for images in ("depth", "exact"):
        assert sorted(path.name for path in (tmp_path / "seq" / images).iterdir()) == [
            "000000.png", "000001.png", "000002.png"]


def test_a_stop_during_the_final_write_keeps_every_frame_as_an_interrupted_sequence(
        tmp_path, monkeypatch):
    import sim.harness.sequence

    real = sim.harness.sequence.write_text_atomic
    stops = []

    def stop_once_at_truth_csv(path, text):
        if path.name == "truth.csv" and not stops:
            stops.append(path)
            raise Interrupted("SIGTERM")
        return real(path, text)

    monkeypatch.setattr(sim.harness.sequence, "write_text_atomic", stop_once_at_truth_csv)
    header = record(RecordConfig(scenario=CI_CORRIDOR, out_dir=str(tmp_path / "seq"),
                                 max_frames=N_FRAMES))
    assert stops and header["ended"] == "interrupted"
    assert header["message"] == "interrupted by SIGTERM"
    sequence = load_sequence(tmp_path / "seq")
    assert sequence.n_frames == N_FRAMES and sequence.ended == "interrupted"


def test_a_stop_while_an_earlier_sequence_is_removed_leaves_a_readable_empty_one(
        sequence_dir, tmp_path, monkeypatch):
    folder = tmp_path / "seq"
    shutil.copytree(sequence_dir, folder)
    real, calls = SequenceWriter._remove_frame_images, []

    def stop_after_some_images(self, images, beyond):
        calls.append(images)
        if len(calls) == 1:
            (self.out_dir / images / "000000.png").unlink()  # one removed, the others not yet
            raise Interrupted("SIGTERM")
        return real(self, images, beyond)

    monkeypatch.setattr(SequenceWriter, "_remove_frame_images", stop_after_some_images)
    header = record(RecordConfig(scenario=CI_CORRIDOR, out_dir=str(folder), max_frames=2))
    assert header["ended"] == "interrupted" and header["frames"] == 0
    assert load_sequence(folder).n_frames == 0
    for images in ("depth", "exact"):
        assert list((folder / images).iterdir()) == []


def test_a_stop_before_the_recording_starts_leaves_an_earlier_sequence_as_it_was(
        sequence_dir, tmp_path, monkeypatch):
    folder = tmp_path / "seq"
    shutil.copytree(sequence_dir, folder)
    before = {path: path.read_bytes() for path in folder.rglob("*") if path.is_file()}

    def stopped(self):
        raise Interrupted("SIGTERM")

    monkeypatch.setattr(SequenceWriter, "start", stopped)
    with pytest.raises(KeyboardInterrupt):
        record(RecordConfig(scenario=CI_CORRIDOR, out_dir=str(folder), max_frames=2))
    assert {path: path.read_bytes() for path in folder.rglob("*") if path.is_file()} == before


def test_a_shorter_recording_replaces_a_sequence_without_leaving_its_frames(sequence_dir,
                                                                           tmp_path):
    folder = tmp_path / "seq"
    shutil.copytree(sequence_dir, folder)
    (folder / "notes.txt").write_text("the user's own file")
    record(RecordConfig(scenario=CI_CORRIDOR, out_dir=str(folder), max_frames=2))
    assert load_sequence(folder).n_frames == 2
    for images in ("depth", "exact"):
        assert sorted(path.name for path in (folder / images).iterdir()) == ["000000.png",
                                                                            "000001.png"]
    assert (folder / "notes.txt").read_text() == "the user's own file"


@pytest.mark.parametrize("own", ["depth/000000.png", "truth.csv", "sequence.json"])
def test_a_folder_of_other_files_named_as_a_sequences_is_refused_and_kept(tmp_path, capsys,
                                                                            own):
    from sim.harness.cli import main

    folder = tmp_path / "mydata"  # another dataset's layout, or notes of the user's own
    (folder / own).parent.mkdir(parents=True, exist_ok=True)
    (folder / own).write_text('{"mine": true}')
    before = {path: path.read_bytes() for path in folder.rglob("*") if path.is_file()}
    assert main(["record", CI_CORRIDOR, "--max-frames", "2", "--out", str(folder),
                 "--quiet"]) == 2
    err = capsys.readouterr().err.strip()
    assert "no sequence of format egostab-sequence" in err and "\n" not in err
    with pytest.raises(FileValueError, match="a new or empty folder"):  # and from Python
        record(RecordConfig(scenario=CI_CORRIDOR, out_dir=str(folder), max_frames=2))
    assert {path: path.read_bytes() for path in folder.rglob("*") if path.is_file()} == before


def test_a_sensor_without_range_limit_is_stored_in_the_coarser_unit(tmp_path):
    header = record(RecordConfig(scenario="noiseless_sensor", out_dir=str(tmp_path / "s"),
                                 max_frames=2))
    assert header["depth_unit_m"] == EXACT_DEPTH_UNIT_M  # it sees the corridor's far room
    frame = load_sequence(tmp_path / "s").frame(0)
    assert float(frame.depth_m.max()) > 65535 * FINE_DEPTH_UNIT_M
    sr4000 = record(RecordConfig(scenario=str(SCENARIOS_DIR / "ci" / "ci_corridor.toml"),
                                 out_dir=str(tmp_path / "r"), max_frames=1))
    assert sr4000["depth_unit_m"] == FINE_DEPTH_UNIT_M


def test_the_default_scenario_records_within_60_mb(tmp_path):
    """Issue 11's size limit for the default 25 s scenario, from its first 30 frames: the images
    take about the same room in every frame (the reported depth is stored uncompressed), so the
    whole sequence takes about 25 s x 30 fps times a frame's share."""
    from scenarios import DEFAULT_SCENARIO

    scenario = load_scenario(DEFAULT_SCENARIO)
    n_frames = round(scenario.duration_s * scenario.sensor.fps)
    record(RecordConfig(scenario=DEFAULT_SCENARIO, out_dir=str(tmp_path / "s"), max_frames=30))
    size = sum(path.stat().st_size for path in (tmp_path / "s").rglob("*") if path.is_file())
    assert size / 30 * n_frames <= 60e6


#: Commands whose runs go into sub-folders of --out, and what the refusal calls that folder.
JOBS_OF_RUNS = [
    (["sweep", str(SCENARIOS_DIR / "sweeps" / "noise_sweep.toml")], "sweep"),
    (["suite", str(SCENARIOS_DIR / "suites" / "ci_suite.toml")], "suite"),
    (["gate"], "gate"),
]


@pytest.mark.parametrize("command, kind", [
    (["run", CI_CORRIDOR, "--max-frames", "2", "--no-record", "--methods", "ecc", "--quiet"],
     "run"),
    (["ideal", "corridor", "--frames", "2", "--methods", "ecc"], "run"),
    *JOBS_OF_RUNS,
])
def test_a_run_into_a_sequence_folder_is_refused(sequence_dir, tmp_path, capsys, command, kind):
    from sim.harness.cli import main

    folder = tmp_path / "seq"
    shutil.copytree(sequence_dir, folder)
    before = sorted(path.name for path in folder.iterdir())
    assert main([*command, "--out", str(folder)]) == 2
    err = capsys.readouterr().err.strip()
    assert ("holds a recorded sequence; accepted: a folder of its own for the " + kind in err
            and "\n" not in err)
    assert sorted(path.name for path in folder.iterdir()) == before


@pytest.mark.parametrize("command, kind", JOBS_OF_RUNS)
def test_a_job_of_runs_into_a_path_too_long_for_the_system_is_refused(tmp_path, capsys,
                                                                      command, kind):
    from sim.harness.cli import main

    assert main([*command, "--out", str(tmp_path / ("a" * 300))]) == 2
    err = capsys.readouterr().err.strip()
    assert "cannot be looked up" in err and "accepted: a folder" in err and "\n" not in err
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("command, kind", JOBS_OF_RUNS)
def test_a_job_of_runs_into_a_run_folder_is_refused(tmp_path, capsys, command, kind):
    from sim.harness.cli import main

    folder = tmp_path / "run"
    folder.mkdir()
    (folder / "metrics.json").write_text("{}")
    assert main([*command, "--out", str(folder)]) == 2
    err = capsys.readouterr().err.strip()
    assert ("holds a run (its metrics.json); accepted: a folder of its own for the " + kind
            in err and "\n" not in err)
    assert [path.name for path in folder.iterdir()] == ["metrics.json"]


def test_a_recording_into_a_run_folder_is_refused(tmp_path, capsys):
    # It mixed the sequence's files into the run's, which aggregate then read as one.
    from sim.harness.cli import main

    folder = tmp_path / "run"
    assert main(["run", CI_CORRIDOR, "--max-frames", "2", "--no-record", "--methods", "ecc",
                 "--quiet", "--out", str(folder)]) == 0
    before = sorted(path.name for path in folder.iterdir())
    assert main(["record", CI_CORRIDOR, "--max-frames", "2", "--quiet", "--out",
                 str(folder)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "holds a run (its metrics.json)" in err[0]
    assert sorted(path.name for path in folder.iterdir()) == before


def test_removing_a_recording_removes_its_entries_not_what_a_link_among_them_points_to(
        tmp_path):
    folder, elsewhere = tmp_path / "sequence", tmp_path / "users_own"
    (folder / "exact").mkdir(parents=True)
    (folder / "exact" / "000000.png").write_bytes(b"png")
    elsewhere.mkdir()
    (elsewhere / "keep.txt").write_text("mine")
    (folder / "depth").symlink_to(elsewhere, target_is_directory=True)
    for name in ("sequence.json", "truth.csv", "notes.txt"):
        (folder / name).write_text("x")
    remove_recording(folder)
    assert sorted(path.name for path in folder.iterdir()) == ["notes.txt"]
    assert (elsewhere / "keep.txt").read_text() == "mine"
