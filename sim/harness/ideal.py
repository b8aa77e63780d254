"""The paper's "ideal environment" experiment (Kang, Zhang & Park 2009, section III-A).

One disparity/depth image is moved along a known trajectory of rigid motions; every method
estimates each moved frame against the original; the errors against the known motions give the
paper's Table I layout, its Fig. 8 (estimate against truth) and a per-frame CSV.

Images accepted (``load_image``):
- an 8-bit PNG: a disparity-like image (brighter = closer, 0 = no measurement);
- a 16-bit PNG: depth in units of ``depth_unit_mm`` millimetres (0 = no measurement): 1 mm
  (as depth cameras export it) unless told otherwise, but for a frame of a sequence folder
  (``depth/`` or ``exact/`` beside its sequence.json, docs/sequence-format.md): the unit that
  sequence.json states (0.1 mm for the SR4000's reported depth);
- a ``.npy`` file: a real (not complex) 2-D array of depth in metres;
- a scene name of ``sim.world.scenes.SCENES``: the noise-free SR4000 frame seen by the standing
  robot at the scene's start (rendered with the "noiseless" sensor preset).
Any other file (a JPEG, a TIFF) is refused.

Trajectories (``load_trajectory``): ``"paper_cycle"`` (default) is one gait cycle with the
magnitudes the paper saw on its walking robot (section III-B: x peaks near +-40 px, y between 2
and 32 px, rotation near +-12 deg): rotation 12 sin(p), x 40 sin(p + pi/3), y 17 - 15 cos(2p),
p = 2 pi k / n; or a frames.csv of a walking run, whose ground-truth motions are replayed, every
frame of it (``n_frames`` applies to the paper cycle only). Its rows with ``truth_status``
"ok" are replayed, those of "no_overlap" skipped (the statuses as the ground truth writes them,
case included; any other is refused), one truth per frame (a frame's rows, one per method,
agree; a frame repeated for one method is refused), each rotation at most
``MAX_TRAJECTORY_ANGLE_DEG`` either way and each shift at most the image's width (x) or height
(y) either way: a larger one moves the whole image out of view, so there is nothing to measure.

An interrupted experiment (Ctrl-C, SIGTERM, SIGHUP) ends as an interrupted ``egostab run``
does: its folder's files are complete and say "interrupted", with the frames done; over a
finished experiment, it is written beside it and dropped, and the finished one stays as it was
(``sim.harness.runner.RunFolder``).
"""

from __future__ import annotations

import csv
import math
import time
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from sim.harness.ground_truth import TRUTH_STATUSES
from sim.harness.methods import method_factory
from sim.harness.sequence import decode_image, frame_depth_unit_m
from stabilizer import apply_motion, available_methods, depth_to_disparity
from stabilizer.api import MAX_SIDE
from stabilizer.inputs import DEFAULT_FAR_M
from stabilizer.motion import OK, Motion

#: Name of the default trajectory.
PAPER_CYCLE = "paper_cycle"
#: Frame rate that puts the trajectory's frames on a time axis (the SR4000's default).
IDEAL_FPS = 30.0
#: Largest image the experiment takes as it is (1280 x 1024): every method's time and memory
#: grow with the pixel count (a 4000 x 3000 image took 3.8 GB and 140 s for 3 frames).
MAX_IMAGE_PIXELS = 1280 * 1024
#: Largest rotation of a replayed trajectory (deg, either way): a half turn; a walking run's
#: truths are a few degrees, and a huge angle (1e300) broke the plots.
MAX_TRAJECTORY_ANGLE_DEG = 180.0
#: Millimetres per unit of a 16-bit depth PNG that is not a sequence's frame.
DEFAULT_DEPTH_UNIT_MM = 1.0
#: The 8 bytes every PNG starts with, and those of image formats that are refused by name.
PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
OTHER_IMAGE_SIGNATURES = ((b"\xff\xd8\xff", "a JPEG image"), (b"II*\x00", "a TIFF image"),
                          (b"MM\x00*", "a TIFF image"), (b"BM", "a BMP image"),
                          (b"GIF8", "a GIF image"), (b"\x00\x00\x00\x0cjP  ", "a JPEG 2000 image"))
