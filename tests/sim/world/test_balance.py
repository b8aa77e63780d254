"""Pushes on the walking humanoid: the push API of RobotSimulation and push recovery by
capture-point step adjustment (docs/walking.md, "Push recovery")."""

import math
from dataclasses import replace
from pathlib import Path

import mujoco
import numpy as np
import pytest

from sim.world.humanoid import TORSO_BODY_NAME
from sim.world.walking import GAIT_PRESETS, RobotSimulation
from sim.world.walking.capture_point import CapturePointStepper
from sim.world.walking.counterbalance import Counterbalance
from sim.world.walking.footsteps import LEFT, RIGHT, SIDE_SIGN, FootstepPlanner, Pose2D
from sim.world.walking import push_recovery
from sim.world.walking.push_recovery import (DIRECTIONS_DEG, HEADING_TOLERANCE_DEG,
                                             LATERAL_TOLERANCE_M, push_trial)
from sim.world.assembly import assemble, compile_world


@pytest.fixture(scope="module")
def model():
    return compile_world(assemble())


def test_schedule_push_delivers_its_impulse_on_the_torso_in_its_window(model):
    dt = model.opt.timestep
    sim = RobotSimulation(model, control_period_s=dt)      # one physics step per step()
    torso = model.body(TORSO_BODY_NAME).id
    sim.schedule_push(0.2, (0.5, -1.5, 0.25), duration_s=0.1)
    delivered = np.zeros(3)
    pushed_times = []
    while sim.time < 0.5:
        start = sim.time
        sim.step()
        force = sim.data.xfrc_applied[torso]
        if np.any(force):
            pushed_times.append(start)
        delivered += force[:3] * dt
        assert not np.any(force[3:])
    np.testing.assert_allclose(delivered, (0.5, -1.5, 0.25), rtol=1e-9)
    assert len(pushed_times) == round(0.1 / dt)
    assert pushed_times[0] == pytest.approx(0.2) and pushed_times[-1] == pytest.approx(0.3 - dt)


def test_a_push_may_start_at_0_and_last_one_physics_step(model):
    # The ends its checks accept: its window [0, dt) is that one step's, and running for no
    # time does not step.
    dt = model.opt.timestep
    sim = RobotSimulation(model, control_period_s=dt)
    push = sim.schedule_push(0.0, (0.0, 0.01, 0.0), duration_s=dt)
    assert push.active(0.0) and not push.active(dt)
    sim.run(0.0)
    assert sim.time == 0.0
    lateral_forces = []
    for _ in range(3):
        sim.step()
        lateral_forces.append(sim.data.xfrc_applied[model.body(TORSO_BODY_NAME).id, 1])
    assert lateral_forces == [pytest.approx(0.01 / dt), 0.0, 0.0]


def test_a_sideways_push_moves_the_robot_sideways(model):
    def lateral_momentum(impulse):
        sim = RobotSimulation(model)
        sim.schedule_push(0.5, (0.0, impulse, 0.0), duration_s=0.1)
        sim.run(0.6)
        torso = model.body(TORSO_BODY_NAME).id
        mujoco.mj_subtreeVel(model, sim.data)
        return sim.data.subtree_linvel[torso, 1] * model.body_subtreemass[torso]
    still = lateral_momentum(0.0)
    assert lateral_momentum(1.0) > still + 0.1
    assert lateral_momentum(-1.0) < still - 0.1


@pytest.mark.parametrize("args, match", [
    ((-1.0, (1.0, 0.0, 0.0), 0.1), "start_s"),
    ((float("nan"), (1.0, 0.0, 0.0), 0.1), "start_s"),
    ((1.0, (1.0, 0.0), 0.1), "impulse_ns"),
    ((1.0, (1.0, float("inf"), 0.0), 0.1), "impulse_ns"),
    ((1.0, "abc", 0.1), "impulse_ns"),
    ((1.0, "123", 0.1), "impulse_ns"),
    ((1.0, (1.0, 0.0, 0.0), 0.0), "duration_s"),
    ((1.0, (1.0, 0.0, 0.0), float("nan")), "duration_s"),
])
def test_bad_pushes_are_value_errors(model, args, match):
    sim = RobotSimulation(model)
    with pytest.raises(ValueError, match=match):
        sim.schedule_push(*args)
    assert sim.pushes == []


