"""Scores of stabilizers against the ground truth: per frame, per gait cycle, per run.

docs/design.md, "Scoring": for each method and each of rotation (deg), x (px) and y (px), the mean,
variance and maximum of the absolute error (the paper's Table I reports mean and variance of
the errors "for one cycle"); the failure rate (frames with no estimate); time per frame; and the
inter-frame transformation fidelity (ITF), the mean PSNR between consecutive compensated frames,
beside the raw stream's ITF. Beside the per-axis errors, the end-point error (EPE): the mean
distance (px) between where the estimate sends each sampled reference pixel and where that pixel
truly went, with the ground truth's own EPE as the floor no 2-D rigid estimate gets far below
(``sim.harness.ground_truth``).

Frames whose ground truth failed are excluded from the error statistics and counted apart.
Variances are population variances (ddof = 0) of the absolute errors.
"""

from __future__ import annotations

import dataclasses
import math
from collections import Counter, defaultdict
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from typing import Any

import cv2
import numpy as np

from sim.harness.ground_truth import GroundTruth
from sim.harness.methods import DROPPED_KEY, RECORDING_KEYS, plain_diagnostics
from stabilizer.motion import OK, Motion, wrap_angle_deg

#: The three displacements of Table I and their units.
AXES = ("rotation", "x", "y")
AXIS_UNITS = {"rotation": "deg", "x": "px", "y": "px"}
#: Name of the uncompensated stream in the ITF accumulator.
RAW_STREAM = "raw"
#: An "ok" estimate off the truth by more than this rotation (deg) or shift along an axis (px)
#: is a large error: an "ok" that should not have been trusted (the limit of issue 15).
LARGE_ERROR_DEG, LARGE_ERROR_PX = 5.0, 10.0


def absolute_errors(estimate: Motion, truth: Motion) -> tuple[float, float, float]:
    """|estimate - truth| along each of :data:`AXES`: the rotation's the short way round, in
    [0, 180] degrees (a turn of 359.5 degrees is one of -0.5), x and y in pixels."""
    return (abs(float(wrap_angle_deg(estimate.angle_deg - truth.angle_deg))),
            abs(estimate.dx - truth.dx), abs(estimate.dy - truth.dy))


@dataclass(frozen=True)
class FrameRecord:
    """One (frame, method) result: estimate, truth, absolute errors, status and time.

    Errors are NaN unless both the estimate and the ground truth succeeded. The rotation error
    is wrapped into (-180, 180] before its absolute value is taken. The end-point errors (the
    fields after ``err_dy_px``, last so that frames.csv keeps its older columns in place):
    ``epe_px`` and ``epe_rms_px`` are the mean and RMS EPE of the estimate, ``truth_epe_px``
    the mean EPE of the truth's rigid fit (its RMS is ``truth_residual_px``); NaN also when the
    truth carries no correspondences.
    """

    frame_index: int
    time_s: float
    gait_cycle: int
    reference_index: int
    method: str
    status: str
    ms: float
    est_angle_deg: float
    est_dx_px: float
    est_dy_px: float
    true_angle_deg: float
    true_dx_px: float
    true_dy_px: float
    truth_status: str
    truth_residual_px: float
    truth_points: int
    err_angle_deg: float
    err_dx_px: float
    err_dy_px: float
    epe_px: float = math.nan
    epe_rms_px: float = math.nan
    truth_epe_px: float = math.nan

    @classmethod
    def score(cls, *, frame_index: int, time_s: float, gait_cycle: int, reference_index: int,
              method: str, estimate: Motion, truth: GroundTruth, ms: float) -> "FrameRecord":
        """Compare ``estimate`` with ``truth`` for one frame and method."""
        errors = (absolute_errors(estimate, truth.motion) if estimate.ok and truth.ok
                  else (math.nan,) * 3)
        epe_px, epe_rms_px = truth.end_point_error(estimate)
        return cls(int(frame_index), float(time_s), int(gait_cycle), int(reference_index),
                   str(method), estimate.status, float(ms),
                   *(float(value) for value in estimate.as_tuple()),
                   *(float(value) for value in truth.motion.as_tuple()),
                   truth.motion.status, float(truth.residual_rms_px), int(truth.n_points),
                   *(float(value) for value in errors), epe_px, epe_rms_px,
                   float(truth.residual_mean_px) if truth.ok else math.nan)

    @property
    def scored(self) -> bool:
        """True when both the estimate and the truth exist, so the errors are numbers."""
        return self.status == OK and self.truth_status == OK

    @property
    def large_error(self) -> bool:
        """True when the estimate is scored and off by more than ``LARGE_ERROR_DEG`` in
        rotation or ``LARGE_ERROR_PX`` along x or y."""
        return self.scored and (self.err_angle_deg > LARGE_ERROR_DEG
                                or max(self.err_dx_px, self.err_dy_px) > LARGE_ERROR_PX)

    def estimate_of(self, axis: str) -> float:
        return getattr(self, _ESTIMATE_FIELDS[axis])

    def truth_of(self, axis: str) -> float:
        return getattr(self, _TRUTH_FIELDS[axis])

    def error_of(self, axis: str) -> float:
        return getattr(self, _ERROR_FIELDS[axis])

    @property
    def epe_scored(self) -> bool:
        """True when the end-point error is a number (scored, and the truth had points)."""
        return not math.isnan(self.epe_px)