#: PNG colour types (the IHDR chunk's byte 25) of the images that are not single-channel.
PNG_COLOUR_TYPES = {2: "an RGB", 3: "a palette (indexed-colour)", 4: "a grey + alpha",
                    6: "an RGBA"}
#: What ``image`` accepts, for the refusals.
ACCEPTED_IMAGES = ("a single-channel 8-bit (disparity) or 16-bit (depth) PNG, a .npy depth in "
                   "metres, or a scene name")


@dataclass(frozen=True)
class IdealConfig:
    """One ideal experiment.

    Attributes:
        image: PNG/.npy path or a scene name (see the module docstring).
        out_dir: folder for frames.csv, metrics.json, summary.md and the plots.
        trajectory: ``"paper_cycle"`` or the path of a walking run's frames.csv.
        methods: methods to score; None = all available.
        n_frames: frames of the paper cycle (None: 30); refused with a frames.csv trajectory,
            which replays each of its frames.
        scene_seed: seed of the scene when ``image`` is a scene name.
        resize: scale an image larger than ``MAX_IMAGE_PIXELS``, or longer than
            ``stabilizer.api.MAX_SIDE`` on a side, down to fit (nearest neighbour, so no
            disparity value is invented); refused otherwise.
        depth_unit_mm: millimetres per unit of a 16-bit depth PNG (None: the unit of its
            sequence folder for a sequence's frame, else ``DEFAULT_DEPTH_UNIT_MM``); refused
            for any other image.
    """

    image: str
    out_dir: str
    trajectory: str = PAPER_CYCLE
    methods: tuple[str, ...] | None = None
    n_frames: int | None = None
    scene_seed: int = 0
    resize: bool = False
    depth_unit_mm: float | None = None

    def __post_init__(self):
        from sim.harness.runner import check_not_a_sequence

        check_not_a_sequence(self.out_dir)


def paper_cycle(n_frames: int = 30) -> list[Motion]:
    """One gait cycle of the paper's magnitudes (see the module docstring)."""
    if n_frames < 2:
        raise ValueError(f"n_frames must be >= 2; got {n_frames}")
    phase = 2.0 * np.pi * np.arange(n_frames) / n_frames
    return [Motion(12.0 * math.sin(p), 40.0 * math.sin(p + math.pi / 3),
                   17.0 - 15.0 * math.cos(2.0 * p)) for p in phase]


