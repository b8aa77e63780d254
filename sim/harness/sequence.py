"""Sequence folders: a simulated walk on disk, readable by any program (docs/sequence-format.md).

A sequence holds what a run needs to be scored again without the simulator: the frames as the
sensor reports them, the exact depth the ground truth uses, the camera poses and the truth, and
the scenario that made them. ``egostab run`` passes every frame through the same encoding
(``encode_frame`` then ``decoded_frame``), so scoring a recorded sequence gives the figures of
the run that recorded it, bit for bit.

Depth is stored as 16-bit PNG (lossless): the reported depth in 0.1 mm units (the SR4000 reports
at most 5 m; its 14-bit range steps are 0.3 mm), the exact depth in 0.5 mm units because scenes
reach beyond 6.5 m (the 0.1 mm limit) up to the renderer's far clip (at most 30 m). 0 means no
measurement (reported depth) or no surface (exact depth).
"""

from __future__ import annotations

import csv
import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Mapping, Sequence as SequenceOf

import numpy as np

from sim.atomic import atomic_path, write_text_atomic
from sim.harness.validation import FileValueError, is_finite_number, is_int
from sim.world.camera import CameraIntrinsics, Frame
from stabilizer import depth_to_disparity

#: The format's name and version, as sequence.json's "format" states them.
FORMAT_NAME, FORMAT_VERSION = "egostab-sequence", 1
FORMAT = f"{FORMAT_NAME}/{FORMAT_VERSION}"
#: Metres per unit of the reported depth PNGs (depth/) of a sensor that reports at most 6.55 m
#: (every SR4000 preset: finer than its 14-bit step of 0.3 mm), and of the exact depth PNGs
#: (exact/) and the reported depth of a sensor without a range limit (up to 32.7 m).
FINE_DEPTH_UNIT_M = 1e-4
EXACT_DEPTH_UNIT_M = 5e-4
DEPTH_UNITS_M = (FINE_DEPTH_UNIT_M, EXACT_DEPTH_UNIT_M)
#: Largest value of a 16-bit PNG.
UINT16_MAX = 65535
#: The last 12 bytes of every complete PNG: its IEND chunk (length 0, type, CRC).
PNG_END = b"\x00\x00\x00\x00IEND\xaeB`\x82"
#: Files and folders of a sequence.
SEQUENCE_JSON, TRUTH_CSV, GROUNDTRUTH_TXT = "sequence.json", "truth.csv", "groundtruth.txt"
DEPTH_DIR, EXACT_DIR = "depth", "exact"
#: How a recording ended (sequence.json "ended"); "incomplete" until its final write.
ENDINGS = ("complete", "fell", "interrupted")
INCOMPLETE = "incomplete"
#: How each folder's PNGs are written: zlib level and OpenCV's PNG filter. The reported
#: depth is noisy in its last digits and compresses to 76% at best, so it is stored
#: uncompressed and unfiltered: decoding then takes 0.05 ms instead of 0.37 ms (zlib level 3
#: with libpng's adaptive filters), for a sequence of 47 MB instead of 38 MB (default
#: scenario). The exact depth of smooth surfaces compresses to a fifth at level 3
#: (uncompressed, it would take the sequence past 60 MB); its "up" filter (each row from the
#: one above) decodes in 0.20 ms against the adaptive filters' 0.26 ms, for 0.5 MB more;
#: level 9 would save 6% more and make recording twice as slow.
PNG_WRITING = {DEPTH_DIR: (0, "IMWRITE_PNG_FILTER_NONE"), EXACT_DIR: (3, "IMWRITE_PNG_FILTER_UP")}
#: Columns of truth.csv, in order (docs/sequence-format.md describes each).
ROTATION_COLUMNS = tuple(f"r{row}{col}" for row in range(3) for col in range(3))
TRUTH_COLUMNS = ("frame", "time_s", "reference_frame", "gait_cycle", "angle_deg", "dx", "dy",
                 "truth_status", "truth_residual_px", "truth_points",
                 "tx", "ty", "tz", *ROTATION_COLUMNS, "qx", "qy", "qz", "qw",
                 "torso_x", "torso_y", "torso_z")
