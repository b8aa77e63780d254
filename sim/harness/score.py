"""Score a recorded sequence without simulating: ``egostab score`` (docs/sequence-format.md).

The frames come from the sequence folder, decoded exactly as ``egostab run`` decodes the frames
it simulates, and go through the runner's one scoring loop (``sim.harness.runner.score_frames``),
so the run folder equals the one ``egostab run`` writes for the same scenario and seed (except
the timings). Methods run in this process or in ``workers`` spawn processes, each on one OpenCV
and one BLAS thread; the work is split by method and by chunks of frames sharing a reference,
so each reference is analysed once per chunk, and merged in frame order. Estimates written by
any program (``estimates_file``) are scored beside them.

This module imports numpy and OpenCV only inside functions: a worker process sets its thread
limits before they load.
"""

from __future__ import annotations

import dataclasses
import hashlib
import io
import math
import os
import re
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Iterator, Mapping, Sequence

#: Chunks per worker: many, so that no worker is left alone with a long chunk at the end (a
#: chunk is cut only where the reference changes, so each reference is still analysed once).
CHUNKS_PER_WORKER = 16
#: Columns of an estimates file; "status" is optional (default "ok").
ESTIMATE_COLUMNS = ("frame", "angle_deg", "dx", "dy")
#: A number of an estimates file: decimal, with an optional exponent, or nan/inf (refused
#: later, in any case, as not finite).
DECIMAL = re.compile(r"[+-]?(\d+\.?\d*|\.\d+)([eE][+-]?\d+)?|[+-]?(nan|inf|infinity)",
                     re.IGNORECASE | re.ASCII)
#: The columns an estimates file's header names in any case.
KNOWN_COLUMNS = (*ESTIMATE_COLUMNS, "status")
#: Status of a frame an estimates file does not mention.
MISSING = "missing"


@dataclass(frozen=True)
class ScoreConfig:
    """What to score and where to write it.

    Attributes:
        sequence: a sequence folder (``egostab record``).
        out_dir: run folder, outside the sequence folder; created; files inside are replaced
            atomically.
        methods: methods to run; None = the scenario's, unless estimate files are given
            (then only those are scored).
        estimates: method name -> CSV file of estimates made by another program.
        check_estimates: pass the estimates files' ``"ok"`` rows through the trust check that
            every method's ``"ok"`` passes (``stabilizer.verification``); a row it cannot
            confirm becomes ``"unverified"``. Default: scored as given.
        trust_check: pass every method's ``"ok"`` estimates through that check, as ``run``
            does (default); False: each method's estimates are scored as the method reports
            them (``--no-check``), figures that are not comparable with a checked run's.
        record: write ``recording.rrd`` if the scenario's ``[recording] enabled`` allows it.
        workers: processes that run the methods (1 = this process; None = one per core,
            or 1 when no method runs).
        max_frames: score only the sequence's first N frames (None: every frame); as
            ``run`` with the same ``max_frames``.
        progress: show a progress bar.
    """

    sequence: str
    out_dir: str
    methods: tuple[str, ...] | None = None
    estimates: Mapping[str, str] = field(default_factory=dict)
    check_estimates: bool = False
    trust_check: bool = True
    record: bool = True
    workers: int | None = 1
    max_frames: int | None = None
    progress: bool = False

    def __post_init__(self):
        from sim.harness.validation import is_int

        if self.max_frames is not None and not (is_int(self.max_frames) and self.max_frames >= 1):
            raise ValueError(f"--max-frames {self.max_frames!r}: accepted: an integer from 1")
        if self.check_estimates and not self.estimates:
            raise ValueError("--check-estimates: no estimates file to check; accepted: with "
                             "--estimates")
        if self.check_estimates and not self.trust_check:
            raise ValueError("--check-estimates with --no-check: the estimates files would pass "
                             "the trust check and the methods not; accepted: one of the two")
        # The run's files would mix with the sequence's.
        if Path(self.out_dir).resolve().is_relative_to(Path(self.sequence).resolve()):
            raise ValueError(f"--out {self.out_dir}: is in the sequence folder; accepted: a "
                             f"folder of its own for the run (default results/<sequence name>)")