def trajectory_from_run(frames_csv: str | Path,
                        image_size: tuple[int, int] | None = None) -> list[Motion]:
    """The ground-truth motions of a walking run's frames.csv, one per frame, in order.

    Rows whose ``truth_status`` is "ok" give the motions, "no_overlap" rows are skipped; any
    other status, a frame repeated (for one method, when there is a ``method`` column), rows of
    one frame that disagree, a value that is not a finite number, a rotation beyond
    ``MAX_TRAJECTORY_ANGLE_DEG`` or a shift beyond ``image_size`` (width, height; without it,
    ``MAX_IMAGE_PIXELS``, longer than any image's side) either way are refused in one line
    naming the file and line (FileValueError).
    """
    from sim.harness.validation import FileValueError

    columns = ("frame_index", "truth_status", "true_angle_deg", "true_dx_px", "true_dy_px")
    kind = "the frames.csv of a walking run"
    width, height = image_size or (MAX_IMAGE_PIXELS, MAX_IMAGE_PIXELS)
    out_of_view = "a larger shift moves the whole image out of view"
    limits = ((MAX_TRAJECTORY_ANGLE_DEG, "deg", "a half turn"),
              (width, "px", f"the image's width: {out_of_view}"),
              (height, "px", f"the image's height: {out_of_view}"))
    motions: dict[int, tuple[Motion, int]] = {}
    rows: dict[tuple, int] = {}
    try:
        with open(frames_csv, newline="", encoding="utf-8-sig") as handle:
            reader = csv.DictReader(handle)
            missing = [name for name in columns if name not in (reader.fieldnames or ())]
            if missing:
                raise FileValueError(str(frames_csv), "header",
                                     f"lacks column(s) {', '.join(missing)}", kind)
            for line, row in enumerate(reader, start=2):
                where = f"{frames_csv}:{line}"
                # csv.DictReader keeps extra cells under the key None, fills missing ones None
                # (and keeps one cell of a column name the header repeats).
                n_cells = (sum(value is not None for key, value in row.items() if key is not None)
                           + len(row.get(None, ())))
                if n_cells != len(set(reader.fieldnames)):
                    raise FileValueError(where, "row", f"has {n_cells} cells (a line cut short "
                                         "or run on?)", f"one per column of the header, "
                                         f"{len(set(reader.fieldnames))}")
                status = row["truth_status"]
                if status not in TRUTH_STATUSES:
                    raise FileValueError(where, "truth_status", f"is {status!r}",
                                         f"{' or '.join(map(repr, TRUTH_STATUSES))}, as a run "
                                         "writes it (lower case)")
                try:
                    index = int(row["frame_index"])
                except (TypeError, ValueError):
                    raise FileValueError(where, "frame_index", f"is {row['frame_index']!r}",
                                         "a whole number") from None
                values = []
                for name in columns[2:] if status == OK else ():
                    try:
                        values.append(float(row[name]))
                    except ValueError:
                        values.append(math.nan)
                    if not math.isfinite(values[-1]):
                        raise FileValueError(where, name, f"is {row[name]!r}",
                                             "a finite number where truth_status is 'ok'")
                key = (index, row.get("method"))
                if key in rows:
                    raise FileValueError(where, "frame_index", f"{index} repeats line "
                                         f"{rows[key]}" + (f" for method {key[1]!r}"
                                                           if key[1] is not None else ""),
                                         "one row per frame (per frame and method)")
                rows[key] = line
                if status != OK:
                    continue
                for name, value, (limit, unit, why) in zip(columns[2:], values, limits):
                    if abs(value) > limit:
                        raise FileValueError(where, name, f"is {value:g}",
                                             f"at most {limit:g} {unit} either way ({why})")
                motion = Motion(*values)
                if index in motions and motions[index][0].as_tuple() != motion.as_tuple():
                    raise FileValueError(where, "row", f"frame {index}'s truth differs from "
                                         f"line {motions[index][1]}'s",
                                         "the same truth on every row of a frame")
                motions.setdefault(index, (motion, line))
    except (UnicodeDecodeError, csv.Error) as error:
        raise FileValueError(str(frames_csv), "content", f"is not a CSV table ({error})",
                             "the frames.csv of a walking run (UTF-8)") from None
    if not motions:
        raise ValueError(f"{frames_csv}: no frame with a ground truth (truth_status ok); "
                         "give the frames.csv of a walking run")
    return [motions[index][0] for index in sorted(motions)]


def load_trajectory(trajectory: str, n_frames: int | None = None,
                    image_size: tuple[int, int] | None = None) -> list[Motion]:
    """The motions of ``trajectory``: the paper cycle of ``n_frames`` frames (None: 30), or a
    walking run's frames.csv (:func:`trajectory_from_run`; ``n_frames`` is refused with it)."""
    if trajectory == PAPER_CYCLE:
        return paper_cycle() if n_frames is None else paper_cycle(n_frames)
    if Path(trajectory).suffix.lower() == ".csv":
        if not Path(trajectory).is_file():
            raise ValueError(f"trajectory {trajectory}: no such file; accepted: "
                             f"{PAPER_CYCLE!r} or the path of a walking run's frames.csv")
        if n_frames is not None:
            raise ValueError(f"--frames {n_frames} with the trajectory {trajectory}: a "
                             "frames.csv is replayed frame by frame; accepted: --frames with "
                             f"{PAPER_CYCLE!r} only")
        return trajectory_from_run(trajectory, image_size)
    raise ValueError(f"unknown trajectory {trajectory!r}; accepted: {PAPER_CYCLE!r} or the "
                     "path of a walking run's frames.csv")


