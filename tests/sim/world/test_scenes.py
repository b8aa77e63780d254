"""Indoor scenes: they compile, are reproducible from the seed and parameters, leave the robot's
lane free, give the sensor objects at several depths, and take checked parameters."""

from __future__ import annotations

import ast
import dataclasses
import hashlib
import math
import os
import re
from pathlib import Path

os.environ.setdefault("MUJOCO_GL", "egl")

import mujoco  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402
from scipy.ndimage import gaussian_filter  # noqa: E402

from sim.world.scenes import (SCENES, Floor, FloorParameterError, SceneParameterError,  # noqa: E402
                              build_scene)
from sim.world.scenes.floor import (START_FLAT_RADIUS_M, BumpField,  # noqa: E402
                                    bump_field)
from sim.world.scenes.lane import (compiled_geom_boxes, lane_intrusions, path_distance,  # noqa: E402
                                   polyline, start_heading_deg)
from sim.world.sensor.sr4000 import SR4000, add_probe_camera  # noqa: E402
from sim.world.sensor.tof_model import TOF_PRESETS  # noqa: E402

SEEDS = (0, 1, 2, 3)


def _with_robot_proxy(scene):
    """The scene plus a free box as wide as the lane and as tall as the robot (0.72 m)."""
    half = scene.clear_half_width_m - 0.01
    proxy = scene.arena.worldbody.add("body", name="proxy")
    proxy.add("freejoint")
    proxy.add("geom", name="proxy", type="box", size=[0.12, half, 0.35], pos=[0, 0, 0.37])
    return scene.compile()


def _lane_contacts(scene) -> set[str]:
    """Geoms that a lane-wide box slid along the path touches (MuJoCo's collision detection)."""
    model = _with_robot_proxy(scene)
    data = mujoco.MjData(model)
    proxy = model.geom("proxy").id
    path = scene.path
    headings = np.arctan2(*np.diff(path, axis=0).T[::-1])
    touching = set()
    for xy, heading in zip(path[:-1], headings):
        data.qpos[:3] = [xy[0], xy[1], 0.0]
        data.qpos[3:7] = [math.cos(heading / 2), 0, 0, math.sin(heading / 2)]
        mujoco.mj_forward(model, data)
        touching |= {model.geom(int(g)).name for c in data.contact[:data.ncon]
                     for g in (c.geom1, c.geom2) if proxy in (c.geom1, c.geom2)}
    return touching - {"proxy"}


@pytest.mark.parametrize("name", list(SCENES))
@pytest.mark.parametrize("seed", SEEDS)
def test_lane_around_the_path_has_no_obstacle(name, seed):
    assert not _lane_contacts(build_scene(name, seed))


def test_lane_checks_find_an_obstacle_on_the_path():
    scene = build_scene("corridor", 0)
    scene.arena.worldbody.add("geom", name="in_the_way", type="box", size=[0.1, 0.1, 0.1],
                              pos=[1.5, 0.2, 0.1])
    assert lane_intrusions(scene.compile(), scene.path) == ["in_the_way"]
    assert _lane_contacts(scene) == {"in_the_way"}


@pytest.mark.parametrize("name", list(SCENES))
def test_same_seed_same_scene_other_seed_other_scene(name):
    first, again, other = build_scene(name, 5), build_scene(name, 5), build_scene(name, 6)
    assert first.arena.to_xml_string() == again.arena.to_xml_string()
    assert first.arena.to_xml_string() != other.arena.to_xml_string()
    np.testing.assert_array_equal(first.path, again.path)


@pytest.mark.parametrize("name", list(SCENES))
def test_the_sensor_sees_objects_at_several_depths(name):
    """From the start pose, surfaces fill at least three 1-m depth bins between 0.5 and 5 m."""
    scene = build_scene(name, 0)
    camera = add_probe_camera(scene.arena, scene.start_xy, scene.start_yaw_deg)
    model = scene.compile()
    data = mujoco.MjData(model)
    with SR4000(model, camera, TOF_PRESETS["noiseless"]) as sensor:
        frame = sensor.capture_still(data)
    depth = frame.depth_m[frame.valid]
    counts, _ = np.histogram(depth, bins=[0.5, 1.5, 2.5, 3.5, 4.5, 5.0])
    assert (counts > 0.02 * depth.size).sum() >= 3, counts
    assert frame.valid.mean() > 0.8  # lit, closed scenes: little sky