def score(config: ScoreConfig) -> dict:
    """Score the sequence of ``config``; return the metrics dict also written to metrics.json.

    The status is as for ``sim.harness.runner.run``: "complete", "fell" (the recording ended
    with the robot's fall), "interrupted" or "error". The run folder is made once the sequence,
    the methods and the estimates files (each read once) are known to be good.
    """
    from sim.atomic import prepare_output_dir
    from sim.harness.methods import check_methods
    from sim.harness.runner import Scoring, score_frames
    from sim.harness.scenario import scenario_from_dict
    from sim.harness.sequence import SEQUENCE_JSON, load_sequence
    from sim.harness.threads import usable_cores, worker_count

    sequence = load_sequence(config.sequence)
    scenario = scenario_from_dict(sequence.scenario, str(sequence.path / SEQUENCE_JSON))
    _check_references(sequence, scenario.evaluation.reference)
    file_methods = {name: FileEstimation(path, sequence, config.check_estimates)
                    for name, path in config.estimates.items()}
    methods = tuple(config.methods or (() if file_methods else scenario.evaluation.methods))
    check_methods(methods)
    workers = worker_count(config.workers, usable_cores() if methods else 1)
    clash = sorted(set(methods) & set(file_methods))
    if clash:
        raise ValueError(f"{', '.join(clash)} named both as a method and as an estimates file; "
                         f"accepted: each name once")
    prepare_output_dir(config.out_dir)
    scoring = Scoring(scenario, methods + tuple(file_methods), Path(config.out_dir),
                      record=config.record and scenario.recording.enabled,
                      meta={"sequence": {"path": str(sequence.path), "ended": sequence.ended,
                                         "message": sequence.header.get("message", "")},
                            "estimates": {name: str(path)
                                          for name, path in config.estimates.items()},
                            "estimates_sha256": {name: estimation.sha256 for name, estimation
                                                 in file_methods.items()},
                            "estimates_checked": config.check_estimates,
                            "trust_check": config.trust_check,
                            "max_frames": config.max_frames, "workers": workers})
    frames = SequenceFrames(sequence, config.max_frames)
    with _method_estimations(sequence, frames.n_frames, methods, workers, config.trust_check,
                             keep_images=scoring.recording_path is not None) as (estimations, pool):
        scoring.plot_pool = pool and pool.processes
        frames.decoded = pool and pool.frame
        return score_frames(frames, scoring, {**estimations, **file_methods}, config.progress)


class SequenceFrames:
    """The frames of a loaded sequence as the scoring loop wants them (see SimulatedFrames).

    ``decoded``, when given, gives each frame by index, decoded elsewhere (by the estimation
    workers, which read every frame anyway) without its exact depth, with its ground truth.
    """

    def __init__(self, sequence, max_frames: int | None = None, decoded=None):
        self.sequence, self.decoded = sequence, decoded
        self.n_frames = min(sequence.n_frames, max_frames or sequence.n_frames)
        self.intrinsics = sequence.intrinsics
        self._done = 0

    def __enter__(self) -> "SequenceFrames":
        return self

    def __exit__(self, *exc_info) -> None:
        pass

    @property
    def fall(self):
        """The recording's fall, once its last frame has been given."""
        return self.sequence.fall if self._done == self.sequence.n_frames else None

    @property
    def sim_time_s(self) -> float:
        if (self._done == self.sequence.n_frames
                and self.sequence.header.get("sim_time_s") is not None):
            return float(self.sequence.header["sim_time_s"])
        return self.sequence.rows[self._done - 1].time_s if self._done else 0.0

    def __iter__(self):
        from sim.harness.runner import SourceFrame

        for index in range(self.n_frames):
            row = self.sequence.rows[index]
            frame, truth = (self.decoded(index) if self.decoded
                            else (self.sequence.frame(index), None))
            self._done = index + 1
            yield SourceFrame(frame, row.gait_cycle, row.torso, truth=truth)


