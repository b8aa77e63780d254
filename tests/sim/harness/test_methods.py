"""Methods by import path and entry point: resolution, the Motion contract, refusals, use."""

from __future__ import annotations

import collections
import csv
import json
import math
import os
import sys
import warnings

import numpy as np
import pytest

from sim.harness.cli import build_parser, main
from sim.harness.methods import (ENTRY_POINT_GROUP, MethodError, as_motion,
                                 list_methods, method_factory)
from sim.harness.runner import timed_estimate
from sim.harness.scenario import ScenarioError, load_scenario
from sim.harness.sweep import sweep_from_dict
from sim.harness.sweep.spec import SweepError
from stabilizer import Stabilizer, apply_motion, available_methods, depth_to_disparity
from stabilizer.motion import Motion
from stabilizer.testing import make_depth_scene
from tests.sim.harness import plugin_methods
from tests.sim.harness.plugin_methods import FIXED

HELPERS = "tests.sim.harness.plugin_methods"


@pytest.fixture(scope="module")
def frames():
    """A reference and the reference moved by FIXED: the helpers' fixed estimate is right."""
    reference = depth_to_disparity(make_depth_scene(3))
    return reference, apply_motion(reference, Motion(*FIXED))


def scored(name, frames, **params):
    """The Motion that the harness records for method ``name`` on the pair ``frames``."""
    reference, current = frames
    motion, ms = timed_estimate(method_factory(name)(reference, **params), current)
    assert ms >= 0
    return motion


@pytest.mark.parametrize("name", ["FixedEstimator", "fixed_motion", "fixed_tuple",
                                  "fixed_array"])
def test_a_class_or_a_function_by_import_path_gives_its_estimate(frames, name):
    motion = scored(f"{HELPERS}:{name}", frames)
    assert motion.ok and motion.as_tuple() == FIXED
    assert all(type(value) is float for value in motion.as_tuple())


def test_a_module_in_the_working_directory_is_found_after_the_installed_ones(
        frames, tmp_path, monkeypatch):
    # An egostab command, unlike python -m, does not search the working directory itself.
    monkeypatch.setattr(sys, "path", [entry for entry in sys.path
                                      if entry not in ("", ".", str(tmp_path))])
    monkeypatch.chdir(tmp_path)
    package = tmp_path / "egostab_cwd_probe"
    package.mkdir()
    (package / "__init__.py").write_text("")
    (package / "mine.py").write_text(f"def fixed(reference, current):\n    return {FIXED!r}\n")
    (package / "broken.py").write_text("import egostab_missing_dependency\n")
    monkeypatch.delitem(sys.modules, "egostab_cwd_probe", raising=False)
    assert scored("egostab_cwd_probe.mine:fixed", frames).as_tuple() == FIXED
    assert sys.path[-1] == str(tmp_path)  # after every installed location
    # A module there whose own import fails names what it lacks, not itself.
    with pytest.raises(MethodError, match="No module named 'egostab_missing_dependency'"):
        method_factory("egostab_cwd_probe.broken:fixed")
    with pytest.raises(MethodError, match=r"cannot import module egostab_nowhere_probe\.mine "
                                          r"\(ModuleNotFoundError"):
        method_factory("egostab_nowhere_probe.mine:fixed")


def test_a_class_gets_the_reference_and_its_params(frames):
    motion = scored(f"{HELPERS}:FixedEstimator", frames, offset_px=1.0)
    assert motion.dx == FIXED[1] + 1.0
    assert motion.diagnostics["shape"] == frames[0].shape


def test_a_plugins_ok_passes_the_trust_check_of_the_built_in_methods(frames):
    reference, _ = frames
    unrelated = depth_to_disparity(make_depth_scene(11))
    wrong = timed_estimate(method_factory(f"{HELPERS}:fixed_motion")(reference), unrelated)[0]
    assert wrong.status == "unverified" and wrong.diagnostics["unverified_motion"] == FIXED
    unchecked = scored(f"{HELPERS}:fixed_motion", (reference, unrelated), verification=None)
    assert unchecked.ok and unchecked.as_tuple() == FIXED