_ESTIMATE_FIELDS = dict(zip(AXES, ("est_angle_deg", "est_dx_px", "est_dy_px")))
_TRUTH_FIELDS = dict(zip(AXES, ("true_angle_deg", "true_dx_px", "true_dy_px")))
_ERROR_FIELDS = dict(zip(AXES, ("err_angle_deg", "err_dx_px", "err_dy_px")))
#: Column order of frames.csv.
RECORD_FIELDS = tuple(f.name for f in dataclasses.fields(FrameRecord))


def failure_entry(*, frame_index: int, method: str, estimate: Motion) -> dict:
    """A failed estimate as failures.jsonl keeps it: the frame, the method, the status and the
    estimate's diagnostics that are plain data (``sim.harness.methods.plain_diagnostics``: a
    plugin's exception message, the motion the trust check rejected); the images and drawings
    only the recording shows are left out."""
    shown = {key: value for key, value in estimate.diagnostics.items()
             if key not in (*RECORDING_KEYS, DROPPED_KEY) and not isinstance(value, np.ndarray)}
    diagnostics = plain_diagnostics(shown)
    # A plugin's diagnostics were made plain already; the names left out then stay named.
    dropped = [*estimate.diagnostics.get(DROPPED_KEY, ()), *diagnostics.pop(DROPPED_KEY, ())]
    if dropped:
        diagnostics[DROPPED_KEY] = dropped
    return {"frame_index": int(frame_index), "method": str(method), "status": estimate.status,
            "diagnostics": diagnostics}


def _float(value: float | None) -> float:
    """A float from JSON, where NaN was written as null."""
    return math.nan if value is None else float(value)


@dataclass(frozen=True)
class ErrorStats:
    """Mean, population variance and maximum of absolute errors over ``n`` scored frames."""

    mean: float
    variance: float
    max: float
    n: int

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> "ErrorStats":
        return cls(_float(data["mean"]), _float(data["variance"]), _float(data["max"]),
                   int(data["n"]))

    @classmethod
    def of(cls, errors: Iterable[float]) -> "ErrorStats":
        values = np.asarray(list(errors), dtype=np.float64)
        if values.size == 0:
            return cls(math.nan, math.nan, math.nan, 0)
        with np.errstate(over="ignore"):  # errors beyond 1e154 have no finite variance
            variance = float(values.var())
        return cls(float(values.mean()), variance, float(values.max()), values.size)


#: The statistics of no frames (a score read from a metrics.json older than the figure).
NO_ERRORS = ErrorStats(math.nan, math.nan, math.nan, 0)


