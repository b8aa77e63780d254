"""Suites: file validation, the held-out suite's seeds, counting rules, outputs, the CI suite.

The counting tests build runs with ``fake_metrics``: a run folder written by the real writer
(``sim.harness.report.write_run_outputs``) from made-up frame records, so the tables read the
real metrics.json layout. The end-to-end test runs the shipped CI suite for real (two 2-s walks).
"""

from __future__ import annotations

import csv
import io
import json
import math
import re
import subprocess
import sys
from pathlib import Path

import pytest

from scenarios import SCENARIOS_DIR, SUITES_DIR
from sim.harness.report import read_metrics, write_run_outputs
from sim.harness.scenario import load_scenario
from sim.harness.scoring import FrameRecord, summarize
from sim.harness.suite import (COLUMNS, FIGURES, TABLE_CSV, TABLE_JSON, TABLE_MD, SuiteError,
                               default_suite_dir, load_suite, plan_suite, run_suite,
                               suite_from_dict, write_suite_outputs)
from sim.harness.sweep import execute as sweep_execute
from sim.harness.sweep import RunOutcome, load_sweep

HELDOUT = SUITES_DIR / "heldout.toml"
CI_SUITE = SUITES_DIR / "ci_suite.toml"
REPO = SCENARIOS_DIR.parent
SCENES = {"corridor", "office", "lab", "hall"}
GAITS = {"default", "paper_like"}
ROTATION = next(iter(FIGURES))


def small_spec(**changes):
    raw = {"name": "tiny", "methods": ["t2fuzzy", "sift"], "max_frames": 3,
           "sequences": [{"scenario": "corridor_straight", "scene_seeds": [5, 6]},
                         {"scenario": "paper_like_gait", "gaits": ["default", "paper_like"],
                          "scene_seeds": [5], "seeds": [0, 1]}]}
    return suite_from_dict({**raw, **changes}, source="tiny.toml")


def sequence_entry(**changes):
    return {"sequences": [{"scenario": "corridor_straight", "scene_seeds": [5], **changes}]}


# --- The file ------------------------------------------------------------------------------

def test_sequences_are_each_entrys_product_in_file_order(tmp_path):
    spec = small_spec()
    assert [s.name for s in spec.sequences] == [
        "corridor_straight__default__scene5__seed0", "corridor_straight__default__scene6__seed0",
        "paper_like_gait__default__scene5__seed0", "paper_like_gait__default__scene5__seed1",
        "paper_like_gait__paper_like__scene5__seed0",
        "paper_like_gait__paper_like__scene5__seed1"]
    assert [s.scene for s in spec.sequences] == ["corridor"] * 2 + ["hall"] * 4
    runs = plan_suite(spec, tmp_path)
    config = runs[5].config
    assert config.out_dir == str(tmp_path / "runs" / runs[5].name)
    assert config.methods == ("t2fuzzy", "sift") and config.max_frames == 3
    assert dict(config.overrides) == {"gait.preset": "paper_like", "scene_seed": 5, "seed": 1}
    scenario = load_scenario(config.scenario, config.overrides)
    assert (scenario.scene, scenario.scene_seed, scenario.seed, scenario.gait.preset) == \
        ("hall", 5, 1, "paper_like")


def test_entry_overrides_apply_over_the_suites():
    spec = small_spec(overrides={"duration_s": 6.0, "sensor.noise_scale": 2.0}, sequences=[
        {"scenario": "corridor_straight", "scene_seeds": [5]},
        {"scenario": "lab_clutter", "scene_seeds": [5], "overrides": {"duration_s": 8.0}}])
    first, second = (dict(s.overrides) for s in spec.sequences)
    assert first["duration_s"] == 6.0 and second["duration_s"] == 8.0
    assert first["sensor.noise_scale"] == second["sensor.noise_scale"] == 2.0


