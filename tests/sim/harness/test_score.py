"""`egostab score`: a recorded sequence scores exactly as the run of the same scenario; workers
change nothing; estimates of any program are scored; bad estimates files are refused by line."""

from __future__ import annotations

import csv
import json
import math
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

import sim.harness.score
from scenarios import SCENARIOS_DIR
from sim.harness.cli import main
from sim.harness.runner import RecordConfig, RunConfig, record, run
from sim.harness.score import ScoreConfig, reference_chunks, score
from sim.harness.sequence import load_sequence
from tests.sim.harness.test_recording import _rows_per_entity
from tests.sim.harness.truth_files import set_truth_cell

CI_CORRIDOR = str(SCENARIOS_DIR / "ci" / "ci_corridor.toml")
METHODS = ("t2fuzzy", "ecc")
N_FRAMES = 20
#: Timings differ from run to run; every other figure is identical bit for bit.
TIMINGS = {"ms", "ms_mean", "ms_median"}


@pytest.fixture(scope="module")
def folders(tmp_path_factory):
    root = tmp_path_factory.mktemp("score")
    record(RecordConfig(scenario=CI_CORRIDOR, out_dir=str(root / "sequence"),
                        max_frames=N_FRAMES))
    run(RunConfig(scenario=CI_CORRIDOR, out_dir=str(root / "run"), methods=METHODS,
                  record=False, max_frames=N_FRAMES))
    for workers in (1, 2):
        score(ScoreConfig(sequence=str(root / "sequence"), out_dir=str(root / f"w{workers}"),
                          methods=METHODS, record=False, workers=workers))
    return root


def _rows(run_dir):
    with open(run_dir / "frames.csv", newline="", encoding="utf-8") as handle:
        return list(csv.DictReader(handle))


def _same_rows(first, second):
    assert len(first) == len(second) > 0
    for a, b in zip(first, second):
        for key in a.keys() - TIMINGS:
            assert a[key] == b[key], (a["frame_index"], a["method"], key)


def _same_summary(first, second, path="summary"):
    if isinstance(first, dict):
        assert first.keys() == second.keys(), path
        for key in first.keys() - TIMINGS:
            _same_summary(first[key], second[key], f"{path}.{key}")
    else:
        assert first == second or (first != first and second != second), path


def _summary(run_dir):
    return json.loads((run_dir / "metrics.json").read_text())["summary"]


def test_scoring_a_recorded_sequence_gives_the_figures_of_the_run(folders):
    _same_rows(_rows(folders / "run"), _rows(folders / "w1"))
    _same_summary(_summary(folders / "run"), _summary(folders / "w1"))
    metrics = json.loads((folders / "w1" / "metrics.json").read_text())
    assert metrics["status"] == "complete" and metrics["run"]["frames_done"] == N_FRAMES
    for name in ("summary.md", "estimates_t2fuzzy.png", "error_histograms.png"):
        assert (folders / "w1" / name).stat().st_size > 0


@pytest.mark.parametrize("workers", [1, 2])
def test_the_first_frames_of_a_sequence_score_as_a_run_of_as_many_frames(folders, tmp_path,
                                                                        workers):
    ran = run(RunConfig(scenario=CI_CORRIDOR, out_dir=str(tmp_path / "run"), methods=METHODS,
                        record=False, max_frames=12))
    metrics = score(ScoreConfig(sequence=str(folders / "sequence"), out_dir=str(tmp_path / "w"),
                                methods=METHODS, record=False, workers=workers, max_frames=12))
    _same_rows(_rows(tmp_path / "run"), _rows(tmp_path / "w"))
    _same_summary(_summary(tmp_path / "run"), _summary(tmp_path / "w"))
    assert metrics["status"] == "complete"
    assert metrics["run"]["sim_time_s"] == ran["run"]["sim_time_s"]  # not the recording's end
    assert (metrics["run"]["frames_done"], metrics["run"]["max_frames"]) == (12, 12)


def test_an_estimates_file_of_every_frame_scores_its_first_frames(folders, tmp_path):
    estimates = _estimates_from_truth(folders / "sequence", tmp_path / "mine.csv", skip={7})
    metrics = score(ScoreConfig(sequence=str(folders / "sequence"), out_dir=str(tmp_path / "w"),
                                estimates={"offset": str(estimates)}, record=False,
                                max_frames=6))
    assert [int(row["frame_index"]) for row in _rows(tmp_path / "w")] == list(range(6))
    assert metrics["summary"]["run"]["offset"]["n_failed"] == 1  # frame 4; 7 is not scored


def test_more_frames_than_the_sequence_holds_score_every_frame(folders, tmp_path):
    metrics = score(ScoreConfig(sequence=str(folders / "sequence"), out_dir=str(tmp_path / "w"),
                                methods=METHODS, record=False, max_frames=N_FRAMES + 1))
    _same_rows(_rows(folders / "w1"), _rows(tmp_path / "w"))
    assert metrics["status"] == "complete" and metrics["run"]["frames_done"] == N_FRAMES


@pytest.mark.parametrize("max_frames", [0, -1, True, 1.5, "2"])
def test_a_frame_count_that_is_no_whole_number_from_1_is_refused(folders, tmp_path, max_frames):
    with pytest.raises(ValueError, match=r"--max-frames .*: accepted: an integer from 1"):
        ScoreConfig(sequence=str(folders / "sequence"), out_dir=str(tmp_path / "w"),
                    max_frames=max_frames)


def test_two_workers_give_the_figures_of_one(folders):
    _same_rows(_rows(folders / "w1"), _rows(folders / "w2"))
    _same_summary(_summary(folders / "w1"), _summary(folders / "w2"))


def test_the_workers_draw_every_plot_of_the_run(folders):
    # With workers, the per-method plots are drawn in the pool: the same files as in-process.
    plots = sorted(path.name for path in (folders / "w1").glob("*.png"))
    assert plots == sorted(path.name for path in (folders / "w2").glob("*.png"))
    assert len(plots) == len(METHODS) + 1
    assert all((folders / "w2" / name).stat().st_size > 10_000 for name in plots)


