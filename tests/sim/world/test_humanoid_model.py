"""The humanoid's MJCF model (robot_models/humanoid/README.md): structure, mass, height, camera,
the assembled world and the README's picture."""

import math
import os
from pathlib import Path

import cv2
import mujoco
import numpy as np
import pytest

from robot_models import HUMANOID_DIR, humanoid_path
from sim.world import render_robot
from sim.world.camera import SR4000_INTRINSICS
from sim.world.humanoid import (CAMERA_NAME, CAMERA_SITE_NAME, MODEL_NAME, humanoid_mjcf,
                                robot_body_ids)
from sim.world.walking import RobotSimulation
from sim.world.assembly import assemble, clip_plane_fractions, compile_world, floor_arena


@pytest.fixture(scope="module")
def world_model():
    return compile_world(assemble())


def test_standalone_scene_compiles_with_a_free_robot():
    model = mujoco.MjModel.from_xml_path(str(humanoid_path("scene.xml")))
    assert model.nu == 24
    assert model.jnt_type[0] == mujoco.mjtJoint.mjJNT_FREE
    assert (HUMANOID_DIR / "README.md").is_file()


def test_unknown_model_file_is_a_value_error():
    with pytest.raises(ValueError, match="available"):
        humanoid_path("nope.xml")


def test_humanoid_mjcf_has_no_free_joint_to_attach():
    robot = humanoid_mjcf()
    assert not [j for j in robot.find_all("joint") if j.tag == "freejoint"]
    assert len(robot.find_all("joint")) == 24
    assert robot.find("camera", "sr4000") is not None


def test_24_position_actuators_on_24_distinct_hinge_joints(world_model):
    m = world_model
    assert m.nu == 24
    assert np.all(m.actuator_trntype == mujoco.mjtTrn.mjTRN_JOINT)
    joints = m.actuator_trnid[:, 0]
    assert len(set(joints.tolist())) == 24
    assert np.all(m.jnt_type[joints] == mujoco.mjtJoint.mjJNT_HINGE)
    robot_hinges = [j for j in range(m.njnt) if m.jnt_type[j] == mujoco.mjtJoint.mjJNT_HINGE]
    assert sorted(robot_hinges) == sorted(joints.tolist())
    # Small-servo class: torque limits of a few N m, every actuator limited.
    assert np.all(m.actuator_forcelimited)
    assert np.all(np.abs(m.actuator_forcerange) <= 8.4 + 1e-9)


def test_total_mass_includes_the_sr4000_on_the_head(world_model):
    m = world_model
    total = m.body_mass[robot_body_ids(m)].sum()
    assert total == pytest.approx(6.0, abs=0.3)
    camera_box = m.geom(f"{MODEL_NAME}/sr4000")
    assert m.body(camera_box.bodyid[0]).name == f"{MODEL_NAME}/head"
    # 65 (w) x 65 (h) x 68 (d) mm and 0.47 kg.
    assert sorted(2 * camera_box.size) == pytest.approx(sorted([0.068, 0.065, 0.065]))
    assert humanoid_mjcf().find("geom", "sr4000").mass == pytest.approx(0.47)


def test_inertias_come_from_geometry(world_model):
    m = world_model
    for body in robot_body_ids(m):
        inertia = m.body_inertia[body]
        assert np.all(inertia > 0)
        # A default unit inertia would be far larger than any link of a 6 kg robot has.
        assert np.all(inertia < 0.05)


def test_imu_gyro_and_accelerometer_in_the_torso(world_model):
    m = world_model
    for name, kind in (("imu_gyro", mujoco.mjtSensor.mjSENS_GYRO),
                       ("imu_accel", mujoco.mjtSensor.mjSENS_ACCELEROMETER)):
        sensor = m.sensor(f"{MODEL_NAME}/{name}")
        assert sensor.type[0] == kind
        site = sensor.objid[0]
        assert m.body(m.site_bodyid[site]).name == f"{MODEL_NAME}/torso"