def test_a_push_trial_measures_the_path_from_the_robots_own_start():
    # Started away from the origin and facing +y, an unpushed walk is back on its path: its
    # heading and lateral offset are measured from its start pose, not the world's origin.
    trial = push_trial(compile_world(assemble(start_xy=(1.0, 2.0), start_yaw_deg=90.0)),
                       "default", 0.0, 0.0, after_s=1.0)
    assert trial.recovered, trial


# -- push recovery ----------------------------------------------------------------------------
# Seeds set the push's moment (push_recovery.push_trial): seeds 0 and 1 push during a step on
# the left foot, seeds 2 and 3 during a step on the right foot, so that each sideways direction
# is pushed towards the support foot's side by two seeds and towards the swing foot's by two.
@pytest.mark.parametrize("gait", ["default", "paper_like"])
@pytest.mark.parametrize("direction", list(DIRECTIONS_DEG))
@pytest.mark.parametrize("seed", range(4))
def test_a_2ns_push_is_survived_and_the_commanded_path_recovered(model, gait, direction, seed):
    trial = push_trial(model, gait, 2.0, DIRECTIONS_DEG[direction], seed=seed)
    assert not trial.fell
    assert abs(trial.heading_error_deg) <= HEADING_TOLERANCE_DEG, trial
    assert abs(trial.lateral_offset_m) <= LATERAL_TOLERANCE_M, trial
    assert trial.recovered


def test_each_push_direction_points_where_its_name_says():
    """Directions in the robot's frame: forward +x, left +y; a two-word name is halfway."""
    unit = {"forward": (1.0, 0.0), "backward": (-1.0, 0.0), "left": (0.0, 1.0),
            "right": (0.0, -1.0)}
    for name, degrees in DIRECTIONS_DEG.items():
        x, y = np.sum([unit[word] for word in name.split("-")], axis=0)
        assert 0.0 <= degrees < 360.0
        assert math.degrees(math.atan2(y, x)) % 360.0 == pytest.approx(degrees), name
    assert len(DIRECTIONS_DEG) == 8


def test_the_walking_document_states_what_recovered_means():
    document = " ".join((Path(__file__).resolve().parents[3] / "docs" / "walking.md")
                        .read_text().split())
    assert (f"its torso's heading is within {HEADING_TOLERANCE_DEG:g}° of the start heading and "
            f"its mean lateral offset from the commanded straight line within "
            f"{LATERAL_TOLERANCE_M * 100:g} cm") in document


@pytest.mark.parametrize("fell, heading_deg, lateral_m, recovered", [
    (False, 0.0, 0.0, True), (True, 0.0, 0.0, False),
    (False, -HEADING_TOLERANCE_DEG, LATERAL_TOLERANCE_M, True),
    (False, 1.01 * HEADING_TOLERANCE_DEG, 0.0, False),
    (False, 0.0, -1.01 * LATERAL_TOLERANCE_M, False)])
def test_recovered_means_standing_and_back_on_the_commanded_path(fell, heading_deg, lateral_m,
                                                                 recovered):
    trial = push_recovery.PushTrial(fell=fell, push_start_s=3.0, heading_error_deg=heading_deg,
                                    lateral_offset_m=lateral_m)
    assert trial.recovered is recovered


@pytest.mark.parametrize("gait, direction, seed", [("paper_like", "forward", 1),
                                                   ("paper_like", "backward", 0)])
def test_step_adjustment_recovers_3ns_pushes_that_topple_the_plain_controller(model, gait,
                                                                              direction, seed):
    plain = push_trial(model, gait, 3.0, DIRECTIONS_DEG[direction], seed=seed, step_adjustment=False)
    adjusted = push_trial(model, gait, 3.0, DIRECTIONS_DEG[direction], seed=seed)
    assert plain.fell
    assert adjusted.recovered, adjusted


@pytest.mark.parametrize("start_yaw_deg", [120.0, -75.0])
@pytest.mark.parametrize("gait, direction, seed", [("paper_like", "forward", 1),
                                                   ("paper_like", "backward", 0)])
