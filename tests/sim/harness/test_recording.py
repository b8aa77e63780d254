"""The rerun recording: written to a file, read back with rerun's own reader."""

import dataclasses
import json
import re
from collections import defaultdict
from types import SimpleNamespace

import numpy as np
import pytest
import rerun as rr
from rerun.chunk import RrdReader
from scipy.spatial.transform import Rotation

from sim.harness.ground_truth import ground_truth, pixel_rays
from sim.harness.recording import (INFINITE_PLANE_HALF_M, PLANE_THICKNESS_M,
                                   POINT_CLOUD_STRIDE, RunRecorder, depth_millimetres,
                                   depth_points_world, ellipse_outline, geom_archetypes,
                                   label_colours, overhead, world_geoms)
from sim.world.camera import SR4000_INTRINSICS
from stabilizer.motion import Motion, compensate
from tests.sim.harness.scene_frames import box_world, camera_matrix, render_frame

METHODS = ("t2fuzzy", "sift")
N_FRAMES = 6
LABELS = np.zeros((144, 176), np.int32)
LABELS[30:60, 40:90] = 1
LABELS[80:100, 100:150] = 2
ELLIPSES = [(65.0, 45.0, 25.0, 15.0, 0.0), (125.0, 90.0, 25.0, 10.0, -30.0)]


def _frames():
    world = box_world()
    return [render_frame(world, [0.02 * i, 0.0, 0.0], camera_matrix(roll_deg=1.5 * i), i, i / 30)
            for i in range(N_FRAMES)]


def _record(path, frame_stride=1, fail_sift_on=(2,)):
    frames = _frames()
    with RunRecorder(path, METHODS, frame_stride=frame_stride,
                     properties={"scenario": {"name": "boxes", "walk": [1, 2]}, "seed": 7}) as rec:
        for frame in frames:
            truth = ground_truth(frames[0], frame)
            estimates = {
                "t2fuzzy": Motion(*truth.motion.as_tuple(),
                                  diagnostics={"labels": LABELS, "ellipses": ELLIPSES}),
                "sift": (Motion.failed("no_structure") if frame.index in fail_sift_on
                         else Motion(*truth.motion.as_tuple())),
            }
            compensated = {m: compensate(frame.disparity8, e) for m, e in estimates.items()}
            rec.log_frame(frame, estimates=estimates, truth=truth, compensated=compensated)
        rec.log_event("run complete")
    return rec


def _rows_per_entity(path):
    """entity -> (static rows, temporal rows, timelines) from the store's summary."""
    rows = defaultdict(lambda: [0, 0, set()])
    pattern = re.compile(r"^(\S+) rows=(\d+) static=(True|False) timelines=\[(.*?)\]")
    for line in RrdReader(str(path)).store().summary().splitlines():
        match = pattern.match(line)
        assert match, line
        entity, count, static, timelines = match.groups()
        rows[entity][0 if static == "True" else 1] += int(count)
        rows[entity][2] |= set(re.findall(r"'([^']+)'", timelines))
    return rows


@pytest.fixture(scope="module")
def recording(tmp_path_factory):
    path = tmp_path_factory.mktemp("rec") / "run" / "recording.rrd"
    recorder = _record(path)
    return path, recorder


def test_recording_holds_every_entity_with_one_row_per_frame(recording):
    path, recorder = recording
    rows = _rows_per_entity(path)
    per_frame = ["/world/camera", "/world/camera/image/depth", "/world/robot_path",
                 "/images/disparity", "/images/segmentation", "/images/segmentation/ellipses",
                 "/images/compensated/t2fuzzy", "/images/compensated/sift",
                 "/series/truth_residual_px"]
    per_frame += [f"/series/{axis}/{name}" for axis in ("rotation", "x", "y")
                  for name in ("truth", "t2fuzzy")]
    per_frame += [f"/errors/{axis}/t2fuzzy" for axis in ("rotation", "x", "y")]
    for entity in per_frame:
        assert rows[entity][1] == N_FRAMES, entity
        assert rows[entity][2] == {"frame", "sim_time"}, entity
    # sift failed on one frame: no estimate, no error logged for it.
    assert rows["/series/x/sift"][1] == N_FRAMES - 1
    assert rows["/errors/y/sift"][1] == N_FRAMES - 1
    assert rows["/events"][1] == 1
    assert recorder.frames_logged == N_FRAMES and recorder.images_logged == N_FRAMES


