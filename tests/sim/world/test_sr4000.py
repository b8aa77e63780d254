"""SR4000 emulation: statistics of the ToF model on simple scenes, FOV, timing and contracts."""

from __future__ import annotations

import dataclasses
import math
import os

os.environ.setdefault("MUJOCO_GL", "egl")

import mujoco  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402
from dm_control import mjcf  # noqa: E402
from scipy.spatial.transform import Rotation  # noqa: E402

from sim.world.camera import SR4000_INTRINSICS  # noqa: E402
from sim.world.sensor.sr4000 import SR4000, add_probe_camera, camera_intrinsics  # noqa: E402
from sim.world.sensor.tof_model import TOF_PRESETS, ToFParams  # noqa: E402
from stabilizer.inputs import depth_to_disparity  # noqa: E402

NOISELESS = TOF_PRESETS["noiseless"]
DEFAULT = TOF_PRESETS["sr4000"]


def box_world(boxes, extent=10.0, znear=0.005, zfar=3.0):
    """Model with boxes (centre xyz, half sizes) and a probe SR4000 at (0, 0, 0.55) looking +x."""
    root = mjcf.RootElement(model="test")
    root.statistic.extent = extent
    root.visual.map.znear, root.visual.map.zfar = znear, zfar
    for centre, half in boxes:
        root.worldbody.add("geom", type="box", pos=list(centre), size=list(half))
    camera = add_probe_camera(root, (0.0, 0.0), 0.0, height_m=0.55)
    model = mujoco.MjModel.from_xml_string(root.to_xml_string())
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    return model, data, camera


def wall(distance_m, half_width=20.0):
    """A wall facing the camera whose front face is ``distance_m`` ahead."""
    return ((distance_m + 0.05, 0.0, 0.55), (0.05, half_width, half_width))


def raw_depth(model, data, camera):
    with mujoco.Renderer(model, 144, 176) as renderer:
        renderer.enable_depth_rendering()
        renderer.update_scene(data, camera=camera)
        return renderer.render().copy()


def stills(model, data, camera, params, n, seed=0):
    with SR4000(model, camera, params, seed=seed) as sensor:
        return [sensor.capture_still(data, k) for k in range(n)]


def test_model_camera_has_the_sr4000_intrinsics():
    model, _, camera = box_world([wall(2.0)])
    got = camera_intrinsics(model, model.camera(camera).id)
    for name in ("fx", "fy", "cx", "cy"):
        assert getattr(got, name) == pytest.approx(getattr(SR4000_INTRINSICS, name), rel=1e-4)


def test_rendered_fov_matches_intrinsics():
    """A square plate at a known camera-frame point appears where the pinhole model puts it,
    with the size it predicts (focal lengths in x and y, principal point)."""
    x_right, y_up, z, half = 0.45, 0.30, 1.5, 0.04
    plate = ((z + 0.002, -x_right, 0.55 + y_up), (0.002, half, half))
    model, data, camera = box_world([wall(3.0), plate])
    depth = raw_depth(model, data, camera)
    rows, cols = np.nonzero(depth < 2.0)
    k = SR4000_INTRINSICS
    assert cols.mean() == pytest.approx(k.cx + k.fx * x_right / z, abs=0.3)
    assert rows.mean() == pytest.approx(k.cy - k.fy * y_up / z, abs=0.3)
    assert np.ptp(cols) + 1 == pytest.approx(2 * half * k.fx / z, abs=1.0)
    assert np.ptp(rows) + 1 == pytest.approx(2 * half * k.fy / z, abs=1.0)


