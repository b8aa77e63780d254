"""A run's rerun recording (.rrd): world, camera, images, segmentation and time series.

One ``rr.RecordingStream`` per run, saved to a file (no viewer, nothing spawned; open it later
with ``rerun path/to/recording.rrd``). The file is written under a temporary name and renamed
when the recorder closes (sim/atomic.py), also when the run ends by an exception or
Ctrl-C, so it always holds every frame logged before the end. rerun-sdk is pinned (0.41.0):
.rrd files migrate only from the previous version. docs/recording.md describes the file for its
readers: how to open it, the layout, and measured file sizes per frame stride.

Entity layout (the blueprint lays these out side by side):

- ``world/scene/...``: the simulated scene's static geoms (boxes, planes as thin boxes,
  cylinders, spheres and ellipsoids, capsules, meshes), logged once in world coordinates;
  ``world/robot/<body>``: each robot body's pose (Transform3D, per frame) above its geoms,
  logged once in the body's frame. Both only when the recorder is given the simulated model.
- ``world/camera``: the camera pose (Transform3D, MuJoCo camera frame: x right, y up, looking
  along -z, i.e. RUB view coordinates); ``world/camera/image``: its Pinhole (static);
  ``world/camera/image/depth``: the raw depth (DepthImage); ``world/depth_points``: the
  depth back-projected into the world (Points3D, every few pixels); ``world/robot_path``: the
  path so far (LineStrips3D).
- ``images/disparity``: the disparity-like uint8 image; ``images/segmentation``: the paper
  method's labels (SegmentationImage, AnnotationContext) with ``images/segmentation/ellipses``
  (fitted ellipses as 2-D line strips); ``images/compensated/<method>``: each method's
  compensated frame.
- ``series/<axis>/truth``, ``series/<axis>/<method>``, ``errors/<axis>/<method>``: scalars
  (rotation in degrees, x and y in pixels) with SeriesLines styling logged once as static;
  ``series/truth_residual_px``; ``events``: text messages (a fall, an interrupt).

Timelines: ``frame`` (sequence) and ``sim_time`` (duration, seconds).
"""

from __future__ import annotations

import colorsys
import json
import math
import os
import zlib
from collections import defaultdict
from collections.abc import Mapping, Sequence
from contextlib import ExitStack
from pathlib import Path
from typing import Any

import cv2
import mujoco
import numpy as np
import rerun as rr
import rerun.blueprint as rrb
from scipy.spatial.transform import Rotation

from sim.atomic import atomic_path
from sim.world.camera import SR4000_INTRINSICS, CameraIntrinsics, Frame
from sim.harness.ground_truth import GroundTruth, pixel_rays
from sim.harness.provenance import provenance
from sim.harness.scoring import AXES, AXIS_UNITS, absolute_errors
from stabilizer import available_methods
from stabilizer.motion import Motion

APPLICATION_ID = "egostab"
#: Points per fitted-ellipse outline.
ELLIPSE_POINTS = 48
#: Scalars are buffered and sent as columns every this many frames (and on close): one
#: rerun call per series instead of one per value, the bulk of the per-frame cost otherwise.
SERIES_BATCH_FRAMES = 50
#: Most points of the robot path logged per frame (the path so far, evenly thinned): keeps a
#: long run's recording from growing with the square of its length.
PATH_MAX_POINTS = 256
#: Rerun puts pixel (row 0, col 0)'s centre at (0.5, 0.5), the harness (and OpenCV) at (0, 0).
PIXEL_CENTRE = 0.5
TRUTH_COLOUR = (20, 20, 20)
#: Fixed method colours (tab10), so every recording colours a method alike.
METHOD_COLOURS = ((31, 119, 180), (255, 127, 14), (44, 160, 44), (214, 39, 40),
                  (148, 103, 189), (140, 86, 75), (227, 119, 194), (127, 127, 127),
                  (188, 189, 34), (23, 190, 207))
MILLIMETRES_PER_METRE = 1000.0


def method_colour(method: str) -> tuple[int, int, int]:
    """A method's colour in every recording, whatever the other methods of the run: a built-in
    method's by its place in ``stabilizer.available_methods()``, any other's from a checksum of
    its name among the colours left."""
    built_in = available_methods()
    if method in built_in:
        return METHOD_COLOURS[built_in.index(method)]
    others = METHOD_COLOURS[len(built_in):]
    return others[zlib.crc32(method.encode("utf-8")) % len(others)]