#: MuJoCo camera axes (x right, y up, looking along -z) -> optical axes (x right, y down,
#: z forward), the convention of TUM RGB-D and OpenCV used by groundtruth.txt's quaternions.
MUJOCO_TO_OPTICAL = np.diag([1.0, -1.0, -1.0])


def frame_file(index: int) -> str:
    """File name of frame ``index`` in depth/ and exact/."""
    return f"{index:06d}.png"


@dataclass(frozen=True)
class EncodedFrame:
    """The two 16-bit images of one frame, as the PNGs store them."""

    depth: np.ndarray
    exact: np.ndarray


def reported_depth_unit_m(farthest_reported_m: float) -> float:
    """Metres per unit of the reported depth PNGs of a sensor that reports at most
    ``farthest_reported_m``: the finest unit that holds it."""
    return FINE_DEPTH_UNIT_M if farthest_reported_m <= UINT16_MAX * FINE_DEPTH_UNIT_M \
        else EXACT_DEPTH_UNIT_M


def _to_units(depth_m: np.ndarray, keep: np.ndarray, unit_m: float, what: str) -> np.ndarray:
    units = np.where(keep, np.rint(np.where(keep, depth_m, 0.0) / unit_m), 0.0)
    largest = float(units.max(initial=0.0))
    if largest > UINT16_MAX:
        raise ValueError(f"{what} reaches {largest * unit_m:.2f} m; a sequence stores at most "
                         f"{UINT16_MAX * unit_m:.4f} m")
    return units.astype(np.uint16)


def encode_frame(frame: Frame, no_surface_depth_m: float, depth_unit_m: float) -> EncodedFrame:
    """The stored images of ``frame``: reported depth where ``valid`` (in ``depth_unit_m``),
    exact depth where a surface was rendered (below ``no_surface_depth_m``, the render's
    no-surface depth)."""
    depth = np.asarray(frame.depth_m, dtype=np.float64)
    exact = np.asarray(frame.true_depth_m, dtype=np.float64)
    surface = np.isfinite(exact) & (exact > 0) & (exact < no_surface_depth_m)
    return EncodedFrame(
        _to_units(depth, np.asarray(frame.valid) & np.isfinite(depth), depth_unit_m,
                  f"frame {frame.index}'s reported depth"),
        _to_units(exact, surface, EXACT_DEPTH_UNIT_M, f"frame {frame.index}'s exact depth"))


def _from_units(units: np.ndarray, unit_m: float) -> np.ndarray:
    return (units.astype(np.float64) * unit_m).astype(np.float32)


def decoded_frame(index: int, time_s: float, cam_pos, cam_mat, encoded: EncodedFrame,
                  depth_unit_m: float) -> Frame:
    """The Frame a sequence gives back for the stored images and pose (what every score sees)."""
    depth = _from_units(encoded.depth, depth_unit_m)
    return Frame(index=int(index), time_s=float(time_s), depth_m=depth, valid=encoded.depth > 0,
                 disparity8=depth_to_disparity(depth),
                 cam_pos=np.asarray(cam_pos, dtype=np.float64),
                 cam_mat=np.asarray(cam_mat, dtype=np.float64),
                 true_depth_m=_from_units(encoded.exact, EXACT_DEPTH_UNIT_M))


def optical_quaternion(cam_mat: np.ndarray) -> tuple[float, float, float, float]:
    """(qx, qy, qz, qw) of the camera's optical frame (x right, y down, z forward) in the world."""
    from scipy.spatial.transform import Rotation

    return tuple(float(q) for q in
                 Rotation.from_matrix(np.asarray(cam_mat) @ MUJOCO_TO_OPTICAL).as_quat())


@dataclass(frozen=True)
class RecordedFall:
    """The robot's fall that ended a recording."""

    time_s: float
    reason: str


