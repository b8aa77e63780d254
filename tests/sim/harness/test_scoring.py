"""Per-frame records, per-cycle/per-run aggregates and the ITF accumulator (docs/design.md, Scoring)."""

import dataclasses
import json
import math

import numpy as np
import pytest

from sim.harness.ground_truth import GroundTruth
from sim.harness.scoring import (AXES, LARGE_ERROR_DEG, LARGE_ERROR_PX, RAW_STREAM,
                                 RECORD_FIELDS, ErrorStats, FrameRecord, ItfAccumulator,
                                 MethodScore, RunSummary, TruthResidual, masked_psnr_db,
                                 summarize)
from stabilizer.motion import Motion, apply_motion, compensate


def _truth(angle=0.0, dx=0.0, dy=0.0) -> GroundTruth:
    return GroundTruth(Motion(angle, dx, dy), 0.5, 1000)


NO_TRUTH = GroundTruth(Motion.failed("no_overlap"), math.nan, 3)


def _record(frame, method, estimate, truth, cycle=0, ms=2.0):
    return FrameRecord.score(frame_index=frame, time_s=frame / 30, gait_cycle=cycle,
                             reference_index=0, method=method, estimate=estimate, truth=truth,
                             ms=ms)


def test_record_holds_estimate_truth_and_absolute_errors():
    record = _record(4, "t2fuzzy", Motion(1.5, -2.0, 3.0), _truth(2.0, 1.0, 3.5))
    assert (record.est_angle_deg, record.est_dx_px, record.est_dy_px) == (1.5, -2.0, 3.0)
    assert (record.true_angle_deg, record.true_dx_px, record.true_dy_px) == (2.0, 1.0, 3.5)
    assert (record.err_angle_deg, record.err_dx_px, record.err_dy_px) == (0.5, 3.0, 0.5)
    assert record.scored and record.truth_residual_px == 0.5 and record.truth_points == 1000
    assert [record.error_of(axis) for axis in AXES] == [0.5, 3.0, 0.5]
    assert record.frame_index == 4 and record.time_s == pytest.approx(4 / 30)
    assert set(RECORD_FIELDS) >= {"frame_index", "gait_cycle", "reference_index", "method",
                                  "status", "ms", "truth_residual_px"}


def test_rotation_error_wraps_around():
    record = _record(0, "m", Motion(179.0, 0, 0), _truth(-179.0))
    assert record.err_angle_deg == pytest.approx(2.0)


@pytest.mark.parametrize("estimate, truth", [
    (Motion.failed("no_structure"), _truth()),
    (Motion(1.0, 1.0, 1.0), NO_TRUTH),
])
def test_missing_estimate_or_truth_gives_nan_errors(estimate, truth):
    record = _record(0, "m", estimate, truth)
    assert not record.scored
    assert all(math.isnan(record.error_of(axis)) for axis in AXES)


def test_error_stats_are_mean_population_variance_and_max():
    stats = ErrorStats.of([1.0, 2.0, 3.0, 6.0])
    assert (stats.mean, stats.variance, stats.max, stats.n) == (3.0, 3.5, 6.0, 4)
    empty = ErrorStats.of([])
    assert empty.n == 0 and math.isnan(empty.mean) and math.isnan(empty.max)


def test_summary_per_run_and_per_cycle():
    records = [
        _record(0, "a", Motion(1.0, 0.0, 0.0), _truth(), cycle=0, ms=1.0),
        _record(1, "a", Motion(3.0, 2.0, 0.0), _truth(), cycle=0, ms=3.0),
        _record(2, "a", Motion.failed("no_structure"), _truth(), cycle=1, ms=5.0),
        _record(3, "a", Motion(0.0, 0.0, 4.0), NO_TRUTH, cycle=1, ms=2.0),
        _record(0, "b", Motion(0.5, 0.0, 0.0), _truth(), cycle=0, ms=10.0),
    ]
    summary = summarize(records)
    assert summary.methods == ("a", "b") and summary.n_frames == 4
    a = summary.run["a"]
    assert (a.n_frames, a.n_failed, a.n_truth_failed, a.n_scored) == (4, 1, 1, 2)
    assert a.failure_rate == 0.25 and a.failures == {"no_structure": 1}
    assert (a.errors["rotation"].mean, a.errors["rotation"].variance) == (2.0, 1.0)
    assert a.errors["x"].max == 2.0 and a.errors["y"].n == 2
    assert (a.ms_mean, a.ms_median) == (2.75, 2.5)
    assert sorted(summary.cycles) == [0, 1]
    assert summary.cycles[0]["a"].n_scored == 2 and "b" not in summary.cycles[1]
    assert summary.cycles[1]["a"].n_scored == 0
    assert math.isnan(summary.cycles[1]["a"].errors["x"].mean)
    assert math.isnan(a.itf_db)
    assert summary.to_dict()["run"]["a"]["errors"]["rotation"]["mean"] == 2.0