def render_scene_still(scene_name: str, seed: int = 0) -> np.ndarray:
    """Noise-free SR4000 depth (metres) seen by the standing robot at the scene's start."""
    from sim.harness.runner import build_robot
    from sim.world.sensor.sr4000 import SR4000
    from sim.world.sensor.tof_model import TOF_PRESETS

    robot = build_robot(scene_name, seed, seed=seed)
    with SR4000(robot.model, robot.camera_name, TOF_PRESETS["noiseless"]) as sensor:
        return sensor.capture_still(robot.data).depth_m


def load_image(image: str, scene_seed: int = 0, resize: bool = False,
               depth_unit_mm: float | None = None) -> np.ndarray:
    """The uint8 disparity-like image of ``image`` (see the module docstring).

    An image of more than ``MAX_IMAGE_PIXELS`` is refused, or scaled down to fit when
    ``resize`` is true.
    """
    disparity, _ = read_image(image, scene_seed, depth_unit_mm)
    return _within_size_limit(disparity, image, resize)


def read_image(image: str, scene_seed: int = 0,
               depth_unit_mm: float | None = None) -> tuple[np.ndarray, float | None]:
    """The uint8 disparity-like image of ``image`` at the size it has, and the millimetres per
    unit it was read with (a 16-bit PNG; None for any other image). ``depth_unit_mm`` (None:
    the unit of its sequence folder for a sequence's frame, else ``DEFAULT_DEPTH_UNIT_MM``)
    is refused for any image other than a 16-bit PNG."""
    from sim.world.scenes import SCENES

    def refuse_unit(what: str) -> None:
        if depth_unit_mm is not None:
            raise ValueError(f"--depth-unit-mm {depth_unit_mm:g} with {image} ({what}); "
                             "accepted: --depth-unit-mm with a 16-bit depth PNG only")

    if image in SCENES:
        refuse_unit("a scene, rendered in metres")
        return depth_to_disparity(render_scene_still(image, scene_seed)), None
    path = Path(image)
    if not path.is_file():
        raise ValueError(f"{image!r} is neither a file nor a scene name; accepted: an 8-bit "
                         f"or 16-bit PNG, a .npy depth in metres, or one of {', '.join(SCENES)}")
    if path.suffix.lower() == ".npy":
        refuse_unit("a .npy depth in metres")
        try:
            with open(path, "rb") as handle:
                # Without the magic, numpy takes any file for a pickle and says so.
                magic = np.lib.format.MAGIC_PREFIX
                if handle.read(len(magic)) != magic:
                    raise ValueError("not a .npy file: it lacks the format's magic bytes")
            depth = np.load(path)  # never pickles: an object array is refused
        except (ValueError, OSError, EOFError) as error:
            raise ValueError(f"{image}: cannot read it as a .npy array ({error}); accepted: "
                             f"a 2-D numeric array of depths in metres (numpy.save)") from None
        # A complex array would lose its imaginary part with a warning; a bool is no depth.
        if depth.ndim != 2 or not (np.issubdtype(depth.dtype, np.integer)
                                   or np.issubdtype(depth.dtype, np.floating)):
            raise ValueError(f"{image}: need a 2-D array of real depths in metres (integer or "
                             f"float); got {depth.dtype} with shape {depth.shape}")
        depth = depth.astype(np.float64)
        _refuse_all_too_far(depth, image, "millimetres? accepted: depths in metres")
        return depth_to_disparity(depth), None
    try:
        data = path.read_bytes()
    except OSError:
        data = b""
    other = next((name for signature, name in OTHER_IMAGE_SIGNATURES
                  if data.startswith(signature)), None)
    pixels = decode_image(data) if data.startswith(PNG_SIGNATURE) else None
    if pixels is None or pixels.ndim != 2 or pixels.dtype not in (np.uint8, np.uint16):
        colour = PNG_COLOUR_TYPES.get(data[25]) if len(data) > 25 else None
        got = (other or "an unreadable file (not a PNG)" if not data.startswith(PNG_SIGNATURE)
               else "an unreadable file" if pixels is None
               else f"{colour} PNG (read as {pixels.dtype} with shape {pixels.shape})" if colour
               else f"{pixels.dtype} with shape {pixels.shape}")
        raise ValueError(f"{image}: need a single-channel 8-bit (disparity) or 16-bit "
                         f"(depth) PNG; got {got}; accepted: {ACCEPTED_IMAGES}")
    if pixels.dtype == np.uint8:
        refuse_unit("an 8-bit disparity PNG")
        return pixels, None
    if depth_unit_mm is None:
        sequence_unit_m = frame_depth_unit_m(path)
        depth_unit_mm = (DEFAULT_DEPTH_UNIT_MM if sequence_unit_m is None
                         else sequence_unit_m * 1000.0)
    depth_m = np.where(pixels > 0, pixels / (1000.0 / depth_unit_mm), np.nan)
    _refuse_all_too_far(depth_m, image, f"another unit than {depth_unit_mm:g} mm? accepted: "
                                        "--depth-unit-mm giving the PNG's unit")
    return depth_to_disparity(depth_m), depth_unit_mm