@pytest.mark.parametrize("camera", [
    {"fovy": "45"},
    {"resolution": "176 144", "focalpixel": "220 231", "sensorsize": "0.00704 0.00576"},
    {"resolution": "176 144", "focalpixel": "220 231", "sensorsize": "0.00704 0.00576",
     "principalpixel": "10 5"},
    {"resolution": "176 144", "focalpixel": "200 240", "sensorsize": "0.00704 0.00576",
     "principalpixel": "-8 -6"},
], ids=["fovy", "focal", "principal", "principal_negative"])
def test_camera_intrinsics_put_a_point_where_mujoco_renders_it(camera):
    """camera_intrinsics of any MJCF camera (a vertical field of view alone, or focal lengths
    with a sensor size and a principal-point offset): a small sphere off the axis in both
    directions renders where those intrinsics project its centre."""
    attributes = " ".join(f'{name}="{value}"' for name, value in camera.items())
    model = mujoco.MjModel.from_xml_string(
        '<mujoco><statistic extent="10"/><visual><map znear="0.005" zfar="3"/></visual>'
        '<worldbody><geom type="box" pos="3.05 0 0" size="0.05 20 20"/>'
        '<geom type="sphere" pos="2.9 -0.3 0.2" size="0.03"/>'
        f'<camera name="c" xyaxes="0 -1 0 0 0 1" {attributes}/></worldbody></mujoco>')
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    rows, cols = np.nonzero(raw_depth(model, data, "c") < 2.95)
    k = camera_intrinsics(model, 0)
    x_right, y_down, z = 0.3, -0.2, 2.9  # the sphere's centre in the camera's frame
    assert cols.size > 10
    assert cols.mean() == pytest.approx(k.cx + k.fx * x_right / z, abs=0.3)
    assert rows.mean() == pytest.approx(k.cy + k.fy * y_down / z, abs=0.3)


def test_a_probe_camera_stands_where_it_is_put_and_looks_along_its_yaw():
    """add_probe_camera at (1.0, -0.5) turned 90 degrees looks along +y: the panel 3 m ahead
    of it fills the image's centre (a backdrop 6 m ahead is seen from anywhere else)."""
    root = mjcf.RootElement(model="probe")
    root.statistic.extent = 10.0
    root.visual.map.znear, root.visual.map.zfar = 0.005, 3.0
    root.worldbody.add("geom", type="box", pos=[1.0, 2.55, 0.55], size=[0.3, 0.05, 0.3])
    root.worldbody.add("geom", type="box", pos=[0.0, 5.55, 0.55], size=[20.0, 0.05, 20.0])
    camera = add_probe_camera(root, (1.0, -0.5), 90.0, height_m=0.55)
    model = mujoco.MjModel.from_xml_string(root.to_xml_string())
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    depth = raw_depth(model, data, camera)
    np.testing.assert_allclose(depth[62:82, 78:98], 3.0, atol=1e-3)
    assert depth[:, :20].min() == pytest.approx(6.0, abs=1e-3)


def test_noiseless_preset_equals_raw_render():
    edge = ((1.0, 0.5, 0.55), (0.05, 0.5, 2.0))
    model, data, camera = box_world([wall(3.0, half_width=1.0), edge])
    raw = raw_depth(model, data, camera)
    (frame,) = stills(model, data, camera, NOISELESS, 1)
    surface = raw < 0.999 * 3.0 * 10.0
    assert (~surface).any() and surface.any()
    np.testing.assert_array_equal(frame.valid, surface)
    np.testing.assert_array_equal(frame.depth_m, np.where(surface, raw, 0).astype(np.float32))


@pytest.mark.parametrize("distance_m", [1.0, 2.0, 4.0])
def test_flat_wall_bias_and_noise_match_the_configured_model(distance_m):
    model, data, camera = box_world([wall(distance_m)])
    raw = raw_depth(model, data, camera).astype(np.float64)
    frames = stills(model, data, camera, DEFAULT, 40)
    assert all(f.valid.all() for f in frames)
    errors = np.stack([f.depth_m - raw for f in frames])
    with SR4000(model, camera, DEFAULT) as sensor:
        tof = sensor.tof
    scale = tof.ray_scale
    true_range = raw * scale
    amplitude = DEFAULT.relative_amplitude(true_range, tof.cos_incidence(raw))
    expected_bias = DEFAULT.wiggle_error_m(true_range) / scale
    expected_sigma = DEFAULT.noise_sigma_m(amplitude) / scale
    assert abs(expected_bias.mean()) > 0.002  # the wiggle is not at a zero crossing here
    assert errors.mean() == pytest.approx(expected_bias.mean(), rel=0.2)
    assert errors.std(axis=0, ddof=1).mean() == pytest.approx(expected_sigma.mean(), rel=0.2)


