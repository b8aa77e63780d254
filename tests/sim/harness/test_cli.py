"""The egostab command: help, listing, error reporting, ideal mode, aggregation."""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path
from types import SimpleNamespace

import cv2
import numpy as np
import pytest

from scenarios import DEFAULT_SCENARIO, SCENARIOS_DIR
from sim.harness.cli import build_parser, main
from sim.harness.scenario import list_scenarios
from stabilizer import depth_to_disparity
from stabilizer.testing import make_depth_scene

SUBCOMMANDS = ("run", "record", "score", "ideal", "aggregate", "list", "methods", "bench", "gate",
               "sweep", "suite")


@pytest.mark.parametrize("argv", [[]] + [[name] for name in SUBCOMMANDS])
def test_help_of_every_subcommand(argv, capsys):
    with pytest.raises(SystemExit) as exit_info:
        main([*argv, "--help"])
    assert exit_info.value.code == 0
    assert "usage: egostab" in capsys.readouterr().out


def test_the_parser_and_the_methods_listing_load_neither_the_scoring_nor_the_simulator():
    """``egostab --help`` and ``egostab methods`` answer at once: building the parser (the
    suite subcommand's too) loads no scipy, matplotlib or MuJoCo, which every run needs and
    which cost a second to import."""
    probe = ("import sys\n"
             "from sim.harness.cli import main\n"
             "main(['methods'])\n"
             "print(sorted({name.split('.')[0] for name in sys.modules}"
             " & {'scipy', 'matplotlib', 'mujoco', 'dm_control', 'rerun'}))\n")
    completed = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True,
                               check=True)
    assert "t2fuzzy" in completed.stdout
    assert completed.stdout.splitlines()[-1] == "[]"


def test_list_shows_every_shipped_scenario(capsys):
    assert main(["list"]) == 0
    out = capsys.readouterr().out
    names = [path.stem for path in list_scenarios()]
    assert DEFAULT_SCENARIO in names and len(names) >= 7
    for name in names:
        assert name in out


def test_unknown_method_is_rejected_with_the_accepted_ones(capsys):
    with pytest.raises(SystemExit) as exit_info:
        build_parser().parse_args(["run", "--methods", "t2fuzzy,no_such_method"])
    assert exit_info.value.code == 2
    err = capsys.readouterr().err
    assert "no_such_method" in err and "fourier_mellin" in err


