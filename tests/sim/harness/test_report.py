"""Run outputs: frames.csv, metrics.json, summary.md (Table I layout), plots, aggregation."""

import csv
import json
import math
import shutil
import subprocess

import numpy as np
import pytest

from sim.harness.ground_truth import GroundTruth
from sim.harness.provenance import git_state, package_versions
from sim.harness.report import (MAX_LISTED_LARGE_ERRORS, MEAN_ERROR_COLUMNS, aggregate_runs,
                                failures_jsonl_text, format_number, large_errors_cell,
                                large_errors_section,
                                markdown_table, read_metrics, score_rows, table_one,
                                terminal_summary, write_run_outputs)
from dataclasses import replace

from sim.harness.scoring import (AXES, RECORD_FIELDS, FrameRecord, ItfAccumulator, LargeError,
                                RunSummary, failure_entry, summarize)
from stabilizer.motion import Motion

METHODS = ("t2fuzzy", "sift")
SCENARIO = {"name": "corridor walk", "seed": 11, "walk": {"speed": 0.1}, "limits": (1, 2)}
#: Reference pixels the truths carry, to score end-point errors.
GRID = np.stack([c.ravel() for c in np.mgrid[0:176:8, 0:144:8]], axis=1)
#: The columns frames.csv had before the end-point error; they keep their places.
OLD_COLUMNS = ("frame_index", "time_s", "gait_cycle", "reference_index", "method", "status",
               "ms", "est_angle_deg", "est_dx_px", "est_dy_px", "true_angle_deg", "true_dx_px",
               "true_dy_px", "truth_status", "truth_residual_px", "truth_points",
               "err_angle_deg", "err_dx_px", "err_dy_px")


def _records(n_frames=40, seed=0):
    rng = np.random.default_rng(seed)
    records = []
    for i in range(n_frames):
        truth = GroundTruth.exact(
            Motion(4 * np.sin(i / 5), 15 * np.sin(i / 4), 3 * np.cos(i / 6)), GRID, (144, 176))
        truth = replace(truth, residual_rms_px=0.4, residual_mean_px=0.3)
        if i == 7:
            truth = GroundTruth(Motion.failed("no_overlap"), math.nan, 0)
        for method in METHODS:
            estimate = Motion(truth.motion.angle_deg + rng.normal(0, 0.3),
                              truth.motion.dx + rng.normal(0, 1.0),
                              truth.motion.dy + rng.normal(0, 1.0))
            if method == "sift" and i % 10 == 3:
                estimate = Motion.failed("too_few_matches")
            records.append(FrameRecord.score(
                frame_index=i, time_s=i / 30, gait_cycle=i // 20, reference_index=20 * (i // 20),
                method=method, estimate=estimate, truth=truth, ms=2.0 + i % 3))
    return records


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    run_dir = tmp_path_factory.mktemp("runs") / "run_a"
    records = _records()
    itf = ItfAccumulator()
    image = np.full((8, 8), 100, np.uint8)
    for _ in range(3):
        for stream in ("raw", *METHODS):
            itf.add(stream, image, gait_cycle=0, reference_index=0)
    summary = summarize(records, itf)
    files = write_run_outputs(run_dir, scenario=SCENARIO, records=records, summary=summary,
                              meta={"seed": 11, "methods": list(METHODS)}, status="complete")
    return run_dir, files, records, summary


def test_every_file_is_written_and_no_temporary_is_left(run):
    run_dir, files, _, _ = run
    names = sorted(p.name for p in run_dir.iterdir())
    assert names == sorted(["frames.csv", "failures.jsonl", "metrics.json", "summary.md",
                            "estimates_t2fuzzy.png", "estimates_sift.png",
                            "error_histograms.png"])
    for plot in files.plots:
        assert plot.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_frames_csv_has_one_row_per_frame_and_method(run):
    _, files, records, _ = run
    with files.frames_csv.open() as handle:
        rows = list(csv.DictReader(handle))
    assert tuple(rows[0]) == RECORD_FIELDS
    assert RECORD_FIELDS == (*OLD_COLUMNS, "epe_px", "epe_rms_px", "truth_epe_px")
    assert len(rows) == len(records) == 80
    first = records[0]
    assert float(rows[0]["est_dx_px"]) == first.est_dx_px  # floats round-trip exactly
    failed = [row for row in rows if row["status"] != "ok"]
    assert {row["status"] for row in failed} == {"too_few_matches"}
    assert all(math.isnan(float(row["err_dx_px"])) for row in failed)
    assert all(math.isnan(float(row["epe_px"])) for row in failed)
    assert float(rows[0]["epe_px"]) == first.epe_px > 0.0
    assert float(rows[0]["truth_epe_px"]) == 0.3