def test_noise_is_calibrated_to_the_datasheet_repeatability():
    """sigma = 4 mm for a 99 % target head-on at 2 m (datasheet repeatability, 1 sigma)."""
    params = dataclasses.replace(DEFAULT, reflectivity=0.99)
    assert params.noise_sigma_m(params.relative_amplitude(2.0)) == pytest.approx(0.004)
    assert params.unambiguous_range_m == pytest.approx(4.9965, abs=1e-3)
    assert params.quantization_step_m == pytest.approx(params.unambiguous_range_m / 2**14)


def test_wall_beyond_the_unambiguous_range_wraps():
    model, data, camera = box_world([wall(6.0)])
    (frame,) = stills(model, data, camera, DEFAULT, 1)
    centre = frame.depth_m[60:84, 76:100]
    assert frame.valid[60:84, 76:100].mean() > 0.9
    assert np.median(centre[centre > 0]) == pytest.approx(6.0 - DEFAULT.unambiguous_range_m,
                                                          abs=0.05)
    no_wrap = dataclasses.replace(DEFAULT, phase_wrapping=False, max_range_m=10.0)
    (unwrapped,) = stills(model, data, camera, no_wrap, 1)
    assert np.median(unwrapped.depth_m[60:84, 76:100]) == pytest.approx(6.0, abs=0.05)


def _edge_scene():
    """A plate at 1 m covering the left half of the view, a wall at 3 m behind."""
    plate = ((1.0, 1.0, 0.55), (0.01, 1.0, 2.0))
    return box_world([wall(3.0), plate])


def test_depth_edge_makes_mixed_pixels():
    model, data, camera = _edge_scene()
    quiet = dataclasses.replace(DEFAULT, noise_sigma_ref_m=0.0, wiggle_amplitude_m=0.0)
    (mixed,) = stills(model, data, camera, quiet, 1)
    (clean,) = stills(model, data, camera,
                      dataclasses.replace(quiet, mixed_pixel_weight=0.0), 1)
    between = lambda f: f.valid & (f.depth_m > 1.05) & (f.depth_m < 2.9)  # noqa: E731
    assert not between(clean).any()
    rows, cols = np.nonzero(between(mixed))
    assert len(rows) > 72  # at least every other row of the edge
    edge_col = np.argmax(clean.depth_m[72] > 2.0)
    assert np.all(np.abs(cols - edge_col) <= 1)


def test_motion_blur_mixes_depth_across_a_moving_edge_and_pose_is_mid_exposure():
    model, data, camera = _edge_scene()
    params = dataclasses.replace(DEFAULT, noise_sigma_ref_m=0.0, wiggle_amplitude_m=0.0,
                                 mixed_pixel_weight=0.0, motion_blur_subframes=3,
                                 integration_time_s=0.02)
    speed = 2.0  # m/s sideways: 4 cm over the integration time, ~9 px at 1 m
    with SR4000(model, camera, params, fps=25.0) as sensor:
        times = sensor.exposure_times(2)
        np.testing.assert_allclose(times, [0.08 + 0.02 * f for f in (1 / 6, 1 / 2, 5 / 6)])
        poses = []
        for t in times:
            data.time = t
            data.mocap_pos[0] = [0.0, speed * t, 0.55]
            sensor.expose(data)
            poses.append(data.cam_xpos[model.camera(camera).id].copy())
        frame = sensor.read_frame(2)
    assert frame.time_s == pytest.approx(times[1])
    np.testing.assert_allclose(frame.cam_pos, poses[1])
    # The exact depth for the ground truth is the middle exposure's render.
    data.mocap_pos[0] = [0.0, speed * times[1], 0.55]
    mujoco.mj_forward(model, data)
    np.testing.assert_array_equal(frame.true_depth_m, raw_depth(model, data, camera))
    between = frame.valid & (frame.depth_m > 1.05) & (frame.depth_m < 2.9)
    assert between.sum(axis=1).min() >= 3  # every row smeared over several pixels