def test_a_robot_facing_any_heading_recovers_those_pushes_alike(start_yaw_deg, gait, direction,
                                                                 seed):
    """The stepper measures the capture point in the support foot's frame and moves the foot in
    the world's; push_trial measures the heading and lateral offset from the start pose. Both
    turn with the robot: facing 120 or -75 degrees, the pushes above end as they do facing +x
    (a rotation the wrong way round in either topples the robot or puts it off its path)."""
    turned = compile_world(assemble(start_yaw_deg=start_yaw_deg))
    plain = push_trial(turned, gait, 3.0, DIRECTIONS_DEG[direction], seed=seed,
                       step_adjustment=False)
    adjusted = push_trial(turned, gait, 3.0, DIRECTIONS_DEG[direction], seed=seed)
    assert plain.fell
    assert adjusted.recovered, adjusted


def test_push_trials_are_deterministic(model):
    first = push_trial(model, "default", 2.0, 45.0, seed=3)
    assert first == push_trial(model, "default", 2.0, 45.0, seed=3)


@pytest.mark.parametrize("gait", ["default", "paper_like"])
def test_unpushed_walking_is_unchanged_by_the_step_adjustment(model, gait):
    def walk(step_adjustment):
        sim = RobotSimulation(model, gait=gait, seed=1, step_adjustment=step_adjustment)
        sim.run(1.0)
        sim.command(forward_speed_mps=sim.gait.max_forward_speed_mps)
        sim.run(5.0)
        sim.command(yaw_rate_dps=sim.gait.max_yaw_rate_dps)
        sim.run(2.0)
        return sim
    adjusted, plain = walk(True), walk(False)
    assert adjusted.controller.step_adjustment.adjusted_steps == 0
    assert adjusted.controller.step_adjustment.disturbed_at_s is None
    assert adjusted.controller.com_feedback_active  # from the start, pushed or not
    assert adjusted.controller.counterbalance is None
    assert np.array_equal(adjusted.data.qpos, plain.data.qpos)


@pytest.mark.parametrize("gait, impulse_ns, direction, seed", [
    ("default", 2.0, "right", 3), ("paper_like", 2.0, "left", 3), ("paper_like", 2.0, "right", 0)])
def test_com_feedback_saves_support_side_pushes_that_topple_the_controller_without_it(
        model, gait, impulse_ns, direction, seed):
    without = push_trial(model, gait, impulse_ns, DIRECTIONS_DEG[direction], seed=seed,
                         com_feedback=False)
    with_feedback = push_trial(model, gait, impulse_ns, DIRECTIONS_DEG[direction], seed=seed)
    assert without.fell
    assert with_feedback.recovered, with_feedback


def test_com_feedback_runs_from_the_start_unless_only_after_a_push(model):
    assert RobotSimulation(model).controller.com_feedback_active
    assert not RobotSimulation(model, com_feedback="after_push").controller.com_feedback_active
    assert not RobotSimulation(model, com_feedback=False).controller.com_feedback_active
    with pytest.raises(ValueError, match="com_feedback must be True, False or 'after_push'"):
        RobotSimulation(model, com_feedback="always")


# Pushes towards the support foot's side in its single support (docs/walking.md, "Push
# recovery"): the controller before, which fed the CoM back only after a push, with the ZMP
# reference at the sole's centre, survived seeds 0 (left) and 3 (right) up to 1.00 and 0.88 N s
# (default), 1.62 and 1.50 N s (paper_like).
@pytest.mark.parametrize("gait", ["default", "paper_like"])
@pytest.mark.parametrize("direction, seed", [("left", 0), ("right", 3)])
def test_feedback_from_the_start_and_the_inward_zmp_save_support_side_pushes_of_2ns(
        model, gait, direction, seed):
    before = push_trial(model, replace(GAIT_PRESETS[gait], lateral_sway_m=0.0), 2.0,
                        DIRECTIONS_DEG[direction], seed=seed, com_feedback="after_push")
    now = push_trial(model, gait, 2.0, DIRECTIONS_DEG[direction], seed=seed)
    assert before.fell
    assert now.recovered, now


@pytest.mark.parametrize("gait, impulse_ns", [("default", 2.25)])
def test_counterbalance_saves_support_side_pushes_that_topple_the_controller_without_it(
        model, gait, impulse_ns):
    # Seed 0 pushes to the left 40 ms into the single support on the left foot.
    without = push_trial(model, gait, impulse_ns, DIRECTIONS_DEG["left"], seed=0,
                         counterbalance=False)
    with_counterbalance = push_trial(model, gait, impulse_ns, DIRECTIONS_DEG["left"], seed=0)
    assert without.fell
    assert with_counterbalance.recovered, with_counterbalance