@dataclass(frozen=True)
class LargeError:
    """An "ok" estimate off by more than the large-error limits (``FrameRecord.large_error``):
    its frame and its absolute errors in rotation (deg), x and y (px)."""

    frame: int
    rotation_deg: float
    x_px: float
    y_px: float

    @classmethod
    def of(cls, record: FrameRecord) -> "LargeError":
        return cls(record.frame_index, record.err_angle_deg, record.err_dx_px, record.err_dy_px)


@dataclass(frozen=True)
class MethodScore:
    """Aggregate scores of one method over a set of frames (a gait cycle or a whole run).

    Attributes:
        n_frames: frames the method was run on.
        n_failed: frames with no estimate (status other than "ok").
        n_truth_failed: frames whose ground truth failed (excluded from the errors).
        n_scored: frames with both an estimate and a truth.
        failure_rate: ``n_failed / n_frames``.
        errors: axis -> ErrorStats of the absolute errors.
        ms_mean, ms_median: estimation time per frame, milliseconds.
        itf_db, itf_raw_db: mean PSNR of consecutive compensated / raw frames (NaN if unknown).
        failures: status -> count of the failed frames.
        epe: ErrorStats of the per-frame mean end-point error (``FrameRecord.epe_px``) over
            the frames that have one.
        epe_floor_px: mean of the truth's own mean end-point error over the same frames.
        n_large_errors: scored frames whose "ok" estimate is off by more than
            ``LARGE_ERROR_DEG`` or ``LARGE_ERROR_PX`` (``FrameRecord.large_error``); None in
            a metrics.json written before it was counted.
        large_errors: those estimates (:class:`LargeError`), in frame order; empty in a
            metrics.json written before they were listed.
    """

    method: str
    n_frames: int
    n_failed: int
    n_truth_failed: int
    n_scored: int
    failure_rate: float
    errors: dict[str, ErrorStats]
    ms_mean: float
    ms_median: float
    itf_db: float = math.nan
    itf_raw_db: float = math.nan
    failures: dict[str, int] = field(default_factory=dict)
    epe: ErrorStats = NO_ERRORS
    epe_floor_px: float = math.nan
    n_large_errors: int | None = None
    large_errors: tuple[LargeError, ...] = ()

    @property
    def epe_above_floor_px(self) -> float:
        """Mean EPE above the truth's own: what the estimates add to the unavoidable part."""
        return self.epe.mean - self.epe_floor_px

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> "MethodScore":
        """Inverse of ``dataclasses.asdict`` after a JSON round trip (None -> NaN).

        A metrics.json written before the end-point error was scored loads with NaN EPE, one
        written before large errors were counted with ``n_large_errors`` None, and one written
        before they were listed with no ``large_errors``.
        """
        values = dict(data)
        values["errors"] = {axis: ErrorStats.from_dict(values["errors"][axis]) for axis in AXES}
        for name in ("failure_rate", "ms_mean", "ms_median", "itf_db", "itf_raw_db"):
            values[name] = _float(values[name])
        values["epe"] = ErrorStats.from_dict(values["epe"]) if "epe" in values else NO_ERRORS
        values["epe_floor_px"] = _float(values.get("epe_floor_px"))
        values["large_errors"] = tuple(LargeError(**entry)
                                       for entry in values.get("large_errors", ()))
        return cls(**values)

    @classmethod
    def of(cls, method: str, records: list[FrameRecord], itf_db: float = math.nan,
           itf_raw_db: float = math.nan) -> "MethodScore":
        scored = [record for record in records if record.scored]
        with_epe = [record for record in records if record.epe_scored]
        failed = Counter(record.status for record in records if record.status != OK)
        times = np.asarray([record.ms for record in records], dtype=np.float64)
        return cls(
            method=method, n_frames=len(records), n_failed=sum(failed.values()),
            n_truth_failed=sum(record.truth_status != OK for record in records),
            n_scored=len(scored),
            failure_rate=sum(failed.values()) / len(records) if records else math.nan,
            errors={axis: ErrorStats.of(r.error_of(axis) for r in scored) for axis in AXES},
            ms_mean=float(times.mean()) if times.size else math.nan,
            ms_median=float(np.median(times)) if times.size else math.nan,
            itf_db=itf_db, itf_raw_db=itf_raw_db, failures=dict(sorted(failed.items())),
            epe=ErrorStats.of(record.epe_px for record in with_epe),
            epe_floor_px=(float(np.mean([record.truth_epe_px for record in with_epe]))
                          if with_epe else math.nan),
            n_large_errors=sum(record.large_error for record in scored),
            large_errors=tuple(LargeError.of(record) for record in
                               sorted((record for record in scored if record.large_error),
                                      key=lambda record: record.frame_index)),
        )