def test_frames_within_a_duration_end_their_exposure_in_it():
    model, _, camera = box_world([wall(2.0)])
    with SR4000(model, camera, DEFAULT, fps=30.0, start_time_s=0.5) as sensor:
        n = sensor.frames_within(10.5)
        assert n == 300
        assert sensor.exposure_times(n - 1)[-1] < 10.5 < sensor.exposure_times(n)[-1]
        assert sensor.frames_within(0.5) == 0


def test_even_subframes_interpolate_the_mid_exposure_pose():
    model, data, camera = box_world([wall(2.0)])
    frame_at_rest = data.cam_xmat[model.camera(camera).id].reshape(3, 3).copy()
    params = dataclasses.replace(NOISELESS, motion_blur_subframes=2)
    with SR4000(model, camera, params) as sensor:
        for t in sensor.exposure_times(0):
            data.time = t
            data.mocap_pos[0] = [0.0, t, 0.55]
            # Turning too, at 100 degrees a second about the vertical.
            data.mocap_quat[0] = Rotation.from_euler("z", 100.0 * t, degrees=True).as_quat(
                scalar_first=True)
            sensor.expose(data)
        frame = sensor.read_frame(0)
    middle = params.integration_time_s / 2
    assert frame.cam_pos[1] == pytest.approx(middle)
    # The body turned as far as at the middle of the exposure, the camera fixed on it.
    turned = Rotation.from_euler("z", 100.0 * middle, degrees=True).as_matrix()
    np.testing.assert_allclose(frame.cam_mat, turned @ frame_at_rest, atol=1e-9)


def test_frames_are_deterministic_from_the_seed_and_disparity_follows_depth():
    model, data, camera = _edge_scene()
    a, b = stills(model, data, camera, DEFAULT, 2, seed=7), stills(model, data, camera,
                                                                   DEFAULT, 2, seed=7)
    (c,) = stills(model, data, camera, DEFAULT, 1, seed=8)
    np.testing.assert_array_equal(a[1].depth_m, b[1].depth_m)
    assert not np.array_equal(a[0].depth_m, a[1].depth_m)
    assert not np.array_equal(a[0].depth_m, c.depth_m)
    frame = a[0]
    assert frame.depth_m.dtype == np.float32 and frame.valid.dtype == bool
    np.testing.assert_array_equal(frame.disparity8, depth_to_disparity(frame.depth_m))
    assert not frame.disparity8[~frame.valid].any()
    assert frame.cam_mat.shape == (3, 3) and frame.cam_pos.shape == (3,)


def test_bad_settings_are_value_errors_naming_the_fix():
    model, data, camera = box_world([wall(2.0)])
    with pytest.raises(ValueError, match="fps"):
        SR4000(model, camera, fps=60.0)
    SR4000(model, camera, fps=0.5).close()  # one frame every 2 s is a frame rate
    with pytest.raises(ValueError, match="integration_time_s"):
        SR4000(model, camera, dataclasses.replace(DEFAULT, integration_time_s=0.025), fps=50.0)
    with pytest.raises(ValueError, match="motion_blur_subframes"):
        ToFParams(motion_blur_subframes=0)
    with pytest.raises(ValueError, match="not in the model"):
        SR4000(model, "no_such_camera")
    with SR4000(model, camera, DEFAULT) as sensor:
        sensor.expose(data)
        with pytest.raises(ValueError, match="needs 3 exposures"):
            sensor.read_frame(0)
        sensor.expose(data)
        sensor.expose(data)
        with pytest.raises(ValueError, match="already 3 exposures"):
            sensor.expose(data)
    # The clip planes must reach from 0.1 m or nearer to 10 m or farther (extent 10 here).
    for znear, zfar, refused in ((0.005, 0.5, True), (0.015, 3.0, True), (0.01, 1.0, False),
                                 (0.005, 1.5, False)):
        clipped, _, clipped_camera = box_world([wall(2.0)], znear=znear, zfar=zfar)
        if refused:
            with pytest.raises(ValueError, match="znear"):
                SR4000(clipped, clipped_camera)
        else:
            SR4000(clipped, clipped_camera).close()
    fovy = mujoco.MjModel.from_xml_string(
        '<mujoco><visual><map znear="0.001" zfar="100"/></visual><worldbody>'
        '<camera name="c" fovy="45"/></worldbody></mujoco>')
    with pytest.raises(ValueError, match="sr4000_camera_attributes"):
        SR4000(fovy, "c")