@pytest.mark.parametrize("name, status", [
    ("raising", "exception:ValueError"),
    ("nan_motion", "nan"),
    ("infinite_tuple", "nan"),
    ("wrong_type", "wrong_type:str"),
    ("wrong_length", "wrong_type:tuple"),
    ("wrong_value_type", "wrong_type:str"),
    ("writes_its_input", "exception:ValueError"),
    ("FailsOnReference", "exception:RuntimeError"),
    ("exits", "exception:SystemExit"),
    ("raises_its_own_base_exception", "exception:OwnBaseException"),
    ("huge_integer", "nan"),
    ("huger_integer", "nan"),
    ("far_out", "out_of_range"),
    ("far_below", "out_of_range"),
    ("list_diagnostics", "wrong_type:diagnostics"),
    ("ExitsOnReference", "exception:SystemExit"),
    ("reported_failure", "no_structure"),
])
def test_a_misbehaving_method_fails_the_frame_with_the_reason(frames, name, status):
    motion = scored(f"{HELPERS}:{name}", frames)
    assert motion.status == status
    assert all(math.isnan(value) for value in motion.as_tuple())


def test_an_estimate_right_at_the_bound_is_an_estimate_not_out_of_range(frames):
    motion = scored(f"{HELPERS}:at_the_bound", frames)
    # The trust check then finds no overlap: no frame shifted so far lines up.
    assert motion.status == "unverified"
    assert motion.diagnostics["unverified_motion"] == (0.0, 1e6, -1e6)


@pytest.mark.parametrize("name", ["writes_its_input", "unwrites_its_input",
                                  "ZeroesItsReference"])
def test_a_method_cannot_change_the_frames_the_others_see(frames, name):
    reference, current = frames
    before = (reference.copy(), current.copy())
    scored(f"{HELPERS}:{name}", frames)
    assert np.array_equal(reference, before[0]) and np.array_equal(current, before[1])


def test_a_method_cannot_change_numpys_settings_the_warning_filters_or_the_directory(frames):
    settings, filters, cwd = np.geterr(), list(warnings.filters), os.getcwd()
    scored(f"{HELPERS}:changes_global_settings", frames)
    assert np.geterr() == settings and warnings.filters == filters and os.getcwd() == cwd


def test_a_methods_diagnostics_keep_plain_data_only(frames):
    motion = as_motion(plugin_methods.odd_diagnostics(*frames))
    assert motion.diagnostics == {"n": 4, "pair": (1.5, "a"),
                                  "dropped_diagnostics": ["callback", "labels"]}
    assert type(motion.diagnostics["n"]) is int


def test_diagnostics_beyond_plain_data_are_named_not_taken_for_the_methods_failure():
    point = collections.namedtuple("Point", "x y")
    looped = [1]
    looped.append(looped)
    motion = as_motion(Motion(1.0, 2.0, 3.0, diagnostics={
        "point": point(1, 2), "looped": looped, "long": list(range(1001)),
        "fits": list(range(1000)), "big": 2**1025, "dropped_diagnostics": "the plugin's own",
        "text": "x\udcff"}))
    assert motion.ok
    assert motion.diagnostics["point"] == (1, 2) and type(motion.diagnostics["point"]) is tuple
    assert motion.diagnostics["fits"] == list(range(1000))
    assert motion.diagnostics["text"] == "x\\udcff"
    assert motion.diagnostics["dropped_diagnostics"] == ["looped", "long", "big",
                                                         "dropped_diagnostics"]


def test_diagnostics_at_their_bounds_are_kept_and_a_step_beyond_is_dropped():
    def nested(depth):  # ``depth`` lists around a number
        value = 1
        for _ in range(depth):
            value = [value]
        return value

    motion = as_motion(Motion(1.0, 2.0, 3.0, diagnostics={
        "widest": 2**1024 - 1, "too_wide": 2**1024, "deepest": nested(8),
        "too_deep": nested(9)}))
    assert motion.diagnostics["widest"] == 2**1024 - 1  # 1024 bits
    assert motion.diagnostics["deepest"] == nested(8)
    assert motion.diagnostics["dropped_diagnostics"] == ["too_wide", "too_deep"]


@pytest.mark.parametrize("status, recorded", [
    ("lost\ntrack", "lost\\ntrack"), ("a\tb", "a\\tb"), ("nicht_gefunden_ä", "nicht_gefunden_ä"),
    ("OK", "wrong_type:status"), (" ok ", "wrong_type:status"), ("   ", "wrong_type:status"),
])
def test_a_failures_status_is_one_line_of_text_other_than_ok(status, recorded):
    assert as_motion(Motion(math.nan, math.nan, math.nan, status)).status == recorded


