"""The SR4000 sensor in the simulation: offscreen depth renders of a model camera + the ToF model.

The sensor never steps physics. The caller advances the simulation and, for frame k, calls
:meth:`SR4000.expose` with the live ``MjData`` at (or just after) each of
:meth:`SR4000.exposure_times`, then :meth:`SR4000.read_frame`:

    with SR4000(model, "head_cam", TOF_PRESETS["sr4000"], fps=30.0, seed=1) as sensor:
        for k in range(n_frames):
            for t in sensor.exposure_times(k):
                step_physics_until(t)
                sensor.expose(data)
            frame = sensor.read_frame(k)

Frame k integrates over [start + k / fps, start + k / fps + integration time]; with motion blur
on (``motion_blur_subframes`` > 1) the window is split into that many equal parts and one render
is taken at the centre of each. The frame's time and camera pose are those at mid-exposure (the
pose interpolated between the two middle renders when their number is even). With
``material_reflectivity`` on, the geom id of every pixel of the centre sub-render (read from
that depth render's colour buffer, :func:`rendered_geom_ids`) gives the frame's reflectivity
image through :mod:`sim.world.sensor.materials`.

Rendering is headless through EGL unless ``MUJOCO_GL`` names another backend (:mod:`sim` sets
the default before mujoco is imported). The measurement model is :mod:`sim.world.sensor.tof_model`; the sensor's published
figures, the intrinsics and the model's known gaps are in docs/sensor.md.
"""

from __future__ import annotations

import math
import os

import mujoco
import numpy as np
from scipy.spatial.transform import Rotation, Slerp

from sim.world.camera import SR4000_INTRINSICS, CameraIntrinsics, Frame
from sim.world.sensor.materials import geom_reflectivity, reflectivity_image
from sim.world.sensor.tof_model import MAX_FPS, TOF_PRESETS, ToFModel, ToFParams
from stabilizer.inputs import depth_to_disparity

#: Rendered depth range that must lie inside the model's clip planes (visual/map znear, zfar
#: times the model extent).
REQUIRED_DEPTH_RANGE_M = (0.1, 10.0)
#: Relative tolerance of the model camera's focal lengths against SR4000_INTRINSICS.
INTRINSICS_TOLERANCE = 0.01


def sr4000_camera_attributes(intrinsics: CameraIntrinsics = SR4000_INTRINSICS) -> dict:
    """MJCF ``<camera>`` attributes that give the SR4000's exact pinhole intrinsics.

    MuJoCo takes separate focal lengths through ``focalpixel`` with ``sensorsize`` and
    ``resolution``; the principal point stays at the image centre (docs/sensor.md).
    """
    pixel_pitch_m = 40e-6
    return {
        "resolution": [intrinsics.width, intrinsics.height],
        "focalpixel": [intrinsics.fx, intrinsics.fy],
        "sensorsize": [intrinsics.width * pixel_pitch_m, intrinsics.height * pixel_pitch_m],
    }


def add_probe_camera(arena, xy, yaw_deg: float, height_m: float = 0.55,
                     name: str = "sr4000_probe") -> str:
    """Add a free-flying SR4000 (a mocap body) to an MJCF arena, looking horizontally along
    ``yaw_deg`` from ``xy`` at ``height_m``; returns the camera's name. For tests and benchmarks
    without the robot: move it with ``data.mocap_pos`` / ``data.mocap_quat``."""
    half = math.radians(yaw_deg) / 2.0
    body = arena.worldbody.add("body", name=name, mocap=True, pos=[xy[0], xy[1], height_m],
                               quat=[math.cos(half), 0.0, 0.0, math.sin(half)])
    # MuJoCo cameras look along -z with +y up: image right = -y of the body, up = +z.
    body.add("camera", name=name, xyaxes=[0, -1, 0, 0, 0, 1], **sr4000_camera_attributes())
    return name