def test_masked_psnr_uses_pixels_valid_in_both():
    first = np.array([[10, 20], [0, 40]], np.uint8)
    second = np.array([[12, 0], [30, 40]], np.uint8)
    # Valid in both: (0, 0) differs by 2, (1, 1) equal -> MSE 2.
    assert masked_psnr_db(first, second) == pytest.approx(10 * math.log10(255 ** 2 / 2.0))
    assert masked_psnr_db(first, first) == 100.0
    assert math.isnan(masked_psnr_db(first, np.zeros_like(first)))


@pytest.mark.parametrize("peak, cap_db", [(0.0, 100.0), (255.0, 0.0), (-1.0, 100.0)])
def test_itf_needs_a_positive_peak_and_cap(peak, cap_db):
    with pytest.raises(ValueError, match="peak and cap_db must be positive"):
        ItfAccumulator(peak=peak, cap_db=cap_db)


def test_itf_is_higher_for_a_well_compensated_stream():
    rng = np.random.default_rng(1)
    reference = np.zeros((144, 176), np.uint8)
    reference[30:110, 40:140] = rng.integers(1, 256, (80, 100), dtype=np.uint8)
    itf = ItfAccumulator()
    for index, shift in enumerate([0.0, 3.0, -4.0, 5.0]):
        motion = Motion(2.0 * shift, shift, -shift)
        current = apply_motion(reference, motion)
        itf.add(RAW_STREAM, current, gait_cycle=0, reference_index=0)
        itf.add("perfect", compensate(current, motion), gait_cycle=0, reference_index=0)
    assert itf.n_pairs(RAW_STREAM) == 3 and itf.n_pairs("perfect") == 3
    assert itf.mean_db("perfect") > itf.mean_db(RAW_STREAM) + 10
    assert itf.streams() == (RAW_STREAM, "perfect")


def test_itf_skips_pairs_across_a_reference_change_and_groups_by_cycle():
    itf = ItfAccumulator()
    image = np.full((8, 8), 100, np.uint8)
    noisy = image.copy()
    noisy[0, 0] = 110
    assert math.isnan(itf.add("m", image, gait_cycle=0, reference_index=0))
    assert itf.add("m", image, gait_cycle=0, reference_index=0) == 100.0
    assert math.isnan(itf.add("m", image, gait_cycle=1, reference_index=2))  # new reference
    psnr = itf.add("m", noisy, gait_cycle=1, reference_index=2)
    assert psnr == pytest.approx(10 * math.log10(255 ** 2 / (100 / 64)))
    assert itf.n_pairs("m") == 2
    assert itf.mean_db("m", 0) == 100.0 and itf.mean_db("m", 1) == pytest.approx(psnr)
    assert math.isnan(itf.mean_db("m", 5)) and math.isnan(itf.mean_db("unknown"))


def test_summary_carries_itf_of_each_method_and_raw():
    itf = ItfAccumulator()
    image = np.full((8, 8), 100, np.uint8)
    for _ in range(2):
        itf.add("a", image, gait_cycle=0, reference_index=0)
        itf.add(RAW_STREAM, image, gait_cycle=0, reference_index=0)
    summary = summarize([_record(0, "a", Motion(0, 0, 0), _truth())], itf)
    assert summary.run["a"].itf_db == 100.0 and summary.run["a"].itf_raw_db == 100.0
    assert summary.cycles[0]["a"].itf_db == 100.0


def test_bad_itf_input_is_rejected():
    with pytest.raises(ValueError, match="2-D"):
        ItfAccumulator().add("m", np.zeros(5), gait_cycle=0, reference_index=0)
    with pytest.raises(ValueError, match="same shape and dtype"):
        masked_psnr_db(np.zeros((2, 2)), np.zeros((3, 3)))


