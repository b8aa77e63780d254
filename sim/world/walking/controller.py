"""The walking controller: commands + IMU -> position-servo targets at a fixed control rate.

Per control period (docs/walking.md, "One control period"):
1. the footstep planner extends the plan and gives the ZMP reference over the preview horizon;
2. ZMP preview control (Kajita 2003) gives the centre-of-mass position;
3. the torso is placed so the whole robot's CoM (computed by MuJoCo's kinematics for the last
   targets, arms and upper-body sway included) lands on that position, corrected by the
   measured CoM's error after a push or with a widened sway (CoM feedback, Englsberger et al.,
   IEEE T-RO 2015, in position-controlled form);
4. analytic leg IK puts the feet on their planned poses, flat on the floor plane the support
   soles measured (floor_estimate.py; level until they measure a slope);
5. IMU feedback: the torso's tilt and angular rate correct the ankles (OP3/Darwin
   walking-module style) and its heading error steers the next footsteps;
6. the waist, neck and arms follow the step phase (upper-body sway, head nod, arm swing); after
   a push towards the support foot, the waist and the swing leg counterbalance it.
"""

from __future__ import annotations

import math

import mujoco
import numpy as np

from sim.world.humanoid import LEG_JOINTS, MODEL_NAME, SIDES
from sim.world.walking.capture_point import CapturePointStepper
from sim.world.walking.counterbalance import Counterbalance
from sim.world.walking.floor_estimate import FloorEstimate
from sim.world.walking.footsteps import SIDE_SIGN, FootstepPlanner, Pose2D, mid_pose
from sim.world.walking.gait import GaitParams
from sim.world.walking.leg_ik import LegIK, rot_y, rot_z
from sim.world.walking.preview import ZmpPreviewController
from sim.world.assembly import free_joint_qpos_address

#: Arms' rest pose: slightly out from the body, elbows bent (radians).
ARM_REST = {"shoulder_roll": 0.15, "elbow": -0.4}