def test_a_method_that_cannot_be_loaded_is_refused_before_any_work(folders, tmp_path):
    from sim.harness.methods import MethodError

    with pytest.raises(MethodError, match="nosuch"):
        score(ScoreConfig(sequence=str(folders / "sequence"), out_dir=str(tmp_path / "out"),
                          methods=("nosuch",), workers=2))
    assert not (tmp_path / "out").exists()


def test_more_workers_than_a_few_per_core_are_refused_before_any_work(folders, tmp_path, capsys):
    out = tmp_path / "out"
    assert main(["score", str(folders / "sequence"), "--out", str(out), "--workers",
                 "100000"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("egostab score: error: --workers 100000: accepted: an integer from 1 to")
    assert "\n" not in err and not out.exists()


@pytest.mark.parametrize("workers", [1, 2])
def test_a_truth_whose_reference_is_not_the_policys_is_refused(folders, tmp_path, capsys,
                                                               workers):
    edited = tmp_path / "edited"
    shutil.copytree(folders / "sequence", edited)
    truth = edited / "truth.csv"
    assert load_sequence(edited).rows[5].reference_frame == 0  # the first gait cycle's
    # Frame 5 against frame 3, an earlier frame, as the format allows.
    truth.write_text(set_truth_cell(truth.read_text(), 5, "reference_frame", "3"))
    assert main(["score", str(edited), "--methods", "ecc", "--out", str(tmp_path / "out"),
                 "--quiet", "--no-record", "--workers", str(workers)]) == 2
    err = capsys.readouterr().err.strip()
    assert err == (f"egostab score: error: {edited / 'truth.csv'}: frame 5: reference_frame is 3 "
                   f"but the reference policy gives 0; accepted: the truth.csv `egostab "
                   f"record` wrote")
    assert not (tmp_path / "out").exists()  # refused before any work


def test_chunks_are_cut_only_where_the_reference_changes():
    references = [0] * 5 + [5] * 4 + [9] * 6
    chunks = reference_chunks(references, 3)
    assert [index for chunk in chunks for index in chunk] == list(range(15))
    for chunk in chunks:
        assert chunk[0] == 0 or references[chunk[0]] != references[chunk[0] - 1]
    assert reference_chunks(list(range(-1, 9)), 5) == [[0, 1], [2, 3], [4, 5], [6, 7], [8, 9]]


def test_workers_whose_chunks_hold_several_references_record_and_score_as_one_process(
        tmp_path, monkeypatch):
    # With each frame's reference the frame before, and four chunks of three frames, every
    # chunk a worker takes spans three references: each frame must be estimated against its
    # own. The paper's method's segmentation comes back from the workers for the recording.
    monkeypatch.setattr(sim.harness.score, "CHUNKS_PER_WORKER", 2)
    sequence = tmp_path / "sequence"
    record(RecordConfig(scenario=CI_CORRIDOR, out_dir=str(sequence), max_frames=12,
                        overrides={"evaluation.reference": "previous",
                                   "recording.enabled": True}))
    for workers in (1, 2):
        score(ScoreConfig(sequence=str(sequence), out_dir=str(tmp_path / f"w{workers}"),
                          methods=("t2fuzzy",), workers=workers))
    one, two = _rows(tmp_path / "w1"), _rows(tmp_path / "w2")
    assert [int(row["reference_index"]) for row in one] == [0] + list(range(11))
    _same_rows(one, two)
    recorded = [_rows_per_entity(tmp_path / f"w{workers}" / "recording.rrd")
                for workers in (1, 2)]
    assert recorded[0] == recorded[1]
    assert recorded[1]["/images/segmentation"][1] == 12
    # --no-record writes no recording, whatever the scenario allows.
    score(ScoreConfig(sequence=str(sequence), out_dir=str(tmp_path / "quiet"),
                      methods=("ecc",), record=False, workers=1))
    assert not (tmp_path / "quiet" / "recording.rrd").exists()


OFFSETS = (0.5, -1.25, 2.0)


def _offsets(frame):  # different per frame (constant errors make a degenerate histogram)
    return tuple(offset * (1 + 0.1 * frame) for offset in OFFSETS)


def _estimates_from_truth(sequence_dir, path, skip=()):
    with open(sequence_dir / "truth.csv", newline="") as handle:
        truth = list(csv.DictReader(handle))
    lines = ["frame,angle_deg,dx,dy,status"]
    for row in truth:
        if int(row["frame"]) in skip:
            continue
        values = [float(row[k]) + offset
                  for k, offset in zip(("angle_deg", "dx", "dy"), _offsets(int(row["frame"])))]
        lines.append(",".join([row["frame"], *map(repr, values), "ok" if row["frame"] != "4"
                               else "lost_track"]))
    path.write_text("\n".join(lines) + "\n")
    return path


def test_estimates_of_another_program_score_their_offsets_as_errors(folders, tmp_path):
    estimates = _estimates_from_truth(folders / "sequence", tmp_path / "mine.csv", skip={7})
    out = tmp_path / "scored"
    metrics = score(ScoreConfig(sequence=str(folders / "sequence"), out_dir=str(out),
                                estimates={"offset": str(estimates)}, record=False,
                                workers=None))
    assert metrics["run"]["workers"] == 1  # by default, no worker when no method runs
    rows = _rows(out)
    assert {row["method"] for row in rows} == {"offset"} and len(rows) == N_FRAMES
    by_frame = {int(row["frame_index"]): row for row in rows}
    assert by_frame[7]["status"] == "missing" and by_frame[4]["status"] == "lost_track"
    for frame, row in by_frame.items():
        if frame in (4, 7) or row["truth_status"] != "ok":
            continue
        errors = (float(row["err_angle_deg"]), float(row["err_dx_px"]), float(row["err_dy_px"]))
        assert errors == pytest.approx(tuple(abs(v) for v in _offsets(frame)), abs=1e-12)
    assert metrics["summary"]["run"]["offset"]["n_failed"] == 2


def test_checked_estimates_pass_the_trust_check_every_methods_ok_passes(folders, tmp_path):
    # The truth, except two rows far off that still say ok: 30 px along x, 25 degrees.
    with open(folders / "sequence" / "truth.csv", newline="") as handle:
        truth = {int(row["frame"]): row for row in csv.DictReader(handle)}
    far_off = {9: (0.0, 30.0, 0.0), 14: (25.0, 0.0, 0.0)}
    lines = ["frame,angle_deg,dx,dy"]
    for frame, row in truth.items():
        offset = far_off.get(frame, (0.0, 0.0, 0.0))
        lines.append(",".join([str(frame), *(repr(float(row[key]) + delta) for key, delta
                                             in zip(("angle_deg", "dx", "dy"), offset))]))
    path = tmp_path / "mine.csv"
    path.write_text("\n".join(lines) + "\n")
    for name, check in (("given", False), ("checked", True)):
        score(ScoreConfig(sequence=str(folders / "sequence"), out_dir=str(tmp_path / name),
                          estimates={"mine": str(path)}, check_estimates=check, record=False))
    given, checked = ({int(row["frame_index"]): row for row in _rows(tmp_path / name)}
                      for name in ("given", "checked"))
    assert {given[frame]["status"] for frame in far_off} == {"ok"}
    assert {checked[frame]["status"] for frame in far_off} == {"unverified"}
    # The check judges each row as it judges a method's: the true motion passes on most frames.
    assert sum(row["status"] == "ok" for row in checked.values()) >= N_FRAMES // 2
    for frame, row in checked.items():
        assert row["status"] in ("ok", "unverified")
        if row["status"] == "ok":
            assert row["est_dx_px"] == given[frame]["est_dx_px"]
    metrics = json.loads((tmp_path / "checked" / "metrics.json").read_text())
    assert metrics["run"]["estimates_checked"] is True
    failures = [json.loads(line) for line in
                (tmp_path / "checked" / "failures.jsonl").read_text().splitlines()]
    assert {entry["frame_index"] for entry in failures} >= set(far_off)
    assert all("verify_failed" in entry["diagnostics"] for entry in failures)


def test_check_estimates_without_estimates_is_refused(folders, tmp_path, capsys):
    from sim.harness.cli import main

    code = main(["score", str(folders / "sequence"), "--methods", "ecc", "--check-estimates",
                 "--out", str(tmp_path / "out"), "--quiet"])
    assert code == 2 and not (tmp_path / "out").exists()
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--check-estimates: no estimates file to check" in err[0]


@pytest.mark.parametrize("workers", [1, 2])
def test_no_check_scores_each_methods_estimates_as_the_method_reports_them(folders, tmp_path,
                                                                            workers):
    from stabilizer import Stabilizer

    # A method whose one answer, whatever the frames, the check cannot confirm on most frames.
    fixed = "tests.sim.harness.plugin_methods:fixed_motion"
    methods = ("t2fuzzy", fixed)
    for name, checked in (("checked", True), ("unchecked", False)):
        score(ScoreConfig(sequence=str(folders / "sequence"), out_dir=str(tmp_path / name),
                          methods=methods, trust_check=checked, record=False, workers=workers))
    checked, unchecked = ({(int(row["frame_index"]), row["method"]): row
                           for row in _rows(tmp_path / name)} for name in ("checked", "unchecked"))
    assert checked.keys() == unchecked.keys()
    assert sum(checked[frame, fixed]["status"] == "unverified" for frame in range(N_FRAMES)) > 0
    assert {unchecked[frame, fixed]["status"] for frame in range(N_FRAMES)} == {"ok"}
    sequence = load_sequence(folders / "sequence")
    for (frame, method), row in unchecked.items():
        assert row["status"] != "unverified"
        if checked[frame, method]["status"] == "ok":  # the check passes what it does not change
            for key in ("est_angle_deg", "est_dx_px", "est_dy_px"):
                assert row[key] == checked[frame, method][key]
        if method == "t2fuzzy":  # as Stabilizer(..., verification=None) gives it
            reference = sequence.frame(int(row["reference_index"]))
            own = Stabilizer(reference.disparity8, "t2fuzzy", verification=None).estimate(
                sequence.frame(frame).disparity8)
            assert row["status"] == own.status
            if own.ok:
                assert [float(row[key]) for key in ("est_angle_deg", "est_dx_px", "est_dy_px")
                        ] == pytest.approx(own.as_tuple(), abs=1e-9)
    metrics = json.loads((tmp_path / "unchecked" / "metrics.json").read_text())
    assert metrics["run"]["trust_check"] is False
    assert "scored without the trust check" in (tmp_path / "unchecked" / "summary.md").read_text()
    assert "without the trust check" not in (tmp_path / "checked" / "summary.md").read_text()


def test_no_check_with_check_estimates_is_refused(folders, tmp_path, capsys):
    path = _estimates_from_truth(folders / "sequence", tmp_path / "mine.csv")
    code = main(["score", str(folders / "sequence"), "--methods", "ecc", "--no-check",
                 "--estimates", str(path), "--check-estimates", "--out", str(tmp_path / "out"),
                 "--quiet"])
    assert code == 2 and not (tmp_path / "out").exists()
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--check-estimates with --no-check" in err[0]


def test_frames_without_an_estimate_enter_the_itf_uncompensated(folders, tmp_path):
    # As the stabilized output shows them: a stream of failures alone is the raw stream.
    failures = tmp_path / "failures.csv"
    failures.write_text("frame,angle_deg,dx,dy,status\n"
                        + "".join(f"{frame},0,0,0,lost_track\n" for frame in range(N_FRAMES)))
    metrics = score(ScoreConfig(sequence=str(folders / "sequence"), out_dir=str(tmp_path / "o"),
                                estimates={"failures": str(failures)}, record=False))
    figures = metrics["summary"]["run"]["failures"]
    assert figures["n_failed"] == N_FRAMES
    assert figures["itf_db"] == figures["itf_raw_db"] and math.isfinite(figures["itf_db"])


def test_a_run_ended_by_systemexit_says_error_not_complete(folders, tmp_path, monkeypatch):
    import sim.harness.ground_truth

    real, calls = sim.harness.ground_truth.ground_truth, []

    def exiting(*args, **kwargs):
        calls.append(1)
        if len(calls) == 3:
            raise SystemExit("something called sys.exit()")
        return real(*args, **kwargs)

    monkeypatch.setattr(sim.harness.ground_truth, "ground_truth", exiting)
    out = tmp_path / "out"
    with pytest.raises(SystemExit):
        score(ScoreConfig(sequence=str(folders / "sequence"), out_dir=str(out),
                          methods=("ecc",), record=False, workers=1))
    metrics = json.loads((out / "metrics.json").read_text())
    assert metrics["status"] == "error" and "SystemExit" in metrics["run"]["message"]
    assert len(_rows(out)) == 2


def test_a_sequence_without_frames_scores_as_an_empty_run_with_workers(folders, tmp_path):
    empty = tmp_path / "empty"
    shutil.copytree(folders / "sequence", empty)
    header = json.loads((empty / "sequence.json").read_text())
    (empty / "sequence.json").write_text(json.dumps({**header, "frames": 0}))
    truth = (empty / "truth.csv").read_text().splitlines()
    (empty / "truth.csv").write_text(truth[0] + "\n")
    metrics = score(ScoreConfig(sequence=str(empty), out_dir=str(tmp_path / "out"),
                                methods=("ecc",), record=False, workers=2))
    assert metrics["status"] == "complete" and metrics["summary"]["n_frames"] == 0


def test_an_interrupted_run_over_a_finished_one_leaves_it_as_it_was(folders, tmp_path,
                                                                     interrupt_ground_truth):
    from sim.harness.runner import STAGING_FOLDER

    out = tmp_path / "out"
    score(ScoreConfig(sequence=str(folders / "sequence"), out_dir=str(out), methods=("ecc",),
                      record=False, workers=1))
    before = {path.name: path.read_bytes() for path in out.iterdir()}
    interrupt_ground_truth(3)
    metrics = score(ScoreConfig(sequence=str(folders / "sequence"), out_dir=str(out),
                                methods=("ecc", "sift"), record=False, workers=1))
    assert metrics["status"] == "interrupted"
    # Its simulated time is the time it reached, that of the frame it stopped in (as a run's
    # simulation), not the whole sequence's.
    with open(folders / "sequence" / "truth.csv", newline="") as handle:
        times = [float(row["time_s"]) for row in csv.DictReader(handle)]
    assert 0 < metrics["run"]["frames_done"] < N_FRAMES
    assert metrics["run"]["sim_time_s"] == times[metrics["run"]["frames_done"]]
    assert {path.name: path.read_bytes() for path in out.iterdir()} == before
    # Finished, the new run replaces the old one.
    rerun = score(ScoreConfig(sequence=str(folders / "sequence"), out_dir=str(out),
                              methods=("ecc", "sift"), record=False, workers=1))
    assert rerun["status"] == "complete"
    assert json.loads((out / "metrics.json").read_text())["summary"]["methods"] == ["ecc",
                                                                                   "sift"]
    assert not (out / STAGING_FOLDER).exists()


def test_a_finished_run_over_a_finished_one_leaves_none_of_the_old_runs_files(folders,
                                                                             tmp_path):
    out = tmp_path / "out"
    score(ScoreConfig(sequence=str(folders / "sequence"), out_dir=str(out),
                      methods=("ecc", "sift"), record=False, workers=1))
    (out / "notes.txt").write_text("mine")  # a file of the user's
    assert (out / "estimates_sift.png").is_file()
    score(ScoreConfig(sequence=str(folders / "sequence"), out_dir=str(out), methods=("ecc",),
                      record=False, workers=1))
    # sift's old plot does not pass for the new run's; the user's file stays.
    assert sorted(path.name for path in out.iterdir()) == [
        "error_histograms.png", "estimates_ecc.png", "failures.jsonl", "frames.csv", "metrics.json",
        "notes.txt", "summary.md"]


def test_a_run_after_one_killed_outright_leaves_none_of_its_leftovers(folders, tmp_path):
    """SIGKILL runs no finally: a killed run leaves atomic_path's temporaries and, over a
    finished run, its staging folder; the next run into the folder removes them."""
    from sim.harness.runner import STAGING_FOLDER

    out = tmp_path / "out"
    score(ScoreConfig(sequence=str(folders / "sequence"), out_dir=str(out), methods=("ecc",),
                      record=False, workers=1))
    (out / ".recording.rrd.k1ll3d0.tmp").write_bytes(b"half a recording")
    (out / STAGING_FOLDER).mkdir()
    (out / STAGING_FOLDER / "estimates_sift.png").write_bytes(b"a killed rerun's plot")
    (out / ".notes.txt").write_text("mine")  # the user's own hidden file: not a temporary
    score(ScoreConfig(sequence=str(folders / "sequence"), out_dir=str(out), methods=("ecc",),
                      record=False, workers=1))
    assert sorted(path.name for path in out.iterdir()) == [
        ".notes.txt", "error_histograms.png", "estimates_ecc.png", "failures.jsonl",
        "frames.csv", "metrics.json", "summary.md"]


def test_a_run_over_an_unfinished_one_leaves_none_of_the_old_runs_files(
        folders, tmp_path, interrupt_ground_truth):
    out = tmp_path / "out"
    interrupt_ground_truth(3)
    stopped = score(ScoreConfig(sequence=str(folders / "sequence"), out_dir=str(out),
                                methods=("ecc", "sift"), record=False, workers=1))
    assert stopped["status"] == "interrupted" and (out / "estimates_sift.png").is_file()
    (out / "notes.txt").write_text("mine")
    score(ScoreConfig(sequence=str(folders / "sequence"), out_dir=str(out), methods=("ecc",),
                      record=False, workers=1))
    assert sorted(path.name for path in out.iterdir()) == [
        "error_histograms.png", "estimates_ecc.png", "failures.jsonl", "frames.csv",
        "metrics.json", "notes.txt", "summary.md"]


def test_the_sequence_folder_is_refused_as_the_run_folder(folders, capsys):
    sequence = folders / "sequence"
    before = sorted(path.name for path in sequence.iterdir())
    for out in (sequence, sequence / "depth", sequence / "runs" / "mine"):
        assert main(["score", str(sequence / "depth" / ".."), "--methods", "ecc",
                     "--out", str(out), "--quiet"]) == 2
        err = capsys.readouterr().err.strip()
        assert "is in the sequence folder" in err and "\n" not in err
    assert sorted(path.name for path in sequence.iterdir()) == before


def test_a_sequence_named_through_dot_dot_scores_into_results_of_its_name(folders, tmp_path,
                                                                         monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    sequence = folders / "sequence"
    assert main(["score", str(sequence / "depth" / ".."), "--methods", "ecc", "--quiet"]) == 0
    # A folder called "sequence" is named by its parent, as a suite's runs/<name>/sequence.
    assert (tmp_path / "results" / folders.name / "metrics.json").is_file()
    assert not (tmp_path / "metrics.json").exists()  # not results/.. = the working directory
    # From inside the sequence folder the default run folder would be inside it: refused, and
    # the message says it is the default, not an --out the user gave.
    monkeypatch.chdir(sequence / "depth")
    capsys.readouterr()
    assert main(["score", "..", "--methods", "ecc", "--quiet"]) == 2
    err = capsys.readouterr().err.strip()
    assert "the default run folder" in err and "\n" not in err
    assert not (sequence / "depth" / "results").exists()


def test_the_python_api_refuses_a_run_folder_in_the_sequence_folder(folders):
    sequence = folders / "sequence"
    before = sorted(path.name for path in sequence.iterdir())
    for out in (sequence, sequence / "runs" / "mine"):
        with pytest.raises(ValueError, match="is in the sequence folder"):
            score(ScoreConfig(sequence=str(sequence / "depth" / ".."), out_dir=str(out),
                              methods=("ecc",), record=False))
    assert sorted(path.name for path in sequence.iterdir()) == before


def test_estimates_saved_by_a_spreadsheet_score_as_written(folders, tmp_path):
    # A byte-order mark, CRLF line ends, quoted fields and an upper-case "OK" change nothing.
    plain = _estimates_from_truth(folders / "sequence", tmp_path / "plain.csv")
    lines = plain.read_text().splitlines()
    quoted = [",".join(f'"{cell}"' for cell in line.split(",")).replace('"ok"', '"OK"')
              for line in lines]
    saved = tmp_path / "saved.csv"
    saved.write_bytes(("\r\n".join(quoted) + "\r\n").encode("utf-8-sig"))
    scored = []
    for name, path in (("plain", plain), ("saved", saved)):
        out = tmp_path / name
        score(ScoreConfig(sequence=str(folders / "sequence"), out_dir=str(out),
                          estimates={"mine": str(path)}, record=False))
        scored.append(_rows(out))
    assert scored[0] == scored[1]
    assert sum(row["status"] == "ok" for row in scored[1]) == N_FRAMES - 1


@pytest.mark.parametrize("text, line, column", [
    ("frame,angle_deg,dx\n0,0,0\n", 1, "header"),
    ("frame,angle_deg,dx,dy\n0,0,0,0\n1,0,zero,0\n", 3, "dx"),
    ("frame,angle_deg,dx,dy\n0,0,0,0\n1,0,0,0\n1,0,0,0\n", 4, "frame"),
    ("frame,angle_deg,dx,dy\n0,0,0,0\n999,0,0,0\n", 3, "frame"),
    ("frame,angle_deg,dx,dy\nfirst,0,0,0\n", 2, "frame"),
    ("frame,angle_deg,dx,dy\n0,0,nan,0\n", 2, "dx"),
    ("frame,angle_deg,dx,dy\n0,0,0,0\n".encode("utf-16"), "", "encoding"),
    ("frame,angle_deg,dx,dy\n\u00b2,0,0,0\n", 2, "frame"),
    ("frame,angle_deg,dx,dy,status\n0,0,0,0," + "x" * 200_000 + "\n", 2, "row"),
    ("frame,angle_deg,dx,dy," + "x" * 200_000 + "\n0,0,0,0\n", 1, "header"),
    ("frame,angle_deg,dx,dy,status,dx\n0,0,0,0,ok,999\n", 1, "header"),  # which dx?
    ("frame,angle_deg,dx,dy\n0,0,1_0,0\n", 2, "dx"),  # Python's float() reads 10
    ("frame,angle_deg,dx,dy\n0,0,\uff11,0\n", 2, "dx"),  # a full-width digit
    # Lines, not rows: a blank line is skipped, a quoted field spans lines.
    ("frame,angle_deg,dx,dy\n0,0,0,0\n\n1,0,zero,0\n", 4, "dx"),
    ('frame,angle_deg,dx,dy\n0,0,0,0\n1,"0\n",zero,0\n', 4, "dx"),
    # A quote left open takes in the rest of the file: the message shows its start only.
    ('frame,angle_deg,dx,dy\n0,"0,0,0\n' + "1,0,0,0\n" * 1000, 1002, "angle_deg"),
], ids=lambda value: None if isinstance(value, (int, str)) and len(str(value)) < 20 else "text")
def test_a_bad_estimates_file_is_refused_by_line(folders, tmp_path, capsys, text, line, column):
    path = tmp_path / "bad.csv"
    path.write_bytes(text if isinstance(text, bytes) else text.encode())
    out = tmp_path / "out"
    assert main(["score", str(folders / "sequence"), "--estimates", f"mine={path}",
                 "--out", str(out), "--quiet", "--no-record"]) == 2
    err = capsys.readouterr().err.strip()
    where = f"{path}:{line}" if line else str(path)
    assert f"{where}: {column}" in err and "\n" not in err and len(err) < 400
    assert not out.exists()  # refused before the run folder is made


@pytest.mark.parametrize("separator", [";", "\t"])
def test_a_file_separated_by_semicolons_or_tabs_is_named_so(folders, tmp_path, capsys,
                                                            separator):
    # A decimal-comma spreadsheet's CSV: the columns are all named, in one field.
    path = tmp_path / "mine.csv"
    path.write_text(separator.join(("Frame", "angle_deg", "dx", "dy", "status")) + "\n"
                    + separator.join(("0", "0", "0", "0", "ok")) + "\n")
    assert main(["score", str(folders / "sequence"), "--estimates", f"mine={path}",
                 "--out", str(tmp_path / "out"), "--quiet", "--no-record"]) == 2
    err = capsys.readouterr().err.strip()
    assert f"{path}:1: header: separates its columns by {separator!r}; allowed:" in err
    assert err.endswith("separated by commas")


def test_a_recording_that_ended_with_a_fall_scores_as_the_run_that_fell(tmp_path, monkeypatch):
    from sim.world.walking import RobotSimulation

    real_step = RobotSimulation.step

    def shove(self):  # 40 N sideways on the torso from 0.3 s on (as test_runner's fall)
        if self.time > 0.3:
            self.data.xfrc_applied[self.model.body("humanoid/torso").id, 1] = 40.0
        real_step(self)

    monkeypatch.setattr(RobotSimulation, "step", shove)
    header = record(RecordConfig(scenario=CI_CORRIDOR, out_dir=str(tmp_path / "seq"),
                                 max_frames=90))
    ran = run(RunConfig(scenario=CI_CORRIDOR, out_dir=str(tmp_path / "run"), methods=("ecc",),
                        record=False, max_frames=90))
    scored = score(ScoreConfig(sequence=str(tmp_path / "seq"), out_dir=str(tmp_path / "score"),
                               methods=("ecc",), record=False))
    assert header["ended"] == "fell" and header["fall"]["reason"]
    assert ran["status"] == scored["status"] == "fell"
    assert ran["run"]["fall"] == scored["run"]["fall"]
    assert ran["run"]["frames_done"] == scored["run"]["frames_done"] == header["frames"] < 90
    _same_rows(_rows(tmp_path / "run"), _rows(tmp_path / "score"))
    # Its frames before the fall score as a run that stops before it, which did not fall.
    before = header["frames"] - 1
    ran = run(RunConfig(scenario=CI_CORRIDOR, out_dir=str(tmp_path / "run_before"),
                        methods=("ecc",), record=False, max_frames=before))
    scored = score(ScoreConfig(sequence=str(tmp_path / "seq"),
                               out_dir=str(tmp_path / "score_before"), methods=("ecc",),
                               record=False, max_frames=before))
    assert ran["status"] == scored["status"] == "complete"
    assert "fall" not in ran["run"] and "fall" not in scored["run"]
    _same_rows(_rows(tmp_path / "run_before"), _rows(tmp_path / "score_before"))


def test_the_recorded_digest_is_of_the_estimates_scored_even_if_the_file_changes(
        folders, tmp_path, monkeypatch):
    import hashlib

    import sim.harness.score

    path = _estimates_from_truth(folders / "sequence", tmp_path / "mine.csv")
    scored_bytes = path.read_bytes()
    parse = sim.harness.score._read_estimates

    def parse_then_change_the_file(*args):
        motions = parse(*args)
        path.write_text("frame,angle_deg,dx,dy\n0,1,2,3\n")  # another program rewrites it
        return motions

    monkeypatch.setattr(sim.harness.score, "_read_estimates", parse_then_change_the_file)
    metrics = score(ScoreConfig(sequence=str(folders / "sequence"), out_dir=str(tmp_path / "o"),
                                estimates={"mine": str(path)}, record=False))
    assert metrics["run"]["estimates_sha256"]["mine"] == hashlib.sha256(scored_bytes).hexdigest()
    assert sum(row["status"] == "ok" for row in _rows(tmp_path / "o")) == N_FRAMES - 1


def test_an_estimates_path_holding_an_equals_sign_is_scored_and_a_missing_one_named(
        folders, tmp_path, monkeypatch, capsys):
    from sim.harness.score import parse_estimates_argument

    monkeypatch.chdir(tmp_path)
    (tmp_path / "run=3").mkdir()
    _estimates_from_truth(folders / "sequence", tmp_path / "run=3" / "est.csv")
    assert parse_estimates_argument("run=3/est.csv") == ("est", "run=3/est.csv")
    assert parse_estimates_argument("x=run=3/est.csv") == ("x", "run=3/est.csv")
    for unnamed_or_pathless in ("=run=3/est.csv", " =est.csv", "x=", "x= "):
        with pytest.raises(ValueError, match="accepted: FILE.csv or NAME=FILE.csv"):
            parse_estimates_argument(unnamed_or_pathless)
    assert main(["score", str(folders / "sequence"), "--estimates", "run=3/est.csv",
                 "--out", "scored", "--no-record", "--quiet"]) == 0
    assert {row["method"] for row in _rows(tmp_path / "scored")} == {"est"}
    assert main(["score", str(folders / "sequence"), "--estimates", "nope.csv",
                 "--out", "none", "--quiet"]) == 2
    err = capsys.readouterr().err.strip()
    assert "nope.csv" in err and "an estimates CSV file" in err and "\n" not in err
    assert not (tmp_path / "none").exists()


@pytest.mark.parametrize("name, problem", [("a\nb", "holds a character that does not print"),
                                           ("a\tb", "holds a character that does not print"),
                                           ("y" * 101, "is 101 bytes long"),
                                           ("é" * 51, "is 102 bytes long")])
def test_an_estimates_name_that_cannot_name_files_and_rows_is_refused_before_any_work(
        folders, tmp_path, capsys, name, problem):
    # A newline in the name broke frames.csv's rows; a name too long for a file name failed
    # the run at its last write, the scoring done.
    path = _estimates_from_truth(folders / "sequence", tmp_path / "plain.csv")
    out = tmp_path / "out"
    with pytest.raises(SystemExit) as exit_info:
        main(["score", str(folders / "sequence"), "--estimates", f"{name}={path}", "--out",
              str(out), "--quiet", "--no-record"])
    assert exit_info.value.code == 2
    err = capsys.readouterr().err
    shown = name if len(name) <= 40 else name[:40] + "..."
    assert f"the name {shown!r} {problem}; accepted: a NAME of printable characters" in err
    assert len(err.strip().splitlines()) == 1 and not out.exists()


def test_an_estimates_name_of_the_longest_accepted_length_names_its_plot(folders, tmp_path):
    path = _estimates_from_truth(folders / "sequence", tmp_path / "plain.csv")
    name = "y" * 100
    assert main(["score", str(folders / "sequence"), "--estimates", f"{name}={path}",
                 "--out", str(tmp_path / "out"), "--quiet", "--no-record"]) == 0
    assert (tmp_path / "out" / f"estimates_{name}.png").stat().st_size


def test_a_frame_number_of_thousands_of_digits_is_refused_as_no_frame(folders, tmp_path, capsys):
    path = tmp_path / "long.csv"
    path.write_text("frame,angle_deg,dx,dy\n" + "1" * 5000 + ",0,0,0\n")
    assert main(["score", str(folders / "sequence"), "--estimates", f"long={path}", "--out",
                 str(tmp_path / "out"), "--quiet", "--no-record"]) == 2
    assert capsys.readouterr().err.strip() == (
        f"egostab score: error: {path}:2: frame: {'1' * 40}... is not a frame of the sequence; "
        f"allowed: an integer from 0 to {N_FRAMES - 1}")


PLUGINS = "tests.sim.harness.plugin_methods"


def _score_command(*args, timeout=240):
    """``egostab score`` in its own process (a hang fails the test instead of stopping it)."""
    return subprocess.run([sys.executable, "-m", "sim.harness.cli", "score", *args],
                          cwd=Path(__file__).resolve().parents[3], capture_output=True,
                          text=True, timeout=timeout)


def test_a_method_that_ends_its_worker_process_ends_the_score_with_an_error_not_a_hang(
        folders, tmp_path):
    out = tmp_path / "out"
    done = _score_command(str(folders / "sequence"), "--methods",
                          f"{PLUGINS}:ends_its_process,ecc", "--workers", "2", "--no-record",
                          "--quiet", "--out", str(out))
    assert done.returncode == 1, done.stderr
    assert done.stderr.splitlines()[-1] == (
        "egostab score: error: a worker process died while estimating (a method crashed it, "
        "in native code or by os._exit); the run folder keeps the frames scored before, with "
        "the status 'error'")
    metrics = json.loads((out / "metrics.json").read_text())
    assert metrics["status"] == "error" and "BrokenProcessPool" in metrics["run"]["message"]
    assert len(_rows(out)) == 2 * metrics["run"]["frames_done"]


def test_a_keyboard_interrupt_a_method_raises_in_a_worker_fails_its_frames_not_the_run(
        folders, tmp_path):
    out = tmp_path / "out"
    done = _score_command(str(folders / "sequence"), "--methods",
                          f"{PLUGINS}:raises_keyboard_interrupt,ecc", "--workers", "2",
                          "--no-record", "--quiet", "--out", str(out))
    assert done.returncode == 0, done.stderr
    rows = _rows(out)
    assert {row["status"] for row in rows if row["method"] != "ecc"} == {
        "exception:KeyboardInterrupt"}
    assert json.loads((out / "metrics.json").read_text())["status"] == "complete"


def test_a_stop_signal_during_an_estimate_stops_a_score_started_with_sigint_ignored(
        folders, tmp_path):
    # As `&` in a script, nohup-like wrappers and batch systems start a job: SIGINT ignored.
    # SIGTERM then still stops it; it was taken for the method's own KeyboardInterrupt, which
    # failed one frame, and the score went on to "complete" with exit status 0.
    out = tmp_path / "out"
    done = subprocess.run(
        [sys.executable, "-c", "import signal, sys; signal.signal(signal.SIGINT, signal.SIG_IGN);"
         " from sim.harness.cli import main; sys.exit(main(sys.argv[1:]))", "score",
         str(folders / "sequence"), "--methods", f"{PLUGINS}:sends_itself_sigterm",
         "--workers", "1", "--no-record", "--quiet", "--out", str(out)],
        cwd=Path(__file__).resolve().parents[3], capture_output=True, text=True, timeout=240)
    assert (done.returncode, done.stderr) == (130, "egostab score: interrupted by SIGTERM\n")
    metrics = json.loads((out / "metrics.json").read_text())
    assert metrics["status"] == "interrupted" and metrics["run"]["frames_done"] == 0


@pytest.mark.filterwarnings("ignore::RuntimeWarning")  # numpy's overflows on the way
def test_estimates_far_out_are_scored_and_plotted_up_to_the_bound_and_refused_beyond(
        folders, tmp_path, capsys):
    # Drawn, huge estimates once broke the plots' axis ticks; 1e308, a "no value" of C
    # programs, turned every mean and variance into n/a or a 300-digit number.
    # A value beyond the bound is shown as written: 1000000.1, rounded, read as the bound.
    for value, status in ((1e6, 0), (-1e6, 0), (1.7e308, 2), (1000001, 2), (1000000.1, 2)):
        path = tmp_path / "far.csv"
        path.write_text("frame,angle_deg,dx,dy\n" + "".join(
            f"{frame},0,{value if frame == 3 else 0.0},0\n" for frame in range(N_FRAMES)))
        out = tmp_path / f"out{value}"
        assert main(["score", str(folders / "sequence"), "--estimates", f"far={path}", "--out",
                     str(out), "--quiet", "--no-record"]) == status
        err = capsys.readouterr().err.strip()
        if status:
            assert err == (f"egostab score: error: {path}:5: dx: is {value}; allowed: a finite "
                           "number within +-1e+06 when the status is ok (for no estimate, a "
                           "failure status)")
            assert not out.exists()
        else:
            assert json.loads((out / "metrics.json").read_text())["status"] == "complete"
            assert (out / "estimates_far.png").stat().st_size
            assert (out / "error_histograms.png").exists()


def test_a_row_with_more_cells_than_the_header_is_refused_unless_they_are_empty(folders,
                                                                                tmp_path,
                                                                                capsys):
    path = tmp_path / "extra.csv"
    rows = [f"{frame},0,0,0" for frame in range(N_FRAMES)]

    def scored(lines: list[str]) -> int:
        path.write_text("frame,angle_deg,dx,dy\n" + "\n".join(lines) + "\n")
        return main(["score", str(folders / "sequence"), "--estimates", f"extra={path}",
                     "--out", str(tmp_path / "out"), "--quiet", "--no-record"])

    assert scored(rows[:2] + ["2,0,1,5,0"] + rows[3:]) == 2
    assert capsys.readouterr().err.strip() == (
        f"egostab score: error: {path}:4: row: has 5 cells, the header 4; allowed: one cell per "
        "column of the header (numbers take a decimal point: a decimal comma splits one in two)")
    # Quoted, the decimal comma keeps the cells in line, and the value is still no number.
    assert scored(rows[:2] + ['2,0,"1,5",0'] + rows[3:]) == 2
    assert capsys.readouterr().err.strip() == (
        f"egostab score: error: {path}:4: dx: '1,5' is not a number; allowed: a decimal number "
        "such as -1.5 or 2e-3")
    assert scored([f"{row},," for row in rows]) == 0


def test_estimates_read_from_a_pipe_are_scored(folders, tmp_path):
    # A pipe (process substitution, /dev/stdin) can be read once: it was read twice, and the
    # second read, empty, was refused as lacking the header.
    import os
    import threading

    plain = _estimates_from_truth(folders / "sequence", tmp_path / "plain.csv").read_bytes()
    fifo = tmp_path / "estimates.pipe"
    os.mkfifo(fifo)
    writer = threading.Thread(target=lambda: fifo.write_bytes(plain), daemon=True)
    writer.start()
    out = tmp_path / "out"
    try:
        assert main(["score", str(folders / "sequence"), "--estimates", f"mine={fifo}",
                     "--out", str(out), "--quiet", "--no-record"]) == 0
    finally:
        writer.join(timeout=10)
    assert sum(row["status"] == "ok" for row in _rows(out)) == N_FRAMES - 1


def test_an_estimates_header_names_its_columns_in_any_case(folders, tmp_path):
    # A spreadsheet's "Status" column was taken for another column and ignored: its
    # lost_track rows were scored as estimates.
    lines = _estimates_from_truth(folders / "sequence", tmp_path / "plain.csv").read_text()
    path = tmp_path / "caps.csv"
    path.write_text(lines.replace("frame,angle_deg,dx,dy,status", "Frame,Angle_deg,DX,dy,Status",
                                  1))
    out = tmp_path / "out"
    assert main(["score", str(folders / "sequence"), "--estimates", f"caps={path}", "--out",
                 str(out), "--quiet", "--no-record"]) == 0
    assert [row["status"] for row in _rows(out)].count("lost_track") == 1


def test_scoring_a_recording_cut_short_says_so(tmp_path, interrupt_ground_truth, capsys):
    interrupt_ground_truth(4)
    record(RecordConfig(scenario=CI_CORRIDOR, out_dir=str(tmp_path / "seq"),
                        max_frames=N_FRAMES))  # the 4th truth is interrupted; later ones are not
    assert main(["score", str(tmp_path / "seq"), "--methods", "ecc", "--out",
                 str(tmp_path / "out"), "--quiet", "--no-record"]) == 0
    note = "Note: the sequence's recording was cut short (interrupted"
    assert note in capsys.readouterr().out
    assert note in (tmp_path / "out" / "summary.md").read_text()
    # A whole sequence gets no such note.
    record(RecordConfig(scenario=CI_CORRIDOR, out_dir=str(tmp_path / "whole"), max_frames=2))
    assert main(["score", str(tmp_path / "whole"), "--methods", "ecc", "--out",
                 str(tmp_path / "whole_out"), "--quiet", "--no-record"]) == 0
    assert "cut short" not in capsys.readouterr().out
    assert "cut short" not in (tmp_path / "whole_out" / "summary.md").read_text()


def test_spreadsheet_rows_of_empty_cells_and_quotes_after_a_space_score_as_meant(folders,
                                                                                tmp_path):
    lines = _estimates_from_truth(folders / "sequence", tmp_path / "plain.csv").read_text()
    spaced = "\n".join(", ".join(f'"{cell}"' if cell in ("ok", "lost_track") else cell
                                  for cell in line.split(","))
                        for line in lines.splitlines())
    path = tmp_path / "exported.csv"
    path.write_text(spaced + "\n,,,,\n,,,,\n")
    # Blank columns, and other columns named twice, are columns this does not read.
    header, *rows = lines.splitlines()
    extra = tmp_path / "extra_columns.csv"
    extra.write_text("\n".join([header + ",,,note,note", *(row + ",,,a,b" for row in rows)]))
    scored = []
    for name, estimates in (("plain", tmp_path / "plain.csv"), ("exported", path),
                            ("extra", extra)):
        out = tmp_path / name
        assert main(["score", str(folders / "sequence"), "--estimates", f"mine={estimates}",
                     "--out", str(out), "--quiet", "--no-record"]) == 0
        scored.append(_rows(out))
    assert scored[0] == scored[1] == scored[2]
