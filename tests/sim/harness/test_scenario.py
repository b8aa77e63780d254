"""Scenario files: the shipped ones load and fit their scenes; bad files fail early and clearly."""

from __future__ import annotations

import json
import pickle
import textwrap

import numpy as np
import pytest

import sim.harness.scenario as scenario_module
from scenarios import SCENARIOS_DIR
from sim.harness.scenario import (ScenarioError, commanded_trajectory, list_scenarios,
                                  load_scenario, resolve_scenario_path)
from sim.world.scenes import SCENES, build_scene
from sim.world.scenes.floor import MAX_BUMP_HEIGHT_M, MAX_SLOPE_DEG
from sim.world.scenes.lane import path_distance
from sim.world.sensor.tof_model import TOF_PRESETS
from stabilizer.api import available_methods

REQUIRED = {"corridor_straight", "office_turn", "lab_clutter", "stop_and_go", "paper_like_gait",
            "high_noise", "noiseless_sensor"}

MINIMAL = 'scene = "lab"\n'


def write(tmp_path, text, name="case.toml"):
    path = tmp_path / name
    path.write_text(text)
    return path


def test_the_required_scenarios_are_shipped_and_load():
    names = {p.stem for p in list_scenarios()}
    assert REQUIRED <= names
    for path in list_scenarios():
        scenario = load_scenario(path)
        assert scenario.name == path.stem and scenario.description
        assert path.parent == SCENARIOS_DIR


@pytest.mark.parametrize("path", list_scenarios(), ids=lambda p: p.stem)
def test_commands_keep_the_walker_on_its_scene_path(path):
    """An ideal walker following the commands stays within 5 cm of the path, up to its end."""
    scenario = load_scenario(path)
    scene = build_scene(scenario.scene, scenario.scene_seed, **scenario.scene_params)
    walked = commanded_trajectory(scenario, scene.start_xy, scene.start_yaw_deg)
    offsets = [path_distance(scene.path, np.r_[xy, xy]) for xy in walked[::10]]
    assert max(offsets) < 0.05
    assert np.linalg.norm(walked[-1] - scene.path[-1]) > 0.1  # stops before the path ends


def test_defaults_are_the_documented_ones(tmp_path):
    scenario = load_scenario(write(tmp_path, MINIMAL))
    assert scenario.name == "case" and scenario.scene == "lab" and scenario.scene_seed == 0
    assert scenario.scene_params == SCENES["lab"]().params()
    assert scenario.duration_s == 20.0 and scenario.seed == 0
    assert [(c.t, c.speed, c.yaw_rate) for c in scenario.commands] == [(0.0, 0.0, 0.0)]
    assert scenario.gait.preset == "default" and scenario.gait.overrides == {}
    assert scenario.sensor.preset == "sr4000" and scenario.sensor.fps == 30.0
    assert scenario.sensor.tof_params() == TOF_PRESETS["sr4000"]
    assert scenario.evaluation.reference == "cycle_start"
    assert scenario.evaluation.methods == available_methods()
    assert scenario.recording.enabled and scenario.recording.frame_stride == 1


def test_a_full_file_is_read_with_overrides_and_round_trips_to_json(tmp_path):
    text = """
name = "mine"
scene = "office"
scene_seed = 3
seed = 9
duration_s = 12.5
[[commands]]
t = 0.0
speed = 0.05
[[commands]]
t = 4
speed = 0.1
yaw_rate = -10.0
[gait]
preset = "paper_like"
overrides = { step_height_m = 0.035 }
[sensor]
preset = "high_noise"
fps = 20
noise_scale = 0.5
overrides = { mixed_pixel_weight = 0.0, motion_blur_subframes = 1, phase_wrapping = false }
[evaluation]
reference = "previous"
methods = ["sift", "t2fuzzy"]
[recording]
enabled = false
frame_stride = 3
"""
    scenario = load_scenario(write(tmp_path, text), overrides={"sensor.noise_scale": 2.0})
    params = scenario.sensor.tof_params()
    assert params.noise_sigma_ref_m == pytest.approx(2.0 * TOF_PRESETS["high_noise"]
                                                     .noise_sigma_ref_m)
    assert params.mixed_pixel_weight == 0.0 and not params.phase_wrapping
    assert scenario.gait.params().step_height_m == 0.035
    assert scenario.command_at(3.9).speed == 0.05 and scenario.command_at(4.0).yaw_rate == -10
    assert scenario.evaluation.methods == ("sift", "t2fuzzy")
    document = json.loads(json.dumps(scenario.to_dict()))
    assert document["commands"][1] == {"t": 4.0, "speed": 0.1, "yaw_rate": -10.0}
    assert document["sensor"]["overrides"]["motion_blur_subframes"] == 1
    assert document["name"] == "mine" and document["recording"]["frame_stride"] == 3