def test_recording_holds_static_setup_and_properties(recording):
    path, _ = recording
    rows = _rows_per_entity(path)
    for entity in ("/world", "/world/camera/image", "/images/segmentation",
                   "/series/rotation/truth", "/series/x/sift", "/errors/y/t2fuzzy",
                   "/__properties/run", "/__properties/provenance"):
        assert rows[entity][0] >= 1, entity
    summary = RrdReader(str(path)).store().summary()
    assert re.search(r"/__properties/run .*'scenario'.*'seed'", summary)
    assert re.search(r"/__properties/provenance .*'git_commit'.*'versions'", summary)
    assert "Pinhole:image_from_camera" in summary and "AnnotationContext:context" in summary
    assert "DepthImage:meter" in summary and "SeriesLines:colors" in summary


def test_properties_keep_the_resolved_scenario(recording):
    path, _ = recording
    chunks = [chunk for chunk in RrdReader(str(path)).stream().to_chunks()
              if chunk.entity_path == "/__properties/run"]
    table = chunks[0].to_record_batch().to_pydict()
    column = next(name for name in table if name.endswith("scenario"))
    stored = table[column][0]
    stored = stored[0] if isinstance(stored, list) else stored
    assert json.loads(stored) == {"name": "boxes", "walk": [1, 2]}


def test_frame_stride_logs_images_of_every_nth_frame_and_all_scalars(tmp_path):
    path = tmp_path / "strided.rrd"
    recorder = _record(path, frame_stride=4)
    rows = _rows_per_entity(path)
    assert rows["/images/disparity"][1] == 2  # frames 0 and 4
    assert rows["/world/camera/image/depth"][1] == 2
    assert rows["/series/x/truth"][1] == N_FRAMES
    assert recorder.images_logged == 2


def test_no_temporary_file_is_left_behind(recording):
    path, _ = recording
    assert sorted(p.name for p in path.parent.iterdir()) == ["recording.rrd"]


def test_interrupted_run_keeps_the_frames_logged(tmp_path):
    path = tmp_path / "interrupted.rrd"
    frames = _frames()
    with pytest.raises(KeyboardInterrupt):
        with RunRecorder(path, ["sift"]) as rec:
            for frame in frames[:3]:
                rec.log_frame(frame, estimates={"sift": Motion(0.0, 0.0, 0.0)})
            raise KeyboardInterrupt
    assert _rows_per_entity(path)["/images/disparity"][1] == 3


def test_methods_without_diagnostics_log_no_segmentation(tmp_path):
    path = tmp_path / "plain.rrd"
    with RunRecorder(path, ["icp"]) as rec:
        rec.log_frame(_frames()[1], estimates={"icp": Motion(1.0, 2.0, 3.0)})
    rows = _rows_per_entity(path)
    assert rows["/images/segmentation"][1] == 0 and rows["/series/x/icp"][1] == 1
    assert rows["/errors/x/icp"][1] == 0  # no truth given, so no error


@pytest.mark.parametrize("n_labels, dtype", [(255, np.uint8), (256, np.uint16)])
def test_segmentation_keeps_every_label_in_the_smallest_type(tmp_path, n_labels, dtype):
    labels = np.zeros((144, 176), np.int32)
    labels.flat[:n_labels] = np.arange(1, n_labels + 1)
    path = tmp_path / "labels.rrd"
    with RunRecorder(path, ["t2fuzzy"]) as rec:
        rec.log_frame(_frames()[1], estimates={"t2fuzzy": Motion(
            0.0, 0.0, 0.0, diagnostics={"labels": labels, "ellipses": []})})
    (buffer,) = _column(path, "/images/segmentation", "SegmentationImage:buffer")
    stored = np.asarray(buffer, dtype=np.uint8).view(dtype).reshape(labels.shape)
    np.testing.assert_array_equal(stored, labels)