@dataclass(frozen=True)
class TruthRow:
    """One row of truth.csv: the frame's time, reference, truth and poses."""

    frame: int
    time_s: float
    reference_frame: int
    gait_cycle: int
    angle_deg: float
    dx: float
    dy: float
    truth_status: str
    truth_residual_px: float
    truth_points: int
    cam_pos: tuple[float, float, float]
    cam_mat: tuple[tuple[float, float, float], ...]
    torso: tuple[float, float, float]

    def cells(self) -> list[str]:
        """The row's cells; floats by repr() so they read back bit for bit."""
        quaternion = optical_quaternion(np.asarray(self.cam_mat))
        values = (self.frame, self.time_s, self.reference_frame, self.gait_cycle,
                  self.angle_deg, self.dx, self.dy, self.truth_status, self.truth_residual_px,
                  self.truth_points, *self.cam_pos, *(v for row in self.cam_mat for v in row),
                  *quaternion, *self.torso)
        return [repr(float(v)) if isinstance(v, float) else str(v) for v in values]

    def tum_line(self) -> str:
        """groundtruth.txt's line: ``timestamp tx ty tz qx qy qz qw`` (TUM RGB-D)."""
        quaternion = optical_quaternion(np.asarray(self.cam_mat))
        return " ".join(repr(float(v)) for v in (self.time_s, *self.cam_pos, *quaternion))


def holds_sequence(folder: str | Path) -> bool:
    """Whether ``folder`` holds a sequence of this format (complete or not): its sequence.json
    names the format."""
    try:
        header = json.loads((Path(folder) / SEQUENCE_JSON).read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, ValueError):
        return False
    return isinstance(header, dict) and str(header.get("format", "")).startswith(
        f"{FORMAT_NAME}/")


def frame_depth_unit_m(png: str | Path) -> float | None:
    """Metres per unit of ``png`` when it is a frame of a sequence folder (a file of its
    ``depth/`` or ``exact/`` folder, beside a sequence.json of this format): that header's
    ``depth_unit_m`` or ``exact_depth_unit_m``; None for any other file. A header whose unit
    is missing or not one of the format's is refused (FileValueError, one line)."""
    path = Path(png).resolve()
    folder, sub = path.parent.parent, path.parent.name
    if sub not in (DEPTH_DIR, EXACT_DIR) or not holds_sequence(folder):
        return None
    header = json.loads((folder / SEQUENCE_JSON).read_text(encoding="utf-8"))
    key, allowed = (("depth_unit_m", DEPTH_UNITS_M) if sub == DEPTH_DIR
                    else ("exact_depth_unit_m", (EXACT_DEPTH_UNIT_M,)))
    unit = header.get(key, _MISSING)
    if unit not in allowed:
        raise FileValueError(str(folder / SEQUENCE_JSON), key,
                             "is missing" if unit is _MISSING else f"is {unit!r}",
                             f"one of {', '.join(map(str, allowed))} (metres per PNG unit)")
    return float(unit)


#: What a recording writes into its folder, and replaces there.
RECORDING_ENTRIES = (DEPTH_DIR, EXACT_DIR, SEQUENCE_JSON, TRUTH_CSV, GROUNDTRUTH_TXT)


def check_recording_folder(out_dir: str | Path) -> None:
    """Refuse a folder that holds what a recording replaces (``depth/``, ``exact/``,
    sequence.json, truth.csv, groundtruth.txt) but no sequence of this format: recording there
    would delete or overwrite files of the user's own (another dataset's ``depth/000000.png``).
    A new or empty folder, a folder of other files (they stay) and a sequence folder (it is
    replaced) are accepted."""
    folder = Path(out_dir)
    present = [name for name in RECORDING_ENTRIES if (folder / name).exists()]
    if not present or holds_sequence(folder):
        return
    raise FileValueError(str(folder), "folder", f"holds {', '.join(present)} but no sequence "
                         f"of format {FORMAT_NAME} (a recording would replace them)",
                         "a new or empty folder, one of other files, or a sequence folder to "
                         "replace")