def test_scene_fields_and_start_pose():
    scene = build_scene("office", 0)
    assert scene.path.ndim == 2 and scene.path.shape[1] == 2 and len(scene.path) > 10
    np.testing.assert_array_equal(scene.start_xy, scene.path[0])
    assert scene.start_yaw_deg == pytest.approx(0.0)
    end_heading = np.degrees(np.arctan2(*(scene.path[-1] - scene.path[-2])[::-1]))
    assert end_heading == pytest.approx(90.0, abs=1.0)  # the office walk turns left


def test_polyline_lengths():
    path = polyline(("line", 1.0), ("arc", 0.5, 90), ("line", 0.5))
    assert np.linalg.norm(np.diff(path, axis=0), axis=1).sum() == pytest.approx(
        1.5 + math.pi / 4, rel=1e-3)
    np.testing.assert_allclose(path[-1], [1.5, 1.0], atol=1e-9)
    with pytest.raises(ValueError, match="line, arc"):
        polyline(("zigzag", 1.0))


def test_a_path_is_measured_between_its_points_and_heads_along_its_first_segment():
    path = np.array([[1.0, 0.0], [2.0, 0.0]])  # a metre between two points
    boxes = np.array([[1.5, 0.1, 1.6, 0.2], [3.0, 0.0, 4.0, 1.0], [1.3, -0.2, 1.4, 0.5]])
    np.testing.assert_allclose(path_distance(path, boxes), [0.1, 1.0, 0.0], atol=1e-12)
    assert start_heading_deg(np.array([[1.0, 1.0], [1.0, 2.0], [5.0, 5.0]])) == 90.0
    assert start_heading_deg(np.array([[2.0, 0.0], [1.0, 0.0]])) == 180.0


def test_compiled_geom_boxes_are_in_the_world_frame():
    model = mujoco.MjModel.from_xml_string("""
        <mujoco><worldbody>
          <geom name="floor" type="plane" size="5 5 0.1"/>
          <body pos="1 2 0" euler="0 0 90">
            <geom name="crate" type="box" pos="0.5 0 0.3" size="0.1 0.2 0.3"/>
          </body>
        </worldbody></mujoco>""")
    boxes, ids = compiled_geom_boxes(model)
    assert [model.geom(int(g)).name for g in ids] == ["crate"]  # no plane
    # Turned a quarter left about the body's origin: the crate's centre at (1, 2.5), its
    # x and y extents swapped.
    np.testing.assert_allclose(boxes, [[0.8, 2.4, 0.0, 1.2, 2.6, 0.6]], atol=1e-9)


def test_bump_heights_are_exact_at_grid_points_bilinear_between_and_0_outside():
    bumps = BumpField(np.arange(9.0).reshape(3, 3), np.array([0.0, 0.0]), np.array([1.0, 2.0]),
                      0.5)  # columns at x = -1, 0, 1; rows at y = -2, 0, 2
    points = [(-1.0, -2.0), (1.0, 2.0), (1.0, -2.0), (-1.0, 2.0), (0.0, 0.0), (0.5, 0.0),
              (0.5, 1.0), (1.0, 1.0), (1.0 + 1e-9, 0.0), (0.0, -2.0 - 1e-9), (5.0, 5.0)]
    np.testing.assert_allclose(bumps.height_at(points),
                               0.5 * np.array([0.0, 8.0, 2.0, 6.0, 4.0, 4.5, 6.0, 6.5, 0, 0, 0]),
                               atol=1e-12)


def test_bad_scene_name_or_seed_is_a_value_error():
    with pytest.raises(ValueError, match="corridor"):
        build_scene("kitchen", 0)
    with pytest.raises(ValueError, match="seed"):
        build_scene("lab", -1)


def test_robot_attaches_and_its_camera_is_an_sr4000():
    from sim.world import assembly, humanoid

    scene = build_scene("corridor", 0)
    model = assembly.compile_world(assembly.assemble(scene.arena, scene.start_xy,
                                                     scene.start_yaw_deg))
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    with SR4000(model, humanoid.CAMERA_NAME, TOF_PRESETS["noiseless"]) as sensor:
        frame = sensor.capture_still(data)
    assert frame.valid.mean() > 0.8
    assert 0.4 < frame.cam_pos[2] < 0.7


# -- parameters -------------------------------------------------------------------------------

