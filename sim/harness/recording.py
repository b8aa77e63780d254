"""A run's rerun recording (.rrd): world, camera, images, segmentation and time series.

One ``rr.RecordingStream`` per run, saved to a file (no viewer, nothing spawned; open it later
with ``rerun path/to/recording.rrd``). The file is written under a temporary name and renamed
when the recorder closes (sim/harness/atomic.py), also when the run ends by an exception or
Ctrl-C, so it always holds every frame logged before the end. rerun-sdk is pinned (0.41.0):
.rrd files migrate only from the previous version. docs/recording.md describes the file for its
readers: how to open it, the layout, and measured file sizes per frame stride.

Entity layout (the blueprint lays these out side by side):

- ``world/camera``: the camera pose (Transform3D, MuJoCo camera frame: x right, y up, looking
  along -z, i.e. RUB view coordinates); ``world/camera/image``: its Pinhole (static);
  ``world/camera/image/depth``: the raw depth (DepthImage, metres), which the 3-D view also
  shows as a point cloud; ``world/robot_path``: the path so far (LineStrips3D).
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
from collections import defaultdict
from collections.abc import Mapping, Sequence
from contextlib import ExitStack
from pathlib import Path
from typing import Any

import numpy as np
import rerun as rr
import rerun.blueprint as rrb

from sim.harness.atomic import atomic_path
from sim.world.camera import SR4000_INTRINSICS, CameraIntrinsics, Frame
from sim.harness.ground_truth import GroundTruth
from sim.harness.provenance import provenance
from sim.harness.scoring import AXES, AXIS_UNITS
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
WORLD = "world"
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


def _property_value(value: Any):
    """Scalars and strings as they are; anything nested as a JSON string."""
    if isinstance(value, (bool, int, float, str)):
        return value
    return json.dumps(value, sort_keys=True, default=str)


def default_blueprint(methods: Sequence[str]) -> rrb.Blueprint:
    """World and depth | disparity and segmentation | compensated frames | time series."""
    compensated = [rrb.Spatial2DView(origin=f"{COMPENSATED}/{method}",
                                     name=f"compensated: {method}") for method in methods]
    series = [rrb.TimeSeriesView(origin=f"series/{axis}", name=f"{axis} ({AXIS_UNITS[axis]})")
              for axis in AXES]
    errors = [rrb.TimeSeriesView(origin=f"errors/{axis}",
                                 name=f"|error| {axis} ({AXIS_UNITS[axis]})") for axis in AXES]
    errors.append(rrb.TimeSeriesView(origin=RESIDUAL, name="truth fit residual (px)"))
    return rrb.Blueprint(
        rrb.Horizontal(
            rrb.Vertical(rrb.Spatial3DView(origin=WORLD, name="world"),
                         rrb.Spatial2DView(origin=IMAGE_PLANE, name="depth")),
            rrb.Vertical(rrb.Spatial2DView(origin=DISPARITY, name="disparity-like"),
                         rrb.Spatial2DView(origin=SEGMENTATION, name="segmentation")),
            rrb.Grid(*compensated) if compensated else rrb.TextLogView(origin=EVENTS),
            rrb.Tabs(rrb.Vertical(*series, name="estimate vs truth"),
                     rrb.Vertical(*errors, name="errors"),
                     rrb.TextLogView(origin=EVENTS, name="events")),
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
        frame_stride: log images, depth, the camera and the path of every ``frame_stride``-th
            frame (sizes: docs/recording.md); scalars are logged for every frame.
        recording_id: rerun's recording id; random when None.
    """

    def __init__(self, path: str | os.PathLike, methods: Sequence[str], *,
                 intrinsics: CameraIntrinsics = SR4000_INTRINSICS,
                 properties: Mapping[str, Any] | None = None, frame_stride: int = 1,
                 recording_id: str | None = None):
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
        self._frames_buffered = 0
        self._n_labels = -1
        self._closed = False
        self._files = ExitStack()
        temporary = self._files.enter_context(atomic_path(self.path))
        self._stream = rr.RecordingStream(APPLICATION_ID, recording_id=recording_id)
        self._stream.set_log_time_enabled(False)  # wall-clock time would make files differ
        self._stream.save(temporary, default_blueprint=default_blueprint(self.methods))
        self._log_static(dict(properties or {}))

    # ------------------------------------------------------------------ setup
    def _log_static(self, properties: dict[str, Any]) -> None:
        stream = self._stream
        for name, values in (("run", properties), ("provenance", provenance())):
            if values:
                stream.send_property(name, rr.AnyValues(
                    **{key: _property_value(value) for key, value in values.items()}))
        stream.log(WORLD, rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)  # MuJoCo's world
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
            for index, method in enumerate(self.methods):
                colour = METHOD_COLOURS[index % len(METHOD_COLOURS)]
                for root in ("series", "errors"):
                    stream.log(f"{root}/{axis}/{method}",
                               rr.SeriesLines(colors=[colour], names=[method]), static=True)

    def _ensure_annotations(self, n_labels: int) -> None:
        if n_labels > self._n_labels:
            self._n_labels = n_labels
            self._stream.log(SEGMENTATION, rr.AnnotationContext(label_colours(n_labels)),
                             static=True)

    # ------------------------------------------------------------------ per frame
    def log_frame(self, frame: Frame, *, estimates: Mapping[str, Motion],
                  truth: GroundTruth | None = None,
                  compensated: Mapping[str, np.ndarray] | None = None,
                  robot_position: np.ndarray | None = None) -> bool:
        """Log one frame. Returns True when its images were logged (see ``frame_stride``).

        Args:
            frame: the SR4000 frame with its exact camera pose.
            estimates: method -> Motion; the paper method's ``diagnostics`` may hold
                ``"labels"`` (H x W int label image, 0 = unlabelled) and ``"ellipses"``
                (``(cx, cy, half_major, half_minor, angle_deg)`` tuples); both optional.
            truth: the frame's ground truth; None when unknown.
            compensated: method -> compensated uint8 frame.
            robot_position: (3,) position added to the robot's path; the camera's when None.
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
        self._buffer_series(int(frame.index), float(frame.time_s), estimates, truth)
        self.frames_logged += 1
        position = frame.cam_pos if robot_position is None else robot_position
        self._path_points.append(np.asarray(position, dtype=np.float32).reshape(3))
        if frame.index % self.frame_stride:
            return False
        stream.log(CAMERA, rr.Transform3D(translation=frame.cam_pos, mat3x3=frame.cam_mat))
        stream.log(ROBOT_PATH, rr.LineStrips3D([self._thinned_path()]))
        stream.log(DEPTH, rr.DepthImage(frame.depth_m, meter=1.0))
        stream.log(DISPARITY, rr.Image(frame.disparity8))
        for method, image in (compensated or {}).items():
            stream.log(f"{COMPENSATED}/{method}", rr.Image(image))
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
        for position, axis in enumerate(AXES):
            if truth_values is not None:
                values.append((f"series/{axis}/truth", truth_values[position]))
            for method, motion in estimates.items():
                if not motion.ok:
                    continue
                value = motion.as_tuple()[position]
                values.append((f"series/{axis}/{method}", value))
                if truth_values is not None:
                    values.append((f"errors/{axis}/{method}", abs(value - truth_values[position])))
        for entity, value in values:
            if math.isfinite(value):
                self._series[entity].append((index, time_s, float(value)))
        self._frames_buffered += 1
        if self._frames_buffered >= SERIES_BATCH_FRAMES:
            self._send_series()

    def _send_series(self) -> None:
        """Send the buffered scalars, one column batch per series, on both timelines."""
        for entity, rows in self._series.items():
            frames, times, values = zip(*rows)
            self._stream.send_columns(
                entity,
                indexes=[rr.TimeColumn("frame", sequence=frames),
                         rr.TimeColumn("sim_time", duration=times)],
                columns=rr.Scalars.columns(scalars=values))
        self._series.clear()
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