@pytest.mark.parametrize("distance_m, change, restore", [
    (0.09, {}, {"min_range_m": 0.0, "saturation_amplitude": math.inf}),  # too near
    (0.15, {"min_range_m": 0.0}, {"saturation_amplitude": math.inf}),  # saturated
    (3.0, {"reflectivity": 0.01}, {"min_amplitude": 0.0}),  # too dark
    (3.0, {"max_range_m": 2.5}, {"max_range_m": 5.0}),  # too far
])
def test_range_and_confidence_limits_invalidate_pixels(distance_m, change, restore):
    model, data, camera = box_world([wall(distance_m)])
    limited = dataclasses.replace(DEFAULT, **change)
    (frame,) = stills(model, data, camera, limited, 1)
    assert not frame.valid.any() and not frame.depth_m.any() and not frame.disparity8.any()
    (frame,) = stills(model, data, camera, dataclasses.replace(limited, **restore), 1)
    assert frame.valid.all()


def test_phasor_mixing_leaves_a_flat_wall_unchanged():
    """Mixed-pixel blending is by complex phasors: on a flat wall it moves nothing (< 0.1 mm)."""
    model, data, camera = box_world([wall(2.0)])
    raw = raw_depth(model, data, camera)
    mixing_only = dataclasses.replace(NOISELESS, mixed_pixel_weight=1.0, phase_wrapping=True)
    (frame,) = stills(model, data, camera, mixing_only, 1)
    np.testing.assert_allclose(frame.depth_m, raw, atol=1e-4)


def test_no_opengl_backend_is_an_error_naming_the_fix(monkeypatch):
    import sim.world.sensor.sr4000 as sr4000

    def no_backend(*args, **kwargs):
        raise mujoco.FatalError("gladLoadGL error")

    monkeypatch.setattr(sr4000.mujoco, "Renderer", no_backend)
    model, _, camera = box_world([wall(2.0)])
    with pytest.raises(RuntimeError, match="apt-get install libegl1.*MUJOCO_GL=osmesa"):
        SR4000(model, camera)
    assert model.vis.quality.offsamples == 4  # the model is left as it was


def test_sub_renders_of_an_unchanged_state_render_once():
    model, data, camera = _edge_scene()
    params = dataclasses.replace(DEFAULT, motion_blur_subframes=3)
    with SR4000(model, camera, params) as sensor:
        renders = []
        render = sensor._renderer.render
        sensor._renderer.render = lambda: renders.append(1) or render()
        for _ in range(3):
            sensor.expose(data)  # same time, same state: one image
        sensor.read_frame(0)
        for step in range(3):
            data.mocap_pos[0] = [0.0, 0.01 * step, 0.55]  # a moved body: a new image each
            sensor.expose(data)
        moved = sensor.read_frame(1)
    assert len(renders) == 1 + 3
    assert moved.valid.any()


def test_the_reflectivity_is_read_once_a_frame_from_the_centre_sub_render():
    """The ToF model builds the reported depth on the middle sub-render, so the pixels'
    materials are read there, once a frame (a segmentation render each)."""
    model, data, camera = _edge_scene()
    params = dataclasses.replace(DEFAULT, motion_blur_subframes=5)
    with SR4000(model, camera, params) as sensor:
        read_after = []
        read = sensor._read_reflectivity
        sensor._read_reflectivity = lambda: read_after.append(len(sensor._exposures)) or read()
        for frame in range(2):
            for step in range(5):
                data.mocap_pos[0] = [0.0, 0.01 * step, 0.55]
                sensor.expose(data)
            sensor.read_frame(frame)
    assert read_after == [3, 3]  # after the third of five exposures, each frame