def _refuse_all_too_far(depth_m: np.ndarray, image: str, advice: str) -> None:
    """A ValueError when every measured pixel (finite, positive) lies beyond the stabilizers'
    far limit: depths in another unit than the one read, not a scene (a far wall still has a
    floor in front of it). An image with no measured pixel at all is a degenerate scene, which
    the run reports frame by frame."""
    measured = depth_m[np.isfinite(depth_m) & (depth_m > 0)]
    if measured.size and measured.min() > DEFAULT_FAR_M:
        raise ValueError(f"{image}: every depth lies beyond {DEFAULT_FAR_M:g} m (from "
                         f"{measured.min():.4g} to {measured.max():.4g} m as read), where no "
                         f"stabilizer measures; {advice}")


def _within_size_limit(disparity: np.ndarray, image: str, resize: bool) -> np.ndarray:
    height, width = disparity.shape
    if height * width <= MAX_IMAGE_PIXELS and max(height, width) <= MAX_SIDE:
        return disparity
    if not resize:
        raise ValueError(f"{image}: {width} x {height} pixels is larger than the ideal "
                         f"experiment accepts ({MAX_IMAGE_PIXELS:,} pixels, e.g. 1280 x 1024, "
                         f"and at most {MAX_SIDE} on a side); pass --resize to scale it down")
    scale = min(math.sqrt(MAX_IMAGE_PIXELS / (height * width)), MAX_SIDE / max(height, width))
    size = (max(1, int(width * scale)), max(1, int(height * scale)))
    return cv2.resize(disparity, size, interpolation=cv2.INTER_NEAREST)