def remove_recording(out_dir: str | Path) -> None:
    """Remove what a recording writes (:data:`RECORDING_ENTRIES`) from ``out_dir``, readable or
    not; other files stay. Only for a folder whose owner knows it holds nothing else of those
    names (a suite's own recording, damaged beyond what :func:`check_recording_folder` lets a
    new recording replace)."""
    import shutil

    for name in RECORDING_ENTRIES:
        path = Path(out_dir) / name
        if path.is_dir() and not path.is_symlink():
            shutil.rmtree(path)
        elif path.exists() or path.is_symlink():
            path.unlink()


class SequenceWriter:
    """Writes a sequence folder frame by frame: ``start``, ``add`` each frame, then ``close``
    writes the tables and sequence.json.

    sequence.json says "incomplete" from ``start`` until ``close``, so a folder whose writer
    was killed is refused by ``load_sequence``. A sequence already in the folder is replaced:
    ``start`` removes its frame images, so that a shorter recording leaves none of them behind
    (other files stay); a folder holding such files but no sequence is refused
    (:func:`check_recording_folder`). ``started`` says whether the folder has been touched.
    """

    def __init__(self, out_dir: str | Path, header: Mapping[str, Any]):
        check_recording_folder(out_dir)
        self.out_dir = Path(out_dir)
        self.header = dict(header)
        self.rows: list[TruthRow] = []
        self.started = False

    def start(self) -> None:
        """Mark the folder incomplete, then remove an earlier sequence's frame images."""
        self.out_dir.mkdir(parents=True, exist_ok=True)
        self.started = True
        self._write_json(INCOMPLETE, "", None)  # first: a sequence being replaced is refused
        for folder in (DEPTH_DIR, EXACT_DIR):
            (self.out_dir / folder).mkdir(parents=True, exist_ok=True)
            self._remove_frame_images(folder, beyond=-1)

    def _remove_frame_images(self, folder: str, beyond: int) -> None:
        for path in (self.out_dir / folder).glob("[0-9]" * 6 + ".png"):
            if int(path.stem) > beyond:
                path.unlink()

    def add(self, encoded: EncodedFrame, row: TruthRow) -> None:
        """Store one frame's images and its truth row."""
        import cv2

        for folder, image in ((DEPTH_DIR, encoded.depth), (EXACT_DIR, encoded.exact)):
            path = self.out_dir / folder / frame_file(row.frame)
            level, png_filter = PNG_WRITING[folder]
            encoded_ok, png = cv2.imencode(".png", image, (
                cv2.IMWRITE_PNG_COMPRESSION, level,
                cv2.IMWRITE_PNG_FILTER, getattr(cv2, png_filter)))
            if not encoded_ok:
                raise OSError(f"{path}: could not encode the PNG")
            with atomic_path(path) as temporary:
                temporary.write_bytes(png.tobytes())
        self.rows.append(row)

    def close(self, ended: str, message: str = "", fall: RecordedFall | None = None, *,
              sim_time_s: float = math.nan) -> dict:
        """Write truth.csv, groundtruth.txt and (last) sequence.json with how it ended and the
        simulated time; return sequence.json's content."""
        if ended not in ENDINGS:
            raise ValueError(f"ended must be one of {', '.join(ENDINGS)}; got {ended!r}")
        # A stop between a frame's images and its row, or while ``start`` removed an earlier
        # sequence's images, leaves images of frames the sequence does not hold: the frames
        # are 0 to len(rows) - 1, each with both images.
        for folder in (DEPTH_DIR, EXACT_DIR):
            (self.out_dir / folder).mkdir(parents=True, exist_ok=True)
            self._remove_frame_images(folder, beyond=len(self.rows) - 1)
        lines = [",".join(TRUTH_COLUMNS)] + [",".join(row.cells()) for row in self.rows]
        write_text_atomic(self.out_dir / TRUTH_CSV, "\n".join(lines) + "\n")
        write_text_atomic(self.out_dir / GROUNDTRUTH_TXT,
                          "# timestamp tx ty tz qx qy qz qw\n"
                          + "".join(row.tum_line() + "\n" for row in self.rows))
        return self._write_json(ended, message, fall, sim_time_s)

    def _write_json(self, ended: str, message: str, fall: RecordedFall | None,
                    sim_time_s: float = math.nan) -> dict:
        content = {"format": FORMAT, **self.header, "frames": len(self.rows),
                   "ended": ended, "message": message,
                   "fall": None if fall is None else {"time_s": fall.time_s,
                                                      "reason": fall.reason},
                   "sim_time_s": None if math.isnan(sim_time_s) else sim_time_s}
        write_text_atomic(self.out_dir / SEQUENCE_JSON, json.dumps(content, indent=2) + "\n")
        return content