def camera_intrinsics(model: mujoco.MjModel, camera_id: int) -> CameraIntrinsics:
    """The pinhole intrinsics MuJoCo renders a camera with, at the SR4000's 176 x 144."""
    width, height = SR4000_INTRINSICS.width, SR4000_INTRINSICS.height
    sensor_w, sensor_h = model.cam_sensorsize[camera_id]
    if sensor_w > 0 and sensor_h > 0:
        focal_x, focal_y, offset_x, offset_y = model.cam_intrinsic[camera_id]
        fx, fy = focal_x / sensor_w * width, focal_y / sensor_h * height
        # MuJoCo moves the principal point against its offset along both image axes.
        cx = (width - 1) / 2.0 - offset_x / sensor_w * width
        cy = (height - 1) / 2.0 - offset_y / sensor_h * height
        return CameraIntrinsics(width, height, fx, fy, cx, cy)
    fy = (height / 2.0) / math.tan(math.radians(model.cam_fovy[camera_id]) / 2.0)
    return CameraIntrinsics(width, height, fy, fy, (width - 1) / 2.0, (height - 1) / 2.0)


def open_depth_renderer(model: mujoco.MjModel) -> mujoco.Renderer:
    """A 176 x 144 depth renderer; a RuntimeError naming the fix if no OpenGL backend starts."""
    # Multisampling does not change the depth read back but costs ~20 % of a software (Mesa)
    # render: build this renderer's buffers without it, then give the model its value back.
    offsamples = model.vis.quality.offsamples
    model.vis.quality.offsamples = 0
    try:
        renderer = mujoco.Renderer(model, SR4000_INTRINSICS.height, SR4000_INTRINSICS.width)
    except Exception as error:  # EGL/OSMesa/GLFW raise different types when they cannot start
        backend = os.environ.get("MUJOCO_GL", "")
        raise RuntimeError(
            f"cannot start offscreen OpenGL rendering with MUJOCO_GL={backend!r} ({error}). "
            "Install Mesa libEGL (apt-get install libegl1), or set MUJOCO_GL=osmesa "
            "(apt-get install libosmesa6) before starting Python."
        ) from error
    finally:
        model.vis.quality.offsamples = offsamples
    renderer.enable_depth_rendering()
    return renderer