def test_scoring_ray_cast_frames_with_the_truth_as_estimate():
    """The runner's loop in miniature: truth, record, ITF of compensated and raw frames."""
    from sim.harness.ground_truth import ground_truth
    from tests.sim.harness.scene_frames import box_world, camera_matrix, render_frame

    world = box_world()
    frames = [render_frame(world, [0.0, 0.0, 0.0], camera_matrix(roll_deg=2.0 * i,
                                                                 yaw_deg=0.5 * i), i, i / 30)
              for i in range(6)]
    itf = ItfAccumulator()
    records = []
    for frame in frames:
        truth = ground_truth(frames[0], frame)
        records.append(FrameRecord.score(frame_index=frame.index, time_s=frame.time_s,
                                         gait_cycle=0, reference_index=0, method="oracle",
                                         estimate=truth.motion, truth=truth, ms=0.0))
        itf.add(RAW_STREAM, frame.disparity8, gait_cycle=0, reference_index=0)
        itf.add("oracle", compensate(frame.disparity8, truth.motion), gait_cycle=0,
                reference_index=0)
    score = summarize(records, itf).run["oracle"]
    assert score.n_scored == 6 and score.failure_rate == 0.0
    assert all(score.errors[axis].max == 0.0 for axis in AXES)
    assert score.itf_db > score.itf_raw_db + 3
    # The truth as estimate sits exactly on the floor: its EPE is the fit's own.
    for record in records:
        assert record.epe_px == pytest.approx(record.truth_epe_px, rel=1e-4, abs=1e-5)
        assert record.epe_rms_px == pytest.approx(record.truth_residual_px, rel=1e-4, abs=1e-5)
    assert score.epe.n == 6 and score.epe.mean > 0.0
    assert score.epe_above_floor_px == pytest.approx(0.0, abs=1e-4)


# --------------------------------------------------------------------------- end-point error
SHAPE = (144, 176)
GRID = np.stack([c.ravel() for c in np.mgrid[0:176:4, 0:144:4]], axis=1)


def _exact_truth(angle=0.0, dx=0.0, dy=0.0, floor_px=0.0) -> GroundTruth:
    """An exact truth with points; ``floor_px`` pretends a fit residual (mean and RMS)."""
    truth = GroundTruth.exact(Motion(angle, dx, dy), GRID, SHAPE)
    return dataclasses.replace(truth, residual_rms_px=floor_px, residual_mean_px=floor_px)


def test_record_holds_the_end_point_errors_of_the_estimate_and_of_the_truth():
    record = _record(0, "m", Motion(2.0, 4.0, -1.0), _exact_truth(2.0, 1.0, 3.0, floor_px=0.7))
    assert record.epe_px == pytest.approx(5.0, abs=1e-4)  # a (3, -4) offset
    assert record.epe_rms_px == pytest.approx(5.0, abs=1e-4)
    assert record.truth_epe_px == 0.7 and record.truth_residual_px == 0.7
    # Records keep numbers only, never the truth's points.
    assert not any(isinstance(value, np.ndarray) for value in dataclasses.asdict(record).values())
    assert RECORD_FIELDS[-3:] == ("epe_px", "epe_rms_px", "truth_epe_px")


@pytest.mark.parametrize("estimate, truth", [
    (Motion.failed("no_structure"), _exact_truth()),
    (Motion(1.0, 1.0, 1.0), NO_TRUTH),
    (Motion(1.0, 1.0, 1.0), _truth()),  # a truth without correspondences
])
def test_end_point_error_is_nan_without_estimate_truth_or_points(estimate, truth):
    record = _record(0, "m", estimate, truth)
    assert math.isnan(record.epe_px) and math.isnan(record.epe_rms_px)
    assert not record.epe_scored


def test_summary_has_epe_statistics_and_the_floor_over_the_same_frames():
    records = [
        _record(0, "a", Motion(0.0, 3.0, 4.0), _exact_truth(floor_px=1.0), cycle=0),
        _record(1, "a", Motion(0.0, 1.0, 0.0), _exact_truth(floor_px=0.5), cycle=0),
        # Left out of EPE and floor alike: no estimate; no truth.
        _record(2, "a", Motion.failed("no_structure"), _exact_truth(floor_px=9.0), cycle=1),
        _record(3, "a", Motion(0.0, 0.0, 0.0), NO_TRUTH, cycle=1),
    ]
    summary = summarize(records)
    score = summary.run["a"]
    assert score.epe.n == 2 and score.epe.mean == pytest.approx(3.0, abs=1e-4)
    assert score.epe.max == pytest.approx(5.0, abs=1e-4)
    assert score.epe.variance == pytest.approx(4.0, abs=1e-3)
    assert score.epe_floor_px == 0.75
    assert score.epe_above_floor_px == pytest.approx(2.25, abs=1e-4)
    assert summary.cycles[1]["a"].epe.n == 0 and math.isnan(summary.cycles[1]["a"].epe_floor_px)
    restored = MethodScore.from_dict(json.loads(json.dumps(summary.to_dict()["run"]["a"])))
    assert restored.epe == score.epe and restored.epe_floor_px == score.epe_floor_px