@dataclass(frozen=True)
class LoadedSequence:
    """A sequence folder read by ``load_sequence``; frames are read from disk on demand.

    Attributes:
        path: the folder.
        header: sequence.json's content.
        scenario: the resolved scenario (a dict, as ``Scenario.to_dict`` without "source").
        intrinsics: the camera's pinhole.
        rows: truth.csv, one TruthRow per frame, in frame order.
        fall: the fall that ended the recording, if one did.
    """

    path: Path
    header: Mapping[str, Any]
    scenario: Mapping[str, Any]
    intrinsics: CameraIntrinsics
    rows: SequenceOf[TruthRow]
    fall: RecordedFall | None

    @property
    def n_frames(self) -> int:
        return len(self.rows)

    @property
    def ended(self) -> str:
        return self.header["ended"]

    def encoded(self, index: int, exact: bool = True) -> EncodedFrame:
        """The stored images of frame ``index`` (the exact depth all 0 unless ``exact``)."""
        depth = self._read_png(DEPTH_DIR, index)
        return EncodedFrame(depth, self._read_png(EXACT_DIR, index) if exact
                            else np.zeros_like(depth))

    def frame(self, index: int, exact: bool = True) -> Frame:
        """Frame ``index`` decoded, with its exact pose; ``exact=False`` skips reading the
        exact depth (all 0: no surface), which only the ground truth needs."""
        row = self.rows[index]
        return decoded_frame(row.frame, row.time_s, row.cam_pos, row.cam_mat,
                             self.encoded(index, exact), self.header["depth_unit_m"])

    def _read_png(self, folder: str, index: int) -> np.ndarray:
        path = self.path / folder / frame_file(index)
        try:
            data = path.read_bytes()
        except OSError:
            data = b""
        # A cut-off file (an interrupted copy, a full disk) lacks the closing IEND chunk: it is
        # refused here, before libpng would print a line of its own beside the refusal.
        image = decode_image(data) if data.endswith(PNG_END) else None
        expected = (self.intrinsics.height, self.intrinsics.width)
        if image is None:
            raise FileValueError(str(path), "image", "missing or not a readable PNG",
                                 f"a {expected[1]} x {expected[0]} 16-bit grey PNG")
        if image.dtype != np.uint16 or image.shape != expected:
            raise FileValueError(str(path), "image",
                                 f"is {image.dtype} with shape {image.shape}",
                                 f"a {expected[1]} x {expected[0]} 16-bit grey PNG")
        return image


def _parse_row(cells: dict[str, str], source: str, line: int) -> TruthRow:
    def number(name: str, kind=float, finite: bool = True):
        """The cell as ``kind``; NaN is allowed only where ``finite`` is False (the truth of a
        frame without one)."""
        try:
            value = kind(cells[name])
        except (TypeError, ValueError):
            raise FileValueError(f"{source}:{line}", name, f"{cells[name]!r} is not a number",
                                 "a number") from None
        if finite and not math.isfinite(value):
            raise FileValueError(f"{source}:{line}", name, f"{cells[name]!r} is not finite",
                                 "a finite number")
        return value

    rotation = [number(name) for name in ROTATION_COLUMNS]
    return TruthRow(
        frame=number("frame", int), time_s=number("time_s"),
        reference_frame=number("reference_frame", int), gait_cycle=number("gait_cycle", int),
        angle_deg=number("angle_deg", finite=False), dx=number("dx", finite=False),
        dy=number("dy", finite=False), truth_status=cells["truth_status"],
        truth_residual_px=number("truth_residual_px", finite=False),
        truth_points=number("truth_points", int),
        cam_pos=tuple(number(name) for name in ("tx", "ty", "tz")),
        cam_mat=tuple(tuple(rotation[3 * r:3 * r + 3]) for r in range(3)),
        torso=tuple(number(name) for name in ("torso_x", "torso_y", "torso_z")))