#: The depth point cloud keeps every n-th pixel in x and y (file size: docs/recording.md).
POINT_CLOUD_STRIDE = 3
POINT_CLOUD_RADIUS_M = 0.015
POINT_CLOUD_COLOUR = (0, 170, 255)
#: MuJoCo's default geom rgba: a geom with a material and this rgba shows the material's.
MUJOCO_DEFAULT_RGBA = (0.5, 0.5, 0.5, 1.0)
#: Geom groups 0-2 are the ones MuJoCo's viewer shows by default; higher groups conventionally
#: hold collision-only geoms.
VISIBLE_GEOM_GROUPS = 3
#: A plane is drawn as a box this thick below it; a plane of size 0 (infinite) this wide.
PLANE_THICKNESS_M = 0.01
INFINITE_PLANE_HALF_M = 50.0
#: Scene geoms whose lowest point is above this height (ceilings) are drawn as wireframes,
#: so the 3-D view still sees the robot from above.
OVERHEAD_MIN_Z_M = 1.5
WORLD = "world"
SCENE = "world/scene"
ROBOT = "world/robot"
DEPTH_POINTS = "world/depth_points"
CAMERA = "world/camera"
IMAGE_PLANE = "world/camera/image"
DEPTH = "world/camera/image/depth"
ROBOT_PATH = "world/robot_path"
DISPARITY = "images/disparity"
SEGMENTATION = "images/segmentation"
ELLIPSES = "images/segmentation/ellipses"
COMPENSATED = "images/compensated"
EVENTS = "events"
RESIDUAL = "series/truth_residual_px"


def ellipse_outline(cx: float, cy: float, half_major: float, half_minor: float,
                    angle_deg: float, n_points: int = ELLIPSE_POINTS) -> np.ndarray:
    """Closed polyline (n_points + 1 x 2) of an ellipse in image coordinates (y down).

    ``angle_deg`` is the major axis' angle from +x toward +y, as the paper method reports it.
    """
    t = np.linspace(0.0, 2.0 * math.pi, n_points + 1)
    cos_a, sin_a = math.cos(math.radians(angle_deg)), math.sin(math.radians(angle_deg))
    along, across = half_major * np.cos(t), half_minor * np.sin(t)
    return np.stack([cx + along * cos_a - across * sin_a,
                     cy + along * sin_a + across * cos_a], axis=1)


def label_colours(n_labels: int) -> list[tuple[int, str, tuple[int, int, int]]]:
    """(id, name, colour) of labels 0..n_labels: 0 black "unlabelled", then spread hues."""
    classes = [(0, "unlabelled", (0, 0, 0))]
    for label in range(1, n_labels + 1):
        red, green, blue = colorsys.hsv_to_rgb((label * 0.618034) % 1.0, 0.75, 0.95)
        classes.append((label, f"cluster {label}", (int(255 * red), int(255 * green),
                                                   int(255 * blue))))
    return classes


def _rgba8(model: mujoco.MjModel, geoms: np.ndarray) -> np.ndarray:
    """Display colours (n x 4 uint8) of ``geoms``: the geom's rgba, or its material's when the
    geom keeps MuJoCo's default rgba (as MuJoCo's renderer does)."""
    rgba = model.geom_rgba[geoms].copy()
    material = model.geom_matid[geoms]
    inherit = (material >= 0) & np.all(rgba == MUJOCO_DEFAULT_RGBA, axis=1)
    rgba[inherit] = model.mat_rgba[material[inherit]]
    return np.round(255.0 * np.clip(rgba, 0.0, 1.0)).astype(np.uint8)


def visible_geoms(model: mujoco.MjModel) -> np.ndarray:
    """Geoms MuJoCo's viewer draws by default: group 0-2 and not fully transparent."""
    visible = (model.geom_group < VISIBLE_GEOM_GROUPS) & (model.geom_rgba[:, 3] > 0)
    return np.flatnonzero(visible)