@pytest.mark.parametrize("changes, key, allowed", [
    ({"colour": 1}, "colour", "keys name, description"),
    ({"methods": ["surf"]}, "methods[0]", "t2fuzzy"),
    ({"methods": ["sift", "sift"]}, "methods[1]", "distinct methods"),
    ({"max_frames": 0}, "max_frames", "integer >= 1"),
    ({"record": "no"}, "record", "true or false"),
    ({"name": "a b"}, "name", "letters, digits"),
    ({"name": ".."}, "name", "not only dots"),  # results/suites/.. is results/ itself
    ({"name": "."}, "name", "not only dots"),
    ({"overrides": {"seed": 3}}, "overrides", "not gait.preset, scene_seed, seed"),
    ({"overrides": {"sensor": {"fps": 20.0}}}, "overrides", "single values"),
    # A value an override sets is refused as the scenario refuses it, named as the override.
    ({"overrides": {"sensor.fsp": 20.0}}, "overrides: sensor.fsp", "keys preset, fps"),
    (sequence_entry(overrides={"sensor.fsp": 20.0}), "sequences[0].overrides: sensor.fsp",
     "keys preset, fps"),
    ({"overrides": {"duration_s": -1}}, "overrides: duration_s", "0 < duration_s <= 3600"),
    ({"sequences": []}, "sequences", "[[sequences]] tables"),
    ({"sequences": ["corridor_straight"]}, "sequences[0]", "a table with keys scenario"),
    (sequence_entry(gait="default"), "sequences[0].gait", "keys scenario, gaits"),
    ({"sequences": [{"scene_seeds": [5]}]}, "sequences[0].scenario", "shipped scenario name"),
    (sequence_entry(scenario="no_such_walk"), "sequences[0].scenario", "shipped scenario"),
    (sequence_entry(scene_seeds=[5, -1]), "sequences[0].scene_seeds[1]",
     "integers from 0 to 2**63 - 1"),
    (sequence_entry(scene_seeds=[2**63]), "sequences[0].scene_seeds[0]",
     "integers from 0 to 2**63 - 1"),
    (sequence_entry(scene_seeds=[5, 5]), "sequences[0].scene_seeds[1]", "distinct"),
    (sequence_entry(seeds=[True]), "sequences[0].seeds[0]", "integers from 0 to 2**63 - 1"),
    (sequence_entry(seeds=[0, 2**63]), "sequences[0].seeds[1]", "integers from 0 to 2**63 - 1"),
    (sequence_entry(gaits=["limp"]), "sequences[0].gaits[0]", "GAIT_PRESETS"),
    (sequence_entry(gaits="default"), "sequences[0].gaits", "non-empty list"),
    (sequence_entry(overrides={"scene_seed": 1}), "sequences[0].overrides", "not gait.preset"),
    # A refusal within an override's value names the overrides, not the scenario.
    (sequence_entry(overrides={"pushes": [{"t": 1.0, "impulse_ns": [0.0, 20.0, 0.0]}]}),
     "sequences[0].overrides: pushes[0].impulse_ns", "each -10 to 10"),
    ({"overrides": {"pushes": [{"t": 1.0, "impulse_ns": [0.0, 20.0, 0.0]}]}},
     "overrides: pushes[0].impulse_ns", "each -10 to 10"),
    ({"sequences": [{"scenario": "corridor_straight", "scene_seeds": [5]},
                    {"scenario": "corridor_straight", "scene_seeds": [6, 5]}]},
     "sequences[1]", "each template, gait, scene seed and seed once"),
])
def test_invalid_suites_name_the_file_the_key_and_what_is_allowed(changes, key, allowed):
    with pytest.raises(SuiteError) as info:
        small_spec(**changes)
    message = str(info.value)
    assert isinstance(info.value, ValueError) and "\n" not in message
    assert message.startswith(f"tiny.toml: {key}: "), message
    assert allowed in message.split("; allowed: ")[-1], message
    assert message.count("; allowed: ") == 1 and "; accepted: " not in message, message


def test_two_templates_of_one_file_name_are_refused_as_such(tmp_path):
    # Both gave sequence corridor_straight__default__scene5__seed0, refused as "listed twice".
    (tmp_path / "mine").mkdir()
    copy = tmp_path / "mine" / "corridor_straight.toml"
    copy.write_text((SCENARIOS_DIR / "corridor_straight.toml").read_text())
    with pytest.raises(SuiteError) as info:
        small_spec(sequences=[{"scenario": "corridor_straight", "scene_seeds": [5]},
                              {"scenario": str(copy), "scene_seeds": [5]}])
    assert str(info.value) == (
        f"tiny.toml: sequences[1]: templates corridor_straight and {copy} share the name of "
        f"sequence corridor_straight__default__scene5__seed0; allowed: templates with distinct "
        f"file names")


def test_missing_keys_bad_toml_and_absent_files_are_named(tmp_path):
    with pytest.raises(SuiteError, match=r"^<dict>: sequences: missing"):
        suite_from_dict({"methods": ["sift"]})
    with pytest.raises(SuiteError, match=r"^<dict>: sequences\[0\]\.scene_seeds: missing"):
        suite_from_dict({"methods": ["sift"], "sequences": [{"scenario": "lab_clutter"}]})
    broken = tmp_path / "broken.toml"
    broken.write_text("methods = [\n")
    with pytest.raises(SuiteError, match=r"broken.toml: \(file\): not valid TOML"):
        load_suite(broken)
    with pytest.raises(FileNotFoundError, match="no suite file"):
        load_suite(tmp_path / "absent.toml")


def test_relative_scenario_paths_are_taken_from_the_suite_files_folder(tmp_path):
    (tmp_path / "walks").mkdir()
    (tmp_path / "walks" / "walk.toml").write_text((SCENARIOS_DIR / "lab_clutter.toml").read_text())
    suite = tmp_path / "my_suite.toml"
    suite.write_text('methods = ["sift"]\n[[sequences]]\nscenario = "walks/walk.toml"\n'
                     'scene_seeds = [5]\n')
    spec = load_suite(suite)
    assert spec.name == "my_suite"
    assert spec.sequences[0].scenario == str((tmp_path / "walks" / "walk.toml").resolve())
    assert spec.sequences[0].name == "walk__default__scene5__seed0"


# --- The held-out suite ----------------------------------------------------------------------

def test_heldout_suite_spans_every_scene_and_gait():
    spec = load_suite(HELDOUT)
    assert len(spec.sequences) >= 24
    assert {s.scene for s in spec.sequences} == SCENES
    assert {(s.scene, s.gait) for s in spec.sequences} == {(c, g) for c in SCENES for g in GAITS}
    for sequence in spec.sequences:
        scenario = load_scenario(sequence.scenario, sequence.overrides)
        walking_s = scenario.duration_s - scenario.commands[1].t
        assert walking_s >= 8.0, sequence.name  # a few gait cycles
    assert not spec.record
    assert default_suite_dir(spec) == Path("results", "suites", "heldout")
    assert default_suite_dir(spec, "elsewhere") == Path("elsewhere", "suites", "heldout")