def read_truth_csv(path: Path, n_frames: int) -> list[TruthRow]:
    """truth.csv's rows, checked: every column, frames 0..n_frames-1 in order, each frame's
    reference the frame itself or an earlier one. UTF-8, with or without a byte-order mark (a
    table saved again by a spreadsheet)."""
    try:
        handle = open(path, newline="", encoding="utf-8-sig")
    except OSError as error:  # missing, a folder in its place, no permission
        raise FileValueError(str(path), "file", f"cannot be read ({error.strerror})",
                             "a readable truth.csv, as `egostab record` writes it") from None
    with handle:
        try:
            reader = csv.DictReader(handle)
            missing = [name for name in TRUTH_COLUMNS if name not in (reader.fieldnames or ())]
            if missing:
                raise FileValueError(str(path), "header", f"lacks column(s) {', '.join(missing)}",
                                     f"the columns {', '.join(TRUTH_COLUMNS)}")
            rows = [_parse_row(cells, str(path), line)
                    for line, cells in enumerate(reader, start=2)]
        except UnicodeDecodeError as error:
            raise FileValueError(str(path), "encoding", f"is not UTF-8 text ({error.reason} at "
                                 f"byte {error.start})", "a UTF-8 CSV file") from None
        except csv.Error as error:  # a field beyond the csv module's size limit, say
            raise FileValueError(f"{path}:{reader.line_num}", "row", f"is not CSV ({error})",
                                 "the rows egostab record writes") from None
    for position, row in enumerate(rows):
        where = f"{path}:{position + 2}"
        if row.frame != position:
            raise FileValueError(where, "frame", f"is {row.frame}",
                                 f"frames 0, 1, 2, ... in order (here {position})")
        if not 0 <= row.reference_frame <= position:
            raise FileValueError(where, "reference_frame", f"is {row.reference_frame}",
                                 f"a frame from 0 to {position} (the frame itself or an "
                                 f"earlier one)")
    if len(rows) != n_frames:
        raise FileValueError(str(path), "rows", f"has {len(rows)} frame(s)",
                             f"one row per frame: sequence.json says {n_frames}")
    return rows


def _checked_header(header: dict, source: str) -> tuple[int, CameraIntrinsics,
                                                         RecordedFall | None]:
    """The frame count, intrinsics and fall of sequence.json's content, each key checked."""
    def check(ok: bool, key: str, value: Any, allowed: str) -> None:
        if not ok:
            raise FileValueError(source, key, "is missing" if value is _MISSING
                                 else f"is {value!r}", allowed)

    frames = header.get("frames", _MISSING)
    check(is_int(frames) and frames >= 0, "frames", frames, "an integer >= 0")
    intrinsics = header.get("intrinsics", _MISSING)
    check(isinstance(intrinsics, dict), "intrinsics", intrinsics,
          "an object with width, height, fx, fy, cx and cy")
    for key in ("width", "height"):
        value = intrinsics.get(key, _MISSING)
        check(is_int(value) and value > 0, f"intrinsics.{key}", value, "an integer > 0")
    for key in ("fx", "fy", "cx", "cy"):
        value = intrinsics.get(key, _MISSING)
        check(is_finite_number(value) and (key in ("cx", "cy") or value > 0),
              f"intrinsics.{key}", value,
              "a finite number" if key in ("cx", "cy") else "a finite number > 0")
    scenario = header.get("scenario", _MISSING)
    check(isinstance(scenario, dict), "scenario", scenario, "an object: the resolved scenario")
    unit = header.get("depth_unit_m", _MISSING)
    check(unit in DEPTH_UNITS_M, "depth_unit_m", unit, f"one of {DEPTH_UNITS_M}")
    unit = header.get("exact_depth_unit_m", _MISSING)
    check(unit == EXACT_DEPTH_UNIT_M, "exact_depth_unit_m", unit, f"{EXACT_DEPTH_UNIT_M}")
    fps = header.get("fps", _MISSING)
    check(is_finite_number(fps) and fps > 0, "fps", fps, "a finite number > 0 (frames/s)")
    message = header.get("message", "")
    check(isinstance(message, str), "message", message,
          "text (why the recording ended early, or empty)")
    sim_time_s = header.get("sim_time_s")
    check(sim_time_s is None or (is_finite_number(sim_time_s) and sim_time_s >= 0),
          "sim_time_s", sim_time_s, "null or a finite number >= 0 (seconds)")
    fall = header.get("fall")
    check(fall is None or (isinstance(fall, dict) and is_finite_number(fall.get("time_s"))
                           and isinstance(fall.get("reason"), str)),
          "fall", fall, 'null or an object {"time_s": seconds, "reason": text}')
    return (frames, CameraIntrinsics(**{key: intrinsics[key] for key in
                                        ("width", "height", "fx", "fy", "cx", "cy")}),
            None if fall is None else RecordedFall(float(fall["time_s"]), fall["reason"]))