@dataclass(frozen=True)
class TruthResidual:
    """The ground truth's own residual over the frames that have one: the median and the
    maximum of the RMS distance (px) between its rigid fit and its points
    (``FrameRecord.truth_residual_px``), over ``n`` frames. No 2-D rigid estimate removes it."""

    median_px: float
    max_px: float
    n: int

    @classmethod
    def of(cls, records: Iterable[FrameRecord]) -> "TruthResidual":
        """Over the distinct frames of ``records`` whose truth succeeded."""
        by_frame = {record.frame_index: record.truth_residual_px for record in records
                    if record.truth_status == OK and math.isfinite(record.truth_residual_px)}
        values = np.asarray(list(by_frame.values()), dtype=np.float64)
        if values.size == 0:
            return cls(math.nan, math.nan, 0)
        return cls(float(np.median(values)), float(values.max()), values.size)

    @classmethod
    def from_dict(cls, data: Mapping[str, Any] | None) -> "TruthResidual":
        """Inverse of ``dataclasses.asdict`` after a JSON round trip; no frames for None (a
        metrics.json written before the residual was summarised)."""
        if data is None:
            return NO_TRUTH_RESIDUAL
        return cls(_float(data["median_px"]), _float(data["max_px"]), int(data["n"]))


#: The residual of no frames.
NO_TRUTH_RESIDUAL = TruthResidual(math.nan, math.nan, 0)


@dataclass(frozen=True)
class RunSummary:
    """Scores of every method over the whole run and over each gait cycle.

    Attributes:
        methods: method names in the order they first appear in the records.
        run: method -> MethodScore over all frames.
        cycles: gait cycle -> method -> MethodScore over that cycle's frames.
        n_frames: number of distinct frames scored.
        truth_residual: the ground truth's own residual over those frames.
    """

    methods: tuple[str, ...]
    run: dict[str, MethodScore]
    cycles: dict[int, dict[str, MethodScore]]
    n_frames: int
    truth_residual: TruthResidual = NO_TRUTH_RESIDUAL

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> "RunSummary":
        """Inverse of ``to_dict``, also after a JSON round trip (metrics.json's "summary")."""
        return cls(tuple(data["methods"]),
                   {m: MethodScore.from_dict(s) for m, s in data["run"].items()},
                   {int(cycle): {m: MethodScore.from_dict(s) for m, s in scores.items()}
                    for cycle, scores in data["cycles"].items()},
                   int(data["n_frames"]), TruthResidual.from_dict(data.get("truth_residual")))

    def to_dict(self) -> dict:
        """Plain nested dicts and lists (NaN kept as float NaN), ready for JSON."""
        return {"methods": list(self.methods), "n_frames": self.n_frames,
                "truth_residual": dataclasses.asdict(self.truth_residual),
                "run": {m: dataclasses.asdict(s) for m, s in self.run.items()},
                "cycles": {str(cycle): {m: dataclasses.asdict(s) for m, s in scores.items()}
                           for cycle, scores in self.cycles.items()}}