def geom_archetypes(model: mujoco.MjModel, geoms: np.ndarray, positions: np.ndarray,
                    quaternions_wxyz: np.ndarray, fill_mode: str = "solid") -> dict[str, Any]:
    """Rerun archetypes drawing MuJoCo geoms, one batch per shape: name -> archetype.

    ``positions`` (n x 3) and ``quaternions_wxyz`` (n x 4, MuJoCo's order) are each geom's
    frame, in whatever frame the archetypes are logged in. MuJoCo's geom conventions
    (mjModel ``geom_size``): box half sizes; plane half width and length (0 = infinite), drawn
    as a thin box under it; sphere radius; ellipsoid semi-axes; cylinder and capsule radius and
    half length along the geom's z, the capsule's caps beyond it (rerun puts a capsule's
    translation at one cap centre, a cylinder's centre at its centre); mesh vertices in the
    geom frame; height fields as a triangle mesh of their grid (:func:`heightfield_mesh`). SDFs
    are not drawn.
    """
    geoms = np.asarray(geoms, dtype=int)
    rotations = Rotation.from_quat(np.asarray(quaternions_wxyz, dtype=np.float64).reshape(-1, 4),
                                   scalar_first=True)
    axes = rotations.as_matrix()
    xyzw = rotations.as_quat().astype(np.float32)  # rerun's order
    positions = np.asarray(positions, dtype=np.float64).reshape(-1, 3)
    colours = _rgba8(model, geoms)
    sizes = model.geom_size[geoms]
    kinds = model.geom_type[geoms]
    z_axes = axes[:, :, 2]
    archetypes: dict[str, Any] = {}

    boxes = (kinds == mujoco.mjtGeom.mjGEOM_BOX) | (kinds == mujoco.mjtGeom.mjGEOM_PLANE)
    if boxes.any():
        plane = kinds[boxes] == mujoco.mjtGeom.mjGEOM_PLANE
        half = sizes[boxes].copy()
        half[plane, :2] = np.where(half[plane, :2] > 0, half[plane, :2], INFINITE_PLANE_HALF_M)
        half[plane, 2] = PLANE_THICKNESS_M / 2.0
        centres = positions[boxes] - plane[:, None] * z_axes[boxes] * PLANE_THICKNESS_M / 2.0
        archetypes["boxes"] = rr.Boxes3D(half_sizes=half, centers=centres,
                                         quaternions=xyzw[boxes], colors=colours[boxes],
                                         fill_mode=fill_mode)
    round_ = (kinds == mujoco.mjtGeom.mjGEOM_SPHERE) | (kinds == mujoco.mjtGeom.mjGEOM_ELLIPSOID)
    if round_.any():
        sphere = kinds[round_] == mujoco.mjtGeom.mjGEOM_SPHERE
        half = np.where(sphere[:, None], sizes[round_][:, :1], sizes[round_])
        archetypes["ellipsoids"] = rr.Ellipsoids3D(half_sizes=half, centers=positions[round_],
                                                   quaternions=xyzw[round_],
                                                   colors=colours[round_], fill_mode=fill_mode)
    for kind, name in ((mujoco.mjtGeom.mjGEOM_CYLINDER, "cylinders"),
                       (mujoco.mjtGeom.mjGEOM_CAPSULE, "capsules")):
        chosen = kinds == kind
        if not chosen.any():
            continue
        radius, half_length = sizes[chosen, 0], sizes[chosen, 1]
        if name == "cylinders":
            archetypes[name] = rr.Cylinders3D(
                lengths=2.0 * half_length, radii=radius, centers=positions[chosen],
                quaternions=xyzw[chosen], colors=colours[chosen], fill_mode=fill_mode)
        else:
            ends = positions[chosen] - z_axes[chosen] * half_length[:, None]
            archetypes[name] = rr.Capsules3D(
                lengths=2.0 * half_length, radii=radius, translations=ends,
                quaternions=xyzw[chosen], colors=colours[chosen], fill_mode=fill_mode)
    for index in np.flatnonzero(kinds == mujoco.mjtGeom.mjGEOM_MESH):
        mesh = model.geom_dataid[geoms[index]]
        first_vertex, first_face = model.mesh_vertadr[mesh], model.mesh_faceadr[mesh]
        vertices = model.mesh_vert[first_vertex:first_vertex + model.mesh_vertnum[mesh]]
        faces = model.mesh_face[first_face:first_face + model.mesh_facenum[mesh]]
        archetypes[f"mesh_{geoms[index]}"] = rr.Mesh3D(
            vertex_positions=vertices @ axes[index].T + positions[index],
            triangle_indices=faces, albedo_factor=colours[index])
    for index in np.flatnonzero(kinds == mujoco.mjtGeom.mjGEOM_HFIELD):
        vertices, triangles = heightfield_mesh(model, model.geom_dataid[geoms[index]])
        archetypes[f"heightfield_{geoms[index]}"] = rr.Mesh3D(
            vertex_positions=vertices @ axes[index].T + positions[index],
            triangle_indices=triangles, albedo_factor=colours[index])
    return archetypes