def test_an_exception_whose_message_cannot_be_read_still_fails_only_its_frame(frames):
    motion = scored(f"{HELPERS}:raises_unreadable", frames)
    assert motion.status == "exception:UnreadableError"
    assert motion.diagnostics["message"] == "(its message could not be read: RuntimeError)"


def test_a_failure_no_file_can_take_as_it_is_is_kept_escaped_and_named(frames):
    motion = scored(f"{HELPERS}:unwritable_failure", frames)
    assert motion.status == "bad\\ud800name"
    assert motion.diagnostics == {"path": "\\udcff.png", "count": 3,
                                  "dropped_diagnostics": ["big"]}
    assert as_motion(plugin_methods.huger_integer(*frames)).diagnostics["values"] == [
        0.0, "an integer of 16610 bits", 0.0]


def test_as_motion_keeps_a_good_motion_and_its_diagnostics():
    motion = as_motion(Motion(1.0, 2.0, 3.0, diagnostics={"n": 4}))
    assert motion == Motion(1.0, 2.0, 3.0) and motion.diagnostics == {"n": 4}
    assert as_motion([1, 2, 3]) == Motion(1.0, 2.0, 3.0)
    assert as_motion(None).status == "wrong_type:NoneType"
    assert as_motion((True, 0.0, 0.0)).status == "wrong_type:bool"
    # Arrays of any other shape, a 0-d one too (which has no len()), are of the wrong type.
    assert as_motion(np.array([1.0, 2.0, 3.0])) == Motion(1.0, 2.0, 3.0)
    for array in (np.array(5.0), np.zeros((3, 1)), np.zeros(4)):
        assert as_motion(array).status == "wrong_type:ndarray"


def test_a_failure_without_text_status_or_with_a_status_diagnostic_is_named():
    # Motion.failed's status is positional-only: a diagnostic called "status" is data.
    nameless = as_motion(Motion.failed(""))
    assert nameless.status == "wrong_type:status" and nameless.diagnostics["status"] == "''"
    failed = as_motion(Motion.failed("lost_track", status="searching"))
    assert failed.status == "lost_track" and failed.diagnostics == {"status": "searching"}


@pytest.mark.parametrize("name", available_methods())
def test_a_built_in_name_is_built_by_stabilizer_as_before(frames, name):
    reference, current = frames
    built = method_factory(name)(reference)
    assert type(built) is Stabilizer and built.method == name
    assert built.estimate(current) == Stabilizer(reference, name).estimate(current)


@pytest.mark.parametrize("name, problem", [
    ("no_such_method", "not a built-in method, not an installed entry point"),
    ("no_such_package.module:Name", "cannot import module no_such_package.module"),
    ("tests.sim.harness.plugin_raises_on_import:f",
     "(ImportTimeFailure: this module refuses to load)"),
    (f"{HELPERS}:Missing", "has no attribute Missing"),
    (f"{HELPERS}:NOT_CALLABLE", "float object is not callable"),
    (f"{HELPERS}:NoEstimate", "has no estimate(current) method"),
    ("a:b:c", "not an import path"),
    ("module:", "not an import path"),
])
def test_a_name_that_cannot_be_resolved_is_refused_in_one_line(name, problem):
    with pytest.raises(MethodError) as error:
        method_factory(name)
    message = str(error.value)
    assert "\n" not in message
    assert f"method {name!r}" in message and problem in message
    assert "accepted:" in message and "package.module:Name" in message
    assert ENTRY_POINT_GROUP in message and "fourier_mellin" in message


def test_the_command_line_refuses_it_with_status_2(capsys):
    with pytest.raises(SystemExit) as exit_info:
        build_parser().parse_args(["run", "--methods", f"ecc,{HELPERS}:Missing"])
    assert exit_info.value.code == 2
    error_line = capsys.readouterr().err.strip().splitlines()[-1]  # after argparse's usage
    assert error_line.startswith("egostab run: error: argument --methods: method ")
    assert f"{HELPERS}:Missing" in error_line and "package.module:Name" in error_line


@pytest.fixture
def installed_entry_points(tmp_path, monkeypatch):
    """A distribution 'fake-methods 0.3' on sys.path declaring three entry points."""
    dist_info = tmp_path / "fake_methods-0.3.dist-info"
    dist_info.mkdir()
    (dist_info / "METADATA").write_text("Metadata-Version: 2.1\nName: fake-methods\n"
                                        "Version: 0.3\n")
    (dist_info / "entry_points.txt").write_text(
        f"[{ENTRY_POINT_GROUP}]\nfixed = {HELPERS}:FixedEstimator\n"
        "broken = no_such_package:Estimator\n"
        f"all = {HELPERS}:FixedEstimator\n")
    monkeypatch.syspath_prepend(str(tmp_path))