def heldout_scene_seeds() -> set[int]:
    return {s.scene_seed for s in load_suite(HELDOUT).sequences}


def test_no_shipped_scenario_sweep_or_other_suite_uses_a_heldout_scene_seed():
    heldout = heldout_scene_seeds()
    scenario_files = sorted(SCENARIOS_DIR.glob("*.toml")) + sorted(SCENARIOS_DIR.glob("ci/*.toml"))
    assert len(scenario_files) >= 10
    for path in scenario_files:
        assert load_scenario(path).scene_seed not in heldout, path
    for path in sorted(SCENARIOS_DIR.glob("sweeps/*.toml")):
        sweep = load_sweep(path)
        for scenario in sweep.scenarios:
            assert load_scenario(scenario, sweep.overrides).scene_seed not in heldout, path
    for path in sorted(SUITES_DIR.glob("*.toml")):
        if path != HELDOUT:
            assert not {s.scene_seed for s in load_suite(path).sequences} & heldout, path


#: A scene seed written in code: ``scene_seed = 3``, ``scene_seed=3``, ``build_scene("lab", 3)``.
SEED_IN_CODE = re.compile(r"scene_seed\s*[=:]\s*(\d+)|build_scene\(\s*[\"'\w]+\s*,\s*"
                          r"(?:seed\s*=\s*)?(\d+)")


def test_no_code_or_test_in_the_repo_builds_a_heldout_scene():
    heldout = heldout_scene_seeds()
    files = [p for folder in ("sim", "stabilizer", "tests", "examples", "scenarios",
                              "benchmarks")
             for p in (REPO / folder).rglob("*") if p.suffix in (".py", ".toml")]
    assert files
    for path in files:
        if path == HELDOUT:
            continue
        for match in SEED_IN_CODE.finditer(path.read_text(encoding="utf-8")):
            seed = int(match.group(1) or match.group(2))
            assert seed not in heldout, f"{path}: {match.group(0)}"