#: SHA-1 of each scene's MJCF at seed 0 with default parameters, as the scenes were first made
#: (before they took parameters). A change means the scene changed (or dm_control's XML writer).
FIRST_SCENES_SHA1 = {
    "corridor": "0749ad0222a26758ba17b29a1e470e37ebb66ff6",
    "office": "f164809fad19029df16ebb4999f2221c54152060",
    "lab": "446619c3f95ff3b60f328976045a62e0340f6388",
    "hall": "e518d3a6717a32542562fc217ef84a41d6bf226a",
}


@pytest.mark.parametrize("name", list(SCENES))
def test_default_parameters_give_the_first_scenes(name):
    scene = build_scene(name, 0)
    assert hashlib.sha1(scene.arena.to_xml_string().encode()).hexdigest() == \
        FIRST_SCENES_SHA1[name]
    explicit = build_scene(name, 0, floor=Floor(), **SCENES[name]().params())
    assert explicit.arena.to_xml_string() == scene.arena.to_xml_string()
    assert scene.params == SCENES[name]().params()


@pytest.mark.parametrize("name", list(SCENES))
def test_the_docstring_documents_every_parameter_and_its_default(name):
    layout = SCENES[name]
    doc = " ".join(layout.__doc__.split())
    for spec in dataclasses.fields(layout):
        assert f" {spec.name}: " in doc, spec.name
        described = doc.split(f" {spec.name}: ")[1]
        for other in layout.parameter_names():  # up to the next parameter's description
            described = described.split(f" {other}: ")[0]
        documented = re.search(r"default (\([^)]*\)|\d+)", described).group(1)
        assert np.array_equal(ast.literal_eval(documented), spec.default), spec.name


def test_parameters_change_the_scene_and_are_reproducible():
    wide = build_scene("corridor", 0, half_width_m=(1.2, 1.2), clutter_count=(0, 0))
    again = build_scene("corridor", 0, half_width_m=[1.2, 1.2], clutter_count=[0, 0])
    assert wide.arena.to_xml_string() == again.arena.to_xml_string()
    assert wide.arena.to_xml_string() != build_scene("corridor", 0).arena.to_xml_string()
    assert wide.params["half_width_m"] == (1.2, 1.2)
    side_walls = [body for body in wide.arena.worldbody.body if body.name.startswith("wall")
                  and abs(abs(body.pos[1]) - 1.2) < 1e-9]
    assert side_walls  # the side walls moved out to y = +-1.2 m
    assert not [body for body in wide.arena.worldbody.body if body.name.startswith("crate")]
    assert not _lane_contacts(wide)


@pytest.mark.parametrize("name", list(SCENES))
def test_every_parameter_at_its_bounds_keeps_the_lane_free(name):
    """All ranges fixed at the low (then high) end of what they accept: the scene builds."""
    layout = SCENES[name]
    for end in (0, 1):
        params = {}
        for spec in dataclasses.fields(layout):
            bound = spec.metadata["within"][end]
            kind = spec.metadata["kind"]
            params[spec.name] = {"integer": min(bound, 4), "integer_range": (min(bound, 6),) * 2,
                                 "real_range": (bound, bound), "positions": (bound,)}[kind]
        if name == "corridor":
            params["side_doors_per_wall"] = (min(end, 1),) * 2
        scene = build_scene(name, 1, **params)
        assert not lane_intrusions(scene.compile(), scene.path)


@pytest.mark.parametrize("params, parameter, accepted", [
    ({"width": 1.0}, "width", "half_width_m, end_wall_past_walk_m"),
    ({"half_width_m": (0.9, 0.8)}, "half_width_m", "low <= high"),
    ({"half_width_m": (0.1, 0.8)}, "half_width_m", "0.45 <= low"),
    ({"half_width_m": 0.8}, "half_width_m", "a pair"),
    ({"half_width_m": (0.7, float("nan"))}, "half_width_m", "a pair"),
    ({"clutter_count": (1.5, 2)}, "clutter_count", "integers"),
    ({"clutter_count": (True, 2)}, "clutter_count", "integers"),
    ({"side_door_slots_m": ()}, "side_door_slots_m", "non-empty"),
    ({"side_doors_per_wall": (1, 4)}, "side_doors_per_wall", "as many doors as slots"),
])
def test_bad_parameters_are_refused_naming_scene_parameter_and_accepted(params, parameter,
                                                                         accepted):
    with pytest.raises(SceneParameterError) as error:
        build_scene("corridor", 0, **params)
    message = str(error.value)
    assert isinstance(error.value, ValueError) and "\n" not in message
    assert error.value.scene == "corridor" and error.value.parameter == parameter
    assert "'corridor'" in message and repr(parameter) in message
    assert accepted in message.split("accepted:")[1]