def test_failures_jsonl_keeps_plain_diagnostics_and_writes_non_finite_numbers_as_null(
        tmp_path):
    failed = Motion.failed("unverified", unverified_motion=(1.0, float("nan"), 2.0),
                           verify_correlation=np.float32(0.25), labels=np.zeros((3, 3)),
                           ellipses=[(1.0, 2.0)], segmentation=np.ones(4), handle=object())
    entry = failure_entry(frame_index=np.int64(4), method="m", estimate=failed)
    assert {key: entry[key] for key in ("frame_index", "method", "status")} == {
        "frame_index": 4, "method": "m", "status": "unverified"}
    # The recording's drawings and images are left out; what is not plain data is named.
    diagnostics = entry["diagnostics"]
    assert diagnostics.keys() == {"unverified_motion", "verify_correlation",
                                  "dropped_diagnostics"}
    assert diagnostics["verify_correlation"] == 0.25
    assert diagnostics["dropped_diagnostics"] == ["handle"]
    text = failures_jsonl_text([entry, entry])
    lines = text.splitlines()
    assert len(lines) == 2 and text.endswith("\n")
    assert json.loads(lines[0])["diagnostics"]["unverified_motion"] == [1.0, None, 2.0]
    assert failures_jsonl_text([]) == ""


def test_metrics_json_has_scenario_seed_status_versions_commit_and_scores(run):
    _, files, _, summary = run
    document = json.loads(files.metrics_json.read_text())
    assert document["status"] == "complete" and document["seed"] == 11
    assert document["scenario"] == {"name": "corridor walk", "seed": 11,
                                    "walk": {"speed": 0.1}, "limits": [1, 2]}
    versions = document["provenance"]["versions"]
    assert set(versions) >= {"python", "numpy", "opencv", "pywt", "mujoco", "dm_control",
                             "rerun"}
    assert versions["rerun"] == "0.41.0"
    assert "git_commit" in document["provenance"]
    sift = document["summary"]["run"]["sift"]
    assert sift["n_failed"] == 4 and sift["n_truth_failed"] == 1
    assert sift["errors"]["x"]["mean"] == pytest.approx(summary.run["sift"].errors["x"].mean)
    assert sift["itf_db"] == 100.0
    assert set(sift["epe"]) == {"mean", "variance", "max", "n"} and sift["epe"]["n"] == 35
    assert sift["epe"]["mean"] == pytest.approx(summary.run["sift"].epe.mean)
    assert sift["epe_floor_px"] == pytest.approx(0.3)
    assert document["summary"]["cycles"]["1"]["sift"]["epe"]["max"] > 0.0
    assert set(document["summary"]["cycles"]) == {"0", "1"}
    assert document["files"]["plots"] == [p.name for p in files.plots]
    assert read_metrics(files.run_dir) == document