def test_ellipses_are_drawn_in_rerun_pixel_coordinates(recording):
    # The method's ellipse centres are at pixel centres = integers; rerun's pixel centres are
    # at +0.5.
    path, _ = recording
    outlines = _column(path, "/images/segmentation/ellipses", "LineStrips2D:strips")
    assert len(outlines) == N_FRAMES
    for outline, (cx, cy, half_major, half_minor, _) in zip(outlines[0], ELLIPSES):
        outline = np.asarray(outline)
        centre = (outline.min(axis=0) + outline.max(axis=0)) / 2.0
        assert centre == pytest.approx([cx + 0.5, cy + 0.5], abs=0.05)
    assert np.ptp(np.asarray(outlines[0][0]), axis=0) == pytest.approx([50.0, 30.0], abs=0.05)


def test_bad_arguments_are_rejected(tmp_path):
    with pytest.raises(ValueError, match="frame_stride"):
        RunRecorder(tmp_path / "a.rrd", ["sift"], frame_stride=0)
    with pytest.raises(ValueError, match="distinct"):
        RunRecorder(tmp_path / "b.rrd", ["sift", "sift"])
    with RunRecorder(tmp_path / "c.rrd", ["sift"]) as rec:
        with pytest.raises(ValueError, match="unknown methods"):
            rec.log_frame(_frames()[0], estimates={"icp": Motion(0.0, 0.0, 0.0)})
    with pytest.raises(ValueError, match="closed"):
        rec.log_frame(_frames()[0], estimates={})


def test_ellipse_outline_follows_the_image_angle_convention():
    # Major axis at +90 deg from +x toward +y (image y down): the ellipse is tall.
    outline = ellipse_outline(10.0, 20.0, 8.0, 3.0, 90.0)
    assert np.allclose(outline[0], outline[-1])
    assert np.ptp(outline[:, 1]) == pytest.approx(16.0, abs=1e-6)
    assert np.ptp(outline[:, 0]) == pytest.approx(6.0, abs=0.05)
    tilted = ellipse_outline(0.0, 0.0, 8.0, 3.0, 30.0)
    # The point of the outline farthest from the centre lies along 30 deg below +x.
    far = tilted[np.argmax(np.hypot(tilted[:, 0], tilted[:, 1]))]
    assert np.degrees(np.arctan2(far[1], far[0])) % 180 == pytest.approx(30.0, abs=4.0)
    # Every point lies on the ellipse: in the frame of its axes, (u / 8)^2 + (v / 3)^2 = 1.
    turn = np.radians(30.0)
    u = tilted[:, 0] * np.cos(turn) + tilted[:, 1] * np.sin(turn)
    v = -tilted[:, 0] * np.sin(turn) + tilted[:, 1] * np.cos(turn)
    np.testing.assert_allclose((u / 8.0) ** 2 + (v / 3.0) ** 2, 1.0, atol=1e-9)


def test_depth_is_logged_in_whole_millimetres_with_no_measurement_as_0():
    depth = np.array([[np.nan, np.inf, 0.0, 1.2346, 70.0]])
    np.testing.assert_array_equal(depth_millimetres(depth), [[0, 0, 0, 1235, 65535]])


def test_depth_points_are_the_valid_pixels_only():
    frame = _frames()[0]
    valid = frame.valid.copy()
    valid[:, :88] = False  # the left half measured nothing, whatever its depth says
    depth = frame.depth_m.copy()
    depth[:, 88:120] = 0.0  # nor do pixels at no distance, though marked valid
    rows, cols, _ = pixel_rays(SR4000_INTRINSICS, POINT_CLOUD_STRIDE)
    kept = valid[rows, cols] & (depth[rows, cols] > 0)
    cloud = depth_points_world(dataclasses.replace(frame, valid=valid, depth_m=depth),
                               SR4000_INTRINSICS)
    assert 0 < len(cloud) == np.count_nonzero(kept) < np.count_nonzero(valid[rows, cols])


def test_label_colours_start_with_unlabelled_black():
    classes = label_colours(3)
    assert classes[0] == (0, "unlabelled", (0, 0, 0))
    assert [c[0] for c in classes] == [0, 1, 2, 3]
    assert len({c[2] for c in classes}) == 4