def heightfield_mesh(model: mujoco.MjModel, hfield: int) -> tuple[np.ndarray, np.ndarray]:
    """Vertices (in the geom's frame) and triangles of height field ``hfield``.

    MuJoCo's convention (``hfield_size`` = radius x, radius y, elevation z, base z): the
    ``nrow x ncol`` grid spans [-radius, radius] in x (columns) and y (rows, first row at -y),
    and a sample h in [0, 1] stands at z = h * elevation; the base below is not drawn.
    """
    rows, cols = int(model.hfield_nrow[hfield]), int(model.hfield_ncol[hfield])
    radius_x, radius_y, elevation, _ = model.hfield_size[hfield]
    start = model.hfield_adr[hfield]
    heights = model.hfield_data[start:start + rows * cols].reshape(rows, cols)
    y, x = np.meshgrid(np.linspace(-radius_y, radius_y, rows),
                       np.linspace(-radius_x, radius_x, cols), indexing="ij")
    vertices = np.stack([x, y, heights * elevation], axis=-1).reshape(-1, 3)
    corner = (np.arange(rows - 1)[:, None] * cols + np.arange(cols - 1)[None, :]).ravel()
    triangles = np.concatenate([np.stack([corner, corner + 1, corner + cols + 1], axis=1),
                                np.stack([corner, corner + cols + 1, corner + cols], axis=1)])
    return vertices, triangles.astype(np.uint32)