def test_summary_md_is_table_one_layout(run):
    _, files, _, summary = run
    text = files.summary_md.read_text()
    assert "| Displacement | Method | Mean of errors | Variance | Max | Frames |" in text
    lines = text.splitlines()
    start = lines.index("| Displacement | Method | Mean of errors | Variance | Max | Frames |")
    body = lines[start + 2:start + 8]
    assert [line.split("|")[1].strip() for line in body] == [
        "Rotation displacement (deg)", "", "X-axis displacement (px)", "",
        "Y-axis displacement (px)", ""]
    assert [line.split("|")[2].strip() for line in body] == ["t2fuzzy", "sift"] * 3
    rotation = summary.run["t2fuzzy"].errors["rotation"]
    assert f"| {rotation.mean:.2f} | {rotation.variance:.2f} | {rotation.max:.2f} |" in body[0]
    assert "ITF raw (dB)" in text and "complete" in text and "Per gait cycle" in text
    header = ("| Method | Mean EPE | Floor (truth's EPE) | Mean above floor | Variance | Max "
              "| Frames |")
    epe_rows = lines[lines.index(header) + 2:lines.index(header) + 4]
    epe = summary.run["sift"].epe
    assert epe_rows[1].startswith(f"| sift | {epe.mean:.2f} | 0.30 | {epe.mean - 0.3:.2f} | ")
    assert "`estimates_sift.png`" in text


def test_terminal_summary_fits_one_screen_and_says_where_files_are(run):
    _, files, _, summary = run
    text = terminal_summary(files.metrics, files.run_dir)
    assert text == terminal_summary(read_metrics(files.run_dir), files.run_dir)
    assert len(text.splitlines()) <= 40
    assert table_one(summary.run) in text and str(files.run_dir) in text
    assert "metrics.json" in text and "estimates_sift.png" in text
    assert "10.0% (4/40)" in text and text.startswith("Run complete: 40 frames.")


def test_rewriting_replaces_files_and_keeps_the_new_status(run, tmp_path):
    _, _, records, summary = run
    for status in ("interrupted", "fell at 3.2 s"):
        files = write_run_outputs(tmp_path, scenario={}, records=records[:10], summary=summary,
                                  meta={}, status=status, plots=False)
        assert json.loads(files.metrics_json.read_text())["status"] == status
    assert sorted(p.name for p in tmp_path.iterdir()) == ["failures.jsonl", "frames.csv",
                                                          "metrics.json", "summary.md"]


def test_terminal_summary_of_a_stopped_run_over_a_finished_one_says_it_was_not_kept(run,
                                                                                     tmp_path):
    _, _, records, summary = run
    finished = write_run_outputs(tmp_path, scenario={}, records=records, summary=summary,
                                 meta={"wall_time_s": 1.5}, status="complete", plots=False)
    # The stopped run's own metrics, which the runner dropped (docs/design.md).
    stopped = {**finished.metrics, "status": "interrupted",
               "run": {**finished.metrics["run"], "wall_time_s": 0.4}}
    text = terminal_summary(stopped, tmp_path)
    assert f"Not kept: {tmp_path}/ holds the previous run (complete), as it was." in text
    assert "Results in" not in text
    assert "Results in" in terminal_summary(finished.metrics, tmp_path)


def test_aggregate_runs_makes_one_table(run, tmp_path):
    run_dir, _, records, _ = run
    other = tmp_path / "run_b"
    write_run_outputs(other, scenario={"name": "lab"}, records=records[:20],
                      summary=summarize(records[:20]), meta={}, status="interrupted",
                      plots=False)
    table = aggregate_runs([run_dir, other])
    lines = table.splitlines()
    assert len(lines) == 2 + 4
    assert lines[2].startswith("| run_a | corridor walk | complete | t2fuzzy | 40 |")
    assert lines[4].startswith("| run_b | lab | interrupted | t2fuzzy | 10 |")


def test_the_compact_table_has_a_column_per_method_and_the_readme_cell_layout(run, tmp_path):
    run_dir, _, records, _ = run
    table = aggregate_runs([run_dir], compact=True)
    header, _, row = table.splitlines()
    methods = [score["method"] for score in score_rows(read_metrics(run_dir))]
    assert header == "| run | " + " | ".join(methods) + " |"
    first = score_rows(read_metrics(run_dir))[0]
    expected = (" / ".join(f"{first[MEAN_ERROR_COLUMNS[axis]]:.2f}" for axis in AXES)
                + f" ({100 * first['failure_rate']:.0f}%)")
    assert row.split(" | ")[:2] == ["| run_a", expected]  # a name no other run has: alone