def test_camera_intrinsics_match_the_sr4000(world_model):
    m = world_model
    cam = m.camera(CAMERA_NAME).id
    assert tuple(m.cam_resolution[cam]) == (176, 144)
    # MuJoCo stores the focal length in length units: f_px = f * resolution / sensor size.
    sensor_w, sensor_h = m.cam_sensorsize[cam]
    fx_px = m.cam_intrinsic[cam][0] / sensor_w * 176
    fy_px = m.cam_intrinsic[cam][1] / sensor_h * 144
    assert fx_px == pytest.approx(SR4000_INTRINSICS.fx, rel=1e-3)
    assert fy_px == pytest.approx(SR4000_INTRINSICS.fy, rel=1e-3)
    site = m.site(CAMERA_SITE_NAME).id
    assert m.site_bodyid[site] == m.cam_bodyid[cam] == m.body(f"{MODEL_NAME}/head").id
    assert m.site_pos[site] == pytest.approx(m.cam_pos[cam])
    assert m.site_quat[site] == pytest.approx(m.cam_quat[cam])


def test_depth_range_covers_the_sr4000(world_model):
    extent = world_model.stat.extent
    assert world_model.vis.map.znear * extent <= 0.1
    assert world_model.vis.map.zfar * extent >= 10.0


@pytest.mark.parametrize("extent_m, near_m, far_m", [(0.0, 0.1, 10.0), (2.0, 0.0, 10.0),
                                                    (2.0, 10.0, 10.0)])
def test_clip_planes_need_an_extent_and_a_depth_range(extent_m, near_m, far_m):
    with pytest.raises(ValueError, match="need extent_m > 0 and 0 < near_m < far_m"):
        clip_plane_fractions(extent_m, near_m, far_m)
    assert clip_plane_fractions(2.0, 0.1, 10.0) == pytest.approx((0.05, 5.0))


def test_standing_height_and_level_forward_camera(world_model):
    sim = RobotSimulation(world_model)
    sim.run(1.0)
    assert sim.fall is None
    head_top = sim.data.site(f"{MODEL_NAME}/head_top").xpos[2]
    assert head_top == pytest.approx(0.60, abs=0.02)
    _, mat = sim.camera_pose()
    looking = -mat[:, 2]
    assert math.degrees(math.acos(looking @ np.array([1.0, 0.0, 0.0]))) < 3.0
    assert mat[:, 1] @ np.array([0.0, 0.0, 1.0]) > math.cos(math.radians(3.0))
    assert sim.foot_contacts() == (True, True)


def test_start_pose_turns_the_robot_and_its_camera():
    sim = RobotSimulation(compile_world(assemble(start_xy=(1.0, -2.0), start_yaw_deg=90.0)))
    pos, mat = sim.camera_pose()
    assert pos[:2] == pytest.approx([1.0, -2.0], abs=0.08)
    assert -mat[:, 2] @ np.array([0.0, 1.0, 0.0]) > math.cos(math.radians(3.0))


@pytest.mark.parametrize("bad", [{"start_xy": (0.0,)}, {"start_xy": (0.0, float("nan"))},
                                 {"start_yaw_deg": float("inf")}])
def test_assemble_rejects_bad_start_pose(bad):
    with pytest.raises(ValueError, match="start_"):
        assemble(**bad)


def test_rendered_field_of_view_matches_the_sr4000():
    """A thin pole 15 deg to the left and a bar 12 deg up land on the columns/rows the
    SR4000's intrinsics predict (u = cx - fx tan(a), v = cy - fy tan(b))."""
    os.environ.setdefault("MUJOCO_GL", "egl")
    arena = floor_arena()
    arena.worldbody.add("geom", name="pole", type="box", size=(0.02, 0.02, 3.0), pos=(5, 0, 0))
    arena.worldbody.add("geom", name="bar", type="box", size=(0.02, 3.0, 0.02), pos=(5, 0, 2))
    model = compile_world(assemble(arena))
    sim = RobotSimulation(model)
    cam_pos, cam_mat = sim.camera_pose()
    distance = 3.0
    left, up = math.radians(15.0), math.radians(12.0)
    forward, right_axis, up_axis = -cam_mat[:, 2], cam_mat[:, 0], cam_mat[:, 1]
    centre = cam_pos + distance * forward
    model.geom("pole").pos = centre - distance * math.tan(left) * right_axis
    model.geom("bar").pos = centre + distance * math.tan(up) * up_axis
    mujoco.mj_forward(model, sim.data)
    with mujoco.Renderer(model, height=144, width=176) as renderer:
        renderer.enable_depth_rendering()
        renderer.update_scene(sim.data, camera=CAMERA_NAME)
        depth = renderer.render()
    k = SR4000_INTRINSICS
    near = np.abs(depth - distance) < 0.1                  # the floor is nearer or farther
    pole_cols = np.flatnonzero(near[round(k.cy)])
    bar_rows = np.flatnonzero(near[: int(k.cy), round(k.cx)])   # above the horizon
    assert pole_cols.mean() == pytest.approx(k.cx - k.fx * math.tan(left), abs=1.0)
    assert bar_rows.mean() == pytest.approx(k.cy - k.fy * math.tan(up), abs=1.0)