# -- floors -----------------------------------------------------------------------------------

#: The hardest floor accepted: 3 degrees, rising towards 60 degrees, 5 mm bumps.
ROUGH = Floor(slope_deg=3.0, slope_direction_deg=60.0, bump_height_m=0.005)


def _floor_hits(model, points_xy, floor):
    """(x, y, z) where a ray straight down from 5 cm above the sloped floor at each point meets
    the floor (plane or bumps); points where it meets furniture first are left out."""
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    floor_geoms = {model.geom("floor").id}
    if "floor_bumps" in [model.geom(g).name for g in range(model.ngeom)]:
        floor_geoms.add(model.geom("floor_bumps").id)
    hit = np.zeros(1, np.int32)
    hits = []
    for x, y in points_xy:
        start = np.array([x, y, floor.height([x, y]) + 0.05])
        distance = mujoco.mj_ray(model, data, start, np.array([0.0, 0.0, -1.0]), None, 1, -1, hit)
        if hit[0] in floor_geoms:
            hits.append([x, y, start[2] - distance])
    return np.array(hits)


@pytest.mark.parametrize("name", list(SCENES))
def test_a_rough_floor_has_the_requested_slope_and_bumps(name):
    """Rays cast down onto the compiled scene: away from the bumps the floor is the plane of
    the requested slope and direction; over the walk it rises 0 to 5 mm above that plane, as
    the scene's bump field says, flat where the robot starts."""
    scene = build_scene(name, 1, floor=ROUGH)
    model = scene.compile()
    bumps = scene.bumps
    rng = np.random.default_rng(0)
    low, high = bumps.centre_xy - bumps.half_size_xy, bumps.centre_xy + bumps.half_size_xy
    outside = _floor_hits(model, rng.uniform(low - 1.0, high + 1.0, (400, 2)), ROUGH)
    outside = outside[np.any((outside[:, :2] < low) | (outside[:, :2] > high), axis=1)]
    assert len(outside) > 30
    gradient, *_ = np.linalg.lstsq(np.c_[outside[:, :2], np.ones(len(outside))], outside[:, 2],
                                   rcond=None)
    assert math.degrees(math.atan(np.hypot(*gradient[:2]))) == pytest.approx(3.0, abs=1e-3)
    assert math.degrees(math.atan2(gradient[1], gradient[0])) == pytest.approx(60.0, abs=1e-3)
    inside = _floor_hits(model, rng.uniform(low, high, (600, 2)), ROUGH)
    assert len(inside) > 300
    bump = inside[:, 2] - ROUGH.height(inside[:, :2])
    assert bump.min() > -0.001 and bump.max() <= 0.005 + 1e-6 and bump.max() > 0.003
    # Between grid points MuJoCo's triangles differ from the bilinear reference a little.
    np.testing.assert_allclose(bump, bumps.height_at(inside[:, :2]), atol=3e-4)
    x, y = bumps.grid_xy()
    grid = np.stack(np.meshgrid(x, y), axis=-1)
    assert bumps.heights.max() == 1.0 and bumps.heights.min() == 0.0
    near_start = np.hypot(*(grid - scene.start_xy).transpose(2, 0, 1)) < START_FLAT_RADIUS_M
    assert np.all(bumps.heights[near_start] == 0.0)
    # The field fades to 0 at its edges: it meets the plane without a step.
    edges = np.concatenate((bumps.heights[[0, -1], :].ravel(), bumps.heights[:, [0, -1]].ravel()))
    assert np.all(edges == 0.0)