@pytest.mark.parametrize("impulse_y_ns, starts", [(2.0, True), (-3.0, False)])
def test_counterbalance_starts_only_for_a_push_towards_the_support_foot(model, impulse_y_ns,
                                                                        starts):
    # 4.04 s is 40 ms into a single support on the left foot (seed 0 of push_trial): a push to
    # the left (+y) goes towards it, one to the right towards the swing foot.
    sim = RobotSimulation(model, gait="default")
    sim.schedule_push(4.04, (0.0, impulse_y_ns, 0.0), duration_s=0.1)
    sim.run(1.0)
    sim.command(forward_speed_mps=0.1)
    sim.run(4.0)
    assert sim.fall is None
    assert sim.controller.step_adjustment.disturbed_at_s is not None
    move = sim.controller.counterbalance
    assert (move is not None) == starts
    if starts:
        assert move.support_side == 0 and 4.04 < move.start_s < move.touchdown_s


def test_counterbalance_rolls_the_waist_into_the_push_and_the_swing_leg_away_from_it():
    # Left support, so the push goes to +y: the waist tilts the top to +y and the right foot
    # moves to -y, both negative rolls; the swing leg is back on its plan before touch-down.
    move = Counterbalance(support_side=0, start_s=1.0, touchdown_s=1.3, waist_roll_rad=0.3,
                          swing_hip_roll_rad=0.4, ramp_in_s=0.05, swing_return_s=0.1,
                          waist_hold_s=0.2, waist_return_s=0.3)
    assert move.swing_side == 1
    assert move.offsets(1.0) == pytest.approx((0.0, 0.0))
    assert move.offsets(1.025) == pytest.approx((-0.15, -0.2))
    assert move.offsets(1.1) == pytest.approx((-0.3, -0.4))
    assert move.offsets(1.25) == pytest.approx((-0.3, -0.2))
    assert move.offsets(1.3) == pytest.approx((-0.3, 0.0))
    assert move.offsets(1.65) == pytest.approx((-0.15, 0.0))
    assert not move.finished(1.79) and move.finished(1.8)
    mirrored = Counterbalance(support_side=1, start_s=1.0, touchdown_s=1.3)
    assert mirrored.swing_side == 0 and mirrored.offsets(1.1) == pytest.approx((0.3, 0.4))


@pytest.mark.parametrize("gait", ["default", "paper_like"])
def test_lateral_sway_walks_20s_and_widens_the_sway(model, gait):
    def walk(sway_m, com_feedback=True):
        sim = RobotSimulation(model, gait=replace(GAIT_PRESETS[gait], lateral_sway_m=sway_m),
                              com_feedback=com_feedback)
        sim.run(1.0)
        sim.command(forward_speed_mps=0.1)
        lateral = []
        while sim.time < 21.0 and sim.fall is None:
            sim.step()
            if sim.time > 5.0:
                lateral.append(sim.data.subtree_com[model.body(TORSO_BODY_NAME).id, 1])
        return sim, (max(lateral) - min(lateral)) if lateral else None
    narrow, narrow_range = walk(0.01)
    wide, wide_range = walk(0.02)
    assert narrow.fall is None and wide.fall is None, (narrow.fall, wide.fall)
    assert narrow.controller.com_feedback_active
    assert wide_range > narrow_range + 0.005
    without_feedback, _ = walk(0.02, com_feedback=False)
    assert without_feedback.fall is not None and without_feedback.fall.time_s < 5.0


@pytest.mark.parametrize("gait", ["default", "paper_like"])
def test_walks_at_0_2_mps_without_falling(model, gait):
    sim = RobotSimulation(model, gait=replace(GAIT_PRESETS[gait], step_length_max_m=0.1))
    start = sim.torso_pose()[0]
    sim.run(1.0)
    sim.command(forward_speed_mps=0.2)
    sim.run(6.0)
    sim.command(0.0, 0.0)
    sim.run(1.5)
    assert sim.fall is None
    assert sim.torso_pose()[0][0] - start[0] > 0.8          # 0.2 m/s for 6 s, minus start-up