def test_the_compact_table_keeps_runs_of_one_name_apart_and_says_which_did_not_finish(
        run, tmp_path):
    run_dir, _, records, _ = run
    for folder, status, max_frames in (("a", "complete", None), ("b", "interrupted", None),
                                       ("c", "complete", 10), ("d", "interrupted", 200)):
        write_run_outputs(tmp_path / folder / "walk", scenario={}, records=records[:20],
                          summary=summarize(records[:20]), status=status, plots=False,
                          meta={"max_frames": max_frames, "frames_done": 10})
    first, second, third, fourth = (tmp_path / folder / "walk" for folder in "abcd")
    rows = aggregate_runs([first, second, third, fourth], compact=True).splitlines()[2:]
    # The limit asked for, and the frames done (a stop leaves fewer).
    assert [row.split(" | ")[0] for row in rows] == [
        f"| {first}", f"| {second} (interrupted)", f"| {third} (--max-frames 10: 10 frames)",
        f"| {fourth} (interrupted) (--max-frames 200: 10 frames)"]
    for compact in (True, False):
        with pytest.raises(ValueError, match="given twice"):
            aggregate_runs([first, first], compact=compact)
    (tmp_path / "binary").mkdir()
    (tmp_path / "binary" / "metrics.json").write_bytes(b"\x89\xaa\xff not text")
    with pytest.raises(ValueError, match="cannot read run metrics .*binary/metrics.json"):
        aggregate_runs([tmp_path / "binary"])


def test_score_rows_read_each_methods_figures_back_from_metrics(run, tmp_path):
    _, files, records, summary = run
    rows = score_rows(files.metrics)
    assert [row["method"] for row in rows] == list(METHODS)
    sift = rows[1]
    assert sift["frames"] == 40 and sift["failure_rate"] == pytest.approx(0.1)
    assert sift[MEAN_ERROR_COLUMNS["x"]] == summary.run["sift"].errors["x"].mean
    assert sift["ms_per_frame"] == summary.run["sift"].ms_mean and sift["itf_db"] == 100.0
    assert sift["epe_mean_px"] == summary.run["sift"].epe.mean
    assert sift["epe_above_floor_px"] == pytest.approx(summary.run["sift"].epe.mean - 0.3)
    without_itf = write_run_outputs(tmp_path, scenario={}, records=records[:10],
                                    summary=summarize(records[:10]), meta={},
                                    status="complete", plots=False)
    assert math.isnan(score_rows(without_itf.metrics)[0]["itf_db"])  # null in metrics.json
    assert score_rows(None) == [] and score_rows({"summary": summarize([]).to_dict()}) == []


def test_aggregate_rejects_folders_without_metrics(tmp_path):
    with pytest.raises(ValueError, match="metrics.json"):
        aggregate_runs([tmp_path])
    with pytest.raises(ValueError, match="no runs"):
        aggregate_runs([])
    (tmp_path / "metrics.json").write_text('{"format": "other"}')
    with pytest.raises(ValueError, match="not a run's metrics"):
        read_metrics(tmp_path)
    (tmp_path / "metrics.json").write_text("[]")
    with pytest.raises(ValueError, match="not a run's metrics"):
        read_metrics(tmp_path)


@pytest.mark.parametrize("figures", [5, None, "x", {"errors": None}])
def test_a_metrics_file_with_mangled_figures_is_named(run, tmp_path, figures):
    document = read_metrics(run[0])
    method = next(iter(document["summary"]["run"]))
    document["summary"]["run"][method] = figures
    (tmp_path / "metrics.json").write_text(json.dumps(document))
    with pytest.raises(ValueError, match=f"metrics.json: 'summary.run.{method}' is not a "
                                         f"method's figures"):
        aggregate_runs([tmp_path])