def test_the_bump_field_is_the_documented_recipe():
    """docs/scenes.md, "Bumps": white noise on a 2 cm grid over the path's bounding box plus
    1 m on every side, from the seed's own stream SeedSequence(seed, spawn_key=(1,)), smoothed
    by a Gaussian of 5 cm, faded in (a raised cosine) over 25 cm from the field's border and
    from 20 cm around the start, the highest point 1 (times bump_height_m)."""
    path = np.array([[0.5, -0.3], [2.0, 0.5], [3.0, -1.0]])
    field = bump_field(path, 7, 0.004)
    low, high = path.min(axis=0) - 1.0, path.max(axis=0) + 1.0
    cols, rows = np.ceil((high - low) / 0.02).astype(int) + 1
    assert field.heights.shape == (rows, cols) and field.height_m == 0.004
    x, y = low[0] + 0.02 * np.arange(cols), low[1] + 0.02 * np.arange(rows)
    np.testing.assert_allclose(field.grid_xy()[0], x, atol=1e-12)
    np.testing.assert_allclose(field.grid_xy()[1], y, atol=1e-12)
    white = np.random.default_rng(np.random.SeedSequence(7, spawn_key=(1,)))
    noise = gaussian_filter(white.standard_normal((rows, cols)), 0.05 / 0.02, mode="reflect")

    def fade_in(distance):
        return 0.5 - 0.5 * np.cos(math.pi * np.clip(distance / 0.25, 0.0, 1.0))

    grid_x, grid_y = np.meshgrid(x, y)
    to_border = np.minimum(np.minimum(grid_x - x[0], x[-1] - grid_x),
                           np.minimum(grid_y - y[0], y[-1] - grid_y))
    to_start = np.hypot(grid_x - path[0, 0], grid_y - path[0, 1]) - 0.2
    expected = (noise - noise.min()) * fade_in(to_border) * fade_in(to_start)
    np.testing.assert_allclose(field.heights, expected / expected.max(), rtol=0, atol=1e-12)


def test_the_building_stands_on_the_sloped_floor_and_keeps_its_layout():
    flat = build_scene("office", 2)
    sloped = build_scene("office", 2, floor=Floor(2.0, 135.0))
    frame = sloped.arena.find("body", "floor_frame")
    assert [(b.name, tuple(b.pos)) for b in frame.body] == \
        [(b.name, tuple(b.pos)) for b in flat.arena.worldbody.body]
    model = sloped.compile()
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    standing = [b.name for b in frame.body if b.pos[2] == 0.0]  # all but the ceilings
    assert len(standing) > 10
    for name in standing:
        position = data.xpos[model.body(name).id]
        assert position[2] == pytest.approx(sloped.floor.height(position[:2]), abs=1e-9)
    assert sloped.bumps is None and "hfield" not in sloped.arena.to_xml_string()


def test_floors_are_reproducible_from_the_seed():
    first, again = build_scene("corridor", 4, floor=ROUGH), build_scene("corridor", 4, floor=ROUGH)
    assert first.arena.to_xml_string() == again.arena.to_xml_string()
    other = build_scene("corridor", 5, floor=ROUGH)
    assert not np.array_equal(first.bumps.heights, other.bumps.heights)
    # The bumps come from their own stream of the seed: the layout is the flat scene's.
    flat = build_scene("corridor", 4)
    assert [b.name for b in first.arena.find("body", "floor_frame").body] == \
        [b.name for b in flat.arena.worldbody.body]
    as_mapping = build_scene("corridor", 4, floor={"slope_deg": 3.0, "slope_direction_deg": 60.0,
                                                   "bump_height_m": 0.005})
    assert as_mapping.arena.to_xml_string() == first.arena.to_xml_string()


@pytest.mark.parametrize("settings, parameter, accepted", [
    ({"slope_deg": 3.5}, "slope_deg", "from 0 to 3"),
    ({"slope_deg": -1.0}, "slope_deg", "from 0 to 3"),
    ({"bump_height_m": 0.01}, "bump_height_m", "from 0 to 0.005"),
    ({"bump_height_m": float("nan")}, "bump_height_m", "from 0 to 0.005"),
    ({"slope_direction_deg": "north"}, "slope_direction_deg", "-360 to 360"),
    ({"slope_deg": True}, "slope_deg", "from 0 to 3"),
    ({"slope": 2.0}, "slope", "slope_deg, slope_direction_deg, bump_height_m"),
])
def test_bad_floor_settings_are_refused_in_one_line(settings, parameter, accepted):
    with pytest.raises(FloorParameterError) as error:
        build_scene("lab", 0, floor=settings)
    message = str(error.value)
    assert isinstance(error.value, ValueError) and "\n" not in message
    assert error.value.parameter == parameter and repr(parameter) in message
    assert accepted in message.split("accepted:")[1]