@pytest.mark.parametrize("body, key", [
    ("scene = 'corridor'\nspeed_of_light = 3\n", "speed_of_light"),
    ("scene = 'corridor'\nduration_s = 'long'\n", "duration_s"),
    ("scene = 'corridor'\n[sensor]\nfps = 90.0\n", "sensor.fps"),
    ("scene = 'garage'\n", "scene"),
])
def test_bad_scenario_file_is_a_clear_error_and_writes_nothing(tmp_path, capsys, body, key):
    scenario = tmp_path / "bad.toml"
    scenario.write_text(body)
    out_dir = tmp_path / "out"
    assert main(["run", str(scenario), "--out", str(out_dir), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert str(scenario) in err and key in err
    assert not out_dir.exists()


def _write_png(path, image):
    assert cv2.imwrite(str(path), image)
    return path


@pytest.mark.parametrize("bits", [8, 16])
def test_ideal_mode_on_a_png(tmp_path, capsys, bits):
    depth = make_depth_scene(5)
    image = depth_to_disparity(depth) if bits == 8 else np.rint(depth * 1000).astype(np.uint16)
    png = _write_png(tmp_path / f"scene{bits}.png", image)
    out_dir = tmp_path / "ideal"
    assert main(["ideal", str(png), "--methods", "t2fuzzy,ecc", "--frames", "8",
                 "--out", str(out_dir)]) == 0
    metrics = json.loads((out_dir / "metrics.json").read_text())
    assert metrics["summary"]["n_frames"] == 8
    assert (out_dir / "estimates_t2fuzzy.png").is_file()
    assert "Rotation displacement" in capsys.readouterr().out


def test_ideal_mode_rejects_what_it_cannot_read(tmp_path, capsys):
    rgb = _write_png(tmp_path / "rgb.png", np.zeros((20, 20, 3), np.uint8))
    assert main(["ideal", str(rgb), "--out", str(tmp_path / "o")]) == 2
    assert "single-channel" in capsys.readouterr().err
    assert main(["ideal", "no_such_file.png", "--out", str(tmp_path / "o")]) == 2
    assert "neither a file nor a scene" in capsys.readouterr().err
    np.save(tmp_path / "objects.npy", np.array([{"depth": 1.0}], dtype=object))
    (tmp_path / "text.npy").write_text("not numpy")
    for name in ("objects.npy", "text.npy"):
        assert main(["ideal", str(tmp_path / name), "--out", str(tmp_path / "o")]) == 2
        err = _one_line_error(capsys, "ideal")
        assert f"{name}: cannot read it as a .npy array" in err


def test_the_ideal_resize_help_names_the_limits_the_experiment_applies(capsys):
    # The help spells the limits out rather than import them when every command starts.
    from sim.harness.ideal import MAX_IMAGE_PIXELS
    from stabilizer.api import MAX_SIDE

    with pytest.raises(SystemExit):
        main(["ideal", "--help"])
    help_text = " ".join(capsys.readouterr().out.split())  # as one line: the help wraps
    assert MAX_IMAGE_PIXELS == 1280 * 1024
    assert (f"--resize scale an image larger than 1280 x 1024 pixels, or longer than "
            f"{MAX_SIDE} on a side, down to fit") in help_text


def test_aggregate_makes_one_table_of_several_runs(tmp_path, capsys):
    png = _write_png(tmp_path / "scene.png", depth_to_disparity(make_depth_scene(2)))
    for name in ("a", "b"):
        assert main(["ideal", str(png), "--methods", "ecc", "--frames", "4",
                     "--out", str(tmp_path / name)]) == 0
    capsys.readouterr()
    table_path = tmp_path / "table.md"
    assert main(["aggregate", str(tmp_path / "a"), str(tmp_path / "b"),
                 "--out", str(table_path)]) == 0
    out = capsys.readouterr().out
    assert out.count("ecc") >= 2
    assert table_path.read_text().strip() == out.strip()


def test_sweep_runs_the_real_runner_and_resumes(tmp_path, capsys):
    sweep = tmp_path / "tiny.toml"
    sweep.write_text(
        f'scenarios = ["{(SCENARIOS_DIR / "ci" / "ci_corridor.toml").as_posix()}"]\n'
        "seeds = [0]\nnoise_levels = [0.5, 2.0]\nmethods = [\"ecc\"]\nmax_frames = 4\n")
    out_dir = tmp_path / "sweep"
    assert main(["sweep", str(sweep), "--out", str(out_dir), "--workers", "2"]) == 0
    runs = sorted((out_dir / "runs").iterdir())
    assert len(runs) == 2
    assert all(json.loads((run / "metrics.json").read_text())["status"] == "complete"
               for run in runs)
    assert (out_dir / "sweep.md").is_file() and "ecc" in capsys.readouterr().out
    stamps = [(run / "metrics.json").stat().st_mtime_ns for run in runs]
    assert main(["sweep", str(sweep), "--out", str(out_dir), "--workers", "2"]) == 0
    assert [(run / "metrics.json").stat().st_mtime_ns for run in runs] == stamps


def _one_line_error(capsys, command: str) -> str:
    err = capsys.readouterr().err.strip()
    assert err.startswith(f"egostab {command}: error: ") and "\n" not in err, err
    assert "Traceback" not in err
    return err


@pytest.mark.parametrize("command", [["run"], ["score", "seq"], ["list"]])
def test_an_unknown_option_is_refused_by_its_subcommand(command, capsys):
    # argparse refused it as the top level's, pointing to `egostab --help`.
    with pytest.raises(SystemExit) as exit_info:
        main([*command, "--bogus"])
    command = command[0]
    err = _one_line_error(capsys, command)
    assert exit_info.value.code == 2
    assert err.endswith(f"unrecognized arguments: --bogus (usage: egostab {command} --help)")


@pytest.mark.parametrize("scenario", ["no_such_scenario", "/no/such/file.toml"])
def test_a_missing_scenario_is_one_line_and_status_2(scenario, tmp_path, capsys):
    assert main(["run", scenario, "--out", str(tmp_path / "run")]) == 2
    assert "scenario" in _one_line_error(capsys, "run")
    assert not (tmp_path / "run").exists()


def test_a_missing_sweep_file_is_one_line_and_status_2(tmp_path, capsys):
    assert main(["sweep", str(tmp_path / "none.toml")]) == 2
    assert "none.toml" in _one_line_error(capsys, "sweep")


def test_a_shipped_scenario_runs_into_a_folder_of_its_own_name(tmp_path, monkeypatch):
    # The output folder is made before the run reads its scenario: it must not stand for it.
    monkeypatch.chdir(tmp_path)
    assert main(["run", "corridor_straight", "--out", "corridor_straight", "--no-record",
                 "--max-frames", "2", "--methods", "ecc", "--quiet"]) == 0
    assert (tmp_path / "corridor_straight" / "metrics.json").is_file()


def test_without_out_each_command_writes_its_folder_of_the_working_folder(tmp_path,
                                                                          monkeypatch):
    monkeypatch.chdir(tmp_path)
    short = ["--max-frames", "2", "--quiet"]
    assert main(["record", "corridor_straight", *short]) == 0
    assert (tmp_path / "sequences" / "corridor_straight" / "sequence.json").is_file()
    shutil.copy(SCENARIOS_DIR / "ci" / "ci_corridor.toml", tmp_path / "mine.toml")
    assert main(["run", "mine.toml", *short, "--no-record", "--methods", "ecc"]) == 0
    assert (tmp_path / "results" / "mine" / "metrics.json").is_file()
    assert main(["score", "sequences/corridor_straight", "--no-record", "--quiet",
                 "--methods", "ecc"]) == 0
    assert (tmp_path / "results" / "corridor_straight" / "metrics.json").is_file()


@pytest.mark.parametrize("command", [["run", "--no-record", "--max-frames", "2"],
                                     ["ideal", "corridor", "--frames", "2"]])
def test_an_output_that_is_a_file_or_unwritable_is_refused_before_any_work(
        command, tmp_path, capsys, monkeypatch):
    import sim.harness.runner as runner

    monkeypatch.setattr(runner, "run", lambda config: pytest.fail("the run started"))
    a_file = tmp_path / "a_file"
    a_file.write_text("")
    for out, problem in ((a_file, "is not a folder"), (a_file / "below", "cannot write there"),
                         ("/proc/egostab-test", "cannot write there"),
                         (tmp_path / ("x" * 300), "cannot be looked up")):
        assert main([*command, "--out", str(out)]) == 2
        assert problem in _one_line_error(capsys, command[0])


@pytest.mark.parametrize("command, option", [(["run"], "--workers"),
                                             (["score", "no_sequence"], "--workers"),
                                             (["sweep", "no_sweep.toml"], "--workers"),
                                             (["suite", "no_suite.toml"], "--workers"),
                                             (["run"], "--max-frames"),
                                             (["record"], "--max-frames"),
                                             (["score", "no_sequence"], "--max-frames")])
@pytest.mark.parametrize("count", ["0", "-2", "two"])
def test_a_bad_count_is_refused(command, option, count, capsys):
    with pytest.raises(SystemExit) as exit_info:
        main([*command, option, count])
    assert exit_info.value.code == 2
    err = capsys.readouterr().err
    assert f"{option}: {count!r}: accepted: an integer >= 1" in err
    assert err.count("\n") == 1 and f"(usage: egostab {command[0]} --help)" in err


@pytest.mark.parametrize("command", [["run", str(SCENARIOS_DIR / "ci" / "ci_corridor.toml")],
                                     ["sweep", str(SCENARIOS_DIR / "sweeps" / "noise_sweep.toml")],
                                     ["suite", str(SCENARIOS_DIR / "suites" / "ci_suite.toml")]])
def test_more_local_workers_than_a_few_per_core_are_refused_before_any_work(command, tmp_path,
                                                                            capsys):
    out = tmp_path / "out"
    assert main([*command, "--out", str(out), "--workers", "100000"]) == 2
    assert "--workers 100000: accepted: an integer from 1 to" in _one_line_error(capsys,
                                                                                 command[0])
    assert not out.exists()


@pytest.mark.parametrize("arguments, accepted", [
    (["run", "--seed", "-1"], "an integer from 0 to 9223372036854775807"),
    (["record", "--seed", str(2**63)], "an integer from 0 to 9223372036854775807"),
    (["ideal", "corridor", "--frames", "1"], "an integer from 2 to 10000"),
])
def test_a_bad_option_value_is_refused_by_the_option(arguments, accepted, capsys):
    with pytest.raises(SystemExit) as exit_info:
        main(arguments)
    assert exit_info.value.code == 2
    assert f"{arguments[-2]}: {arguments[-1]!r}: accepted: {accepted}" in capsys.readouterr().err


def test_a_baseline_that_is_a_folder_is_refused_before_the_gate_runs(tmp_path, capsys,
                                                                      monkeypatch):
    import sim.harness.gate

    monkeypatch.setattr(sim.harness.gate, "run_gate",
                        lambda **kwargs: pytest.fail("the gate ran"))
    assert main(["gate", "--update-baseline", "--baseline", str(tmp_path),
                 "--out", str(tmp_path / "gate")]) == 2
    assert "is a folder" in _one_line_error(capsys, "gate")


@pytest.mark.parametrize("command, message", [
    (["ideal", "no_such_image.png"], "no_such_image.png"),
    (["gate", "--baseline", "no_such_baseline.json"], "no baseline at no_such_baseline.json"),
])
def test_a_refused_command_leaves_no_output_folder(command, message, tmp_path, capsys,
                                                   monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert main([*command, "--out", str(tmp_path / "out")]) == 2
    assert message in _one_line_error(capsys, command[0])
    assert not (tmp_path / "out").exists()


def test_output_to_a_reader_that_has_gone_ends_quietly_with_status_141():
    # `egostab list | head -1`: the pipe's reading end closed before the first line (-u: each
    # line is written at once, inside the command).
    read_end, write_end = os.pipe()
    os.close(read_end)
    try:
        done = subprocess.run([sys.executable, "-u", "-m", "sim.harness.cli", "list"],
                              stdout=write_end, stderr=subprocess.PIPE, text=True, timeout=120)
    finally:
        os.close(write_end)
    assert done.returncode == 141 and done.stderr == ""


def test_a_method_given_twice_is_refused(capsys):
    with pytest.raises(SystemExit) as exit_info:
        main(["run", "--methods", "sift,ecc,sift", "--max-frames", "2"])
    assert exit_info.value.code == 2
    assert "sift given more than once" in capsys.readouterr().err


def test_all_among_other_methods_is_refused(capsys):
    with pytest.raises(SystemExit) as exit_info:
        main(["run", "--methods", "all,ecc", "--max-frames", "2"])
    assert exit_info.value.code == 2
    assert "'all' among other methods; accepted: 'all' alone" in capsys.readouterr().err


@pytest.mark.parametrize("command", [
    ["score", "no_sequence", "--estimates", "a=x.csv", "--estimates", "a=y.csv"],
    ["suite", str(SCENARIOS_DIR / "suites" / "heldout.toml"),
     "--estimates", "a=x/{sequence}.csv", "--estimates", "a=y/{sequence}.csv"]])
def test_an_estimates_name_given_twice_is_refused(command, tmp_path, capsys):
    assert main([*command, "--out", str(tmp_path / "out")]) == 2
    assert "the name 'a' given twice (" in _one_line_error(capsys, command[0])
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("command", [["sweep", str(SCENARIOS_DIR / "sweeps" / "noise_sweep.toml")],
                                     ["suite", str(SCENARIOS_DIR / "suites" / "ci_suite.toml")]])
def test_a_ray_address_without_ray_is_refused_before_any_work(command, tmp_path, capsys,
                                                              monkeypatch):
    import sim.harness.runset as runset

    monkeypatch.setattr(runset, "run_on_command_line",
                        lambda *args, **kwargs: pytest.fail("the runs started"))
    assert main([*command, "--ray-address", "auto", "--out", str(tmp_path / "out")]) == 2
    assert "--ray-address needs --ray" in _one_line_error(capsys, command[0])
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("command", [["sweep", str(SCENARIOS_DIR / "sweeps" / "noise_sweep.toml")],
                                     ["suite", str(SCENARIOS_DIR / "suites" / "ci_suite.toml")]])
@pytest.mark.parametrize("address, problem", [("127.0.0.1:1", "nothing answers at 127.0.0.1:1"),
                                              ("ray://127.0.0.1:1", "nothing answers at"),
                                              ("", "is not an address"),
                                              ("not an address", "is not an address"),
                                              ("host:99999", "is not an address"),
                                              ("127.0.0.1:0", "is not an address"),
                                              ("127.0.0.1:\uff11", "is not an address"),
                                              ("127.0.0.1:65536", "is not an address"),
                                              ("127.0.0.1:65535",
                                               "nothing answers at 127.0.0.1:65535")])
def test_a_ray_address_nothing_answers_at_is_refused_before_any_work(command, address, problem,
                                                                     tmp_path, capsys,
                                                                     monkeypatch):
    # Ray, given 127.0.0.1:1, logged its retries and waited for minutes.
    import sim.harness.runset as runset

    monkeypatch.setattr(runset, "run_on_command_line",
                        lambda *args, **kwargs: pytest.fail("the runs started"))
    assert main([*command, "--ray", "--ray-address", address,
                 "--out", str(tmp_path / "out")]) == 2
    message = _one_line_error(capsys, command[0])
    assert problem in message and "accepted: 'auto' or 'local', or the HOST:PORT" in message
    assert not (tmp_path / "out").exists()


def test_rays_own_address_words_and_a_bracketed_ipv6_host_are_taken():
    from sim.harness.runset import check_ray_address, command_line_backend

    assert command_line_backend(True, "auto", None) == command_line_backend(True, "local", 2) \
        == "ray"
    with pytest.raises(ValueError) as refusal:  # the brackets are the address's, not the host's
        check_ray_address("[::1]:1")
    assert "nothing answers at ::1:1 (" in str(refusal.value)


@pytest.mark.parametrize("failed, status", [([], 0), (["corridor__seed1"], 1)])
def test_a_sweep_or_suite_prints_its_tables_and_fails_with_a_failed_run(failed, status, tmp_path,
                                                                       capsys):
    from sim.harness.runset import run_on_command_line

    def run(spec, out_dir, **options):
        return SimpleNamespace(markdown="| the table |", failed=[
            SimpleNamespace(run=SimpleNamespace(name=name), error="RuntimeError: boom")
            for name in failed])

    folder = tmp_path / "out"  # made by the command before
    folder.mkdir()
    assert run_on_command_line("sweep", run, None, folder, "local", 1, None) == status
    out, err = capsys.readouterr()
    assert out == f"| the table |\nsweep folder: {folder}\n"
    assert err == "".join(f"run failed: {name}: RuntimeError: boom\n" for name in failed)


def test_an_oversized_image_is_refused_or_resized_on_request(tmp_path, capsys):
    from sim.harness.ideal import MAX_IMAGE_PIXELS, load_image

    image = np.kron(depth_to_disparity(make_depth_scene(3)), np.ones((10, 10), np.uint8))
    png = tmp_path / "large.png"
    cv2.imwrite(str(png), image)  # 1760 x 1440 pixels
    assert main(["ideal", str(png), "--methods", "ecc", "--frames", "2",
                 "--out", str(tmp_path / "o")]) == 2
    assert "1760 x 1440 pixels is larger" in _one_line_error(capsys, "ideal")
    resized = load_image(str(png), resize=True)
    assert resized.size <= MAX_IMAGE_PIXELS and resized.shape[1] / resized.shape[0] == \
        pytest.approx(1760 / 1440, rel=0.01)
    assert set(np.unique(resized)) <= set(np.unique(image))  # nothing interpolated


def test_score_of_a_folder_that_is_no_sequence_is_one_line_and_status_2(tmp_path, capsys):
    (tmp_path / "not_a_sequence").mkdir()
    assert main(["score", str(tmp_path / "not_a_sequence"), "--out", str(tmp_path / "out"),
                 "--quiet"]) == 2
    err = capsys.readouterr().err.strip()
    assert "sequence.json" in err and "\n" not in err
    assert not (tmp_path / "out").exists()


def test_a_scores_default_folder_is_named_after_its_sequence_or_its_suite_run(tmp_path,
                                                                              monkeypatch):
    from sim.harness.cli import _sequence_name

    assert _sequence_name(Path("sequences/corridor_straight")) == "corridor_straight"
    assert _sequence_name(Path("results/suites/heldout/runs/office__default__scene1000__seed0/"
                               "sequence")) == "office__default__scene1000__seed0"
    monkeypatch.chdir(tmp_path)
    assert _sequence_name(Path(".")) == tmp_path.name


def test_all_methods_may_be_written_with_spaces_or_a_trailing_comma():
    from stabilizer import available_methods

    for text in (" all", "all,", " all , "):
        args = build_parser().parse_args(["run", "--methods", text])
        assert args.methods == available_methods()


def test_an_empty_output_path_is_refused_not_taken_for_the_working_directory(tmp_path,
                                                                            monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    commands = (["run"], ["record"], ["sweep", "s.toml"], ["aggregate", "r"], ["score", "s"],
                ["ideal", "corridor"], ["suite", "s.toml"], ["bench"], ["gate"])
    subcommands = next(action for action in build_parser()._actions
                       if isinstance(action, argparse._SubParsersAction))
    with_out = {name for name, parser in subcommands.choices.items()
                if any("--out" in action.option_strings for action in parser._actions)}
    assert with_out == {command[0] for command in commands}
    for command in commands:
        with pytest.raises(SystemExit) as exited:
            main([*command, "--out", ""])
        assert exited.value.code == 2
        assert "an empty one" in _one_line_error(capsys, command[0])
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("command", [["score"], ["aggregate"]])
def test_an_empty_folder_to_read_is_refused_not_taken_for_the_working_directory(
        command, tmp_path, monkeypatch, capsys):
    # `egostab score ""` read the working directory as the sequence.
    monkeypatch.chdir(tmp_path)
    with pytest.raises(SystemExit) as exited:
        main([*command, "", "--out", str(tmp_path / "out")])
    assert exited.value.code == 2
    assert "an empty one" in _one_line_error(capsys, command[0])
    assert list(tmp_path.iterdir()) == []


def test_a_file_given_as_the_sequence_is_named_as_a_file(tmp_path, capsys):
    (tmp_path / "afile").write_text("")
    assert main(["score", str(tmp_path / "afile"), "--out", str(tmp_path / "out")]) == 2
    assert "afile: is a file, not a sequence folder; accepted: a folder written by" in \
        _one_line_error(capsys, "score")


def test_aggregate_refuses_a_folder_as_its_table_and_leaves_no_folder_when_refused(
        tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "a_folder").mkdir()
    assert main(["aggregate", "no_run", "--out", "new/t.md"]) == 2
    _one_line_error(capsys, "aggregate")
    assert not (tmp_path / "new").exists()
    run = Path(__file__).parents[3] / "results" / "corridor_straight"
    for folder in ("a_folder", "."):
        assert main(["aggregate", str(run), "--out", folder]) == 2
        assert "is a folder" in _one_line_error(capsys, "aggregate")


def test_aggregate_refuses_to_write_its_table_over_a_file_of_a_run_it_reads(tmp_path, capsys):
    # --out run/metrics.json replaced the run's metrics with the table, and the run could no
    # longer be read.
    run = tmp_path / "run"
    shutil.copytree(Path(__file__).parents[3] / "results" / "corridor_straight", run)
    before = {path.name: path.read_bytes() for path in run.iterdir()}
    for name in ("metrics.json", "summary.md", "estimates_ecc.png"):
        for given in (run, run / "metrics.json"):
            assert main(["aggregate", str(given), "--out", str(run / name)]) == 2
            assert "is a file of the run" in _one_line_error(capsys, "aggregate")
    assert {path.name: path.read_bytes() for path in run.iterdir()} == before
    assert main(["aggregate", str(run), "--out", str(run / "table.md")]) == 0


def test_a_tilde_the_shell_left_in_an_output_path_is_the_home_folder(tmp_path, monkeypatch):
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    args = build_parser().parse_args(["run", "--out=~/runs/a"])
    assert args.out == tmp_path / "home" / "runs" / "a"