class WalkingController:
    """Computes the 24 servo targets of the humanoid in a compiled world.

    Args:
        model: a world built by sim.world.assembly.assemble.
        gait: gait parameters.
        control_period_s: period of the control loop (a multiple of the physics timestep).
        preview_s: ZMP preview horizon.
        heading_gain: fraction of the heading error turned back per step: the commanded
            heading (the integral of the yaw-rate commands) at the end of the planned steps
            less the heading the plan will reach there from the torso's measured heading. It
            corrects the slow yaw drift of the feet slipping on the floor.
        max_heading_correction_deg: limit of that correction per step.
        step_adjustment: a CapturePointStepper (push recovery: moves the step under way from
            the measured capture point), or None for none.
        com_feedback_gain: centre-of-mass feedback (``com_feedback_active``): the torso is
            placed this fraction of the measured CoM error away from the planned CoM, against
            the error.
        com_feedback_velocity_s: weight of the CoM velocity error in that error, s.
        com_feedback_after_push: the CoM feedback only once the step adjustment has seen a
            disturbance, or with an outward sway (``lateral_sway_m`` > 0): the controller before
            the feedback ran from the start (docs/walking.md, "Push recovery"); False: always.
        slip_tolerance_m: after a disturbance, a slip of the support foot from its planned
            position beyond this moves the plan onto it (``_follow_slip``).
        counterbalance: after a push detected in single support towards the support foot's
            side, the waist rolls the upper body into the push and the swing leg swings away
            from it (counterbalance.py).
        follow_floor: plan the feet on the floor's slope as the support soles measure it
            (floor_estimate.py); False plans for a level floor.
    """

    def __init__(self, model: mujoco.MjModel, gait: GaitParams, control_period_s: float,
                 preview_s: float = 1.6, heading_gain: float = 0.3,
                 max_heading_correction_deg: float = 4.0,
                 step_adjustment: CapturePointStepper | None = None,
                 com_feedback_gain: float = 0.2, com_feedback_velocity_s: float = 0.6,
                 com_feedback_after_push: bool = False, slip_tolerance_m: float = 0.01,
                 counterbalance: bool = True, follow_floor: bool = True):
        self.model = model
        self.gait = gait
        self.control_period_s = control_period_s
        self._scratch = mujoco.MjData(model)          # kinematics of the targets, never stepped
        self._free_qpos = free_joint_qpos_address(model)
        self._torso_id = model.body(f"{MODEL_NAME}/torso").id
        self._soles = [model.site(f"{MODEL_NAME}/{s}_sole").id for s in SIDES]
        self._gyro_adr = model.sensor_adr[model.sensor(f"{MODEL_NAME}/imu_gyro").id]
        self._actuator = {name: model.actuator(f"{MODEL_NAME}/{name}").id
                          for name in self._joint_names()}
        self._joint_qpos = {name: model.jnt_qposadr[model.joint(f"{MODEL_NAME}/{name}").id]
                            for name in self._joint_names()}
        self._leg_actuators = [np.array([self._actuator[f"{s}_{j}"] for j in LEG_JOINTS])
                               for s in SIDES]
        self._upper_body_actuators = np.array([self._actuator[name] for name in (
            "waist_roll", "waist_yaw", "neck_tilt", "neck_pan",
            "l_shoulder_pitch", "l_shoulder_roll", "l_shoulder_yaw", "l_elbow",
            "r_shoulder_pitch", "r_shoulder_roll", "r_shoulder_yaw", "r_elbow")])
        self._upper_body_amplitudes = tuple(math.radians(a) for a in (
            gait.waist_roll_amp_deg, gait.waist_yaw_amp_deg, gait.head_nod_amp_deg,
            gait.arm_swing_deg))
        # Actuator order -> qpos address, to write the targets into the scratch state at once.
        self._actuator_qpos = np.empty(model.nu, dtype=int)
        for name, act in self._actuator.items():
            self._actuator_qpos[act] = self._joint_qpos[name]
        # Leg geometry read from the model: hip joint offsets, segment lengths, ankle height.
        self._hip_offsets = np.array([model.body_pos[model.body(f"{MODEL_NAME}/{s}_thigh").id]
                                      for s in SIDES])
        thigh = -model.body_pos[model.body(f"{MODEL_NAME}/l_shank").id][2]
        shank = -model.body_pos[model.body(f"{MODEL_NAME}/l_foot").id][2]
        self._ankle_height = -model.site_pos[model.site(f"{MODEL_NAME}/l_sole").id][2]
        self._ik = LegIK(thigh, shank)
        self._preview = ZmpPreviewController(gait.com_height_m, control_period_s, preview_s)
        self._preview_times = control_period_s * np.arange(1, self._preview.horizon + 1)
        self._lean = math.radians(gait.torso_lean_deg)
        self._lean_rot = rot_y(self._lean)
        self._heading_gain = heading_gain
        self._max_heading_correction = math.radians(max_heading_correction_deg)
        self._yaw_rate = 0.0
        self.step_adjustment = step_adjustment
        self.com_feedback_gain = com_feedback_gain
        self.com_feedback_velocity_s = com_feedback_velocity_s
        self.com_feedback_after_push = bool(com_feedback_after_push)
        self.slip_tolerance_m = slip_tolerance_m
        self._slip_checked_step_s: float | None = None
        self.counterbalance_enabled = counterbalance
        #: The counterbalance move under way, if any.
        self.counterbalance: Counterbalance | None = None
        self.follow_floor = follow_floor
        #: The floor's slope the feet are planned on (reset by ``reset``).
        self.floor = FloorEstimate(control_period_s)
        self._floor_measured_step_s: float | None = None
        self.targets = np.zeros(model.nu)
        self.planner: FootstepPlanner | None = None

    @staticmethod
    def _joint_names() -> list[str]:
        legs = [f"{s}_{j}" for s in SIDES for j in LEG_JOINTS]
        arms = [f"{s}_{j}" for s in SIDES
                for j in ("shoulder_pitch", "shoulder_roll", "shoulder_yaw", "elbow")]
        return legs + ["waist_yaw", "waist_roll", "neck_pan", "neck_tilt"] + arms

    # -- setup ----------------------------------------------------------------------------
    def reset(self, start: Pose2D) -> tuple[np.ndarray, np.ndarray]:
        """Plan standing at ``start`` (the point between the feet); returns the standing
        torso pose (position (3,), quaternion (4,)) and leaves the standing targets."""
        g = self.gait
        self.planner = FootstepPlanner(start, g.step_period_s, g.double_support_ratio,
                                       g.step_width_m, g.step_height_m, g.lateral_sway_m)
        self._preview.reset(start.xy)
        self._heading_goal = start.yaw
        self.counterbalance = None
        self.floor = FloorEstimate(self.control_period_s)
        self._floor_measured_step_s = None
        self._yaw_rate = 0.0
        self._com_offset = np.zeros(3)
        self._torso_height = g.com_height_m
        # Fixed point: the torso offset from the CoM depends on the pose it produces.
        for _ in range(4):
            self._set_targets(0.0, np.zeros(3))
            self._update_com_offset()
            self._torso_height = g.com_height_m + self._com_offset[2]
        self._set_targets(0.0, np.zeros(3))
        self._update_com_offset()
        return self._torso_pos.copy(), self._torso_quat.copy()

    def standing_qpos(self) -> dict[str, float]:
        """Joint angles of the current targets, by joint name (for initial placement)."""
        return {name: float(self.targets[act]) for name, act in self._actuator.items()}

    @property
    def joint_qpos_address(self) -> dict[str, int]:
        return self._joint_qpos

    @property
    def com_feedback_active(self) -> bool:
        """Whether the measured CoM feeds back into the torso placement: always, unless
        ``com_feedback_after_push`` (then with an outward ZMP sway, ``lateral_sway_m`` > 0, and
        once the step adjustment has seen a disturbance) or the gain is 0."""
        if not self.com_feedback_gain:
            return False
        return not self.com_feedback_after_push or self.gait.lateral_sway_m > 0.0 or (
            self.step_adjustment is not None and self.step_adjustment.disturbed_at_s is not None)

    # -- control --------------------------------------------------------------------------
    def command(self, forward_speed_mps: float, yaw_rate_dps: float, now_s: float) -> None:
        """Walk at a forward speed and yaw rate, clipped to the gait's limits; (0, 0) stops."""
        g = self.gait
        v = _clip(float(forward_speed_mps), g.max_forward_speed_mps)
        w = _clip(float(yaw_rate_dps), g.max_yaw_rate_dps)
        self._yaw_rate = math.radians(w)
        self.planner.set_command(v * g.step_period_s, self._yaw_rate * g.step_period_s, now_s)

    def update(self, now_s: float, data: mujoco.MjData) -> np.ndarray:
        """Targets for the control period starting at ``now_s``; written into ``data.ctrl``."""
        gyro = data.sensordata[self._gyro_adr:self._gyro_adr + 3]
        self._heading_goal += self._yaw_rate * self.control_period_s
        torso_mat = data.xmat[self._torso_id]
        # A correction turns only steps planned after it, up to a preview horizon ahead: compare
        # the goal at the plan's end with the heading the plan will reach from the measured one
        # (a Smith predictor), or the correction lags by that horizon and the heading swings.
        planner = self.planner
        planned_now = mid_pose(*planner.feet_now(now_s)[0]).yaw
        plan_end_s = planner.steps[-1].end_s if planner.steps else now_s
        predicted = math.atan2(torso_mat[3], torso_mat[0]) + planner.centre.yaw - planned_now
        goal_at_plan_end = self._heading_goal + self._yaw_rate * max(0.0, plan_end_s - now_s)
        heading_error = math.remainder(goal_at_plan_end - predicted, 2.0 * math.pi)
        planner.turn_correction_rad = _clip(self._heading_gain * heading_error,
                                            self._max_heading_correction)
        planner.update(now_s, self._preview_times[-1])
        if self.step_adjustment is not None:
            self.step_adjustment.update(now_s, data, self.planner)
            if self.step_adjustment.disturbed_at_s is not None:
                self._follow_slip(data)
                if self.step_adjustment.disturbed_at_s == now_s:
                    self._start_counterbalance(now_s)
            self.planner.update(now_s, self._preview_times[-1])
        if self.follow_floor:
            self._measure_floor(now_s, data)
        reference = self.planner.zmp_reference(now_s + self._preview_times)
        self._preview.step(reference)
        roll, pitch = math.atan2(torso_mat[7], torso_mat[8]), -math.asin(torso_mat[6])
        com_correction = (0.0, 0.0)
        if self.com_feedback_active:
            # Relative to the support foot: the feet slip on the floor, so the plan and the
            # real robot drift apart in the world.
            step = self.planner.current_step
            side = step.support_side if step is not None else 0
            planned_foot = self.planner.feet_landed[side]
            com_error = (data.subtree_com[self._torso_id, :2]
                         - data.site_xpos[self._soles[side], :2]
                         - self._preview.state[0] + (planned_foot.x, planned_foot.y))
            mujoco.mj_subtreeVel(self.model, data)
            com_error += self.com_feedback_velocity_s * (
                data.subtree_linvel[self._torso_id, :2] - self._preview.state[1])
            com_correction = -self.com_feedback_gain * com_error
        self._set_targets(now_s + self.control_period_s, gyro, (roll, pitch - self._lean),
                          com_correction)
        self._update_com_offset()
        data.ctrl[:] = self.targets
        return self.targets

    def _start_counterbalance(self, now_s: float) -> None:
        """Start the counterbalance when the push just detected came in single support and
        moved the capture point mostly outwards of the support foot (towards its side, more
        than forward or backward: a forward push's small sideways part must not start it)."""
        stepper, step = self.step_adjustment, self.planner.current_step
        forward, left = stepper.disturbance_m
        if (self.counterbalance_enabled and stepper.disturbed_in_single_support
                and SIDE_SIGN[step.support_side] * left > abs(forward)):
            self.counterbalance = Counterbalance(step.support_side, now_s, step.end_s)

    def _follow_slip(self, data: mujoco.MjData) -> None:
        """At each step start after a disturbance, move the plan onto the support foot's
        measured position when the feet have slipped more than ``slip_tolerance_m`` from it
        (a push slides the robot): the following steps then walk back to the commanded path,
        which the plan alone would believe it never left."""
        step = self.planner.current_step
        if step is None or step.start_s == self._slip_checked_step_s:
            return
        self._slip_checked_step_s = step.start_s
        planned = self.planner.feet_landed[step.support_side]
        slip = data.site_xpos[self._soles[step.support_side], :2] - (planned.x, planned.y)
        if math.hypot(*slip) > self.slip_tolerance_m:
            self.planner.translate(slip)
            self._preview.translate(slip)

    def _measure_floor(self, now_s: float, data: mujoco.MjData) -> None:
        """Once per step, half-way through it, give the support sole's measured orientation to
        the floor estimate; then move the planned floor plane one period towards the estimate.
        Half-way the support foot carries the robot alone and lies flattest: on a level floor
        its tilt's standard deviation is then 0.2 degrees, against 0.7-1.9 degrees as single
        support starts.
        """
        step = self.planner.current_step
        if (step is not None and step.start_s != self._floor_measured_step_s
                and now_s >= (step.start_s + step.end_s) / 2.0):
            self._floor_measured_step_s = step.start_s
            self.floor.measure(data.site_xmat[self._soles[step.support_side]].reshape(3, 3))
        self.floor.advance()

    def _step_phase(self) -> tuple[float, float]:
        """(side sign of the support foot, sin(pi * progress of the step)); (0, 0) standing."""
        step = self.planner.current_step
        if step is None:
            return 0.0, 0.0
        progress = (self._now - step.start_s) / (step.end_s - step.start_s)
        return SIDE_SIGN[step.support_side], math.sin(math.pi * min(1.0, max(0.0, progress)))

    def _set_targets(self, now_s: float, gyro: np.ndarray, tilt=(0.0, 0.0),
                     com_correction=(0.0, 0.0)) -> None:
        g = self.gait
        self._now = now_s
        feet, lifts = self.planner.feet_now(now_s)
        yaw = mid_pose(*feet).yaw
        body_rot = rot_z(yaw) @ self._lean_rot
        com_xy = self._preview.state[0] + com_correction
        torso_pos = np.array([com_xy[0] + self._com_offset[0], com_xy[1] + self._com_offset[1],
                              self._torso_height])
        ankle_roll_fb = g.gyro_ankle_roll_gain * float(gyro[0]) + g.tilt_ankle_gain * tilt[0]
        ankle_pitch_fb = g.gyro_ankle_pitch_gain * float(gyro[1]) + g.tilt_ankle_gain * tilt[1]
        t = self.targets
        hips = torso_pos + self._hip_offsets @ body_rot.T
        floor = self.floor
        floor_tilt = None if floor.is_level else floor.tilt()
        for side, (foot, lift, hip) in enumerate(zip(feet, lifts, hips)):
            if floor_tilt is None:
                foot_rot = rot_z(foot.yaw)
                ankle = np.array([foot.x, foot.y, self._ankle_height + lift])
            else:
                # The sole flat on the planned plane, which passes under the planned CoM at
                # the level floor's height: the torso's height above the floor stays the same.
                foot_rot = floor_tilt @ rot_z(foot.yaw)
                ankle = self._ankle_height * foot_rot[:, 2]
                ankle[0] += foot.x
                ankle[1] += foot.y
                ankle[2] += floor.height(foot.x, foot.y, com_xy[0], com_xy[1]) + lift
            hip_yaw, hip_roll, hip_pitch, knee, ankle_pitch, ankle_roll = self._ik.solve(
                hip, body_rot, ankle, foot_rot)
            t[self._leg_actuators[side]] = (hip_yaw, hip_roll, hip_pitch, knee,
                                            ankle_pitch + ankle_pitch_fb, ankle_roll + ankle_roll_fb)
        support_sign, swell = self._step_phase()
        sway = support_sign * swell
        nod = max(lifts) / g.step_height_m
        waist_roll_amp, waist_yaw_amp, nod_amp, arm_amp = self._upper_body_amplitudes
        arm = arm_amp * sway
        roll, elbow = ARM_REST["shoulder_roll"], ARM_REST["elbow"]
        # The upper body rolls towards the swing side (positive roll tilts the top towards -y);
        # the CoM placement then shifts the pelvis further over the support foot. The arms
        # swing against the legs; the neck keeps the camera level against the torso's lean.
        t[self._upper_body_actuators] = (
            waist_roll_amp * sway, waist_yaw_amp * sway, -self._lean + nod_amp * nod, 0.0,
            arm, roll, 0.0, elbow, -arm, -roll, 0.0, elbow)
        if self.counterbalance is not None and not self.counterbalance.finished(now_s):
            waist_roll, swing_hip_roll = self.counterbalance.offsets(now_s)
            t[self._actuator["waist_roll"]] += waist_roll
            t[self._actuator[f"{SIDES[self.counterbalance.swing_side]}_hip_roll"]] += swing_hip_roll
        self._torso_pos = torso_pos
        quat = np.empty(4)
        mujoco.mju_mat2Quat(quat, body_rot.ravel())
        self._torso_quat = quat

    def _update_com_offset(self) -> None:
        """Offset of the torso from the robot's CoM for the current targets (MuJoCo kinematics)."""
        scratch = self._scratch
        adr = self._free_qpos
        scratch.qpos[adr:adr + 3] = self._torso_pos
        scratch.qpos[adr + 3:adr + 7] = self._torso_quat
        scratch.qpos[self._actuator_qpos] = self.targets
        mujoco.mj_kinematics(self.model, scratch)
        mujoco.mj_comPos(self.model, scratch)
        self._com_offset = self._torso_pos - scratch.subtree_com[self._torso_id]


def _clip(value: float, limit: float) -> float:
    """``value`` limited to [-limit, limit] (scalar; cheaper than numpy in the control loop)."""
    return max(-limit, min(limit, value))