@pytest.mark.parametrize("text, key, allowed", [
    ('scene = "lab"\nspeed = 1\n', "speed", "keys name"),
    ('scene = "kitchen"\n', "scene", "corridor"),
    ('scene = "lab"\nduration_s = "long"\n', "duration_s", "duration_s <="),
    ('scene = "lab"\nduration_s = -1.0\n', "duration_s", "0 < duration_s"),
    ('scene = "lab"\nduration_s = 0.001\n', "duration_s", "at least one frame period"),
    ('duration_s = 0.0333\n', "duration_s", "(1 / sensor.fps = 0.0333333333 s)"),
    ('scene = "lab"\n[sensor.overrides]\nquantization_bits = 33\n', "sensor.overrides",
     "0 (off) to 32"),
    ('scene = "lab"\n[sensor.overrides]\nnoise_sigma_ref_m = 1e300\n', "sensor.overrides",
     "0 to 20.0 m"),
    ('scene = "lab"\n[gait.overrides]\ncom_height_m = 1e20\n', "gait.overrides",
     "0 to 2.0 m"),
    ('scene = "lab"\n[gait.overrides]\nstep_period_s = 1e-6\n', "gait.overrides",
     "0.1 to 60.0 s"),
    ('scene = "lab"\nscene_seed = 1.5\n', "scene_seed", "integer"),
    ('scene = "lab"\nseed = true\n', "seed", "integer"),
    ('scene = "lab"\nseed = 9223372036854775808\n', "seed", "2**63 - 1"),
    ('scene = "lab"\nscene_seed = -1\n', "scene_seed", "2**63 - 1"),
    ('scene = "lab"\n[sensor]\nfps = 60\n', "sensor.fps", "54"),
    ('scene = "lab"\n[sensor]\npreset = "kinect"\n', "sensor.preset", "noiseless"),
    ('scene = "lab"\n[sensor]\ngain = 2\n', "sensor.gain", "keys preset"),
    ('scene = "lab"\n[sensor]\noverrides = { noise = 1.0 }\n', "sensor.overrides.noise",
     "noise_sigma_ref_m"),
    ('scene = "lab"\n[sensor]\noverrides = { quantization_bits = 12.5 }\n',
     "sensor.overrides.quantization_bits", "int"),
    ('scene = "lab"\n[sensor]\noverrides = { reflectivity = 2.0 }\n', "sensor.overrides",
     "reflectivity"),
    ('scene = "lab"\n[sensor]\nfps = 50\noverrides = { integration_time_s = 0.025 }\n',
     "sensor.fps", "fps <"),
    ('scene = "lab"\n[sensor.overrides]\nmax_range_m = inf\n', "sensor.overrides.max_range_m",
     "a finite number"),
    ('scene = "lab"\n[gait.overrides]\nstep_height_m = nan\n', "gait.overrides.step_height_m",
     "a finite number"),
    ('scene = "lab"\n[gait]\npreset = "run"\n', "gait.preset", "paper_like"),
    # Within the robot's reach: these ran, and the robot fell or stood still.
    ('scene = "lab"\n[gait.overrides]\nlateral_sway_m = 1000.0\n', "gait.overrides",
     "-0.0375 to 0.0375 m (half the sole's width)"),
    ('scene = "lab"\n[gait.overrides]\nstep_width_m = 5.0\n', "gait.overrides",
     "0 to 0.3 m (the leg's length)"),
    ('scene = "lab"\n[gait.overrides]\narm_swing_deg = -1000.0\n', "gait.overrides",
     "-90 to 90 deg"),
    ('scene = "lab"\n[gait.overrides]\ntilt_ankle_gain = 1e6\n', "gait.overrides",
     "0 to 5 (the ankle's range"),
    ('scene = "lab"\n[gait.overrides]\ngyro_ankle_pitch_gain = 1000.0\n', "gait.overrides",
     "0 to 1 s"),
    ('scene = "lab"\n[gait.overrides]\ngyro_ankle_roll_gain = -1000.0\n', "gait.overrides",
     "0 to 1 s"),
    ('scene = "lab"\n[gait]\noverrides = { stride = 1.0 }\n', "gait.overrides.stride",
     "step_period_s"),
    ('scene = "lab"\n[gait]\noverrides = 3\n', "gait.overrides", "a table of GaitParams fields"),
    ('scene = "lab"\n[sensor]\noverrides = "quiet"\n', "sensor.overrides",
     "a table of ToFParams fields"),
    ('scene = "lab"\n[evaluation]\nmethods = ["sift", "orb"]\n', "evaluation.methods",
     "fourier_mellin"),
    ('scene = "lab"\n[evaluation]\nmethods = []\n', "evaluation.methods", "non-empty"),
    ('scene = "lab"\n[evaluation]\nreference = "last"\n', "evaluation.reference", "previous"),
    ('scene = "lab"\n[recording]\nframe_stride = 0\n', "recording.frame_stride", "1 to 1000"),
    ('scene = "lab"\n[[commands]]\nt = 1.0\n', "commands[0].t", "first at t = 0"),
    ('scene = "lab"\n[[commands]]\nt = 0.0\n[[commands]]\nt = 0.0\n', "commands[1].t",
     "increasing"),
    ('scene = "lab"\nduration_s = 5.0\n[[commands]]\nt = 0.0\n[[commands]]\nt = 6.0\n',
     "commands[1].t", "increasing"),
    ('scene = "lab"\n[[commands]]\nt = 0.0\nspeed = 0.3\n', "commands[0].speed", "m/s"),
    ('scene = "lab"\n[[commands]]\nt = 0.0\nspeed = -0.1\n', "commands[0].speed", "0 to 0.5"),
    ('scene = "lab"\n[[commands]]\nt = 0.0\nyaw_rate = 60.0\n', "commands[0].yaw_rate",
     "deg/s"),
    ('scene = "lab"\n[[commands]]\nt = 0.0\nturn = 1.0\n', "commands[0].turn", "yaw_rate"),
    ('scene = "lab"\ncommands = 3\n', "commands", "[[commands]]"),
    ('scene = "lab"\nsensor = 3\n', "sensor", "[sensor]"),
    ('scene = "lab\n', "(file)", "TOML"),
    ('scene = "lab"\nscene_params = 3\n', "scene_params", "[scene_params]"),
    ('scene = "lab"\n[scene_params]\nwidth = 5.0\n', "scene_params.width",
     "room_past_walk_m, half_width_m"),
    ('scene = "lab"\n[scene_params]\nhalf_width_m = [3.0, 2.0]\n', "scene_params.half_width_m",
     "low <= high"),
    ('scene = "lab"\n[scene_params]\nhalf_width_m = [0.2, 2.0]\n',
     "scene_params.half_width_m", "1 <= low"),
    ('scene = "lab"\n[scene_params]\nextra_clutter_count = 3\n',
     "scene_params.extra_clutter_count", "a pair [low, high] of integers"),
    ('scene = "office"\n[scene_params]\ncrates_ahead = [1, 2]\n', "scene_params.crates_ahead",
     "an integer from 0"),
    ('scene = "corridor"\n[scene_params]\nside_doors_per_wall = [1, 4]\n',
     "scene_params.side_doors_per_wall", "as many doors as slots"),
    ('[floor]\nslope_deg = 4.0\n', "floor.slope_deg", "from 0 to 3"),
    ('[floor]\nbump_height_m = 0.01\n', "floor.bump_height_m", "from 0 to 0.005"),
    ('[floor]\nslope_direction_deg = "north"\n', "floor.slope_direction_deg", "-360 to 360"),
    ('[floor]\nroughness = 1.0\n', "floor.roughness", "slope_deg, slope_direction_deg"),
    ('floor = 2\n', "floor", "a table [floor]"),
    ('pushes = 3\n', "pushes", "[[pushes]] with t, impulse_ns, duration_s"),
    ('name = "walk\\nEND"\n', "name", "without control characters"),
    ('name = "walk\\u001b[31m"\n', "name", "without control characters"),
    ('[[pushes]]\nt = 1.0\nimpulse_ns = [1.0, 2.0]\n', "pushes[0].impulse_ns", "three numbers"),
    ('[[pushes]]\nt = 1.0\nimpulse_ns = [0.0, 12.0, 0.0]\n', "pushes[0].impulse_ns",
     "each -10 to 10"),
    ('[[pushes]]\nt = 1.0\nimpulse_ns = [0.0, true, 0.0]\n', "pushes[0].impulse_ns",
     "three numbers"),
    ('duration_s = 5.0\n[[pushes]]\nt = 5.0\nimpulse_ns = [0.0, 1.0, 0.0]\n', "pushes[0].t",
     "before duration_s"),
    ('[[pushes]]\nt = -1.0\n', "pushes[0].t", "a time >= 0 s"),
    ('duration_s = 5.0\n[[pushes]]\nt = 4.95\nimpulse_ns = [0.0, 1.0, 0.0]\nduration_s = 0.1\n',
     "pushes[0].duration_s", "a push that ends by duration_s"),
    ('[[pushes]]\nt = 1.0\nimpulse_ns = [0.0, 1.0, 0.0]\nduration_s = 0.001\n',
     "pushes[0].duration_s", "whole number of physics steps"),
    ('[[pushes]]\nt = 1.0\nimpulse_ns = [0.0, 1.0, 0.0]\nduration_s = 0.101\n',
     "pushes[0].duration_s", "whole number of physics steps"),
    ('[[pushes]]\nt = 1.0\nimpulse_ns = [0.0, 1.0, 0.0]\n[[pushes]]\nt = 2.0\n',
     "pushes[1].impulse_ns", "three numbers"),
    ('[[pushes]]\nimpulse_ns = [0.0, 1.0, 0.0]\n', "pushes[0].t", "a time >= 0 s"),
    ('[[pushes]]\nt = 1.0\nforce = 3.0\n', "pushes[0].force", "t, impulse_ns, duration_s"),
])
def test_bad_files_name_the_file_the_key_and_what_is_allowed(tmp_path, text, key, allowed):
    path = write(tmp_path, text)
    with pytest.raises(ScenarioError) as error:
        load_scenario(path)
    message = str(error.value)
    assert isinstance(error.value, ValueError)
    assert error.value.key == key
    assert str(path) in message and key in message and message.count("allowed:") == 1
    assert allowed in message.split("allowed:")[1] or allowed in message