def summarize(records: Iterable[FrameRecord], itf: "ItfAccumulator | None" = None) -> RunSummary:
    """Aggregate per-frame records per run and per gait cycle, for every method."""
    records = list(records)
    by_method: dict[str, list[FrameRecord]] = defaultdict(list)
    by_cycle: dict[int, dict[str, list[FrameRecord]]] = defaultdict(lambda: defaultdict(list))
    for record in records:
        by_method[record.method].append(record)
        by_cycle[record.gait_cycle][record.method].append(record)

    def itf_of(stream: str, cycle: int | None) -> float:
        return itf.mean_db(stream, cycle) if itf is not None else math.nan

    run = {method: MethodScore.of(method, group, itf_of(method, None), itf_of(RAW_STREAM, None))
           for method, group in by_method.items()}
    cycles = {cycle: {method: MethodScore.of(method, group, itf_of(method, cycle),
                                             itf_of(RAW_STREAM, cycle))
                      for method, group in groups.items()}
              for cycle, groups in sorted(by_cycle.items())}
    return RunSummary(tuple(by_method), run, cycles,
                      len({record.frame_index for record in records}),
                      TruthResidual.of(records))


def masked_psnr_db(first: np.ndarray, second: np.ndarray, peak: float = 255.0,
                   cap_db: float = 100.0) -> float:
    """PSNR (dB) of two images on the pixels valid (non-zero) in both; NaN if none are.

    Identical images have an infinite PSNR; it is capped at ``cap_db`` so means stay finite.
    """
    if first.shape != second.shape or first.dtype != second.dtype:
        raise ValueError(f"images must have the same shape and dtype; got {first.shape} "
                         f"{first.dtype} and {second.shape} {second.dtype}")
    both = ((first != 0) & (second != 0)).view(np.uint8)
    count = cv2.countNonZero(both)
    if count == 0:
        return math.nan
    mse = cv2.norm(first, second, cv2.NORM_L2SQR, mask=both) / count
    if mse == 0.0:
        return cap_db
    return min(cap_db, 10.0 * math.log10(peak * peak / mse))


class ItfAccumulator:
    """Incremental inter-frame transformation fidelity: mean PSNR of consecutive frames.

    Feed each stream (a method's output frames: compensated, or as measured where it failed;
    and the raw frames as ``RAW_STREAM``) one frame at a time in frame order. A pair counts
    only when both frames belong to the same reference frame: across a reference change the
    two frames are aligned to different images by design (so with the previous-frame
    reference policy only the first pair counts, frame 0 being its own reference and frame
    1's). A pair belongs to the gait cycle of its second frame.

    Args:
        peak: largest pixel value (255 for the uint8 disparity-like images).
        cap_db: PSNR given to identical pairs (their PSNR is infinite).
    """

    def __init__(self, peak: float = 255.0, cap_db: float = 100.0):
        if peak <= 0 or cap_db <= 0:
            raise ValueError(f"peak and cap_db must be positive; got {peak} and {cap_db}")
        self.peak = peak
        self.cap_db = cap_db
        self._previous: dict[str, tuple[int, np.ndarray]] = {}
        self._pairs: dict[str, list[tuple[int, float]]] = defaultdict(list)

    def add(self, stream: str, image: np.ndarray, *, gait_cycle: int,
            reference_index: int) -> float:
        """Add the next frame of ``stream``; returns the PSNR of the pair it closes (or NaN)."""
        image = np.asarray(image)
        if image.ndim != 2:
            raise ValueError(f"ITF frames must be 2-D images; got shape {image.shape}")
        previous = self._previous.get(stream)
        self._previous[stream] = (reference_index, image.copy())
        if previous is None or previous[0] != reference_index:
            return math.nan
        psnr = masked_psnr_db(previous[1], image, self.peak, self.cap_db)
        if not math.isnan(psnr):
            self._pairs[stream].append((int(gait_cycle), psnr))
        return psnr

    def mean_db(self, stream: str, gait_cycle: int | None = None) -> float:
        """Mean PSNR of the stream's pairs (of one gait cycle, or all); NaN if it has none."""
        values = [psnr for cycle, psnr in self._pairs.get(stream, ())
                  if gait_cycle is None or cycle == gait_cycle]
        return float(np.mean(values)) if values else math.nan

    def n_pairs(self, stream: str) -> int:
        return len(self._pairs.get(stream, ()))

    def streams(self) -> tuple[str, ...]:
        return tuple(self._previous)