def test_an_entry_point_is_a_method_by_its_name(installed_entry_points, frames):
    assert scored("fixed", frames).as_tuple() == FIXED
    with pytest.raises(MethodError, match="fake-methods 0.3 cannot be loaded"):
        method_factory("broken")


def test_egostab_methods_lists_every_method_and_where_it_comes_from(installed_entry_points,
                                                                     capsys):
    origins = {info.name: info.origin for info in list_methods()}
    assert all(origins[name] == "built-in" for name in available_methods())
    assert origins["fixed"] == (f"entry point fixed -> {HELPERS}:FixedEstimator from "
                                "distribution fake-methods 0.3")
    assert main(["methods"]) == 0
    out = capsys.readouterr().out
    assert "fixed" in out and "fake-methods 0.3" in out and "t2fuzzy_paper" in out
    # "all" on the command line is every built-in method, never this entry point.
    assert "not on the command line, where --methods all means every built-in" in origins["all"]
    assert build_parser().parse_args(["run", "--methods", "all"]).methods == available_methods()
    assert "Import paths are accepted too" in out


def test_a_scenario_file_takes_import_paths_and_refuses_bad_names(tmp_path):
    good = tmp_path / "good.toml"
    good.write_text(f'[evaluation]\nmethods = ["ecc", "{HELPERS}:fixed_tuple"]\n')
    assert load_scenario(good).evaluation.methods == ("ecc", f"{HELPERS}:fixed_tuple")
    bad = tmp_path / "bad.toml"
    bad.write_text(f'[evaluation]\nmethods = ["ecc", "{HELPERS}:Missing"]\n')
    with pytest.raises(ScenarioError) as error:
        load_scenario(bad)
    assert error.value.key == "evaluation.methods"
    assert str(bad) in str(error.value) and "has no attribute Missing" in str(error.value)


def test_a_sweep_file_takes_import_paths_and_refuses_bad_names(tmp_path):
    raw = {"scenarios": ["corridor_straight"], "seeds": [0], "noise_levels": [1.0],
           "methods": ["ecc", f"{HELPERS}:fixed_tuple"]}
    assert sweep_from_dict(raw).methods == ("ecc", f"{HELPERS}:fixed_tuple")
    with pytest.raises(SweepError) as error:
        sweep_from_dict({**raw, "methods": ["ecc", "no_such_package:Name"]}, source="s.toml")
    assert error.value.key == "methods[1]"
    assert "s.toml" in str(error.value) and "cannot import module" in str(error.value)


def test_the_ideal_experiment_names_a_plugin_by_the_string_given(tmp_path, frames):
    image = tmp_path / "scene.npy"
    np.save(image, make_depth_scene(3))
    out_dir = tmp_path / "ideal"
    name = f"{HELPERS}:fixed_tuple"
    assert main(["ideal", str(image), "--methods", f"ecc,{name},{HELPERS}:raising",
                 "--frames", "3", "--out", str(out_dir)]) == 0
    with open(out_dir / "frames.csv", newline="") as handle:
        rows = [row for row in csv.DictReader(handle)]
    plugin = [row for row in rows if row["method"] == name]
    assert len(plugin) == 3
    # The same fixed motion for every frame of the paper's cycle is wrong: the trust check
    # that every method's "ok" passes turns it into a failure.
    assert {row["status"] for row in plugin} == {"unverified"}
    assert {row["status"] for row in rows if row["method"] == f"{HELPERS}:raising"} == {
        "exception:ValueError"}
    failures = [json.loads(line) for line in (out_dir / "failures.jsonl").read_text().splitlines()]
    assert [(f["frame_index"], f["method"]) for f in failures] == [
        (int(row["frame_index"]), row["method"]) for row in rows if row["status"] != "ok"]
    assert {f["diagnostics"]["message"] for f in failures
            if f["method"] == f"{HELPERS}:raising"} == {"this method always fails"}
    metrics = json.loads((out_dir / "metrics.json").read_text())
    assert name in metrics["run"]["methods"]
    assert (out_dir / "estimates_tests.sim.harness.plugin_methods_fixed_tuple.png").is_file()
