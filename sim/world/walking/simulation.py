"""RobotSimulation: the humanoid walking under MuJoCo physics, driven by commands."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import mujoco
import numpy as np

from sim.world.humanoid import CAMERA_NAME, MODEL_NAME, TORSO_BODY_NAME
from sim.world.walking.capture_point import CapturePointStepper
from sim.world.walking.controller import WalkingController
from sim.world.walking.falls import FallDetector, FallEvent
from sim.world.walking.footsteps import Pose2D
from sim.world.walking.gait import GaitParams, resolve_gait
from sim.world.assembly import free_joint_qpos_address


@dataclass(frozen=True)
class Push:
    """A scheduled push: a constant world-frame force ``impulse_ns / duration_s`` (N) on the
    torso's centre of mass during [start_s, start_s + duration_s)."""

    start_s: float
    impulse_ns: tuple[float, float, float]
    duration_s: float

    @property
    def force_n(self) -> np.ndarray:
        return np.asarray(self.impulse_ns) / self.duration_s

    def active(self, time_s: float) -> bool:
        return self.start_s <= time_s < self.start_s + self.duration_s


class RobotSimulation:
    """The humanoid in a compiled world (sim.world), standing at its start pose.

    Physics advances only through ``step``/``run``: each control period the walking controller
    sets the servo targets, then MuJoCo integrates several physics steps. Nothing is
    teleported or replayed; the base is free.

    Args:
        model: world from ``compile_world(assemble(...))``.
        gait: GaitParams or a preset name of GAIT_PRESETS.
        seed: seeds the small random perturbation of the initial joint angles.
        control_period_s: control loop period (100 Hz by default, as OP3's walking module's
            order of magnitude); rounded to a whole number of physics steps.
        init_joint_noise_rad: amplitude of the uniform initial joint-angle perturbation.
        step_adjustment: push recovery: move the footsteps from the measured capture point
            (CapturePointStepper, docs/walking.md "Push recovery"); False plans from the
            commands alone.
        com_feedback: the measured centre of mass feeds back into the torso placement
            (WalkingController.com_feedback_active) from the start; "after_push": only once
            the step adjustment has seen a disturbance, or with ``lateral_sway_m`` > 0 (the
            controller before, docs/walking.md "Push recovery"); False: never.
        counterbalance: push recovery: after a push detected in single support towards the
            support foot's side, the waist rolls the upper body into the push and the swing leg
            swings away from it (counterbalance.py); False never.
    """

    def __init__(self, model: mujoco.MjModel, gait: GaitParams | str = "default", seed: int = 0,
                 control_period_s: float = 0.01, init_joint_noise_rad: float = 0.002,
                 step_adjustment: bool = True, com_feedback: bool | str = True,
                 counterbalance: bool = True):
        if com_feedback not in (True, False, "after_push"):
            raise ValueError(f"com_feedback must be True, False or 'after_push'; got "
                             f"{com_feedback!r}")
        if control_period_s < model.opt.timestep:
            raise ValueError(f"control_period_s must be >= the physics timestep "
                             f"{model.opt.timestep}, got {control_period_s}")
        self.model = model
        self.gait = resolve_gait(gait)
        self.seed = int(seed)
        self.physics_steps_per_control = round(control_period_s / model.opt.timestep)
        self.control_period_s = self.physics_steps_per_control * model.opt.timestep
        self.camera_name = CAMERA_NAME
        self.camera_id = model.camera(CAMERA_NAME).id
        self.data = mujoco.MjData(model)
        stepper = (CapturePointStepper(model, self.gait.com_height_m,
                                       control_period_s=self.control_period_s,
                                       longest_step_s=1.0 + self.gait.step_period_s)
                   if step_adjustment else None)
        self.controller = WalkingController(model, self.gait, self.control_period_s,
                                            step_adjustment=stepper, counterbalance=counterbalance,
                                            com_feedback_after_push=com_feedback == "after_push",
                                            **({} if com_feedback else {"com_feedback_gain": 0.0}))
        self._falls = FallDetector(model)
        self.fall: FallEvent | None = None
        self.pushes: list[Push] = []
        self._torso_id = model.body(TORSO_BODY_NAME).id
        self._place_standing(init_joint_noise_rad)

    def _place_standing(self, noise_rad: float) -> None:
        """Reset fully and put the robot in its standing pose on the floor at its start pose."""
        model, data = self.model, self.data
        mujoco.mj_resetData(model, data)               # zeroes qacc_warmstart too
        adr = free_joint_qpos_address(model)
        x, y = data.qpos[adr:adr + 2]
        w, _, _, z = data.qpos[adr + 3:adr + 7]
        start = Pose2D(float(x), float(y), 2.0 * math.atan2(z, w))
        torso_pos, torso_quat = self.controller.reset(start)
        data.qpos[adr:adr + 3] = torso_pos
        data.qpos[adr + 3:adr + 7] = torso_quat
        rng = np.random.default_rng(self.seed)
        for name, angle in self.controller.standing_qpos().items():
            data.qpos[self.controller.joint_qpos_address[name]] = angle + rng.uniform(-noise_rad, noise_rad)
        data.ctrl[:] = self.controller.targets
        mujoco.mj_forward(model, data)

    @property
    def time(self) -> float:
        return float(self.data.time)

    @property
    def gait_cycle(self) -> int:
        """Index of the gait cycle (two steps); 0 before the first step, then +1 at every
        other step start."""
        return (self.controller.planner.steps_started + 1) // 2

    def command(self, forward_speed_mps: float = 0.0, yaw_rate_dps: float = 0.0) -> None:
        """Walk forward at a speed (m/s) while turning at a yaw rate (deg/s, counter-clockwise
        positive); (0, 0) stops and stands. Commands are clipped to the gait's limits."""
        if not (math.isfinite(forward_speed_mps) and math.isfinite(yaw_rate_dps)):
            raise ValueError(f"commands must be finite numbers, got {forward_speed_mps!r}, {yaw_rate_dps!r}")
        self.controller.command(forward_speed_mps, yaw_rate_dps, self.time)

    def schedule_push(self, start_s: float, impulse_ns: Sequence[float], duration_s: float = 0.1) -> Push:
        """Push the torso: a constant world-frame force ``impulse_ns / duration_s`` (N) applied
        at the torso's centre of mass (``data.xfrc_applied``) during every physics step whose
        start time is in [start_s, start_s + duration_s) (simulation time, to within half a
        physics step). ``impulse_ns`` is (x, y, z) in N s.

        The force is applied per physics step, so the delivered impulse is exact when
        ``duration_s`` is a multiple of the physics timestep. Pushes may overlap (forces add).
        Once a push is scheduled, ``step`` sets the torso's ``xfrc_applied`` force every
        physics step (zero outside the pushes).
        """
        if not (isinstance(start_s, (int, float)) and math.isfinite(start_s) and start_s >= 0):
            raise ValueError(f"schedule_push: start_s must be a finite number >= 0, got {start_s!r}")
        if not (isinstance(duration_s, (int, float)) and math.isfinite(duration_s)
                and duration_s >= self.model.opt.timestep):
            raise ValueError(f"schedule_push: duration_s must be a finite number >= the physics "
                             f"timestep {self.model.opt.timestep}, got {duration_s!r}")
        try:
            if isinstance(impulse_ns, str):
                raise TypeError
            impulse = tuple(float(v) for v in impulse_ns)
        except (TypeError, ValueError):
            raise ValueError(f"schedule_push: impulse_ns must be 3 numbers (N s), got {impulse_ns!r}") from None
        if len(impulse) != 3 or not all(math.isfinite(v) for v in impulse):
            raise ValueError(f"schedule_push: impulse_ns must be 3 finite numbers (N s), got {impulse_ns!r}")
        push = Push(float(start_s), impulse, float(duration_s))
        self.pushes.append(push)
        return push

    def step(self) -> None:
        """Advance one control period: new servo targets, then the physics steps (with any
        scheduled push). A fall is recorded in ``fall``; the simulation keeps running."""
        self.controller.update(self.time, self.data)
        if not self.pushes:
            mujoco.mj_step(self.model, self.data, nstep=self.physics_steps_per_control)
        else:
            for _ in range(self.physics_steps_per_control):
                self._apply_pushes()
                mujoco.mj_step(self.model, self.data)
        if self.fall is None:
            self.fall = self._falls.check(self.data)

    def _apply_pushes(self) -> None:
        """Set the torso's external force to the sum of the pushes active now."""
        # Half a timestep of slack: data.time accumulates rounding errors.
        now = self.data.time + self.model.opt.timestep / 2.0
        force = np.zeros(3)
        for push in self.pushes:
            if push.active(now):
                force += push.force_n
        self.data.xfrc_applied[self._torso_id, :3] = force

    def run(self, duration_s: float) -> None:
        """Step for ``duration_s`` of simulated time (whole control periods)."""
        if not (math.isfinite(duration_s) and duration_s >= 0):
            raise ValueError(f"duration_s must be a finite number >= 0, got {duration_s!r}")
        for _ in range(round(duration_s / self.control_period_s)):
            self.step()

    def camera_pose(self) -> tuple[np.ndarray, np.ndarray]:
        """The SR4000's pose now: position (3,) and orientation (3, 3), columns = camera x
        (right), y (up), z (backwards: it looks along -z) in world coordinates."""
        return (self.data.cam_xpos[self.camera_id].copy(),
                self.data.cam_xmat[self.camera_id].reshape(3, 3).copy())

    def foot_contacts(self) -> tuple[bool, bool]:
        """(left, right): whether each foot touches the world."""
        return self._falls.foot_contacts(self.data)

    def torso_pose(self) -> tuple[np.ndarray, float]:
        """Torso position (3,) and heading (rad) from the physics state."""
        body = self.model.body(f"{MODEL_NAME}/torso").id
        mat = self.data.xmat[body]
        return self.data.xpos[body].copy(), math.atan2(mat[3], mat[0])