@pytest.mark.parametrize("content, missing", [
    ({}, "'status'"), ({"status": "complete", "scenario": {}, "run": {}}, "'summary'"),
    ({"status": "complete", "scenario": {}, "run": {}, "summary": {}}, "'summary.run'"),
])
def test_a_metrics_file_with_the_right_tag_and_no_content_is_named(tmp_path, content, missing):
    (tmp_path / "metrics.json").write_text(json.dumps({"format": "egostab-metrics/1", **content}))
    with pytest.raises(ValueError, match=f"metrics.json: {missing} is missing"):
        aggregate_runs([tmp_path])


def test_bad_status_is_rejected(run, tmp_path):
    _, _, records, summary = run
    with pytest.raises(ValueError, match="status"):
        write_run_outputs(tmp_path, scenario={}, records=records, summary=summary, meta={},
                          status="")


def test_provenance_without_git_is_none(tmp_path):
    assert git_state(tmp_path) == {"commit": None, "dirty": None}
    assert package_versions()["numpy"] == np.__version__


@pytest.mark.skipif(shutil.which("git") is None, reason="needs git")
def test_provenance_is_dirty_when_code_changed_not_when_results_did(tmp_path):
    def git(*args):
        subprocess.run(["git", "-c", "user.name=t", "-c", "user.email=t@t", *args], cwd=tmp_path,
                       check=True, capture_output=True)

    (tmp_path / "results").mkdir()
    (tmp_path / "results" / "metrics.json").write_text("{}")
    (tmp_path / "code.py").write_text("x = 1\n")
    git("init", "-q")
    git("add", ".")
    git("commit", "-q", "-m", "code and results")
    (tmp_path / "results" / "metrics.json").write_text('{"rerun": true}')
    git_state.cache_clear()
    state = git_state(tmp_path)
    assert len(state["commit"]) == 40 and state["dirty"] is False
    (tmp_path / "code.py").write_text("x = 2\n")
    git_state.cache_clear()
    assert git_state(tmp_path)["dirty"] is True
    git_state.cache_clear()


def test_a_run_that_scored_nothing_still_writes_every_file(tmp_path):
    empty = summarize([])
    files = write_run_outputs(tmp_path / "fell", scenario={"name": "stairs"}, records=[],
                              summary=empty, meta={}, status="fell at 0.0 s")
    assert json.loads(files.metrics_json.read_text())["status"] == "fell at 0.0 s"
    assert "Run fell at 0.0 s: 0 frames." in terminal_summary(files.metrics)
    table_path = tmp_path / "table.md"
    table = aggregate_runs([files.run_dir], out_path=table_path)
    assert "| fell | stairs | fell at 0.0 s | - | 0 |" in table
    assert table_path.read_text() == table + "\n"


def test_recording_is_listed_with_how_to_open_it(run, tmp_path):
    _, _, records, summary = run
    files = write_run_outputs(tmp_path, scenario={}, records=records, summary=summary, meta={},
                              status="complete", plots=False,
                              recording=tmp_path / "recording.rrd")
    assert "`recording.rrd`" in files.summary_md.read_text()
    assert "rerun FILE" in terminal_summary(files.metrics, tmp_path)


def test_summary_survives_the_json_round_trip(run):
    _, files, _, summary = run
    restored = RunSummary.from_dict(json.loads(files.metrics_json.read_text())["summary"])
    assert restored.methods == summary.methods and restored.n_frames == summary.n_frames
    assert restored.run["sift"].errors == summary.run["sift"].errors
    assert restored.cycles[1]["t2fuzzy"].n_scored == summary.cycles[1]["t2fuzzy"].n_scored


def test_equal_errors_still_plot(run, tmp_path):
    from sim.harness.report import plot_error_histograms

    _, _, records, _ = run
    constant = [replace(record, err_angle_deg=1.0, err_dx_px=2.0, err_dy_px=5.0 + 1e-14 * i)
                for i, record in enumerate(records)]
    path = plot_error_histograms(tmp_path / "h.png", constant, [records[0].method])
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_figures_without_a_value_read_n_a_in_the_tables():
    # A method that scored no frame has NaN means; an error beyond float range, inf.
    assert [format_number(value) for value in (None, math.nan, math.inf, -math.inf)] == ["n/a"] * 4
    assert format_number(1.234) == "1.23" and format_number(2.0, digits=3) == "2.000"