def test_render_robot_writes_a_picture_of_the_requested_size(tmp_path, capsys):
    path = tmp_path / "robot.png"
    render_robot.main(["--out", str(path), "--width", "60", "--height", "80"])
    assert str(path) in capsys.readouterr().out
    image = cv2.imread(str(path))
    assert image.shape == (80, 60, 3)
    assert image.std() > 10                              # not a blank frame
    # The robot (dark grey) stands in the middle, against the lighter sky and floor.
    middle_column = image[:, 25:35].mean(axis=(1, 2))
    assert middle_column.min() < 0.6 * middle_column.max()


def test_an_interrupted_picture_write_leaves_the_previous_picture(tmp_path, monkeypatch):
    path = tmp_path / "robot.png"
    render_robot.save_png(np.full((8, 6, 3), 200, np.uint8), path)
    before = path.read_bytes()

    def stopped_half_way(self, data):
        with open(self, "wb") as file:
            file.write(data[: len(data) // 2])
        raise KeyboardInterrupt

    monkeypatch.setattr(Path, "write_bytes", stopped_half_way)
    with pytest.raises(KeyboardInterrupt):
        render_robot.save_png(np.zeros((8, 6, 3), np.uint8), path)
    assert path.read_bytes() == before
    assert [entry.name for entry in tmp_path.iterdir()] == ["robot.png"]


def test_the_readme_shows_the_rendered_picture():
    readme = (HUMANOID_DIR / "README.md").read_text()
    assert "humanoid.png" in readme and "python -m sim.world.render_robot" in readme
    assert render_robot.DEFAULT_PICTURE_PATH == HUMANOID_DIR / "humanoid.png"
    assert render_robot.DEFAULT_PICTURE_PATH.is_file()


@pytest.mark.parametrize("bad", [{"width": 0}, {"height": 0},
                                 {"width": render_robot.MAX_SIDE_PX + 1},
                                 {"height": render_robot.MAX_SIDE_PX + 1}, {"distance_m": 0.0}])
def test_render_robot_rejects_bad_sizes(bad):
    with pytest.raises(ValueError, match=f"{next(iter(bad))}"):
        render_robot.render_humanoid(**bad)


@pytest.mark.parametrize("width, height", [(1, 1), (render_robot.MAX_SIDE_PX, 1),
                                           (1, render_robot.MAX_SIDE_PX)])
def test_render_robot_draws_pictures_of_every_size_it_accepts(width, height):
    assert render_robot.render_humanoid(width=width, height=height).shape == (height, width, 3)


def test_the_readme_names_each_joints_servo_class_as_the_model_does():
    import re
    import xml.etree.ElementTree as ElementTree

    readme = (HUMANOID_DIR / "README.md").read_text()
    table = dict(re.findall(r"^\| `(\w+)` \| [xyz] \| .+ \| `(\w+)` \|$", readme, re.MULTILINE))
    assert len(table) == 14  # legs 6, waist 2, neck 2, arms 4 per side or centre
    root = ElementTree.parse(humanoid_path("humanoid.xml")).getroot()
    for kind in ("joint", "position"):  # the joint and its servo
        classes = {re.sub(r"^[lr]_", "", element.get("name")): element.get("class")
                   for element in root.iter(kind) if element.get("name")}
        assert classes == table, kind