def test_pinhole_uses_rerun_pixel_corner_convention(recording):
    # Rerun's principal point for a centred 176 x 144 camera is (88, 72); the harness' is
    # (87.5, 71.5) with pixel centres at integers.
    path, _ = recording
    chunk = next(chunk for chunk in RrdReader(str(path)).stream().to_chunks()
                 if chunk.entity_path == "/world/camera/image")
    table = chunk.to_record_batch().to_pydict()
    column = next(name for name in table if name.endswith("image_from_camera"))
    matrix = np.array(table[column][0], dtype=np.float64).reshape(-1)
    matrix = matrix.reshape(3, 3, order="F")  # rerun stores Mat3x3 column-major
    assert matrix[0, 2] == pytest.approx(88.0) and matrix[1, 2] == pytest.approx(72.0)
    assert matrix[0, 0] == pytest.approx(220.0, abs=0.1)
    assert matrix[1, 1] == pytest.approx(231.2, abs=0.1)


def test_long_paths_are_thinned_but_keep_their_ends(tmp_path, monkeypatch):
    monkeypatch.setattr("sim.harness.recording.PATH_MAX_POINTS", 4)
    path = tmp_path / "path.rrd"
    frame = _frames()[0]
    with RunRecorder(path, ["icp"], frame_stride=10) as rec:
        for index in range(11):
            rec.log_frame(dataclasses.replace(frame, index=index), estimates={},
                          robot_position=[float(index), 0.0, 0.0])
    strips = []
    for chunk in RrdReader(str(path)).stream().to_chunks():
        if chunk.entity_path == "/world/robot_path":
            table = chunk.to_record_batch().to_pydict()
            strips += table[next(name for name in table if name.endswith("strips"))]
    assert [[point[0] for point in row[0]] for row in strips] == [[0.0], [0.0, 3.0, 7.0, 10.0]]


# ------------------------------------------------------------------ the 3-D world

#: A small world: every shape the recorder draws, a ceiling, a material colour, and a free
#: body (standing in for the robot) with a box and a capsule.
WORLD_XML = """
<mujoco>
  <asset>
    <material name="red" rgba="1 0 0 1"/>
    <mesh name="tetra" vertex="0 0 0  1 0 0  0 1 0  0 0 1"/>
  </asset>
  <worldbody>
    <geom name="floor" type="plane" size="5 4 0.1" material="red"/>
    <geom name="crate" type="box" size="0.1 0.2 0.3" pos="1 2 0.3" euler="0 0 90"/>
    <geom name="barrel" type="cylinder" size="0.2 0.4" pos="-1 0 0.4"/>
    <geom name="post" type="capsule" size="0.05 0.5" pos="0 -2 0.55"/>
    <geom name="ball" type="sphere" size="0.25" pos="2 -1 0.25"/>
    <geom name="rock" type="mesh" mesh="tetra" pos="3 3 0"/>
    <geom name="hidden" type="box" size="1 1 1" group="3"/>
    <geom name="glass" type="box" size="0.5 0.5 0.5" pos="-2 2 0.5" rgba="1 1 1 0"/>
    <body name="ceiling" pos="0 0 2.5">
      <geom type="box" size="5 4 0.05"/>
    </body>
    <body name="walker" pos="0 0 1">
      <freejoint/>
      <geom type="box" size="0.1 0.1 0.1" rgba="0 1 0 1"/>
      <geom type="capsule" size="0.03 0.2" pos="0 0 -0.3" rgba="0 0 1 1"/>
    </body>
  </worldbody>
</mujoco>
"""


def _column(path, entity, component, static=None):
    """Every row of one component of ``entity``, in file order (the chunks of a recording
    written here come in logging order)."""
    rows = []
    for chunk in RrdReader(str(path)).stream().to_chunks():
        if chunk.entity_path != entity:
            continue
        batch = chunk.to_record_batch()
        if component in batch.schema.names and (static is None or
                                                ("frame" not in batch.schema.names) == static):
            rows += batch.column(component).to_pylist()
    return rows


def _walker_world():
    import mujoco

    model = mujoco.MjModel.from_xml_string(WORLD_XML)
    return SimpleNamespace(model=model, data=mujoco.MjData(model))