def run_ideal(config: IdealConfig) -> dict:
    """Run the ideal experiment; write and return the metrics (metrics.json).

    Its status is "complete", or "interrupted" (Ctrl-C, SIGTERM, SIGHUP; the message says
    which, the files hold the frames done), or "error" (the exception is re-raised after the
    files are written); see the module docstring for a run over a finished one.
    """
    from sim.atomic import prepare_output_dir
    from sim.harness.ground_truth import GroundTruth
    from sim.harness.interrupts import interrupt_reason, stop_signals_interrupt, stops_held
    from sim.harness.report import write_run_outputs
    from sim.harness.runner import (CHECKPOINT_S, COMPLETE, ERROR, INCOMPLETE, INTERRUPTED,
                                    RunFolder, timed_estimate)
    from sim.harness.scoring import (RAW_STREAM, FrameRecord, ItfAccumulator, failure_entry,
                                     summarize)
    from stabilizer import compensate

    methods = tuple(config.methods or available_methods())
    read, depth_unit_mm = read_image(config.image, config.scene_seed, config.depth_unit_mm)
    reference = _within_size_limit(read, config.image, config.resize)
    height, width = reference.shape
    motions = load_trajectory(config.trajectory, config.n_frames, (width, height))
    stabilizers = {method: method_factory(method)(reference) for method in methods}
    rows, cols = np.nonzero(reference[::2, ::2])  # the walking truth's stride-2 sample
    source = np.stack([2 * cols, 2 * rows], axis=1)
    records, failures = [], []
    itf = ItfAccumulator()
    scenario = {"name": f"ideal:{Path(config.image).stem}", "mode": "ideal",
                "image": config.image, "trajectory": config.trajectory,
                "n_frames": len(motions), "scene_seed": config.scene_seed}
    meta = {"seed": config.scene_seed, "methods": list(methods),
            "created": time.strftime("%Y-%m-%d"), "resize": config.resize,
            "image_size": [width, height], "image_size_read": [read.shape[1], read.shape[0]],
            "depth_unit_mm": depth_unit_mm}
    status, message = COMPLETE, ""
    # After the inputs: a refused one leaves no folder.
    folder = RunFolder(prepare_output_dir(config.out_dir))

    def write(final: bool) -> dict:
        meta["frames_done"] = len(records) // max(len(methods), 1)
        return write_run_outputs(folder.out_dir, scenario=scenario, records=records,
                                 failures=failures, summary=summarize(records, itf), meta=meta,
                                 status=status if final else INCOMPLETE, plots=final).metrics

    with stop_signals_interrupt():
        wall_start = time.perf_counter()
        try:
            try:
                write(final=False)  # the folder says "incomplete" until the final write
                last_write = time.perf_counter()
                for index, truth_motion in enumerate(motions):
                    current = apply_motion(reference, truth_motion)
                    truth = GroundTruth.exact(truth_motion, source, reference.shape)
                    frame_records, frame_itf, frame_failures = [], [], []
                    for method in methods:
                        motion, ms = timed_estimate(stabilizers[method], current)
                        frame_itf.append((method, compensate(current, motion)))
                        frame_records.append(FrameRecord.score(
                            frame_index=index, time_s=index / IDEAL_FPS, gait_cycle=0,
                            reference_index=-1, method=method, estimate=motion, truth=truth,
                            ms=ms))
                        if not motion.ok:
                            frame_failures.append(failure_entry(
                                frame_index=index, method=method, estimate=motion))
                    # A frame counts once every method has estimated it.
                    itf.add(RAW_STREAM, current, gait_cycle=0, reference_index=-1)
                    for method, compensated in frame_itf:
                        itf.add(method, compensated, gait_cycle=0, reference_index=-1)
                    records.extend(frame_records)
                    failures.extend(frame_failures)
                    if time.perf_counter() - last_write >= CHECKPOINT_S:
                        write(final=False)
                        last_write = time.perf_counter()
            except KeyboardInterrupt as interrupt:
                status, message = INTERRUPTED, interrupt_reason(interrupt)
            except BaseException as error:  # the folder must not say "complete"
                status, message = ERROR, f"{type(error).__name__}: {error}"
                raise
            finally:
                with stops_held(final_write=True):  # a stop now ends the job after it
                    meta.update(message=message, wall_time_s=time.perf_counter() - wall_start)
                    metrics = write(final=True)
        finally:
            folder.settle(finished=status == COMPLETE)
    return metrics