def _check_references(sequence, policy: str) -> None:
    """ValueError unless each frame's ``reference_frame`` in truth.csv is the frame that the
    scenario's reference ``policy`` gives it (sim.harness.runner.ReferencePolicy), as
    ``egostab record`` writes it: the methods are scored against the policy's references, the
    estimates files against truth.csv's."""
    from sim.harness.runner import ReferencePolicy

    references = ReferencePolicy(policy)
    for row in sequence.rows:
        given = references.reference_for(row.frame, row.gait_cycle)
        if row.reference_frame != given:
            raise ValueError(f"{sequence.path / 'truth.csv'}: frame {row.frame}: "
                             f"reference_frame is {row.reference_frame} but the reference "
                             f"policy gives {given}; accepted: the truth.csv `egostab record` "
                             f"wrote")


class FileEstimation:
    """Estimates written by another program, one CSV row per frame (docs/sequence-format.md).

    Columns ``frame, angle_deg, dx, dy`` and optionally ``status`` (empty = "ok"); the motion
    of each frame against its reference_frame in truth.csv, in the README's Motion convention.
    A frame without a row is a failure with status "missing". Values of a row whose status is
    not "ok" are ignored. With ``checked``, an "ok" row passes the trust check every method's
    "ok" passes, or becomes "unverified". The time per frame is unknown (NaN).
    """

    def __init__(self, path: str | os.PathLike, sequence, checked: bool = False):
        self.path, self.checked = Path(path), checked
        # One read: the digest is of the very bytes scored, even if the file changes meanwhile.
        self.motions, self.sha256 = read_estimates(self.path, sequence.n_frames)
        self.analysis_ms: list[float] = []
        self._check, self._check_reference = None, None  # the trust check of one reference

    def estimate(self, reference, frame):
        from sim.harness.runner import Estimate
        from stabilizer import compensate
        from stabilizer.motion import Motion
        from stabilizer.verification import VerificationParams, shared_verifier

        motion = self.motions.get(frame.index) or Motion.failed(MISSING)
        if self.checked and motion.ok:
            if reference.index != self._check_reference:
                self._check = shared_verifier(reference.disparity8, VerificationParams())
                self._check_reference = reference.index
            motion = self._check(frame.disparity8, motion)
        return Estimate(motion, math.nan, compensate(frame.disparity8, motion))


def file_sha256(path: str | os.PathLike) -> str:
    """The SHA-256 of a file's bytes, in hex: what tells a changed estimates file from the one
    a run scored (a suite resumes a run only if its files are unchanged)."""
    with open(path, "rb") as file:
        return hashlib.file_digest(file, "sha256").hexdigest()


def read_estimates(path: Path, n_frames: int) -> tuple[dict, str]:
    """Frame -> Motion of an estimates file, and the SHA-256 (hex) of the bytes read; a bad row
    is refused with its line number."""
    from sim.harness.validation import FileValueError

    try:
        data = Path(path).read_bytes()
    except OSError as error:
        raise FileValueError(str(path), "file", f"cannot be read ({error.strerror or error})",
                             "an estimates CSV file (docs/sequence-format.md)") from None
    try:
        return _read_estimates(path, data.decode("utf-8-sig"), n_frames), \
            hashlib.sha256(data).hexdigest()
    except UnicodeDecodeError as error:
        raise FileValueError(str(path), "encoding", f"is not UTF-8 text ({error.reason} at byte "
                             f"{error.start})", "a UTF-8 CSV file (a byte-order mark is "
                             "allowed)") from None


def _shortened(text: str, limit: int = 40) -> str:
    """``text`` cut to ``limit`` characters (a quote left open takes in the rest of the file)."""
    return text if len(text) <= limit else text[:limit] + "..."