def _walker_poses():
    """(position, quaternion w x y z) of the free body in three frames."""
    return [(np.array([0.1 * i, -0.05 * i, 1.0 + 0.02 * i]),
             Rotation.from_euler("z", 20.0 * i, degrees=True).as_quat(scalar_first=True))
            for i in range(3)]


@pytest.fixture(scope="module")
def world_recording(tmp_path_factory):
    import mujoco

    path = tmp_path_factory.mktemp("world") / "recording.rrd"
    world = _walker_world()
    frames = _frames()
    with RunRecorder(path, ["sift"], model=world.model, frame_stride=2) as rec:
        for frame, (position, quaternion) in zip(frames, _walker_poses()):
            world.data.qpos[:3], world.data.qpos[3:7] = position, quaternion
            mujoco.mj_kinematics(world.model, world.data)
            rec.log_frame(frame, estimates={"sift": Motion(0.0, 0.0, 0.0)},
                          body_poses=(world.data.xpos, world.data.xquat))
    return path


def test_scene_geoms_are_logged_once_in_world_coordinates(world_recording):
    rows = _rows_per_entity(world_recording)
    for entity in ("/world/scene/boxes", "/world/scene/cylinders", "/world/scene/capsules",
                   "/world/scene/ellipsoids", "/world/scene/mesh_5",
                   "/world/scene/overhead/boxes"):
        assert rows[entity][0] == 1 and rows[entity][1] == 0, entity
    # The floor plane is a 1 cm box under z = 0, red from its material; the crate turned 90 deg.
    (half_sizes,) = _column(world_recording, "/world/scene/boxes", "Boxes3D:half_sizes")
    (centres,) = _column(world_recording, "/world/scene/boxes", "Boxes3D:centers")
    (colours,) = _column(world_recording, "/world/scene/boxes", "Boxes3D:colors")
    (quaternions,) = _column(world_recording, "/world/scene/boxes", "Boxes3D:quaternions")
    assert len(half_sizes) == 2  # floor and crate; the group-3 and transparent geoms are not
    assert np.allclose(half_sizes[0], [5.0, 4.0, 0.005]) and np.allclose(centres[0], [0, 0, -0.005])
    assert colours[0] == 0xFF0000FF and colours[1] == 0x808080FF  # rgba packed, MuJoCo grey
    assert np.allclose(half_sizes[1], [0.1, 0.2, 0.3]) and np.allclose(centres[1], [1, 2, 0.3])
    assert np.allclose(np.abs(quaternions[1]), [0, 0, np.sqrt(0.5), np.sqrt(0.5)], atol=1e-6)
    # A rerun capsule starts at one cap centre: 0.5 m below the geom's centre along its axis.
    (ends,) = _column(world_recording, "/world/scene/capsules", "Capsules3D:translations")
    (lengths,) = _column(world_recording, "/world/scene/capsules", "Capsules3D:lengths")
    assert np.allclose(ends, [[0.0, -2.0, 0.05]]) and np.allclose(lengths, [1.0])
    (cylinder_lengths,) = _column(world_recording, "/world/scene/cylinders",
                                  "Cylinders3D:lengths")
    assert np.allclose(cylinder_lengths, [0.8])
    (sphere,) = _column(world_recording, "/world/scene/ellipsoids", "Ellipsoids3D:half_sizes")
    assert np.allclose(sphere, [[0.25, 0.25, 0.25]])
    (vertices,) = _column(world_recording, "/world/scene/mesh_5", "Mesh3D:vertex_positions")
    assert len(vertices) == 4 and np.allclose(np.min(vertices, axis=0), [3.0, 3.0, 0.0],
                                              atol=1e-5)
    (triangles,) = _column(world_recording, "/world/scene/mesh_5", "Mesh3D:triangle_indices")
    assert len(triangles) == 4 and set(np.ravel(triangles)) == {0, 1, 2, 3}  # the tetrahedron
    # The ceiling is drawn as a wireframe so the robot stays visible from above.
    (ceiling,) = _column(world_recording, "/world/scene/overhead/boxes", "Boxes3D:centers")
    assert np.allclose(ceiling, [[0.0, 0.0, 2.5]])
    (fill,) = _column(world_recording, "/world/scene/overhead/boxes", "Boxes3D:fill_mode")
    (solid,) = _column(world_recording, "/world/scene/boxes", "Boxes3D:fill_mode")
    assert fill != solid