@pytest.mark.parametrize("turn_rad, lead", [(0.0, LEFT), (0.1, LEFT), (-0.1, RIGHT)])
def test_the_first_step_from_standing_leads_with_the_foot_on_the_side_of_the_turn(turn_rad,
                                                                                 lead):
    planner = FootstepPlanner(Pose2D(0.0, 0.0, 0.0), 0.5, 0.2, 0.09, 0.03, 0.0)
    planner.set_command(0.05, turn_rad, 0.0)
    planner.update(0.0, 3.0)
    assert planner.current_step.swing_side == lead


@pytest.mark.parametrize("heading_rad", [0.0, 0.5])
def test_a_footstep_moves_at_most_its_limits_and_never_across_the_support_foot(model,
                                                                              heading_rad):
    """CapturePointStepper's limits on the move of a step under way, in the support foot's
    frame (forward, left) and back to the world: forward and back at most ``max_forward_m``
    (8 cm), away from the support foot at most ``max_outward_m`` (8 cm), towards it no nearer
    than ``min_step_width_m`` (8 cm from it); smaller moves pass unchanged."""
    planner = FootstepPlanner(Pose2D(0.0, 0.0, heading_rad), 0.5, 0.2, 0.09, 0.03, 0.0,
                              path_return_m=0.02)
    planner.set_command(0.05, 0.0, 0.0)
    planner.update(0.0, 3.0)
    planner.update(1.0, 3.0)                    # second step, mid-swing
    step = planner.current_step
    support = planner.feet_landed[step.support_side]
    c, s = math.cos(support.yaw), math.sin(support.yaw)
    outward = SIDE_SIGN[step.swing_side]        # + left when the swing foot is the left one
    width = outward * (-s * (step.planned_swing_to.x - support.x)
                       + c * (step.planned_swing_to.y - support.y))
    assert width > 0.08
    stepper = CapturePointStepper(model, 0.3, 0.01, 2.0)

    def moved(forward, left):
        world = stepper._limited(np.array([forward, left]), step, planner, c, s)
        return c * world[0] + s * world[1], -s * world[0] + c * world[1]  # back to the foot's

    assert moved(0.03, outward * 0.02) == pytest.approx((0.03, outward * 0.02))
    assert moved(1.0, 0.0) == pytest.approx((0.08, 0.0))
    assert moved(-1.0, 0.0) == pytest.approx((-0.08, 0.0))
    assert moved(0.0, outward * 1.0) == pytest.approx((0.0, outward * 0.08))
    assert moved(0.0, -outward * 1.0) == pytest.approx((0.0, -outward * (width - 0.08)))


@pytest.mark.parametrize("gain, single_support", [(1.0, True), (0.5, True), (1.0, False)])
def test_a_departure_of_the_capture_point_moves_the_swing_foot_by_gain_times_it(
        model, gain, single_support):
    """Steady steps teach the stepper their capture point's pattern (here none: the error
    stays 0); then the capture point departs from it by 7 cm (more than ``trigger_m``): the
    disturbance is noted, with whether it came in single support, and from the next control
    period of single support the swing foot's target moves by ``gain`` times the departure
    (growth rate 0, within the limits); ``recovery_steps`` (2) steps of recovery follow."""
    period = 1.0 / 64.0  # exact in binary: every step's times fall in the same bins
    planner = FootstepPlanner(Pose2D(0.0, 0.0, 0.0), 0.5, 0.25, 0.09, 0.03, 0.0)
    planner.set_command(0.04, 0.0, 0.0)
    stepper = CapturePointStepper(model, 0.3, period, 1.5, gain=gain)
    departure = np.zeros(2)
    stepper.capture_point_from_support = lambda data, planner: departure
    moves, adjust = [], planner.adjust_current_step

    def recorded_adjust(offset, now_s):
        moves.append((now_s, offset))
        adjust(offset, now_s)

    planner.adjust_current_step = recorded_adjust
    pushed_at = None
    for tick in range(int(5.0 / period)):
        now = tick * period
        planner.update(now, 3.0)
        step = planner.current_step
        into_step = step.double_support_s + 2 * period if single_support else period
        if pushed_at is None and now >= 3.6 and now == step.start_s + into_step:
            pushed_at, pushed_step_end = now, step.end_s
            departure = np.array([-0.03, 0.06 * SIDE_SIGN[step.swing_side]])  # outward
        stepper.update(now, None, planner)
    assert pushed_at is not None and stepper.disturbed_at_s == pushed_at
    assert stepper.disturbed_in_single_support == single_support
    np.testing.assert_array_equal(stepper.disturbance_m, departure)
    if single_support:
        assert stepper.adjusted_steps == 1
        assert len(moves) == 1 and moves[0][0] == pushed_at + period
        np.testing.assert_allclose(moves[0][1], gain * departure, atol=1e-12)
        # The two steps after the adjusted one are a recovery: nothing learnt or adjusted.
        recovered_at = pushed_step_end + 2 * planner.step_period_s
        assert stepper.recovering(recovered_at - period) and not stepper.recovering(recovered_at)