@pytest.mark.parametrize("direction_deg", [0.0, 90.0])
def test_the_robot_walks_on_a_3_degree_slope_with_5_mm_bumps(direction_deg):
    """Physics only: stand 1 s, walk 4 s at 0.1 m/s up (or across) the roughest floor."""
    from sim.world.assembly import assemble, compile_world
    from sim.world.walking import RobotSimulation

    scene = build_scene("corridor", 0, floor=Floor(3.0, direction_deg, 0.005))
    robot = RobotSimulation(compile_world(assemble(scene.arena, scene.start_xy,
                                                   scene.start_yaw_deg)))
    robot.run(1.0)
    robot.command(0.1, 0.0)
    robot.run(4.0)
    assert robot.fall is None
    assert robot.torso_pose()[0][0] > 0.25


# -- documentation ----------------------------------------------------------------------------

@pytest.mark.parametrize("name", list(SCENES))
def test_the_scenes_document_tabulates_each_parameter_its_default_and_bounds(name):
    """docs/scenes.md's table of each scene: a row per parameter, in the code's order, with
    its default and the bounds a value is accepted within (the code refuses a value beyond
    them; a change of either fails here until the document says it)."""
    document = (Path(__file__).resolve().parents[3] / "docs" / "scenes.md").read_text()
    section = document.split(f"\n### {name}\n", 1)[1]
    table = section.split("| parameter | default | bounds | meaning |\n", 1)[1]
    rows = [row.split(" | ") for row in table.split("\n\n", 1)[0].splitlines()[1:]]
    fields = [f for f in dataclasses.fields(SCENES[name]()) if "within" in f.metadata]
    assert [row[0] for row in rows] == [f"| `{f.name}`" for f in fields]

    for row, field in zip(rows, fields):
        assert ast.literal_eval(row[1]) == field.default, field.name
        bounds = re.match(r"(each )?(-?[0-9.]+)-(-?[0-9.]+)(,|$)", row[2])
        assert bounds and bool(bounds[1]) == (field.metadata["kind"] == "positions"), field.name
        assert (float(bounds[2]), float(bounds[3])) == field.metadata["within"], field.name


# -- fixed structures -------------------------------------------------------------------------
def _built(build):
    """The footprints a structure reserves, the xy box around the geoms it builds (the floor
    left out; :func:`~sim.world.scenes.lane.compiled_geom_boxes`), and the compiled model and
    data: ``build(structure)`` builds it."""
    from sim.world.scenes.arena import Arena
    from sim.world.scenes.lane import compiled_geom_boxes
    from sim.world.scenes.placement import Placement
    from sim.world.scenes.structure import Structure

    arena = Arena("structures")
    placement = Placement(np.zeros((2, 2)), np.random.default_rng(0))
    build(Structure(arena, placement))
    model = mujoco.MjModel.from_xml_string(arena.root.to_xml_string(),
                                           arena.root.get_assets())
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)  # the lights' world positions too
    boxes, _ = compiled_geom_boxes(model)
    box = np.concatenate([boxes[:, :2].min(axis=0), boxes[:, 3:5].max(axis=0)])
    return placement._footprints, box, model, data


@pytest.mark.parametrize("start, end", [((1.0, 2.0), (4.0, 2.0)), ((0.5, -1.0), (2.5, 2.0))])
def test_a_wall_reserves_the_floor_it_stands_on(start, end):
    (reserved,), built, _, _ = _built(lambda structure: structure.wall(start, end))
    np.testing.assert_allclose(reserved, built, atol=1e-9)


@pytest.mark.parametrize("yaw_deg", [0.0, 90.0, 30.0])
def test_a_doorway_reserves_its_frame_and_closed_leaf(yaw_deg):
    """Furniture keeps off a doorway: its reserved footprint is the frame's, jambs included."""
    (reserved,), built, _, _ = _built(lambda structure: structure.doorway((1.0, -2.0), yaw_deg))
    np.testing.assert_allclose(reserved, built, atol=1e-9)


def test_a_rooms_ceiling_lights_hang_1_m_inside_its_walls():
    """Lights 3 m apart from 1 m inside the walls, none nearer than 1 m to them: in this room,
    9 m across, a fourth light 3 m past the third would hang outside the walls."""
    xmin, xmax, ymin, ymax = -3.0, 6.0, -2.0, 7.0
    _, _, model, data = _built(lambda structure: structure.room(xmin, xmax, ymin, ymax))
    lights = data.light_xpos
    assert len(lights) == 3 * 3
    assert lights[:, 0].min() == pytest.approx(xmin + 1) and lights[:, 0].max() <= xmax - 1
    assert lights[:, 1].min() == pytest.approx(ymin + 1) and lights[:, 1].max() <= ymax - 1