#: Height fields (one turned, one high up), boxes about the overhead height and an infinite
#: plane.
HEIGHTS_XML = """
<mujoco>
  <asset>
    <hfield name="bumps" nrow="3" ncol="4" size="1 0.5 0.2 0.05"
            elevation="0 0.5 1 0.25  0.75 0 0.5 1  1 0.25 0 0.5"/>
  </asset>
  <worldbody>
    <geom name="ground" type="hfield" hfield="bumps" pos="2 1 0.3" euler="0 0 90"/>
    <geom name="loft" type="hfield" hfield="bumps" pos="0 0 1.62"/>
    <geom name="wall" type="box" size="1 0.05 0.9" pos="0 3 1.0"/>
    <geom name="beam" type="box" size="0.1 1 0.05" pos="0 -3 2.0" euler="90 0 0"/>
    <geom name="board" type="box" size="1 1 0.05" pos="0 -5 1.6"/>
    <geom name="sea" type="plane" size="0 0 1" pos="0 0 -1"/>
  </worldbody>
</mujoco>
"""


def _heights_world():
    import mujoco

    model = mujoco.MjModel.from_xml_string(HEIGHTS_XML)
    return model, world_geoms(model)


def test_a_height_field_is_drawn_where_mujoco_collides_with_it():
    import mujoco

    model, (geoms, positions, quaternions) = _heights_world()
    archetypes = geom_archetypes(model, geoms, positions, quaternions)
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    hit = np.array([-1], dtype=np.int32)
    for geom in (0, 1):
        mesh = archetypes[f"heightfield_{geom}"]
        vertices = np.array(mesh.vertex_positions.as_arrow_array().to_pylist())
        triangles = np.array(mesh.triangle_indices.as_arrow_array().to_pylist())
        assert vertices.shape == (12, 3) and triangles.shape == (12, 3)  # 3 x 4 samples
        # Each triangle's centre lies on the surface MuJoCo's ray meets from above.
        for x, y, z in vertices[triangles].mean(axis=1):
            distance = mujoco.mj_ray(model, data, np.array([x, y, 5.0]),
                                     np.array([0.0, 0.0, -1.0]), None, 1, -1, hit)
            assert hit[0] == geom and 5.0 - distance == pytest.approx(z, abs=1e-6)


def test_an_infinite_plane_is_drawn_as_a_wide_thin_box_under_it():
    import mujoco

    model, (geoms, positions, quaternions) = _heights_world()
    boxes = geom_archetypes(model, geoms, positions, quaternions)["boxes"]
    half_sizes = np.array(boxes.half_sizes.as_arrow_array().to_pylist())
    centres = np.array(boxes.centers.as_arrow_array().to_pylist())
    # The boxes' batch holds the boxes and the planes, in geom order.
    box_like = [model.geom(int(geom)).name for geom in geoms if int(model.geom_type[geom]) in (
        int(mujoco.mjtGeom.mjGEOM_BOX), int(mujoco.mjtGeom.mjGEOM_PLANE))]
    sea = box_like.index("sea")
    assert half_sizes[sea] == pytest.approx([INFINITE_PLANE_HALF_M, INFINITE_PLANE_HALF_M,
                                             PLANE_THICKNESS_M / 2.0])
    assert centres[sea] == pytest.approx([0.0, 0.0, -1.0 - PLANE_THICKNESS_M / 2.0])


def test_overhead_geoms_lie_wholly_above_the_overhead_height():
    # The loft's lowest point is 1.57 m (its base 5 cm under its origin), the board's 1.55 m;
    # the wall rises from 0.1 m, the beam, upright, from 1.0 m.
    model, (geoms, positions, quaternions) = _heights_world()
    assert [model.geom(geom).name for geom in geoms[overhead(model, geoms, positions,
                                                             quaternions)]] == ["loft", "board"]