def expected_offsets(offset, path_return_m, shortened_first, n_steps=4):
    """The walking centre's offsets from the path, (n_steps, 2), over the steps after a move
    by ``offset``: shortened by ``path_return_m`` a step along it, from the first step on when
    ``shortened_first`` (else from the second)."""
    length = math.hypot(*offset)
    start = 1 if shortened_first else 0
    return [[value * max(length - path_return_m * n, 0.0) / length for value in offset]
            for n in range(start, start + n_steps)]


@pytest.mark.parametrize("offset", [(0.0, -0.04), (0.03, -0.04)])
def test_planner_moves_the_step_under_way_and_returns_to_the_path(offset):
    planner = FootstepPlanner(Pose2D(0.0, 0.0, 0.0), 0.5, 0.2, 0.09, 0.03, 0.0, path_return_m=0.02)
    planner.set_command(0.05, 0.0, 0.0)
    planner.update(0.0, 3.0)
    planner.update(1.0, 3.0)                    # second step (start 0.9 s), mid-swing
    step = planner.current_step
    planned = [later.centre_after for later in planner.steps]
    now = 1.1
    before, _ = planner.feet_now(now)
    planner.adjust_current_step(offset, now)
    after, _ = planner.feet_now(now)
    moved = planner.current_step
    assert moved.swing_to.x == pytest.approx(step.planned_swing_to.x + offset[0])
    assert moved.swing_to.y == pytest.approx(step.planned_swing_to.y + offset[1])
    # No jump of the swing foot, along either axis, and it lands on the new target.
    assert after[step.swing_side].x == pytest.approx(before[step.swing_side].x)
    assert after[step.swing_side].y == pytest.approx(before[step.swing_side].y)
    landed, _ = planner.feet_now(moved.end_s)
    assert landed[step.swing_side].x == pytest.approx(moved.swing_to.x)
    assert landed[step.swing_side].y == pytest.approx(moved.swing_to.y)
    # The next steps start from the moved foot and come back 2 cm per step, along the offset.
    planner.update(now, 3.0)
    expected = expected_offsets(offset, 0.02, shortened_first=False)
    np.testing.assert_allclose([s.centre_offset for s in list(planner.steps)[:4]], expected,
                               atol=1e-12)
    # The walking centre is the planned one moved by that offset.
    np.testing.assert_allclose([s.centre_after.xy for s in list(planner.steps)[:4]],
                               [centre.xy for centre in planned[:4]] + np.array(expected),
                               atol=1e-12)
    assert planner.steps[1].zmp_on == pytest.approx(moved.swing_to.xy)
    with pytest.raises(ValueError, match="landed"):
        planner.adjust_current_step((0.0, 0.01), moved.end_s)