def test_a_score_written_before_the_end_point_error_loads_with_nan_epe():
    data = summarize([_record(0, "a", Motion(1.0, 0.0, 0.0), _truth())]).to_dict()["run"]["a"]
    del data["epe"], data["epe_floor_px"]
    score = MethodScore.from_dict(data)
    assert score.epe.n == 0 and math.isnan(score.epe.mean) and math.isnan(score.epe_floor_px)
    assert score.errors["rotation"].mean == 1.0


def test_ok_estimates_beyond_the_large_error_limits_are_counted_per_method():
    just = 1e-6
    records = [
        _record(0, "a", Motion(LARGE_ERROR_DEG + just, 0.0, 0.0), _truth()),
        _record(1, "a", Motion(LARGE_ERROR_DEG - just, LARGE_ERROR_PX - just,
                               -(LARGE_ERROR_PX - just)), _truth()),
        _record(2, "a", Motion(0.0, 0.0, 0.0), _truth(dy=LARGE_ERROR_PX + 1.0)),
        _record(3, "a", Motion(-170.0, 0.0, 0.0), _truth(angle=175.0)),  # 15 deg, wrapped
        _record(4, "a", Motion(40.0, 0.0, 0.0), NO_TRUTH),  # not scored: no truth
        _record(5, "a", Motion.failed("no_structure"), _truth()),
        _record(0, "b", Motion(0.0, 0.0, 0.0), _truth()),
    ]
    assert [record.large_error for record in records] == [True, False, True, True, False, False,
                                                          False]
    summary = summarize(records)
    assert summary.run["a"].n_large_errors == 3 and summary.run["b"].n_large_errors == 0
    assert summary.to_dict()["run"]["a"]["n_large_errors"] == 3
    # Each is listed with its frame and absolute errors, in frame order.
    assert [(e.frame, round(e.rotation_deg, 6), e.x_px, e.y_px)
            for e in summary.run["a"].large_errors] == [
        (0, round(LARGE_ERROR_DEG + just, 6), 0.0, 0.0), (2, 0.0, 0.0, LARGE_ERROR_PX + 1.0),
        (3, 15.0, 0.0, 0.0)]
    assert summary.run["b"].large_errors == ()
    restored = RunSummary.from_dict(json.loads(json.dumps(summary.to_dict())))
    assert restored.run["a"].large_errors == summary.run["a"].large_errors


def test_the_large_error_limits_are_issue_15s_and_an_error_right_at_them_is_not_beyond():
    # "No ok frame off by more than 5 deg or 10 px": the README and docs quote these figures.
    assert (LARGE_ERROR_DEG, LARGE_ERROR_PX) == (5.0, 10.0)
    at_limits = [_record(0, "a", Motion(5.0, 0.0, 0.0), _truth()),
                 _record(1, "a", Motion(0.0, 10.0, -10.0), _truth()),
                 _record(2, "a", Motion(0.0, 0.0, 0.0), _truth(dx=10.5))]
    assert [record.large_error for record in at_limits] == [False, False, True]


def test_a_score_written_before_large_errors_were_counted_loads_without_a_count():
    data = summarize([_record(0, "a", Motion(9.0, 0.0, 0.0), _truth())]).to_dict()["run"]["a"]
    assert MethodScore.from_dict(json.loads(json.dumps(data))).n_large_errors == 1
    del data["n_large_errors"], data["large_errors"]
    older = MethodScore.from_dict(data)
    assert older.n_large_errors is None and older.large_errors == ()


def test_the_truths_own_residual_is_summarised_over_distinct_frames_with_a_truth():
    def truth(residual):
        return GroundTruth(Motion(0.0, 0.0, 0.0), residual, 1000)

    records = [_record(frame, method, Motion(0.0, 0.0, 0.0), truth(residual))
               for frame, residual in enumerate((0.5, 1.0, 4.0, 2.0)) for method in "ab"]
    records.append(_record(4, "a", Motion(0.0, 0.0, 0.0), NO_TRUTH))  # no truth: left out
    summary = summarize(records)
    # Four frames (each once, not once per method): median 1.5, largest 4.
    assert summary.truth_residual == TruthResidual(1.5, 4.0, 4)
    restored = RunSummary.from_dict(json.loads(json.dumps(summary.to_dict())))
    assert restored.truth_residual == summary.truth_residual
    data = summary.to_dict()
    del data["truth_residual"]  # a metrics.json from before
    assert RunSummary.from_dict(data).truth_residual.n == 0
    assert summarize([_record(0, "a", Motion(0.0, 0.0, 0.0), NO_TRUTH)]).truth_residual.n == 0