def test_moving_bodies_are_posed_every_frame_over_geoms_logged_once(world_recording):
    body = "/world/robot/walker"
    rows = _rows_per_entity(world_recording)
    assert rows[body][1] == 3 and rows[body][2] == {"frame", "sim_time"}
    assert rows[f"{body}/boxes"][0] == 1 and rows[f"{body}/boxes"][1] == 0
    # Its geoms in the body's frame: the capsule's end 0.3 + 0.2 m below the body origin.
    (ends,) = _column(world_recording, f"{body}/capsules", "Capsules3D:translations")
    assert np.allclose(ends, [[0.0, 0.0, -0.5]])
    translations = np.reshape(_column(world_recording, body, "Transform3D:translation"), (-1, 3))
    quaternions = np.reshape(_column(world_recording, body, "Transform3D:quaternion"), (-1, 4))
    assert len(translations) == len(quaternions) == 3
    for (position, quaternion), translation, logged in zip(_walker_poses(), translations,
                                                           quaternions):
        assert np.allclose(translation, position, atol=1e-6)
        assert np.allclose(logged, np.roll(quaternion, -1), atol=1e-6)  # rerun: x y z w
    assert not any(entity.startswith("/world/robot/ceiling") for entity in rows)


def test_depth_points_lie_on_the_surfaces_seen(world_recording):
    # frame_stride 2: frames 0 and 2 of the box world (walls facing +x at these distances).
    clouds = _column(world_recording, "/world/depth_points", "Points3D:positions", static=False)
    assert len(clouds) == 2
    rectangles = box_world()
    for cloud in clouds:
        cloud = np.asarray(cloud, dtype=np.float64).reshape(-1, 3)
        assert len(cloud) > 1000
        on_some_rectangle = np.zeros(len(cloud), dtype=bool)
        for rectangle in rectangles:
            offset = cloud - rectangle.centre
            inside = np.abs(offset[:, 0]) < 1e-4
            for half in (rectangle.half_u, rectangle.half_v):
                half = np.asarray(half)
                extent = np.linalg.norm(half)
                inside &= np.abs(offset @ half / extent) <= extent + 1e-4
            on_some_rectangle |= inside
        assert on_some_rectangle.all()


def test_a_recording_without_the_simulation_has_no_world(recording):
    path, _ = recording
    rows = _rows_per_entity(path)
    assert not [entity for entity in rows if entity.startswith(("/world/scene",
                                                                "/world/robot/"))]
    assert rows["/world/depth_points"][1] == N_FRAMES


def test_a_run_records_its_scene_and_the_walking_robot(tmp_path):
    from scenarios import SCENARIOS_DIR
    from sim.harness.runner import RunConfig, run, scenario_robot
    from sim.harness.scenario import load_scenario
    from sim.world.humanoid import robot_body_ids

    scenario = str(SCENARIOS_DIR / "ci" / "ci_corridor.toml")
    run(RunConfig(scenario=scenario, out_dir=str(tmp_path), methods=("ecc",), max_frames=4,
                  overrides={"recording.enabled": True, "recording.frame_stride": 1}))
    path = tmp_path / "recording.rrd"
    rows = _rows_per_entity(path)
    model = scenario_robot(load_scenario(scenario, {})).model
    scene_instances = sum(len(_column(path, entity, component)[0])
                          for entity in rows if entity.startswith("/world/scene/")
                          for component in (f"{kind}:{field}" for kind, field in (
                              ("Boxes3D", "half_sizes"), ("Cylinders3D", "lengths"),
                              ("Capsules3D", "lengths"), ("Ellipsoids3D", "half_sizes")))
                          if _column(path, entity, component))
    assert scene_instances == np.sum(model.body_weldid[model.geom_bodyid] == 0)
    # One posed entity per robot body with geoms (MJCF names them "humanoid/<part>": the "/"
    # is escaped in the entity path), each with a Transform3D a frame.
    robot_bodies = {"/world/robot/" + rr.escape_entity_path_part(model.body(body).name)
                    for body in robot_body_ids(model) if model.body_geomnum[body]}
    posed = {entity for entity in rows if rows[entity][1] == 4
             and re.fullmatch(r"/world/robot/(?:[^/\\]|\\.)+", entity)}
    assert len(robot_bodies) == 14 and posed == robot_bodies
    # The torso's pose is the robot path's newest point (both the torso's position).
    torso = np.reshape(_column(path, "/world/robot/humanoid\\/torso",
                               "Transform3D:translation"), (-1, 3))
    path_strips = _column(path, "/world/robot_path", "LineStrips3D:strips")
    assert np.allclose(torso[-1], path_strips[-1][0][-1], atol=1e-6)
    assert 0.2 < torso[-1, 2] < 0.5  # standing height of the torso