class SR4000:
    """Emulated SR4000 on a model camera. Use as a context manager (closes the renderer).

    Args:
        model: the compiled model; its clip planes must cover 0.1-10 m.
        camera: name or id of the model camera; its intrinsics must be SR4000_INTRINSICS (use
            :func:`sr4000_camera_attributes` in the MJCF).
        params: the ToF model's parameters; default the datasheet's (``TOF_PRESETS["sr4000"]``).
        fps: frame rate, default 30; at most 54 (the SR4000's limit) and the integration time
            must fit in one frame period.
        seed: seed of the noise; frame k's noise depends only on (seed, k).
        start_time_s: simulation time at which frame 0's integration starts; default 0.
    """

    def __init__(self, model: mujoco.MjModel, camera: str | int,
                 params: ToFParams = TOF_PRESETS["sr4000"], fps: float = 30.0, seed: int = 0,
                 start_time_s: float = 0.0):
        if not (0 < fps <= MAX_FPS):
            raise ValueError(f"fps={fps} is out of range; the SR4000 runs at 0 < fps <= "
                             f"{MAX_FPS:g}")
        if params.integration_time_s >= 1.0 / fps:
            raise ValueError(f"integration_time_s={params.integration_time_s} does not fit in a "
                             f"frame period of {1.0 / fps:.4f} s at fps={fps}")
        self.model = model
        self.camera_id = self._camera_id(model, camera)
        self._check_intrinsics(model)
        self._check_clip_planes(model)
        self.params = params
        self.fps = float(fps)
        self.seed = int(seed)
        self.start_time_s = float(start_time_s)
        far_clip_m = model.vis.map.zfar * model.stat.extent
        self.tof = ToFModel(params, self.intrinsics, no_surface_depth_m=0.999 * far_clip_m)
        #: Reflectivity of each geom from its material; None: every surface params.reflectivity.
        self.geom_reflectivity = (geom_reflectivity(model, params.reflectivity)
                                  if params.material_reflectivity else None)
        self._reflectivity: np.ndarray | None = None
        self._exposures: list[tuple[float, np.ndarray, np.ndarray, np.ndarray]] = []
        self._exposed_state: np.ndarray | None = None  # positions of the last render
        self._renderer = open_depth_renderer(model)

    @staticmethod
    def _camera_id(model, camera) -> int:
        if isinstance(camera, str):
            camera_id = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_CAMERA, camera)
        else:
            camera_id = int(camera)
        if not 0 <= camera_id < model.ncam:
            names = [model.camera(i).name for i in range(model.ncam)]
            raise ValueError(f"camera {camera!r} is not in the model; cameras: {names}")
        return camera_id

    def _check_intrinsics(self, model):
        self.intrinsics = camera_intrinsics(model, self.camera_id)
        want, got = SR4000_INTRINSICS, self.intrinsics
        for name in ("fx", "fy", "cx", "cy"):
            if abs(getattr(got, name) / getattr(want, name) - 1) > INTRINSICS_TOLERANCE:
                raise ValueError(
                    f"camera {model.camera(self.camera_id).name!r} has {name}="
                    f"{getattr(got, name):.2f} px at 176 x 144; the SR4000 needs "
                    f"{getattr(want, name):.2f}. Give the MJCF camera the attributes "
                    f"sim.world.sensor.sr4000.sr4000_camera_attributes(): {sr4000_camera_attributes()}")

    @staticmethod
    def _check_clip_planes(model):
        near = model.vis.map.znear * model.stat.extent
        far = model.vis.map.zfar * model.stat.extent
        lo, hi = REQUIRED_DEPTH_RANGE_M
        if near > lo or far < hi:
            raise ValueError(
                f"the model's clip planes cover {near:.3f}-{far:.1f} m (visual/map znear, zfar "
                f"times the extent {model.stat.extent:.2f}); the SR4000 needs {lo}-{hi} m: set "
                f"znear <= {lo / model.stat.extent:.4g} and zfar >= {hi / model.stat.extent:.4g}")

    def __enter__(self) -> "SR4000":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def close(self) -> None:
        self._renderer.close()

    @property
    def frame_period_s(self) -> float:
        return 1.0 / self.fps

    def exposure_times(self, frame_index: int) -> list[float]:
        """Simulation times of the sub-renders of frame ``frame_index`` (ascending)."""
        if frame_index < 0:
            raise ValueError(f"frame_index must be >= 0; got {frame_index}")
        n = self.params.motion_blur_subframes
        window = self.params.integration_time_s
        start = self.start_time_s + frame_index * self.frame_period_s
        return [start + (j + 0.5) * window / n for j in range(n)]

    def frames_within(self, end_time_s: float) -> int:
        """How many frames (0, 1, ...) finish integrating by ``end_time_s``."""
        last_start = end_time_s - self.params.integration_time_s - self.start_time_s
        return max(0, math.floor(last_start * self.fps + 1e-9) + 1)

    def expose(self, data: mujoco.MjData) -> None:
        """Render depth at the current state of ``data`` (one sub-frame of the next frame).

        Recomputes the kinematics and camera poses of ``data`` (``mj_kinematics``,
        ``mj_camlight``: derived quantities only, the state is untouched) so that the image,
        the pose and ``data.time`` agree; after ``mj_step`` they would lag one step.
        """
        if len(self._exposures) >= self.params.motion_blur_subframes:
            raise ValueError(f"already {len(self._exposures)} exposures for this frame; call "
                             "read_frame() before exposing the next frame")
        centre = len(self._exposures) == self.params.motion_blur_subframes // 2
        state = np.concatenate([data.qpos, data.mocap_pos.ravel(), data.mocap_quat.ravel()])
        if self._exposures and self._exposures[-1][0] == data.time \
                and np.array_equal(self._exposed_state, state):
            # Sub-renders that fall on the same control step see the same state: the same image.
            self._exposures.append(self._exposures[-1])
        else:
            mujoco.mj_kinematics(self.model, data)
            mujoco.mj_camlight(self.model, data)
            self._renderer.update_scene(data, camera=self.camera_id)
            depth = self._renderer.render()
            self._exposed_state = state
            self._exposures.append((float(data.time), depth.copy(),
                                    data.cam_xpos[self.camera_id].copy(),
                                    data.cam_xmat[self.camera_id].reshape(3, 3).copy()))
        if centre:
            self._read_reflectivity()

    def _read_reflectivity(self) -> None:
        """Reflectivity image of the last depth render: its geom id per pixel
        (:func:`rendered_geom_ids`) through the geoms' material reflectivities. Once per frame,
        at the centre sub-render that the ToF model builds the reported depth on."""
        if self.geom_reflectivity is not None:
            self._reflectivity = reflectivity_image(rendered_geom_ids(self._renderer),
                                                    self.geom_reflectivity,
                                                    self.params.reflectivity)

    def read_frame(self, frame_index: int) -> Frame:
        """Apply the ToF model to this frame's exposures and return the Frame."""
        n = self.params.motion_blur_subframes
        if len(self._exposures) != n:
            raise ValueError(f"frame {frame_index} needs {n} exposures (one at each of "
                             f"exposure_times({frame_index})); got {len(self._exposures)}")
        exposures, self._exposures = self._exposures, []
        reflectivity, self._reflectivity = self._reflectivity, None
        times = np.array([e[0] for e in exposures])
        rng = np.random.default_rng([self.seed, frame_index])
        depth, valid = self.tof.apply([e[1] for e in exposures], rng, reflectivity)
        mid_time = float(times.mean())
        cam_pos, cam_mat = _pose_at(mid_time, exposures)
        # The exact depth of the middle exposure, for the ground truth: the reported depth
        # carries noise, wrapping and mixed pixels that would corrupt the true correspondences.
        true_depth = exposures[(n - 1) // 2][1].astype(np.float32)
        return Frame(index=frame_index, time_s=mid_time, depth_m=depth, valid=valid,
                     disparity8=depth_to_disparity(depth), cam_pos=cam_pos, cam_mat=cam_mat,
                     true_depth_m=true_depth)

    def capture_still(self, data: mujoco.MjData, frame_index: int = 0) -> Frame:
        """One frame of a static scene: one render reused for every sub-frame."""
        self.expose(data)
        if self._reflectivity is None:
            self._read_reflectivity()
        self._exposures *= self.params.motion_blur_subframes
        return self.read_frame(frame_index)


def rendered_geom_ids(renderer: mujoco.Renderer) -> np.ndarray:
    """Geom id per pixel (H x W int32, -1 where no geom) of the renderer's last depth render.

    ``mujoco.Renderer`` draws a depth render with segmentation colours (``mjRND_SEGMENT`` and
    ``mjRND_IDCOLOR``: each geom in the colour segid + 1, 0 for the background), so reading
    back that render's colour buffer gives the segmentation for the price of a 76 KB read
    instead of a second render (docs/sensor.md). The read goes through the renderer's
    ``_mjr_context`` and ``_rect``, which are not public API:
    ``tests/sim/world/test_tof_model.py`` checks the result against the public segmentation
    render (``enable_segmentation_rendering``).
    """
    rgb = np.empty((renderer.height, renderer.width, 3), dtype=np.uint8)
    mujoco.mjr_readPixels(rgb, None, renderer._rect, renderer._mjr_context)
    # OpenGL's rows run bottom-up.
    colour = np.flipud(rgb).astype(np.int32)
    segment = colour[..., 0] | colour[..., 1] << 8 | colour[..., 2] << 16
    scene = renderer.scene
    lookup = np.full(scene.ngeom + 1, -1, dtype=np.int32)
    for geom in scene.geoms[:scene.ngeom]:
        if geom.segid >= 0 and geom.objtype == mujoco.mjtObj.mjOBJ_GEOM:
            lookup[geom.segid + 1] = geom.objid
    return np.where(segment < lookup.size, lookup[np.minimum(segment, lookup.size - 1)], -1)


def _pose_at(time_s, exposures):
    """Camera pose at ``time_s`` between the two middle exposures (exact one when n is odd)."""
    n = len(exposures)
    before, after = exposures[(n - 1) // 2], exposures[n // 2]
    if before is after or after[0] == before[0]:
        return before[2], before[3]
    s = (time_s - before[0]) / (after[0] - before[0])
    position = (1 - s) * before[2] + s * after[2]
    slerp = Slerp([0.0, 1.0], Rotation.from_matrix([before[3], after[3]]))
    return position, slerp([s]).as_matrix()[0]