def world_geoms(model: mujoco.MjModel) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The scene: visible geoms welded to the world body, with their world positions (n x 3)
    and orientations (n x 4, w x y z) from MuJoCo's kinematics (which for these does not
    depend on the joints)."""
    geoms = visible_geoms(model)
    geoms = geoms[model.body_weldid[model.geom_bodyid[geoms]] == 0]
    data = mujoco.MjData(model)  # scratch state: the simulation's own is left untouched
    mujoco.mj_kinematics(model, data)
    quaternions = np.empty((geoms.size, 4))
    for row, geom in enumerate(geoms):
        mujoco.mju_mat2Quat(quaternions[row], data.geom_xmat[geom])
    return geoms, data.geom_xpos[geoms].copy(), quaternions


def overhead(model: mujoco.MjModel, geoms: np.ndarray, positions: np.ndarray,
             quaternions_wxyz: np.ndarray) -> np.ndarray:
    """Whether each geom lies wholly above OVERHEAD_MIN_Z_M (from its bounding box)."""
    if geoms.size == 0:
        return np.zeros(0, dtype=bool)
    aabb = model.geom_aabb[geoms]  # centre (3) and half sizes (3), in the geom frame
    axes = Rotation.from_quat(quaternions_wxyz, scalar_first=True).as_matrix()
    centre_z = positions[:, 2] + np.einsum("nj,nj->n", axes[:, 2, :], aabb[:, :3])
    half_z = np.einsum("nj,nj->n", np.abs(axes[:, 2, :]), aabb[:, 3:])
    return centre_z - half_z > OVERHEAD_MIN_Z_M


def moving_bodies(model: mujoco.MjModel) -> dict[int, np.ndarray]:
    """Bodies not welded to the world (the robot) -> their visible geoms."""
    geoms = visible_geoms(model)
    geoms = geoms[model.body_weldid[model.geom_bodyid[geoms]] != 0]
    bodies = model.geom_bodyid[geoms]
    return {int(body): geoms[bodies == body] for body in np.unique(bodies)}


def body_entity(model: mujoco.MjModel, body: int) -> str:
    """The entity of a robot body: ``world/robot/<body name>`` (named ``body<id>`` when
    unnamed; a "/" in the name, as in MJCF-attached ``humanoid/torso``, is escaped)."""
    name = model.body(body).name or f"body{body}"
    return f"{ROBOT}/{rr.escape_entity_path_part(name)}"


def depth_points_world(frame: Frame, intrinsics: CameraIntrinsics,
                       stride: int = POINT_CLOUD_STRIDE) -> np.ndarray:
    """The frame's valid depth pixels (every ``stride``-th in x and y) as world points (n x 3,
    float32): each pixel's ray per metre of planar depth (the ground truth's
    :func:`~sim.harness.ground_truth.pixel_rays`, MuJoCo's camera frame) times its depth, then
    cam_mat, cam_pos."""
    rows, cols, rays = pixel_rays(intrinsics, stride)
    depth = np.asarray(frame.depth_m, dtype=np.float64)[rows, cols]
    keep = np.asarray(frame.valid)[rows, cols] & (depth > 0) & np.isfinite(depth)
    camera = rays[keep] * depth[keep, None]
    world = camera @ np.asarray(frame.cam_mat, dtype=np.float64).T + np.asarray(frame.cam_pos)
    return world.astype(np.float32)


def png_image(image: np.ndarray) -> rr.EncodedImage:
    """A uint8 image as a lossless PNG: a third of the raw bytes for these frames."""
    encoded, png = cv2.imencode(".png", np.ascontiguousarray(image))
    if not encoded:
        raise ValueError(f"cannot encode an image of shape {np.shape(image)} as PNG")
    return rr.EncodedImage(contents=png.tobytes(), media_type="image/png")


def depth_millimetres(depth_m: np.ndarray) -> np.ndarray:
    """Depth as uint16 millimetres (0 stays invalid; beyond 65.535 m saturates): half the
    bytes of float32 metres, and 1 mm is far below the sensor's noise."""
    depth = np.nan_to_num(np.asarray(depth_m, dtype=np.float64), nan=0.0, posinf=0.0)
    return np.clip(np.round(depth * MILLIMETRES_PER_METRE), 0, np.iinfo(np.uint16).max) \
        .astype(np.uint16)


def _property_value(value: Any):
    """Scalars and strings as they are; anything nested as a JSON string."""
    if isinstance(value, (bool, int, float, str)):
        return value
    return json.dumps(value, sort_keys=True, default=str)


def default_blueprint(methods: Sequence[str]) -> rrb.Blueprint:
    """The 3-D world | the images (depth, disparity, segmentation, compensated frames) | the
    time series. The 3-D view draws the depth as the ``world/depth_points`` cloud, not the
    DepthImage again."""
    images = [rrb.Spatial2DView(origin=IMAGE_PLANE, name="depth"),
              rrb.Spatial2DView(origin=DISPARITY, name="disparity-like"),
              rrb.Spatial2DView(origin=SEGMENTATION, name="segmentation")]
    images += [rrb.Spatial2DView(origin=f"{COMPENSATED}/{method}", name=f"compensated: {method}")
               for method in methods]
    series = [rrb.TimeSeriesView(origin=f"series/{axis}", name=f"{axis} ({AXIS_UNITS[axis]})")
              for axis in AXES]
    errors = [rrb.TimeSeriesView(origin=f"errors/{axis}",
                                 name=f"|error| {axis} ({AXIS_UNITS[axis]})") for axis in AXES]
    errors.append(rrb.TimeSeriesView(origin=RESIDUAL, name="truth fit residual (px)"))
    return rrb.Blueprint(
        rrb.Horizontal(
            rrb.Spatial3DView(origin=WORLD, name="world",
                              contents=["+ $origin/**", f"- /{DEPTH}"]),
            rrb.Grid(*images),
            rrb.Tabs(rrb.Vertical(*series, name="estimate vs truth"),
                     rrb.Vertical(*errors, name="errors"),
                     rrb.TextLogView(origin=EVENTS, name="events")),
            column_shares=[3, 3, 2],
        ),
        collapse_panels=True,
    )