def test_the_tuning_script_refuses_to_record_a_heldout_scene(tmp_path):
    done = subprocess.run([sys.executable, str(REPO / "benchmarks" / "t2fuzzy_failures.py"),
                           "record", "--seeds", "2001", str(min(heldout_scene_seeds())),
                           "--out", str(tmp_path / "walks")],
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 2 and done.stderr.count("\n") == 1
    assert "is a seed of the held-out suite" in done.stderr
    assert not (tmp_path / "walks").exists()  # refused before the first recording


def test_the_tuning_script_tables_a_recorded_sequence_and_refuses_folders_without_one(tmp_path):
    # Its "before" configuration (no rotation range: math.inf) was refused by Refinements,
    # which ended `table` in a traceback before its first line.
    script = str(REPO / "benchmarks" / "t2fuzzy_failures.py")
    sequence = tmp_path / "cor_de_2001"
    done = subprocess.run([sys.executable, "-m", "sim.harness.cli", "record", "corridor_straight",
                           "--max-frames", "50", "--quiet", "--out", str(sequence)],
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    done = subprocess.run([sys.executable, script, "table", str(sequence)],
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    rows = [line for line in done.stdout.splitlines() if line.startswith("| cor_de_2001 |")]
    assert len(rows) == 6 and sum("| before |" in row for row in rows) == 2, done.stdout
    # Two switches of the check, off together and on together, on every 10th frame.
    done = subprocess.run([sys.executable, script, "switch", str(sequence), "--methods", "ecc",
                           "--stride", "10", "--param", "image_border", "plain_shift_rivals"],
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    with open(sequence / "truth.csv", newline="") as file:
        scored = sum(row["truth_status"] == "ok" for row in csv.DictReader(file)
                     if int(row["frame"]) % 10 == 0)
    for setting in ("off", "on"):
        assert re.search(rf"^ecc, image_border \+ plain_shift_rivals {setting}: \d+ ok of "
                         rf"{scored}, ", done.stdout, re.MULTILINE), done.stdout
    # A summary with a refinement of t2fuzzy's: its line, then the sequence's signed errors.
    done = subprocess.run([sys.executable, script, "summary", str(sequence), "--methods",
                           "t2fuzzy", "--stride", "10", "--refinements",
                           "final_overlap_shift=True"], capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    assert re.search(r"^t2fuzzy: rotation / x / y \d\.\d{3} / \d\.\d{3} / \d\.\d{3}, ",
                     done.stdout, re.MULTILINE), done.stdout
    assert re.search(r"^   signed x / y error, mean, sequence by sequence \(px\): "
                     r"[+-]\d\.\d\d / [+-]\d\.\d\d$", done.stdout, re.MULTILINE), done.stdout
    done = subprocess.run([sys.executable, script, "table", str(tmp_path / "nothing")],
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 2 and done.stderr.count("\n") == 1
    assert "no sequence among the 1 folder(s) given" in done.stderr


# --- Counting and outputs (fake runs) --------------------------------------------------------

def fake_metrics(run_dir: Path, methods: dict[str, float | None], frames: int = 4) -> dict:
    """A run folder whose methods have the given |error| on every frame (None: every frame
    failed); returns its metrics.json."""
    records = []
    for frame in range(frames):
        for method, error in methods.items():
            failed = error is None
            value = math.nan if failed else error
            records.append(FrameRecord(
                frame_index=frame, time_s=frame / 30, gait_cycle=0, reference_index=0,
                method=method, status="too_few_matches" if failed else "ok", ms=1.0,
                est_angle_deg=value, est_dx_px=value, est_dy_px=value, true_angle_deg=0.0,
                true_dx_px=0.0, true_dy_px=0.0, truth_status="ok", truth_residual_px=0.1,
                truth_points=100, err_angle_deg=value, err_dx_px=value, err_dy_px=value))
    write_run_outputs(run_dir, scenario={"name": run_dir.name}, records=records,
                      summary=summarize(records), meta={"frames_done": frames},
                      status="complete", plots=False)
    return read_metrics(run_dir)


def outcomes_of(spec, tmp_path, errors_per_run):
    """Outcomes of ``spec``'s runs from fake metrics: per run a dict method -> error, or a
    string (the run raised with that message)."""
    outcomes = []
    for suite_run_, errors in zip(plan_suite(spec, tmp_path), errors_per_run):
        if isinstance(errors, str):
            outcomes.append(RunOutcome(suite_run_, None, error=errors))
        else:
            outcomes.append(RunOutcome(suite_run_, fake_metrics(Path(suite_run_.config.out_dir),
                                                                errors)))
    return outcomes


def twelve_sequence_spec():
    return small_spec(sequences=[{"scenario": "corridor_straight", "scene_seeds": list(range(12))}])


def test_a_method_without_successful_estimates_counts_as_failing_and_leaves_error_means(tmp_path):
    spec = small_spec(sequences=[{"scenario": "corridor_straight", "scene_seeds": [5, 6, 7]}])
    outcomes = outcomes_of(spec, tmp_path, [{"t2fuzzy": 0.1, "sift": 0.5},
                                            {"t2fuzzy": 0.2, "sift": None},
                                            "RuntimeError: simulated crash"])
    result = write_suite_outputs(tmp_path, spec, outcomes)
    means = result.figures["means"]
    assert means["t2fuzzy"][ROTATION]["n"] == 2 and means["sift"][ROTATION]["n"] == 1
    assert means["sift"][ROTATION]["mean"] == pytest.approx(0.5)
    assert means["sift"]["failure_rate"]["mean"] == pytest.approx(0.5)  # 0 and 1
    assert means["sift"]["failure_rate"]["n"] == 2  # the crashed run counts for no method
    assert len(result.rows) == 4 and len(result.failed) == 1
    assert "1 failed" in result.markdown and "2 scored frames and are counted" in result.markdown


def test_a_method_with_no_figure_reads_n_a_in_the_tables(tmp_path):
    spec = small_spec(sequences=[{"scenario": "corridor_straight", "scene_seeds": [5]}])
    outcomes = outcomes_of(spec, tmp_path, ["RuntimeError: simulated crash"])
    markdown = write_suite_outputs(tmp_path, spec, outcomes).markdown
    assert "| t2fuzzy | n/a no interval (n=0) |" in markdown and "n/a%" not in markdown


def test_paired_differences_say_which_method_is_lower_and_whether_the_data_say_so(tmp_path):
    spec = twelve_sequence_spec()
    errors = [{"t2fuzzy": 0.1 + 0.05 * i, "sift": 0.3 + 0.05 * i + 0.01 * (i % 3)}
              for i in range(12)]
    result = write_suite_outputs(tmp_path, spec, outcomes_of(spec, tmp_path, errors))
    rotation = next(d for d in result.figures["differences"] if d["figure"] == ROTATION)
    assert (rotation["first"], rotation["second"], rotation["lower"]) == ("t2fuzzy", "sift",
                                                                        "t2fuzzy")
    assert rotation["clear"] and rotation["high"] < 0 and rotation["n"] == 12
    failure = next(d for d in result.figures["differences"] if d["figure"] == "failure_rate")
    assert not failure["clear"] and failure["mean"] == 0.0 and failure["lower"] == ""  # a tie
    assert "t2fuzzy is lower (interval excludes 0)" in result.markdown
    assert "no clear difference (interval contains 0)" in result.markdown
    # A difference of failure rates is in percentage points, not a relative %.
    assert "| t2fuzzy | sift | Failure rate (points) | 0.0 | [0.0, 0.0] | 12 |" in result.markdown


def test_a_suite_of_one_method_says_there_is_nothing_to_compare(tmp_path):
    spec = small_spec(methods=["t2fuzzy"],
                      sequences=[{"scenario": "corridor_straight", "scene_seeds": [5, 6]}])
    result = write_suite_outputs(tmp_path, spec, outcomes_of(
        spec, tmp_path, [{"t2fuzzy": 0.1}, {"t2fuzzy": 0.2}]))
    assert result.figures["differences"] == []
    assert "No pairs to compare: the suite scores one method." in result.markdown
    assert "| First | Second |" not in result.markdown


def test_ok_estimates_off_by_more_than_the_limits_are_counted_over_all_sequences(tmp_path):
    spec = small_spec(sequences=[{"scenario": "corridor_straight", "scene_seeds": [5, 6]}])
    # fake_metrics: every frame (4 a run) off by the error given, on every axis.
    result = write_suite_outputs(tmp_path, spec, outcomes_of(
        spec, tmp_path, [{"t2fuzzy": 12.0, "sift": 0.1}, {"t2fuzzy": 0.1, "sift": None}]))
    first = result.rows[0]["sequence"]
    assert result.figures["large_errors"] == {
        "t2fuzzy": {"count": 4, "scored_frames": 8,
                    "frames": [{"sequence": first, "frame": frame, "rotation_deg": 12.0,
                                "x_px": 12.0, "y_px": 12.0} for frame in range(4)]},
        "sift": {"count": 0, "scored_frames": 4, "frames": []}}
    assert "Ok but off (> 5° or 10 px), all sequences |" in result.markdown
    # Each such estimate is listed: where, and how far off.
    assert "### Ok but off (> 5° or 10 px): the frames" in result.markdown
    assert f"| t2fuzzy | {first} | 3 | 12.00 | 12.00 | 12.00 |" in result.markdown
    listed = json.loads((tmp_path / TABLE_JSON).read_text())["large_errors"]["t2fuzzy"]
    assert [entry["frame"] for entry in listed["frames"]] == [0, 1, 2, 3]
    assert "(n=2) | 4 of 8 |" in result.markdown and "| 0 of 4 |" in result.markdown
    rows = list(csv.DictReader(io.StringIO((tmp_path / TABLE_CSV).read_text())))
    assert [(row["method"], row["scored_frames"], row["large_errors"]) for row in rows] == [
        ("t2fuzzy", "4", "4"), ("sift", "4", "0"), ("t2fuzzy", "4", "0"), ("sift", "0", "0")]


def test_failed_frames_are_pooled_by_status_over_all_sequences(tmp_path):
    spec = small_spec(sequences=[{"scenario": "corridor_straight", "scene_seeds": [5, 6, 7]}])
    outcomes = outcomes_of(spec, tmp_path, [{"t2fuzzy": 0.1, "sift": None},
                                            {"t2fuzzy": 0.1, "sift": None},
                                            {"t2fuzzy": 0.1, "sift": 0.1}])
    # fake_metrics fails every frame as too_few_matches; one run's check doubted two more.
    sift = outcomes[2].metrics["summary"]["run"]["sift"]
    sift["n_failed"], sift["failures"] = 2, {"unverified": 2}
    result = write_suite_outputs(tmp_path, spec, outcomes)
    assert result.figures["failures"] == {
        "t2fuzzy": {"frames": 12, "failed": 0, "by_status": {}},
        "sift": {"frames": 12, "failed": 10,
                 "by_status": {"too_few_matches": 8, "unverified": 2}}}
    assert "| t2fuzzy | 0 of 12 (0.0%) | - |" in result.markdown
    assert ("| sift | 10 of 12 (83.3%) | too_few_matches 8 (66.7%), unverified 2 (16.7%) |"
            in result.markdown)


def test_runs_from_before_large_errors_were_counted_give_no_total(tmp_path):
    spec = small_spec(sequences=[{"scenario": "corridor_straight", "scene_seeds": [5, 6]}])
    outcomes = outcomes_of(spec, tmp_path, [{"t2fuzzy": 12.0, "sift": 0.1}] * 2)
    for method in outcomes[0].metrics["summary"]["run"].values():
        del method["n_large_errors"], method["large_errors"]
    result = write_suite_outputs(tmp_path, spec, outcomes)
    totals = result.figures["large_errors"]["t2fuzzy"]
    assert (totals["count"], totals["scored_frames"]) == (None, 8)
    assert {entry["sequence"] for entry in totals["frames"]} == {result.rows[-1]["sequence"]}
    assert "(n=2) | n/a |" in result.markdown


def test_few_sequences_give_intervals_but_no_verdict(tmp_path):
    spec = small_spec(sequences=[{"scenario": "corridor_straight", "scene_seeds": [5, 6, 7]}])
    errors = [{"t2fuzzy": 0.1 * i, "sift": 0.1 * i + 1.0} for i in range(3)]
    result = write_suite_outputs(tmp_path, spec, outcomes_of(spec, tmp_path, errors))
    rotation = next(d for d in result.figures["differences"] if d["figure"] == ROTATION)
    assert rotation["high"] < 0 and not rotation["clear"]
    assert "too few sequences for a verdict" in result.markdown


@pytest.mark.parametrize("n_sequences, verdict", [(9, False), (10, True)])
def test_a_difference_gets_a_verdict_from_ten_sequences_on(tmp_path, n_sequences, verdict):
    spec = small_spec(sequences=[{"scenario": "corridor_straight",
                                  "scene_seeds": list(range(n_sequences))}])
    errors = [{"t2fuzzy": 0.1 * i, "sift": 0.1 * i + 1.0} for i in range(n_sequences)]
    result = write_suite_outputs(tmp_path, spec, outcomes_of(spec, tmp_path, errors))
    rotation = next(d for d in result.figures["differences"] if d["figure"] == ROTATION)
    assert rotation["n"] == n_sequences and rotation["high"] < 0
    assert rotation["clear"] is verdict and rotation["lower"] == "t2fuzzy"
    assert ("t2fuzzy is lower (interval excludes 0)" in result.markdown) is verdict
    assert ("too few sequences for a verdict (n < 10)" in result.markdown) is not verdict


def test_the_summary_counts_the_sequences_that_fell(tmp_path):
    spec = small_spec(sequences=[{"scenario": "corridor_straight", "scene_seeds": [5, 6, 7]}])
    outcomes = outcomes_of(spec, tmp_path, [{"t2fuzzy": 0.1, "sift": 0.2}] * 3)
    outcomes[1].metrics["status"] = "fell"
    result = write_suite_outputs(tmp_path, spec, outcomes)
    assert "3 planned, 3 finished (0 already done before this call), 0 failed, 1 fell" in \
        result.markdown


def test_an_interrupted_suite_writes_the_tables_of_the_runs_finished(tmp_path, monkeypatch):
    spec = small_spec(sequences=[{"scenario": "corridor_straight", "scene_seeds": [5, 6]}])

    def first_then_interrupt(pending, run_fn, workers, ray_address):
        yield RunOutcome(pending[0], fake_metrics(Path(pending[0].config.out_dir),
                                                  {"t2fuzzy": 0.1, "sift": 0.2}))
        raise KeyboardInterrupt

    monkeypatch.setattr(sweep_execute, "_run_local", first_then_interrupt)
    with pytest.raises(KeyboardInterrupt):
        run_suite(spec, tmp_path)
    assert "2 planned, 1 finished" in (tmp_path / TABLE_MD).read_text()
    assert len(json.loads((tmp_path / TABLE_JSON).read_text())["rows"]) == 2


def test_a_rescore_interrupted_at_once_keeps_the_earlier_runs_in_the_tables(tmp_path,
                                                                           monkeypatch):
    """sift added to a suite whose runs scored t2fuzzy, stopped before any run finished anew:
    the tables still count every sequence (sift has no figure yet)."""
    spec = small_spec(sequences=[{"scenario": "corridor_straight", "scene_seeds": [5, 6]}])
    for planned, error in zip(plan_suite(spec, tmp_path), (0.1, 0.3)):
        fake_metrics(Path(planned.config.out_dir), {"t2fuzzy": error})

    def interrupted_at_once(pending, run_fn, workers, ray_address):
        raise KeyboardInterrupt

    monkeypatch.setattr(sweep_execute, "_run_local", interrupted_at_once)
    with pytest.raises(KeyboardInterrupt):
        run_suite(spec, tmp_path)
    document = json.loads((tmp_path / TABLE_JSON).read_text())
    assert [entry["name"] for entry in document["sequences"]] == [
        planned.name for planned in plan_suite(spec, tmp_path)]
    assert document["means"]["t2fuzzy"][ROTATION]["mean"] == pytest.approx(0.2)
    assert document["means"]["sift"][ROTATION]["n"] == 0
    assert "2 planned, 2 finished (2 already done before this call)" in (
        tmp_path / TABLE_MD).read_text()


def test_a_file_where_a_sequence_folder_goes_is_refused_before_any_run(tmp_path):
    def never_run(config):
        raise AssertionError("a run started")

    planned = plan_suite(small_spec(), tmp_path)[2]
    Path(planned.config.out_dir).mkdir(parents=True)
    (Path(planned.config.out_dir) / "sequence").write_text("a hand-made file")
    with pytest.raises(ValueError, match=f"{planned.name}/sequence: is a file where run "
                                         f"{planned.name} keeps a folder; accepted: a folder "
                                         f"there, or nothing"):
        run_suite(small_spec(), tmp_path, workers=1, run_fn=never_run)
    assert not (tmp_path / TABLE_MD).exists()


def test_bad_backend_and_workers_are_refused(tmp_path):
    with pytest.raises(ValueError, match="unknown backend .dask.; accepted: local, ray"):
        run_suite(small_spec(), tmp_path, backend="dask")
    with pytest.raises(ValueError, match=r"workers \S+: accepted: an integer from 1 to \d+"):
        run_suite(small_spec(), tmp_path, workers=0)


@pytest.mark.parametrize("estimates, message", [
    ({"sift": "{sequence}.csv"}, "--estimates sift: sift is also a method of the suite"),
    ({"mine": "mine.csv"}, "the path has no {sequence}"),
    ({"mine": "missing/{sequence}.csv"}, r"no file .*missing/corridor_straight__default__"
                                         r"scene5__seed0.csv \(6 of the suite's 6 sequences"),
])
def test_estimates_files_that_cannot_be_scored_are_refused_before_any_work(
        tmp_path, monkeypatch, estimates, message):
    monkeypatch.chdir(tmp_path)
    with pytest.raises(ValueError, match=message):
        run_suite(small_spec(), tmp_path / "out", estimates=estimates)
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("bad_row, message", [
    ("1,0,0,0\n", "1 appears a second time"), ("3,0,0,0\n", "frame: 3"),
    ("2,zero,0,0\n", "'zero' is not a number")])
def test_an_estimates_file_with_a_bad_row_is_refused_before_any_run(tmp_path, monkeypatch,
                                                                    bad_row, message):
    # Found only when its sequence was scored, it failed that run, and so every method's
    # figures on that sequence left the tables.
    monkeypatch.chdir(tmp_path)
    spec = small_spec()  # max_frames 3: frames 0, 1 and 2
    (tmp_path / "mine").mkdir()
    for sequence in spec.sequences:
        (tmp_path / "mine" / f"{sequence.name}.csv").write_text(
            "frame,angle_deg,dx,dy\n1,0,0,0\n" if sequence is not spec.sequences[-1]
            else "frame,angle_deg,dx,dy\n1,0,0,0\n" + bad_row)
    with pytest.raises(ValueError, match=message) as refused:
        run_suite(spec, tmp_path / "out", estimates={"mine": "mine/{sequence}.csv"})
    assert str(refused.value).startswith(f"mine/{spec.sequences[-1].name}.csv:3: ")
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("argument", [" =mine/{sequence}.csv", "=mine/{sequence}.csv",
                                      "mine= "])
def test_an_estimates_argument_with_a_blank_name_or_path_is_refused(argument, capsys):
    from sim.harness.cli import main

    with pytest.raises(SystemExit) as exit_info:
        main(["suite", str(CI_SUITE), "--estimates", argument])
    err = capsys.readouterr().err
    assert exit_info.value.code == 2 and err.count("\n") == 1
    assert f"--estimates: {argument!r}: accepted: NAME=PATH, NAME not blank" in err


def test_check_estimates_without_estimates_is_refused_before_any_folder(tmp_path, capsys):
    from sim.harness.cli import main

    code = main(["suite", str(CI_SUITE), "--check-estimates", "--out", str(tmp_path / "out")])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and not (tmp_path / "out").exists()
    assert "--check-estimates: no estimates file to check; accepted: with --estimates" in err


# --- The CI suite, for real ------------------------------------------------------------------

def run_command(argv: list[str]) -> int:
    from sim.harness.cli import main

    return main(argv)


def test_ci_suite_runs_end_to_end_and_resumes(tmp_path, capsys):
    out = tmp_path / "suite"
    assert run_command(["suite", str(CI_SUITE), "--out", str(out), "--workers", "2"]) == 0
    markdown = (out / TABLE_MD).read_text()
    assert "## Means over sequences" in markdown and "## Paired differences" in markdown
    assert re.search(r"\| t2fuzzy \| \d+\.\d+ \[\d+\.\d+, \d+\.\d+\] \(n=2\)", markdown)
    with open(out / TABLE_CSV, newline="", encoding="utf-8") as handle:
        rows = list(csv.DictReader(handle))
    assert tuple(rows[0]) == COLUMNS
    assert [(r["sequence"], r["method"]) for r in rows] == [
        (f"ci_corridor__default__scene{seed}__seed0", method)
        for seed in (0, 1) for method in ("t2fuzzy", "sift")]
    assert all(r["run_status"] == "complete" and r["frames"] == "60" for r in rows)
    document = json.loads((out / TABLE_JSON).read_text())
    for method in ("t2fuzzy", "sift"):
        for figure in FIGURES:
            interval = document["means"][method][figure]
            assert interval["n"] == 2 and interval["method"] in ("BCa", "percentile")
            assert interval["low"] <= interval["mean"] <= interval["high"]
    assert [(d["first"], d["second"]) for d in document["differences"]] == \
        [("t2fuzzy", "sift")] * len(FIGURES)
    assert "suite folder:" in capsys.readouterr().out
    # Run again: both runs are done, so nothing is simulated and the tables are the same.
    assert run_command(["suite", str(CI_SUITE), "--out", str(out)]) == 0
    again = (out / TABLE_MD).read_text()
    assert "2 finished (2 already done before this call)" in again
    assert json.loads((out / TABLE_JSON).read_text())["means"] == document["means"]
    # A method added to the suite file: the recorded sequences are scored again with every
    # method (none is simulated again), and the new method gets its figures.
    recorded = sorted(path.stat().st_mtime_ns for path in out.glob("runs/*/sequence/*.json"))
    widened = tmp_path / "ci_suite.toml"
    widened.write_text(CI_SUITE.read_text().replace(
        'methods = ["t2fuzzy", "sift"]', 'methods = ["t2fuzzy", "sift", "ecc"]').replace(
        '"../ci/ci_corridor.toml"', json.dumps(str(SCENARIOS_DIR / "ci" / "ci_corridor.toml"))))
    assert run_command(["suite", str(widened), "--out", str(out), "--workers", "2"]) == 0
    assert "2 finished (0 already done before this call)" in (out / TABLE_MD).read_text()
    assert sorted(path.stat().st_mtime_ns for path in out.glob("runs/*/sequence/*.json")) \
        == recorded
    widened_means = json.loads((out / TABLE_JSON).read_text())["means"]
    assert widened_means["ecc"]["failure_rate"]["n"] == 2
    assert {method: widened_means[method] for method in ("t2fuzzy", "sift")} == document["means"]
    # Another program's estimates, one CSV per sequence (here the truth plus known offsets),
    # are scored and compared like a method.
    def write_estimates(sequence: Path, angle_offset_deg: float) -> None:
        with open(sequence / "truth.csv", newline="", encoding="utf-8") as handle:
            truth = list(csv.DictReader(handle))
        (tmp_path / f"{sequence.parent.name}.csv").write_text("frame,angle_deg,dx,dy\n" + "".join(
            f"{row['frame']},{float(row['angle_deg']) + angle_offset_deg},"
            f"{float(row['dx']) - 1.0},{row['dy']}\n" for row in truth))

    sequences = sorted(out.glob("runs/*/sequence"))
    for sequence in sequences:
        write_estimates(sequence, 0.5)
    with_estimates = ["suite", str(widened), "--out", str(out), "--workers", "2",
                      "--estimates", f"mine={tmp_path}/{{sequence}}.csv"]
    assert run_command(with_estimates) == 0
    scored = json.loads((out / TABLE_JSON).read_text())
    assert scored["estimates"] == {"mine": f"{tmp_path}/{{sequence}}.csv"}
    mine = scored["means"]["mine"]
    assert mine[ROTATION]["mean"] == pytest.approx(0.5) and mine[ROTATION]["n"] == 2
    assert mine["failure_rate"]["mean"] == 0.0
    assert ("t2fuzzy", "mine") in {(d["first"], d["second"]) for d in scored["differences"]}
    assert scored["means"]["ecc"] == widened_means["ecc"]
    # An estimates file changed under the same path is scored again, and only its sequence.
    write_estimates(sequences[0], 1.5)
    assert run_command(with_estimates) == 0
    assert "2 finished (1 already done before this call)" in (out / TABLE_MD).read_text()
    rescored = json.loads((out / TABLE_JSON).read_text())["means"]
    assert rescored["mine"][ROTATION]["mean"] == pytest.approx(1.0)
    # Asked to check the estimates, every sequence is scored again, through the trust check.
    assert run_command([*with_estimates, "--check-estimates"]) == 0
    assert "2 finished (0 already done before this call)" in (out / TABLE_MD).read_text()
    checked = json.loads((out / TABLE_JSON).read_text())
    assert checked["estimates_checked"] is True
    assert "Their ok rows passed the trust check" in (out / TABLE_MD).read_text()
    assert set(checked["failures"]["mine"]["by_status"]) <= {"unverified"}


def test_a_suite_sequence_is_recorded_once_and_scored_as_a_run_would(tmp_path):
    from sim.harness.runner import RunConfig, run
    from sim.harness.sequence import load_sequence
    from sim.harness.suite.run import SEQUENCE_FOLDER, record_then_score

    config = RunConfig(scenario=str(SCENARIOS_DIR / "ci" / "ci_corridor.toml"),
                       out_dir=str(tmp_path / "job"), methods=("ecc",), record=False,
                       max_frames=12, overrides={"scene_seed": 3})
    scored = record_then_score(config)
    assert load_sequence(tmp_path / "job" / SEQUENCE_FOLDER).n_frames == 12
    direct = run(RunConfig(**{**config.__dict__, "out_dir": str(tmp_path / "run")}))
    run_errors = direct["summary"]["run"]["ecc"]["errors"]
    assert scored["summary"]["run"]["ecc"]["errors"] == run_errors
    # A job resumed after its scoring was cut short scores the recording it has.
    recorded = (tmp_path / "job" / SEQUENCE_FOLDER / "sequence.json").stat().st_mtime_ns
    assert record_then_score(config)["summary"]["run"]["ecc"]["errors"] == run_errors
    assert (tmp_path / "job" / SEQUENCE_FOLDER / "sequence.json").stat().st_mtime_ns == recorded
    # Another max_frames, or damaged frames, are recorded again; an interrupted recording is
    # not scored, and the stop goes on.
    longer = RunConfig(**{**config.__dict__, "max_frames": 14})
    run_errors_14 = record_then_score(longer)["summary"]["run"]["ecc"]["errors"]
    assert load_sequence(tmp_path / "job" / SEQUENCE_FOLDER).n_frames == 14
    (tmp_path / "job" / SEQUENCE_FOLDER / "depth" / "000005.png").write_bytes(b"damaged")
    assert record_then_score(longer)["summary"]["run"]["ecc"]["errors"] == \
        record_then_score(longer)["summary"]["run"]["ecc"]["errors"]
    assert load_sequence(tmp_path / "job" / SEQUENCE_FOLDER).frame(5).depth_m.size
    # A sequence.json lost or unreadable, too: the recording's remains were refused as a
    # folder of someone else's files, on every run of the suite again.
    header = tmp_path / "job" / SEQUENCE_FOLDER / "sequence.json"
    (tmp_path / "job" / SEQUENCE_FOLDER / "notes.txt").write_text("mine")
    for damage in ("", "{", "{}", "[1]", None):
        if damage is None:
            header.unlink()
        else:
            header.write_text(damage)
        assert record_then_score(longer)["summary"]["run"]["ecc"]["errors"] == run_errors_14
        assert load_sequence(tmp_path / "job" / SEQUENCE_FOLDER).n_frames == 14
    assert (tmp_path / "job" / SEQUENCE_FOLDER / "notes.txt").read_text() == "mine"
    # A recording that ended with a fall is finished with fewer frames than planned; one with
    # more is recorded again.
    document = json.loads(header.read_text())
    header.write_text(json.dumps({**document, "ended": "fell",
                                  "fall": {"time_s": 0.4, "reason": "torso too low"}}))
    recorded = header.stat().st_mtime_ns
    record_then_score(RunConfig(**{**config.__dict__, "max_frames": 16}))
    assert header.stat().st_mtime_ns == recorded
    record_then_score(config)
    assert load_sequence(tmp_path / "job" / SEQUENCE_FOLDER).n_frames == 12


def test_an_interrupted_recording_is_not_scored_and_is_recorded_again(tmp_path, monkeypatch):
    import sim.harness.runner
    from sim.harness.runner import RunConfig
    from sim.harness.suite.run import SEQUENCE_FOLDER, record_then_score

    config = RunConfig(scenario=str(SCENARIOS_DIR / "ci" / "ci_corridor.toml"),
                       out_dir=str(tmp_path / "job"), methods=("ecc",), record=False,
                       max_frames=6)
    real = sim.harness.runner.frame_truth
    calls = []

    def interrupted_at_the_fourth(*args):
        calls.append(1)
        if len(calls) == 4:
            raise KeyboardInterrupt
        return real(*args)

    monkeypatch.setattr(sim.harness.runner, "frame_truth", interrupted_at_the_fourth)
    with pytest.raises(KeyboardInterrupt):
        record_then_score(config)
    assert not (tmp_path / "job" / "metrics.json").exists()
    monkeypatch.setattr(sim.harness.runner, "frame_truth", real)
    assert record_then_score(config)["summary"]["n_frames"] == 6
    sequence = json.loads((tmp_path / "job" / SEQUENCE_FOLDER / "sequence.json").read_text())
    assert sequence["ended"] == "complete" and sequence["frames"] == 6