#: A key sequence.json lacks (None is a value: JSON's null).
_MISSING = object()


def load_sequence(path: str | Path) -> LoadedSequence:
    """Open and check a sequence folder (format, version, tables, every frame's files).

    Raises:
        FileValueError: a wrong format or version, an unfinished recording, a missing or
            malformed table, a missing frame file: one line naming the file.
        FileNotFoundError: no such folder.
    """
    folder = Path(path)
    if not folder.is_dir():
        problem = "is a file, not a sequence folder" if folder.exists() else \
            "no such sequence folder"
        raise FileNotFoundError(f"{folder}: {problem}; accepted: a folder written by "
                                f"`egostab record`")
    json_path = folder / SEQUENCE_JSON
    try:
        header = json.loads(json_path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise FileValueError(str(json_path), "file", "is missing",
                             "a sequence folder written by `egostab record`") from None
    except OSError as error:  # a folder in its place, no permission
        raise FileValueError(str(json_path), "file", f"cannot be read ({error.strerror})",
                             "a readable file, as `egostab record` writes it") from None
    except (json.JSONDecodeError, UnicodeDecodeError) as error:
        raise FileValueError(str(json_path), "content", f"is not JSON ({error})",
                             "a JSON object") from None
    if not isinstance(header, dict) or header.get("format") != FORMAT:
        found = header.get("format") if isinstance(header, dict) else header
        raise FileValueError(str(json_path), "format", f"is {found!r}",
                             f"{FORMAT!r} (this version of egostab reads that one)")
    if header.get("ended") not in ENDINGS:
        raise FileValueError(str(json_path), "ended", f"is {header.get('ended')!r}: the "
                             "recording did not finish", f"one of {', '.join(ENDINGS)}; "
                             "record the sequence again")
    n_frames, intrinsics, fall = _checked_header(header, str(json_path))
    scenario = header["scenario"]
    rows = read_truth_csv(folder / TRUTH_CSV, n_frames)
    for index in range(n_frames):
        for sub in (DEPTH_DIR, EXACT_DIR):
            if not (folder / sub / frame_file(index)).is_file():
                raise FileValueError(str(folder / sub / frame_file(index)), "file",
                                     "is missing", f"one PNG per frame in {sub}/ "
                                     f"(frames 0 to {n_frames - 1})")
    return LoadedSequence(folder, header, scenario, intrinsics, rows, fall)


def decode_image(data: bytes) -> np.ndarray | None:
    """An encoded image (PNG or another format OpenCV reads) as stored, or None when it cannot
    be decoded; OpenCV's own log line about a broken file is held back, so that the caller's
    refusal is the only line."""
    import cv2

    level = cv2.utils.logging.getLogLevel()
    cv2.utils.logging.setLogLevel(cv2.utils.logging.LOG_LEVEL_SILENT)
    try:
        return cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_UNCHANGED)
    except cv2.error:  # a header claiming more than OpenCV decodes (2**30 pixels)
        return None
    finally:
        cv2.utils.logging.setLogLevel(level)