class RunRecorder:
    """Writes one run's .rrd; use as a context manager, call ``log_frame`` for each frame.

    Args:
        path: the .rrd file to write (its folder is created).
        methods: names of the stabilizers whose estimates will be logged (fixes their colours
            and the blueprint's views).
        intrinsics: the camera's pinhole; default the SR4000's.
        properties: stored as recording properties under "run" (e.g. ``scenario`` (nested
            mappings become JSON strings), ``seed``); package versions and the git commit are
            added under "provenance".
        frame_stride: log images, depth, its point cloud, the camera and the path of every
            ``frame_stride``-th frame (sizes: docs/recording.md); scalars and body poses are
            logged for every frame.
        recording_id: rerun's recording id; random when None.
        model: the simulated world shown in the 3-D view (mujoco.MjModel). Its geoms welded
            to the world are logged once as the scene; every other body (the robot) gets its
            geoms once in its own frame, posed by ``log_frame``'s ``body_poses``. None (a
            sequence scored without the simulator): no scene and no robot.
    """

    def __init__(self, path: str | os.PathLike, methods: Sequence[str], *,
                 intrinsics: CameraIntrinsics = SR4000_INTRINSICS,
                 properties: Mapping[str, Any] | None = None, frame_stride: int = 1,
                 recording_id: str | None = None, model: mujoco.MjModel | None = None):
        if isinstance(frame_stride, bool) or not isinstance(frame_stride, int) or frame_stride < 1:
            raise ValueError(f"frame_stride must be a positive integer; got {frame_stride!r}")
        if isinstance(methods, str) or len(set(methods)) != len(methods):
            raise ValueError(f"methods must be a sequence of distinct names; got {methods!r}")
        self.path = Path(path)
        self.methods = tuple(methods)
        self.intrinsics = intrinsics
        self.frame_stride = frame_stride
        self.frames_logged = 0
        self.images_logged = 0
        self._path_points: list[np.ndarray] = []
        self._series: dict[str, list[tuple[int, float, float]]] = defaultdict(list)
        self._bodies: dict[int, str] = {}
        self._poses: list[tuple[int, float, np.ndarray, np.ndarray]] = []
        self._frames_buffered = 0
        self._n_labels = -1
        self._closed = False
        # Interrupted or failing before it is made, the recorder leaves no temporary file.
        with ExitStack() as files:
            temporary = files.enter_context(atomic_path(self.path))
            self._stream = rr.RecordingStream(APPLICATION_ID, recording_id=recording_id)
            self._stream.set_log_time_enabled(False)  # wall-clock time would make files differ
            self._stream.save(temporary, default_blueprint=default_blueprint(self.methods))
            self._log_static(dict(properties or {}))
            if model is not None:
                self._log_world(model)
            self._files = files.pop_all()

    # ------------------------------------------------------------------ setup
    def _log_static(self, properties: dict[str, Any]) -> None:
        stream = self._stream
        for name, values in (("run", properties), ("provenance", provenance())):
            if values:
                stream.send_property(name, rr.AnyValues(
                    **{key: _property_value(value) for key, value in values.items()}))
        stream.log(WORLD, rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)  # MuJoCo's world
        stream.log(DEPTH_POINTS, rr.Points3D.from_fields(
            radii=[POINT_CLOUD_RADIUS_M], colors=[POINT_CLOUD_COLOUR]), static=True)
        image_from_camera = self.intrinsics.matrix
        image_from_camera[:2, 2] += PIXEL_CENTRE
        stream.log(IMAGE_PLANE, rr.Pinhole(
            image_from_camera=image_from_camera,
            resolution=[self.intrinsics.width, self.intrinsics.height],
            camera_xyz=rr.ViewCoordinates.RUB), static=True)
        stream.log(RESIDUAL, rr.SeriesLines(colors=[TRUTH_COLOUR], names=["truth fit residual"]),
                   static=True)
        for axis in AXES:
            stream.log(f"series/{axis}/truth",
                       rr.SeriesLines(colors=[TRUTH_COLOUR], names=["truth"], widths=[2.0]),
                       static=True)
            for method in self.methods:
                colour = method_colour(method)
                for root in ("series", "errors"):
                    stream.log(f"{root}/{axis}/{method}",
                               rr.SeriesLines(colors=[colour], names=[method]), static=True)

    def _log_world(self, model: mujoco.MjModel) -> None:
        """The scene once in world coordinates (ceilings as wireframes: OVERHEAD_MIN_Z_M) and
        each moving body's geoms once in the body's frame, all static."""
        geoms, positions, quaternions = world_geoms(model)
        above = overhead(model, geoms, positions, quaternions)
        for parent, chosen, fill_mode in ((SCENE, ~above, "solid"),
                                          (f"{SCENE}/overhead", above, "majorwireframe")):
            for name, archetype in geom_archetypes(model, geoms[chosen], positions[chosen],
                                                   quaternions[chosen], fill_mode).items():
                self._stream.log(f"{parent}/{name}", archetype, static=True)
        for body, body_geoms in moving_bodies(model).items():
            entity = body_entity(model, body)
            self._bodies[body] = entity
            for name, archetype in geom_archetypes(model, body_geoms, model.geom_pos[body_geoms],
                                                   model.geom_quat[body_geoms]).items():
                self._stream.log(f"{entity}/{name}", archetype, static=True)

    def _ensure_annotations(self, n_labels: int) -> None:
        if n_labels > self._n_labels:
            self._n_labels = n_labels
            self._stream.log(SEGMENTATION, rr.AnnotationContext(label_colours(n_labels)),
                             static=True)

    # ------------------------------------------------------------------ per frame
    def log_frame(self, frame: Frame, *, estimates: Mapping[str, Motion],
                  truth: GroundTruth | None = None,
                  compensated: Mapping[str, np.ndarray] | None = None,
                  robot_position: np.ndarray | None = None,
                  body_poses: tuple[np.ndarray, np.ndarray] | None = None) -> bool:
        """Log one frame. Returns True when its images were logged (see ``frame_stride``).

        Args:
            frame: the SR4000 frame with its exact camera pose.
            estimates: method -> Motion; the paper method's ``diagnostics`` may hold
                ``"labels"`` (H x W int label image, 0 = unlabelled) and ``"ellipses"``
                (``(cx, cy, half_major, half_minor, angle_deg)`` tuples); both optional.
            truth: the frame's ground truth; None when unknown.
            compensated: method -> compensated uint8 frame.
            robot_position: (3,) position added to the robot's path; the camera's when None.
            body_poses: every body's position and quaternion (w x y z) when the frame was
                taken (``data.xpos``, ``data.xquat`` of the model given), posing the robot.
        """
        if self._closed:
            raise ValueError("the recorder is closed; create a new RunRecorder")
        unknown = set(estimates) - set(self.methods)
        if unknown:
            raise ValueError(f"estimates for unknown methods {sorted(unknown)}; the recorder "
                             f"was created for {list(self.methods)}")
        stream = self._stream
        stream.set_time("frame", sequence=int(frame.index))
        stream.set_time("sim_time", duration=float(frame.time_s))
        if self._bodies and body_poses is not None:
            bodies = list(self._bodies)
            positions, quaternions = body_poses
            self._poses.append((int(frame.index), float(frame.time_s),
                                np.array(positions[bodies]), np.array(quaternions[bodies])))
        self._buffer_series(int(frame.index), float(frame.time_s), estimates, truth)
        self.frames_logged += 1
        position = frame.cam_pos if robot_position is None else robot_position
        self._path_points.append(np.asarray(position, dtype=np.float32).reshape(3))
        if frame.index % self.frame_stride:
            return False
        stream.log(CAMERA, rr.Transform3D(translation=frame.cam_pos, mat3x3=frame.cam_mat))
        stream.log(ROBOT_PATH, rr.LineStrips3D([self._thinned_path()]))
        stream.log(DEPTH, rr.DepthImage(depth_millimetres(frame.depth_m),
                                        meter=MILLIMETRES_PER_METRE))
        stream.log(DEPTH_POINTS, rr.Points3D(depth_points_world(frame, self.intrinsics)))
        stream.log(DISPARITY, png_image(frame.disparity8))
        for method, image in (compensated or {}).items():
            stream.log(f"{COMPENSATED}/{method}", png_image(image))
        self._log_diagnostics(estimates)
        self.images_logged += 1
        return True

    def _thinned_path(self) -> np.ndarray:
        """The path so far, at most PATH_MAX_POINTS points, first and last always kept."""
        n = len(self._path_points)
        keep = np.unique(np.linspace(0, n - 1, min(n, PATH_MAX_POINTS)).round().astype(int))
        return np.stack([self._path_points[i] for i in keep])

    def _buffer_series(self, index: int, time_s: float, estimates: Mapping[str, Motion],
                       truth: GroundTruth | None) -> None:
        values: list[tuple[str, float]] = []
        truth_values = truth.motion.as_tuple() if truth is not None and truth.ok else None
        if truth_values is not None:
            values.append((RESIDUAL, truth.residual_rms_px))
        errors = ({method: absolute_errors(motion, truth.motion)
                   for method, motion in estimates.items() if motion.ok}
                  if truth_values is not None else {})
        for position, axis in enumerate(AXES):
            if truth_values is not None:
                values.append((f"series/{axis}/truth", truth_values[position]))
            for method, motion in estimates.items():
                if not motion.ok:
                    continue
                values.append((f"series/{axis}/{method}", motion.as_tuple()[position]))
                if method in errors:
                    values.append((f"errors/{axis}/{method}", errors[method][position]))
        for entity, value in values:
            if math.isfinite(value):
                self._series[entity].append((index, time_s, float(value)))
        self._frames_buffered += 1
        if self._frames_buffered >= SERIES_BATCH_FRAMES:
            self._send_series()

    def _send_series(self) -> None:
        """Send the buffered scalars and body poses, one column batch per series and body, on
        both timelines."""
        for entity, rows in self._series.items():
            frames, times, values = zip(*rows)
            self._stream.send_columns(
                entity,
                indexes=[rr.TimeColumn("frame", sequence=frames),
                         rr.TimeColumn("sim_time", duration=times)],
                columns=rr.Scalars.columns(scalars=values))
        if self._poses:
            frames, times, positions, quaternions = zip(*self._poses)
            positions = np.stack(positions)
            xyzw = np.roll(np.stack(quaternions), -1, axis=2)  # MuJoCo w x y z -> rerun x y z w
            for column, entity in enumerate(self._bodies.values()):
                self._stream.send_columns(
                    entity,
                    indexes=[rr.TimeColumn("frame", sequence=frames),
                             rr.TimeColumn("sim_time", duration=times)],
                    columns=rr.Transform3D.columns(translation=positions[:, column],
                                                   quaternion=xyzw[:, column]))
        self._series.clear()
        self._poses.clear()
        self._frames_buffered = 0

    def _log_diagnostics(self, estimates: Mapping[str, Motion]) -> None:
        """The segmentation and ellipses of the first estimate that carries them."""
        for motion in estimates.values():
            labels = motion.diagnostics.get("labels")
            if labels is None:
                continue
            labels = np.asarray(labels)
            n_labels = int(labels.max(initial=0))
            self._ensure_annotations(n_labels)
            # A few labels: uint8 stores them in a quarter of the int32 bytes.
            compact = np.uint8 if n_labels < 256 else np.uint16
            self._stream.log(SEGMENTATION, rr.SegmentationImage(labels.astype(compact)))
            ellipses = motion.diagnostics.get("ellipses") or ()
            outlines = [ellipse_outline(*map(float, ellipse)) + PIXEL_CENTRE
                        for ellipse in ellipses]
            self._stream.log(ELLIPSES, rr.LineStrips2D(outlines, colors=[(255, 255, 0)],
                                                       radii=[0.4]))
            return

    def log_event(self, text: str, level: str = "INFO") -> None:
        """A text message at the current time (e.g. "fell at 3.2 s", "interrupted")."""
        self._stream.log(EVENTS, rr.TextLog(text, level=level))

    # ------------------------------------------------------------------ end
    def close(self) -> None:
        """Flush, close and move the finished file into place. Idempotent."""
        if self._closed:
            return
        self._closed = True
        try:
            self._send_series()
            self._stream.flush()
            self._stream.disconnect()
        finally:
            self._files.close()

    def __enter__(self) -> "RunRecorder":
        return self

    def __exit__(self, *exc_info) -> bool:
        self.close()  # also after an error or Ctrl-C: the frames logged so far are kept
        return False