def test_planner_translation_keeps_relative_poses_and_returns_to_the_path():
    planner = FootstepPlanner(Pose2D(0.0, 0.0, 0.0), 0.5, 0.2, 0.09, 0.03, 0.0, path_return_m=0.02)
    planner.set_command(0.05, 0.0, 0.0)
    planner.update(0.0, 3.0)
    planner.update(1.0, 3.0)                    # second step, mid-swing
    now = 1.1
    feet_before, lifts_before = planner.feet_now(now)
    zmp_before = planner.zmp_reference(np.array([now]))
    planner.translate((0.01, 0.05))
    feet_after, lifts_after = planner.feet_now(now)
    assert lifts_after == lifts_before
    for before, after in zip(feet_before, feet_after):
        assert (after.x, after.y, after.yaw) == pytest.approx((before.x + 0.01, before.y + 0.05,
                                                               before.yaw))
    # The commanded path stays put: the later steps, planned again, come back to it, 2 cm per
    # step.
    planner.update(now, 3.0)
    np.testing.assert_allclose(planner.zmp_reference(np.array([now])), zmp_before + (0.01, 0.05))
    np.testing.assert_allclose([s.centre_offset for s in list(planner.steps)[:4]],
                               expected_offsets((0.01, 0.05), 0.02, shortened_first=False),
                               atol=1e-12)


def test_planner_translated_while_standing_walks_back_to_the_path_once_walking():
    planner = FootstepPlanner(Pose2D(0.0, 0.0, 0.0), 0.5, 0.2, 0.09, 0.03, 0.0, path_return_m=0.02)
    planner.update(0.0, 3.0)
    assert planner.current_step is None and not planner.steps
    planner.translate((0.01, 0.05))
    feet, _ = planner.feet_now(0.0)
    assert [value for foot in feet for value in (foot.x, foot.y)] == pytest.approx(
        [0.01, 0.095, 0.01, 0.005])
    planner.update(0.5, 3.0)                    # standing still stays where it was moved
    assert not planner.steps
    planner.set_command(0.05, 0.0, 0.5)
    planner.update(0.5, 3.0)
    np.testing.assert_allclose([s.centre_offset for s in list(planner.steps)[:4]],
                               expected_offsets((0.01, 0.05), 0.02, shortened_first=True),
                               atol=1e-12)
    # Back on the commanded path (y = 0), 5 cm forward per step from where it stood.
    back = planner.steps[3]
    assert back.centre_after.y == pytest.approx(0.0, abs=1e-12)
    assert back.centre_after.x == pytest.approx(4 * 0.05, abs=1e-12)


def test_planner_zmp_reference_shifts_onto_each_support_and_settles_between_the_feet():
    """Linear between the corners: from between the feet onto the support foot (moved out by
    the lateral sway) in the double support, there through the single support, and back between
    the feet in ``settle_s`` after the last step."""
    planner = FootstepPlanner(Pose2D(0.0, 0.0, 0.0), 0.5, 0.2, 0.09, 0.03, 0.02,
                              start_delay_s=0.4, settle_s=0.5)
    planner.set_command(0.05, 0.0, 0.0)
    planner.update(0.0, 3.0)
    first = planner.steps[0]
    assert (first.start_s, first.double_support_s, first.support_side) == (0.0, 0.4, RIGHT)
    on_right = (0.0, -0.045 - 0.02)
    np.testing.assert_allclose(planner.zmp_reference(np.array([0.0, 0.2, 0.4, 0.6, first.end_s])),
                               [(0.0, 0.0), (0.0, on_right[1] / 2), on_right, on_right, on_right],
                               atol=1e-12)
    # A step is over at its end: the next one is under way.
    planner.update(first.end_s, 3.0)
    assert planner.current_step.start_s == first.end_s and planner.current_step is not first
    # Told to stop: the steps that close the feet side by side, then the settling.
    planner.set_command(0.0, 0.0, first.end_s)
    planner.update(first.end_s, 3.0)
    last = planner.steps[-1]
    between = np.array([[last.feet_after[0].x, 0.0]])
    np.testing.assert_allclose(planner.zmp_reference(np.array([last.end_s])), [last.zmp_on],
                               atol=1e-12)
    np.testing.assert_allclose(planner.zmp_reference(np.array([last.end_s + 0.25])),
                               (np.asarray(last.zmp_on) + between) / 2, atol=1e-12)
    np.testing.assert_allclose(planner.zmp_reference(np.array([last.end_s + 0.5, last.end_s + 5])),
                               np.repeat(between, 2, axis=0), atol=1e-12)