def _read_estimates(path: Path, text: str, n_frames: int) -> dict:
    import csv

    from sim.harness.methods import MAX_ESTIMATE, status_text
    from sim.harness.validation import FileValueError
    from stabilizer.motion import OK, Motion

    motions: dict[int, Motion] = {}
    # Decoded as utf-8-sig: spreadsheets and some shells (PowerShell, .NET) start UTF-8 with a
    # byte-order mark. newline="": the csv module reads the line endings itself.
    with io.StringIO(text, newline="") as handle:
        # skipinitialspace: writers that separate by ", " quote after the space (`, "ok"`).
        reader = csv.DictReader(handle, skipinitialspace=True)
        try:
            # Spreadsheets capitalise: "Status" is the status column, not another one.
            header = [name.strip().lower() if name.strip().lower() in KNOWN_COLUMNS
                      else name.strip() for name in (reader.fieldnames or ())]
        except csv.Error as error:
            raise FileValueError(f"{path}:1", "header", f"is not CSV ({error})",
                                 f"columns {', '.join(ESTIMATE_COLUMNS)} and optionally "
                                 f"status") from None
        missing = [name for name in ESTIMATE_COLUMNS if name not in header]
        if missing:
            # A spreadsheet of a decimal-comma locale separates by ";" (or a tab): the names are
            # all there, in one column.
            separator = next((mark for mark in (";", "\t") if len(header) == 1
                              and all(name in header[0].lower() for name in ESTIMATE_COLUMNS)
                              and mark in header[0]), None)
            problem = (f"separates its columns by {separator!r}" if separator else
                       f"lacks column(s) {', '.join(missing)}")
            raise FileValueError(f"{path}:1", "header", problem,
                                 f"columns {', '.join(ESTIMATE_COLUMNS)} and optionally status, "
                                 f"separated by commas")
        # Only the columns read: blank or other names a spreadsheet repeats are ignored.
        twice = sorted({name for name in header if name in KNOWN_COLUMNS
                        and header.count(name) > 1})
        if twice:
            raise FileValueError(f"{path}:1", "header", f"names column {twice[0]} twice",
                                 "each column once")
        reader.fieldnames = header
        frames = (f"an integer from 0 to {n_frames - 1}" if n_frames
                  else "no row: the sequence holds no frame")
        while True:
            try:
                cells = next(reader, None)
            except csv.Error as error:  # a field beyond the csv module's size limit, say
                # The line being read when the error came is not counted yet.
                raise FileValueError(f"{path}:{reader.line_num + 1}", "row",
                                     f"is not CSV ({error})",
                                     "rows of frame, angle_deg, dx, dy and optionally "
                                     "status") from None
            if cells is None:
                break
            if not any(value.strip() for value in cells.values() if isinstance(value, str)):
                continue  # a row of empty cells (`,,,,`), as spreadsheets export below the data
            # The line the row ends on: blank lines are skipped, a quoted field may span lines.
            where = f"{path}:{reader.line_num}"
            # Cells beyond the header's (csv puts them under None): a decimal comma shifts the
            # values; empty ones (a trailing comma) are harmless.
            if any(value.strip() for value in cells.get(None) or ()):
                raise FileValueError(where, "row", f"has {len(header) + len(cells[None])} "
                                     f"cells, the header {len(header)}",
                                     "one cell per column of the header (numbers take a "
                                     "decimal point: a decimal comma splits one in two)")

            def number(name: str) -> float:
                text = (cells.get(name) or "").strip()
                # Python's float() also reads "1_0" and non-ASCII digits: a typo, not a number
                # any other program writes.
                if not DECIMAL.fullmatch(text):
                    raise FileValueError(where, name, f"{_shortened(text)!r} is not a number",
                                         "a decimal number such as -1.5 or 2e-3")
                return float(text)

            text = (cells.get("frame") or "").strip()
            if not (text.isascii() and text.isdigit()):
                raise FileValueError(where, "frame",
                                     f"{_shortened(text)!r} is not a frame number", frames)
            digits = text.lstrip("0") or "0"
            # Longer than n_frames's digits is beyond it: int() refuses thousands of digits.
            frame = int(digits) if len(digits) <= len(str(n_frames)) else n_frames
            if frame >= n_frames:
                raise FileValueError(where, "frame",
                                     f"{_shortened(digits)} is not a frame of the sequence",
                                     frames)
            if frame in motions:
                raise FileValueError(where, "frame", f"{frame} appears a second time",
                                     "each frame at most once")
            status = (cells.get("status") or "").strip() or OK
            if status.lower() == OK:  # "OK" and "Ok" too: no failure status reads "ok"
                values = tuple(number(name) for name in ESTIMATE_COLUMNS[1:])
                for name, value in zip(ESTIMATE_COLUMNS[1:], values):
                    if not abs(value) <= MAX_ESTIMATE:  # NaN too
                        # As written: rounded, 1000000.1 would read as the bound itself.
                        raise FileValueError(
                            where, name, f"is {_shortened(cells[name].strip())}",
                            f"a finite number within +-{MAX_ESTIMATE:g} when the status is ok "
                            "(for no estimate, a failure status)")
                motions[frame] = Motion(*values)
            else:
                motions[frame] = Motion.failed(status_text(status))
    return motions