def test_a_table_cell_from_another_program_stays_one_cell():
    # Failure statuses and method names may come from estimates files and plugins.
    table = markdown_table(("Method", "Reasons"), [("mine|v2", "lost\ntrack 3, a|b 1")])
    header, rule, row = table.splitlines()
    assert row == "| mine\\|v2 | lost track 3, a\\|b 1 |"
    assert row.replace("\\|", "").count("|") == header.count("|")


def test_methods_whose_file_names_coincide_get_a_plot_each():
    from sim.harness.report import estimates_plot_names

    names = estimates_plot_names(["t2fuzzy", "a/b", "a_b", "a|b", "a_b_2", "日本", "中国"])
    assert len(set(names)) == len(names)
    assert names[:3] == ["estimates_t2fuzzy.png", "estimates_a_b.png", "estimates_a_b_2.png"]


def test_the_summary_counts_ok_estimates_off_by_more_than_the_large_error_limits(tmp_path):
    records = _records(n_frames=10)
    far = next(index for index, record in enumerate(records)
               if record.method == "t2fuzzy" and record.scored)
    truth = Motion(records[far].true_angle_deg, records[far].true_dx_px, records[far].true_dy_px)
    records[far] = FrameRecord.score(
        frame_index=records[far].frame_index, time_s=0.0, gait_cycle=0, reference_index=0,
        method="t2fuzzy", estimate=Motion(truth.angle_deg, truth.dx + 12.0, truth.dy),
        truth=GroundTruth.exact(truth, GRID, (144, 176)), ms=2.0)
    summary = summarize(records)
    files = write_run_outputs(tmp_path, scenario={}, records=records, summary=summary, meta={},
                              status="complete", plots=False)
    text = files.summary_md.read_text()
    assert "| Truth failed | Ok but off (> 5° or 10 px) | ms/frame mean |" in text
    n_scored = summary.run["t2fuzzy"].n_scored
    assert f"| t2fuzzy | 0.0% (0/10) | - | 1 | 1 of {n_scored} |" in text
    rows = {row["method"]: row for row in score_rows(files.metrics)}
    assert (rows["t2fuzzy"]["large_errors"], rows["t2fuzzy"]["scored_frames"]) == (1, n_scored)
    assert rows["sift"]["large_errors"] == 0
    # The estimate is listed: its frame and absolute errors.
    assert [error.frame for error in rows["t2fuzzy"]["large_error_frames"]] == [
        records[far].frame_index]
    assert "### Ok but off (> 5° or 10 px): the frames" in text
    assert f"| t2fuzzy | {records[far].frame_index} | 0.00 | 12.00 | 0.00 |" in text


def test_a_summary_without_such_estimates_lists_none_and_a_long_list_is_cut(tmp_path):
    records = _records(n_frames=10)
    text = write_run_outputs(tmp_path, scenario={}, records=records, summary=summarize(records),
                             meta={}, status="complete", plots=False).summary_md.read_text()
    assert ": the frames" not in text
    errors = [LargeError(frame, 6.0, 0.0, 0.0) for frame in range(MAX_LISTED_LARGE_ERRORS + 3)]
    table = "\n".join(large_errors_section([("m", None, error) for error in errors]))
    assert large_errors_section([]) == [] and "| Sequence |" not in table
    assert table.count("| m |") == MAX_LISTED_LARGE_ERRORS + 1
    assert f"| m | {MAX_LISTED_LARGE_ERRORS - 1} | 6.00 |" in table
    assert "| m | and 3 more |" in table
    exactly = large_errors_section([("m", None, error)
                                    for error in errors[:MAX_LISTED_LARGE_ERRORS]])
    assert "more |" not in "\n".join(exactly)
    with_sources = "\n".join(large_errors_section([("m", "walk 1", errors[0]),
                                                   ("m", None, errors[1])]))
    assert "| Sequence |" in with_sources
    assert "| m | walk 1 | 0 |" in with_sources and "| m |  | 1 |" in with_sources