def test_the_largest_survived_impulse_is_bisected_to_the_resolution(monkeypatch):
    """Bisection on [0, upper_ns]: the first trial is at the upper end, each next one halves
    the interval until it is no wider than the resolution; the answer is the largest impulse
    shown to be survived."""
    asked = []

    def trial(model, gait, impulse_ns, direction_deg, seed, **options):
        asked.append(impulse_ns)
        return push_recovery.PushTrial(impulse_ns > 1.3, 3.4, 0.0, 0.0)

    monkeypatch.setattr(push_recovery, "push_trial", trial)
    assert push_recovery.largest_survived_impulse(None, "default", 90.0) == 1.25
    assert asked == [8.0, 4.0, 2.0, 1.0, 1.5, 1.25, 1.375]
    asked.clear()
    assert push_recovery.largest_survived_impulse(None, "default", 90.0, upper_ns=1.0) == 1.0
    assert asked == [1.0]


@pytest.mark.parametrize("option", ["upper_ns", "resolution_ns"])
@pytest.mark.parametrize("value", [0.0, -0.125, math.nan, math.inf, True])
def test_a_bisection_with_no_interval_or_no_resolution_is_refused(monkeypatch, option, value):
    # A resolution of 0 bisected for ever.
    monkeypatch.setattr(push_recovery, "push_trial", lambda *args, **options: pytest.fail(
        "a trial ran"))
    with pytest.raises(ValueError, match=f"{option} .*: accepted: a finite number of N s above 0"):
        push_recovery.largest_survived_impulse(None, "default", 90.0, **{option: value})


# 3 N s to 0.1: 1.5, 0.75, 0.375, 0.1875, 0.09375; an interval narrower than the resolution: none.
@pytest.mark.parametrize("upper_ns, resolution_ns, trials", [(3.0, 0.1, 5), (0.1, 0.25, 0)])
def test_the_bisection_runs_as_many_trials_as_halve_the_interval_to_the_resolution(
        monkeypatch, upper_ns, resolution_ns, trials):
    asked = []

    def trial(model, gait, impulse_ns, direction_deg, seed, **options):
        asked.append(impulse_ns)
        return push_recovery.PushTrial(True, 3.4, 0.0, 0.0)  # every push topples it

    monkeypatch.setattr(push_recovery, "push_trial", trial)
    assert push_recovery.largest_survived_impulse(None, "default", 90.0, upper_ns=upper_ns,
                                                  resolution_ns=resolution_ns) == 0.0
    assert len(asked) == 1 + trials  # the upper end, then the halvings


def test_the_push_table_gives_the_worst_and_the_best_seed_per_direction(monkeypatch, capsys):
    """``python -m sim.world.walking.push_recovery``'s table (docs/walking.md, "Push
    recovery"), with trials in which seed s survives up to 1 + s / 2 N s pushed left and half as
    much pushed right; the controller's switches reach every trial."""
    options_seen = []

    def trial(model, gait, impulse_ns, direction_deg, seed, **options):
        options_seen.append(options)
        limit = (1.0 + seed / 2.0) * (1.0 if direction_deg == 90.0 else 0.5)
        return push_recovery.PushTrial(impulse_ns > limit, 3.4, 0.0, 0.0)

    monkeypatch.setattr(push_recovery, "push_trial", trial)
    monkeypatch.setattr(push_recovery, "assemble", lambda: None)
    monkeypatch.setattr(push_recovery, "compile_world", lambda world: None)
    push_recovery.main(["--gaits", "default", "--directions", "left", "right", "--seeds", "3",
                        "--no-counterbalance"])
    assert capsys.readouterr().out.splitlines() == [
        "| direction | `default`: worst / best seed (N s) |", "|---|---|",
        "| left | 1.00 / 2.00 |", "| right | 0.50 / 1.00 |"]
    assert all(options == dict(speed_mps=0.1, step_adjustment=True, com_feedback=True,
                               counterbalance=False) for options in options_seen)
    options_seen.clear()
    gaits_seen = []

    def trial_of_gait(model, gait, *args, **options):
        gaits_seen.append(gait)
        return trial(model, gait, *args, **options)

    monkeypatch.setattr(push_recovery, "push_trial", trial_of_gait)
    push_recovery.main(["--gaits", "default", "--directions", "left", "--seeds", "1",
                        "--com-feedback-after-push", "--lateral-sway", "0"])
    assert options_seen and all(options["com_feedback"] == "after_push"
                                for options in options_seen)
    assert all(gait == replace(GAIT_PRESETS["default"], lateral_sway_m=0.0) for gait in gaits_seen)