def test_a_heightfield_is_drawn_where_mujoco_has_its_surface():
    import mujoco

    from sim.harness.recording import heightfield_mesh

    # An asymmetric field on a moved geom: every grid vertex must lie on MuJoCo's surface.
    model = mujoco.MjModel.from_xml_string("""<mujoco><asset>
      <hfield name="bumps" nrow="3" ncol="4" size="1.5 1.0 0.2 0.05"
              elevation="0 0.1 0.2 0.3  0.4 0.5 0.6 0.7  0.8 0.9 1.0 0.5"/></asset>
      <worldbody><geom type="hfield" hfield="bumps" pos="0.3 -0.2 0.1"/></worldbody></mujoco>""")
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    vertices, triangles = heightfield_mesh(model, 0)
    assert vertices.shape == (12, 3) and triangles.shape == (2 * 2 * 3, 3)
    hit = np.zeros(1, np.int32)
    for vertex in vertices + data.geom_xpos[0]:
        distance = mujoco.mj_ray(model, data, np.array([vertex[0], vertex[1], 5.0]),
                                 np.array([0.0, 0.0, -1.0]), None, 1, -1, hit)
        assert abs(5.0 - distance - vertex[2]) < 1e-9
    # The triangles tile the field's 3 m x 2 m once, each facing up (counter-clockwise seen
    # from above), each within one cell of the grid.
    a, b, c = (vertices[triangles[:, corner], :2] for corner in range(3))
    areas = ((b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1])
             - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0])) / 2.0
    assert (areas > 0).all() and areas.sum() == pytest.approx(3.0 * 2.0, abs=1e-9)
    rows, cols = np.divmod(triangles.astype(int), 4)  # the grid's 4 columns
    assert (np.ptp(rows, axis=1) == 1).all() and (np.ptp(cols, axis=1) == 1).all()


def test_a_method_has_one_colour_in_every_recording():
    from sim.harness.recording import METHOD_COLOURS, method_colour
    from stabilizer import available_methods

    built_in = [method_colour(method) for method in available_methods()]
    assert len(set(built_in)) == len(built_in)
    # Not by its place in a run's list: icp is icp's colour beside t2fuzzy alone, too.
    assert method_colour("icp") == METHOD_COLOURS[available_methods().index("icp")]
    plugin = method_colour("my_package.module:Mine")
    assert plugin == method_colour("my_package.module:Mine") and plugin not in built_in


def _scalars(path, entity):
    """The values logged to ``entity`` over time, in order."""
    values = []
    for chunk in RrdReader(str(path)).stream().to_chunks():
        batch = chunk.to_record_batch()
        if chunk.entity_path == entity and "Scalars:scalars" in batch.schema.names:
            values += [row[0] for row in batch.column("Scalars:scalars").to_pylist()]
    return values


def test_the_errors_logged_are_the_errors_scored_rotation_the_short_way_round(tmp_path):
    """An estimate a whole turn and (1, -2) px off the truth: frames.csv scores 0 degrees, 1 px
    and 2 px (sim.harness.scoring.absolute_errors), and the recording plots the same."""
    frames = _frames()[:3]
    path = tmp_path / "recording.rrd"
    with RunRecorder(path, ("mine",)) as recorder:
        for frame in frames:
            truth = ground_truth(frames[0], frame)
            angle, dx, dy = truth.motion.as_tuple()
            estimate = Motion(angle + 360.0, dx + 1.0, dy - 2.0)
            recorder.log_frame(frame, estimates={"mine": estimate}, truth=truth,
                               compensated={"mine": compensate(frame.disparity8, estimate)})
    for axis, error in (("rotation", 0.0), ("x", 1.0), ("y", 2.0)):
        assert _scalars(path, f"/errors/{axis}/mine") == pytest.approx([error] * 3, abs=1e-9)