def test_the_summary_states_the_truths_own_residual(run):
    _, files, _, summary = run
    text = files.summary_md.read_text()
    # _records: residual 0.4 px on every frame with a truth (frame 7 has none).
    assert summary.truth_residual.n == 39
    assert ("Ground truth's own residual (RMS distance between its rigid fit and its points: "
            "parallax and zoom no 2-D rigid motion removes): median 0.40 px, largest 0.40 px, "
            "over 39 frames") in text


def test_a_run_from_before_large_errors_were_counted_reads_n_a():
    summary = summarize(_records(n_frames=4)).to_dict()
    for data in summary["run"].values():
        del data["n_large_errors"]
    assert [row["large_errors"] for row in score_rows({"summary": summary})] == [None, None]
    assert large_errors_cell(None, 4) == "n/a" and large_errors_cell(2, 1234) == "2 of 1,234"


def test_each_plot_draws_its_methods_estimates_errors_and_failures(monkeypatch, tmp_path):
    import matplotlib.axes

    import sim.harness.report as report

    drawn, histograms = {}, []
    real_hist = matplotlib.axes.Axes.hist

    def keep_figure(figure, path):
        drawn[path.name] = figure
        return path

    def hist(ax, values, **kwargs):
        histograms.append((kwargs["label"], list(values)))
        return real_hist(ax, values, **kwargs)

    monkeypatch.setattr(report, "save_figure", keep_figure)
    monkeypatch.setattr(matplotlib.axes.Axes, "hist", hist)
    records = _records(n_frames=40)
    write_run_outputs(tmp_path, scenario={}, records=records, summary=summarize(records),
                      meta={}, status="complete")
    own = [record for record in records if record.method == "sift"]
    failed = [record for record in own if record.status != "ok"]
    assert len(failed) == 4
    for ax, axis in zip(drawn["estimates_sift.png"].axes, AXES):
        truth, estimate, crosses = ax.get_lines()
        expected = np.array([record.truth_of(axis) for record in own])
        np.testing.assert_array_equal(truth.get_ydata(), expected)
        np.testing.assert_array_equal(estimate.get_ydata(),
                                      [record.estimate_of(axis) for record in own])
        np.testing.assert_array_equal(crosses.get_xdata(), [record.time_s for record in failed])
        np.testing.assert_array_equal(crosses.get_ydata(),
                                      [record.truth_of(axis) for record in failed])
        # The truth's fit residual (0.4 px) is a band around x and y only; a dotted line
        # where the reference changes (frame 20).
        *band, changes = ax.collections
        assert len(band) == (0 if axis == "rotation" else 1)
        if band:
            edges = np.concatenate([path.vertices[:, 1] for path in band[0].get_paths()])
            assert np.nanmin(edges) == pytest.approx(np.nanmin(expected) - 0.4)
            assert np.nanmax(edges) == pytest.approx(np.nanmax(expected) + 0.4)
        assert [segment[0][0] for segment in changes.get_segments()] == [20 / 30]
    # The histograms: each method's scored errors, per axis.
    assert histograms == [(method, [record.error_of(axis) for record in records
                                    if record.method == method and record.scored])
                          for axis in AXES for method in METHODS]


def test_histogram_bins_span_the_errors_by_the_square_root_rule():
    from sim.harness.report import MAX_HISTOGRAM_BINS, MIN_HISTOGRAM_RANGE, _shared_bins

    edges = _shared_bins(np.array([1.0, 3.0, 2.0, 7.0, 5.0]))
    assert edges[0] == 1.0 and edges[-1] == 7.0 and len(edges) == 3 + 1  # ceil(sqrt(5)) bins
    assert len(_shared_bins(np.arange(1e5))) == MAX_HISTOGRAM_BINS + 1
    equal = _shared_bins(np.full(9, 2.0))
    np.testing.assert_allclose([equal[0], equal[-1]], [2.0 - MIN_HISTOGRAM_RANGE / 2,
                                                       2.0 + MIN_HISTOGRAM_RANGE / 2])