#: The longest name of an estimates file, bytes in UTF-8: the run folder's plot of it,
#: estimates_NAME.png, is named after it (sim.harness.report.estimates_plot_names), and file
#: names end at 255 bytes.
MAX_ESTIMATES_NAME = 100


def parse_estimates_argument(text: str) -> tuple[str, str]:
    """``NAME=FILE.csv`` or ``FILE.csv`` (named by its stem) -> (name, file). A file whose
    path holds "=" (``run=3/est.csv``) is taken whole when the part after the first "=" is no
    file and the whole is one."""
    name, separator, path = text.partition("=")
    if not separator or (not _is_file(path.strip()) and _is_file(text)):
        name, path = Path(text).stem, text
    name, path = name.strip(), path.strip()
    if not name or not path:
        raise ValueError(f"--estimates {text!r}: accepted: FILE.csv or NAME=FILE.csv")
    size = len(name.encode("utf-8", "replace"))
    problem = (f"is {size} bytes long" if size > MAX_ESTIMATES_NAME
               else "holds a character that does not print" if not name.isprintable()
               else None)
    if problem:
        raise ValueError(f"--estimates {_shortened(text)!r}: the name {_shortened(name)!r} "
                         f"{problem}; accepted: a NAME of printable characters, at most "
                         f"{MAX_ESTIMATES_NAME} bytes in UTF-8 (it names the method's rows in "
                         f"the tables and its plot; NAME=FILE.csv names a file other than by "
                         f"its stem)")
    return name, path


def _is_file(path: str) -> bool:
    """Whether ``path`` is a file; False also for one the system cannot look up (a name
    longer than it allows)."""
    try:
        return Path(path).is_file()
    except OSError:
        return False


def estimates_by_name(pairs: Sequence[tuple[str, str]] | None) -> dict[str, str]:
    """The ``--estimates`` arguments, (name, path) pairs, as name -> path; a ValueError when a
    name is given twice."""
    estimates: dict[str, str] = {}
    for name, path in pairs or ():
        if name in estimates:
            raise ValueError(f"--estimates: the name {name!r} given twice ({estimates[name]} "
                             f"and {path}); accepted: each NAME once (NAME=FILE.csv names a "
                             "file other than by its stem)")
        estimates[name] = path
    return estimates


# -- methods: in this process, or in worker processes -------------------------------------------

@contextmanager
def _method_estimations(sequence, n_frames: int, methods: tuple[str, ...], workers: int,
                        checked: bool, keep_images: bool) -> Iterator[tuple[dict, Any]]:
    """Each method's estimation (through the trust check if ``checked``) and the pool behind
    them (None): in this process, or in a pool of ``workers`` processes (whose estimates come
    back without their diagnostic images unless ``keep_images``: a recording shows them,
    nothing else reads them, and pickling them costs more than the estimates); the pool
    estimates the first ``n_frames`` frames."""
    from sim.harness.pipeline import PooledMethod
    from sim.harness.runner import MethodEstimation

    if workers == 1 or not methods or not n_frames:
        yield {method: MethodEstimation(method, checked) for method in methods}, None
        return
    pool = _EstimationPool(sequence, n_frames, methods, workers, checked, keep_images)
    try:
        yield {method: PooledMethod(pool, method) for method in methods}, pool
    finally:
        pool.close()