@pytest.mark.parametrize("command, refused", [
    ("speed = 0.12", None), ("speed = 0.121", "0 to 0.120 m/s"),
    ("yaw_rate = -24.0", None), ("yaw_rate = 24.1", "at most +-24.0 deg/s")])
def test_commands_are_limited_to_the_gaits_largest_step_each_step_period(tmp_path, command,
                                                                          refused):
    # The default gait: steps of at most 0.06 m and 12 deg every 0.5 s.
    path = write(tmp_path, f'scene = "lab"\n[[commands]]\nt = 0.0\n{command}\n')
    if refused is None:
        load_scenario(path)
        return
    with pytest.raises(ScenarioError, match=refused.replace("+", r"\+")):
        load_scenario(path)


def test_names_resolve_to_shipped_files_and_unknown_names_list_them():
    assert resolve_scenario_path("lab_clutter") == SCENARIOS_DIR / "lab_clutter.toml"
    with pytest.raises(FileNotFoundError, match="corridor_straight"):
        resolve_scenario_path("no_such_scenario")
    with pytest.raises(ScenarioError, match="sensor.fps"):
        load_scenario("lab_clutter", overrides={"sensor.fps": 100.0})


def test_a_folder_does_not_hide_a_shipped_scenario_of_its_name(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    for name in ("corridor_straight", "not_shipped"):
        (tmp_path / name).mkdir()  # e.g. the output folder of `--out corridor_straight`
    assert resolve_scenario_path("corridor_straight") == SCENARIOS_DIR / "corridor_straight.toml"
    with pytest.raises(FileNotFoundError, match="not_shipped is a folder"):
        resolve_scenario_path("not_shipped")


@pytest.mark.parametrize("given, problem", [
    ("", "no scenario ''"),
    ("/dev/null", "/dev/null is not a regular file"),
    # Paths, not names: the shipped folder is not searched for them.
    ("ci/ci_corridor", "no scenario file ci/ci_corridor"),
    ("../pyproject", "no scenario file ../pyproject"),
    (str(SCENARIOS_DIR / "ci" / "ci_corridor"), "no scenario file"),
])
def test_a_scenario_that_is_no_file_or_name_is_named_as_given(given, problem, monkeypatch):
    monkeypatch.chdir(SCENARIOS_DIR)
    with pytest.raises(FileNotFoundError) as error:
        resolve_scenario_path(given)
    assert str(error.value).startswith(problem) and "accepted: a scenario TOML file" in str(
        error.value)


def test_scenario_errors_survive_pickling(tmp_path):
    """Runs go through process pools: their errors must pickle."""
    with pytest.raises(ScenarioError) as error:
        load_scenario(write(tmp_path, 'scene = "kitchen"\n'))
    again = pickle.loads(pickle.dumps(error.value))
    assert str(again) == str(error.value) and again.key == "scene"


def test_the_documented_example_is_a_valid_scenario(tmp_path):
    doc = scenario_module.__doc__
    example = textwrap.dedent(doc.split("Example::")[1].split("Any unknown key")[0])
    scenario = load_scenario(write(tmp_path, example))
    assert scenario.name == "corridor_straight" and len(scenario.commands) == 2
    assert scenario.sensor.tof_params().mixed_pixel_weight == 0.3


def test_scene_params_vary_the_scene_and_are_recorded(tmp_path):
    """A [scene_params] table builds another scene than the defaults; the resolved scenario
    lists every parameter of the scene (metrics.json records them)."""
    varied = load_scenario(write(tmp_path, 'scene = "corridor"\n[scene_params]\n'
                                 'half_width_m = [1.1, 1.2]\nclutter_count = [0, 1]\n'))
    default = load_scenario(write(tmp_path, 'scene = "corridor"\n', "default.toml"))
    assert varied.scene_params["half_width_m"] == (1.1, 1.2)
    assert varied.scene_params["end_room_depth_m"] == default.scene_params["end_room_depth_m"]
    document = json.loads(json.dumps(varied.to_dict()))
    assert document["scene_params"]["half_width_m"] == [1.1, 1.2]
    assert set(document["scene_params"]) == set(SCENES["corridor"].parameter_names())
    varied_scene = build_scene(varied.scene, varied.scene_seed, **varied.scene_params)
    default_scene = build_scene(default.scene, default.scene_seed, **default.scene_params)
    assert varied_scene.arena.to_xml_string() != default_scene.arena.to_xml_string()
    assert default_scene.arena.to_xml_string() == build_scene("corridor", 0).arena.to_xml_string()
    again = load_scenario(write(tmp_path, 'scene = "corridor"\n', "again.toml"),
                          overrides={"scene_params.half_width_m": [1.1, 1.2],
                                     "scene_params.clutter_count": [0, 1]})
    assert again.scene_params == varied.scene_params


# -- floors and pushes ------------------------------------------------------------------------

ROUGH_AND_PUSHED = """
scene = "corridor"
scene_seed = 2
duration_s = 4.0

[floor]
slope_deg = 2.5
slope_direction_deg = -30
bump_height_m = 0.004

[[pushes]]
t = 1.0
impulse_ns = [0.0, 1.5, 0]
duration_s = 0.05

[[pushes]]
t = 2.5
impulse_ns = [-1.0, 0.0, 0.5]
"""


def test_floor_and_pushes_are_read_checked_and_recorded(tmp_path):
    from sim.world.scenes import Floor

    scenario = load_scenario(write(tmp_path, ROUGH_AND_PUSHED))
    assert scenario.floor.floor() == Floor(2.5, -30.0, 0.004)
    assert [(p.t, p.impulse_ns, p.duration_s) for p in scenario.pushes] == [
        (1.0, (0.0, 1.5, 0.0), 0.05), (2.5, (-1.0, 0.0, 0.5), 0.1)]
    document = json.loads(json.dumps(scenario.to_dict()))
    assert document["floor"] == {"slope_deg": 2.5, "slope_direction_deg": -30.0,
                                 "bump_height_m": 0.004}
    assert document["pushes"][1] == {"t": 2.5, "impulse_ns": [-1.0, 0.0, 0.5], "duration_s": 0.1}
    # A sequence folder's scenario (sequence.json) validates back to the same scenario.
    stored = {k: v for k, v in document.items() if k != "source"}
    assert scenario_module.scenario_from_dict(stored) == scenario
    plain = load_scenario(write(tmp_path, MINIMAL, "plain.toml"))
    assert plain.floor.floor().is_flat and plain.pushes == ()
    assert load_scenario(write(tmp_path, MINIMAL, "o.toml"), overrides={
        "floor.slope_deg": 1.0}).floor.slope_deg == 1.0


def test_the_scenario_robot_stands_on_its_floor_with_its_pushes_scheduled(tmp_path):
    import mujoco

    from sim.harness.runner import scenario_robot

    scenario = load_scenario(write(tmp_path, ROUGH_AND_PUSHED))
    robot = scenario_robot(scenario)
    assert robot.model.geom("floor_bumps").type == mujoco.mjtGeom.mjGEOM_HFIELD
    assert [(p.start_s, p.impulse_ns, p.duration_s) for p in robot.pushes] == [
        (p.t, p.impulse_ns, p.duration_s) for p in scenario.pushes]


def _robot_momentum_after_push(text: str, until_s: float, contacts: bool):
    """The robot's total linear momentum (N s) at ``until_s`` of the scenario ``text``."""
    import mujoco

    from sim.harness.runner import scenario_robot
    from sim.world.humanoid import TORSO_BODY_NAME

    robot = scenario_robot(scenario_module.scenario_from_dict(__import__("tomllib").loads(text)))
    # The controller's CoM feedback answers the push (and, without contacts, the free fall)
    # with joint motions that move the twins apart: off, the two differ by the push alone.
    robot.controller.com_feedback_gain = 0.0
    if not contacts:
        robot.model.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_CONTACT
    robot.run(until_s)
    torso = robot.model.body(TORSO_BODY_NAME).id
    mujoco.mj_subtreeVel(robot.model, robot.data)
    mass = robot.model.body_subtreemass[torso]
    return mass * robot.data.subtree_linvel[torso], mass


@pytest.mark.parametrize("impulse", [[0.0, 1.5, 0.0], [-1.0, 0.5, 0.8]])
def test_a_scheduled_push_changes_the_robots_momentum_by_its_impulse(impulse):
    """Without contacts (the robot falls freely) a push changes the robot's momentum by its
    impulse against an unpushed twin: it reaches the robot, in the world frame. (To 1e-3 N s:
    MuJoCo integrates in joint coordinates, where the bodies' momentum is kept only to the
    integration error, here 2e-4 N s between the two robots' different motions.)"""
    base = 'scene = "corridor"\nduration_s = 2.0\n'
    pushed = base + f"[[pushes]]\nt = 0.5\nimpulse_ns = {impulse}\nduration_s = 0.05\n"
    twin, _ = _robot_momentum_after_push(base, 0.6, contacts=False)
    momentum, mass = _robot_momentum_after_push(pushed, 0.6, contacts=False)
    np.testing.assert_allclose(momentum - twin, impulse, atol=1e-3)
    assert mass == pytest.approx(5.98, abs=0.01)


def test_a_push_on_the_standing_robot_moves_it_mostly_by_impulse_over_mass():
    """On the floor the feet's friction takes part of a sideways push: the centre of mass
    gains most of impulse / mass along the push (0.25 m/s for 1.5 N s), never more."""
    base = 'scene = "corridor"\nduration_s = 2.0\n'
    pushed = base + "[[pushes]]\nt = 0.5\nimpulse_ns = [0.0, 1.5, 0.0]\nduration_s = 0.0025\n"
    twin, mass = _robot_momentum_after_push(base, 0.51, contacts=True)
    momentum, _ = _robot_momentum_after_push(pushed, 0.51, contacts=True)
    gained = (momentum - twin) / mass
    assert 0.7 * 1.5 / mass < gained[1] <= 1.5 / mass + 1e-9
    assert abs(gained[0]) < 0.05 * gained[1]


def test_every_sensor_preset_takes_the_largest_noise_scale(tmp_path):
    from sim.world.sensor.tof_model import TOF_PRESETS

    for preset in TOF_PRESETS:
        scenario = load_scenario(write(tmp_path, f'scene = "lab"\n[sensor]\npreset = "{preset}"\n'
                                                 f'noise_scale = 100.0\n'))
        assert scenario.sensor.noise_scale == 100.0


LONG_STEPS = '[gait]\noverrides = { step_length_max_m = 0.3, step_yaw_max_deg = 50.0 }\n'


@pytest.mark.parametrize("text, refused", [
    ('duration_s = 3600.0\n', None),
    ('duration_s = 3600.0025\n', "0 < duration_s <= 3600"),
    ('duration_s = 0.035\n', None),  # one frame at 30 frames/s, the least
    ('duration_s = 2.0\n[sensor]\nfps = 0.5\n', None),
    ('[sensor]\nnoise_scale = 0.0\n', None),
    ('[sensor]\nnoise_scale = 100.5\n', "0 to 100"),
    ('[sensor]\nfps = 40\noverrides = { integration_time_s = 0.025 }\n', "fps < 40.0"),
    ('[recording]\nframe_stride = 1000\n', None),
    ('[recording]\nframe_stride = 1001\n', "1 to 1000"),
    ('duration_s = 5.0\n[[pushes]]\nt = 4.5\nimpulse_ns = [10.0, -10.0, 0.0]\nduration_s = 0.5\n',
     None),  # the largest impulse, ending with the scenario
    ('[[pushes]]\nt = 1.0\nimpulse_ns = [0.0, 1.0, 0.0]\nduration_s = 1.0\n', None),
    ('[[pushes]]\nt = 1.0\nimpulse_ns = [0.0, 1.0, 0.0]\nduration_s = 1.0025\n', "0.0025 to 1 s"),
    ('duration_s = 0.0\n', "0 < duration_s <= 3600"),
    ('[sensor]\nfps = 54.0\n', None),  # the SR4000's fastest
    ('[sensor]\nfps = 0.0\n', "0 < fps <= 54"),
    ('[floor]\nslope_deg = 0.0\nslope_direction_deg = -360.0\nbump_height_m = 0.0\n', None),
    (f'[floor]\nslope_deg = {MAX_SLOPE_DEG!r}\nslope_direction_deg = 360.0\n'
     f'bump_height_m = {MAX_BUMP_HEIGHT_M!r}\n', None),
    ('[floor]\nslope_direction_deg = 360.5\n', "from -360 to 360"),
    ('[[commands]]\nt = 0.0\nspeed = 0.0\n', None),
    # A gait of long steps: the command's own range is the limit.
    (f'{LONG_STEPS}[[commands]]\nt = 0.0\nspeed = 0.5\nyaw_rate = 90.0\n', None),
    (f'{LONG_STEPS}[[commands]]\nt = 0.0\nyaw_rate = -90.0\n', None),
    (f'{LONG_STEPS}[[commands]]\nt = 0.0\nspeed = 0.51\n', "0 to 0.5 m/s"),
    (f'{LONG_STEPS}[[commands]]\nt = 0.0\nyaw_rate = 90.5\n', "-90 to 90 deg/s"),
    ('[[pushes]]\nt = 0.0\nimpulse_ns = [0.0, 1.0, 0.0]\nduration_s = 0.0025\n', None),
    ('[[pushes]]\nt = 1.0\nimpulse_ns = [0.0, 1.0, 0.0]\nduration_s = 0.00125\n',
     "0.0025 to 1 s"),
    ('[[commands]]\nt = 0.0\n[[commands]]\nt = 2.0\n[[commands]]\nt = 2.0\n', "increase"),
    ('duration_s = 5.0\n[[commands]]\nt = 0.0\n[[commands]]\nt = 5.0\n', "before duration_s"),
    # Without duration_s, the default 20 s bounds the commands and pushes.
    ('[[commands]]\nt = 0.0\n[[commands]]\nt = 21.0\n', "increasing"),
    ('[[pushes]]\nt = 21.0\nimpulse_ns = [0.0, 1.0, 0.0]\n', "before duration_s"),
])
def test_values_at_each_limit_load_and_values_just_beyond_are_refused(tmp_path, text, refused):
    path = write(tmp_path, text)
    if refused is None:
        load_scenario(path)
        return
    with pytest.raises(ScenarioError, match=refused):
        load_scenario(path)


def test_the_commanded_trajectory_walks_every_command_from_the_start():
    scenario = load_scenario(SCENARIOS_DIR / "ci" / "ci_corridor.toml")  # 0.1 m/s from 0.5 s
    walked = commanded_trajectory(scenario, (1.0, 2.0), 90.0)
    np.testing.assert_allclose(walked[0], [1.0, 2.0])
    np.testing.assert_allclose(walked[-1], [1.0, 2.0 + 0.1 * (scenario.duration_s - 0.5)],
                               atol=1e-9)