def reference_chunks(reference_frames: list[int], n_chunks: int) -> list[list[int]]:
    """Frame indices split into about ``n_chunks`` runs of consecutive frames, cut only where
    the reference changes (so a chunk analyses each of its references once)."""
    groups: list[list[int]] = []
    for index, reference in enumerate(reference_frames):
        if groups and reference_frames[groups[-1][0]] == reference:
            groups[-1].append(index)
        else:
            groups.append([index])
    target = max(1, math.ceil(len(reference_frames) / max(n_chunks, 1)))
    chunks: list[list[int]] = []
    for group in groups:
        if chunks and len(chunks[-1]) < target:
            chunks[-1].extend(group)
        else:
            chunks.append(list(group))
    return chunks


_WORKER_SEQUENCES: dict[str, Any] = {}
#: The key of a decoded frame and its ground truth among a worker's results (no method is
#: named "").
FRAME = ""


def _estimate_chunk(task: tuple[str, tuple[str, ...], list[int], bool, bool]):
    """In a worker: every method's estimates of a chunk of frames, each frame decoded (without
    its exact depth, which only the truth needs) with its ground truth (each frame read once),
    and the methods' analysis times."""
    from sim.harness.runner import MethodEstimation, frame_truth
    from sim.harness.sequence import load_sequence

    path, methods, indices, checked, keep_images = task
    if path not in _WORKER_SEQUENCES:
        _WORKER_SEQUENCES[path] = load_sequence(path)
    sequence = _WORKER_SEQUENCES[path]
    estimations = {method: MethodEstimation(method, checked) for method in methods}
    reference = None
    estimates = []
    for index in indices:
        reference_index = sequence.rows[index].reference_frame
        if reference is None or reference.index != reference_index:
            reference = sequence.frame(reference_index)
        frame = sequence.frame(index)
        estimates.append((FRAME, index, (dataclasses.replace(frame, true_depth_m=None),
                                         frame_truth(reference, frame, sequence.intrinsics))))
        for method, estimation in estimations.items():
            estimate = estimation.estimate(reference, frame)
            estimates.append((method, index,
                              estimate if keep_images else estimate.without_images()))
    return estimates, {method: e.analysis_ms for method, e in estimations.items()}


class _EstimationPool:
    """Spawn workers estimating chunks of frames with every method, and decoding them with
    their ground truth; results are taken in task order."""

    def __init__(self, sequence, n_frames: int, methods: tuple[str, ...], workers: int,
                 checked: bool, keep_images: bool):
        from sim.harness.threads import single_thread_pool

        chunks = reference_chunks([row.reference_frame for row in sequence.rows[:n_frames]],
                                  workers * CHUNKS_PER_WORKER)
        tasks = [(str(sequence.path), methods, chunk, checked, keep_images) for chunk in chunks]
        self.processes = single_thread_pool(min(workers, len(tasks)))
        self.results = self.processes.map(_estimate_chunk, tasks)
        self.ready: dict[tuple[str, int], Any] = {}
        self.analysis_ms: dict[str, list[float]] = {method: [] for method in methods}

    def estimate(self, method: str, reference, frame):
        return self._take(method, frame.index)

    def frame(self, index: int):
        """Frame ``index`` decoded without its exact depth, and its ground truth."""
        return self._take(FRAME, index)

    def _take(self, method: str, index: int):
        while (method, index) not in self.ready:
            estimates, analysis_ms = next(self.results)
            for done_method, times in analysis_ms.items():
                self.analysis_ms[done_method].extend(times)
            self.ready.update(((done_method, done_index), estimate)
                              for done_method, done_index, estimate in estimates)
        return self.ready.pop((method, index))

    def close(self) -> None:
        self.processes.terminate()
