"""Step adjustment from the capture point: where to put the swing foot after a push.

The linear inverted pendulum's instantaneous capture point (Pratt et al., "Capture point: a
step toward humanoid push recovery", Humanoids 2006), also called the divergent component of
motion (Englsberger et al., "Bipedal walking control based on capture point dynamics", IROS
2011), is xi = c + c_dot / omega with omega = sqrt(g / z_c): the point where the robot must
step to come to rest. Where it lies relative to the support foot at each moment of a step
repeats from step to step in steady walking; a push moves it away, and moving the swing foot
by the same amount keeps the motion after the step what it would have been, shifted with the
foot (Englsberger 2011, section IV).

Measured quantity: the robot's capture point (MuJoCo's whole-body CoM and its velocity) minus
the support foot's sole position, in the support foot's frame. Its nominal pattern (the robot
is not a point mass and sways less than the pendulum model, so it is far from constant) is
learnt online per support side and time to touch-down, as an exponential average of the
unpushed steps; an adjustment starts when the measurement departs from the pattern by
``trigger_m`` during single support, so unpushed walking stays exactly as planned.

With the centre of pressure held, the pendulum's capture-point error grows as
e exp(omega t), which would move the foot by e exp(omega (t_touchdown - t)). This robot is
position-controlled and stiff: its measured error grows far slower (about 2.5 s^-1 instead of
omega = 5.5 s^-1 after a 1 N s push, not at all for the errors of nominal walking), and moving
the foot by the extrapolated error made it fall more often than not adjusting at all
(docs/walking.md, "Push recovery"). The growth rate is therefore a parameter, 0 by default:
the foot moves by the error measured now, updated every control period while it grows.

The same departure, at any moment of a step but its last ``freeze_s``, marks a disturbance
(``disturbed_at_s``), which turns on the controller's CoM feedback and slip following.
"""

from __future__ import annotations

import math

import mujoco
import numpy as np

from sim.world.humanoid import MODEL_NAME, SIDES, TORSO_BODY_NAME
from sim.world.walking.footsteps import SIDE_SIGN, FootstepPlanner, Step
from sim.world.walking.preview import GRAVITY_MPS2


class CapturePointStepper:
    """Moves the swing foot of the step under way from the measured capture point.

    Args:
        model: a world built by sim.world.assembly.assemble.
        com_height_m: z_c of the linear inverted pendulum.
        control_period_s: period of the calls to ``update``.
        longest_step_s: longest step (the first one from standing, with its start delay).
        trigger_m: departure of the capture point (relative to the support foot) from its
            nominal pattern that starts adjusting a step, checked in single support until
            ``freeze_s`` before touch-down; the step is then adjusted every control period
            until then.
        gain: footstep move per metre of departure.
        divergence_rate_per_s: the error is extrapolated to touch-down by
            exp(rate * time left); the pendulum's rate is omega, this robot's measured one far
            lower (module docstring).
        max_forward_m: largest forward or backward move of a footstep.
        max_outward_m: largest move of a footstep away from the support foot.
        min_step_width_m: the swing foot lands at least this far to its side of the support
            foot (the legs do not cross).
        freeze_s: the target is no longer moved this long before touch-down.
        learning_rate: weight of each new step in the average nominal error.
        min_seen: steps of nominal pattern to see before adjusting.
        recovery_steps: steps after an adjusted one during which the robot is recovering:
            the nominal pattern is not learnt and no new adjustment starts.
    """

    def __init__(self, model: mujoco.MjModel, com_height_m: float, control_period_s: float,
                 longest_step_s: float, trigger_m: float = 0.05, gain: float = 1.0,
                 divergence_rate_per_s: float = 0.0, max_forward_m: float = 0.08,
                 max_outward_m: float = 0.08, min_step_width_m: float = 0.08,
                 freeze_s: float = 0.15, learning_rate: float = 0.3, min_seen: int = 2,
                 recovery_steps: int = 2):
        self.omega = math.sqrt(GRAVITY_MPS2 / com_height_m)
        self.trigger_m = trigger_m
        self.gain = gain
        self.divergence_rate = divergence_rate_per_s
        self.max_forward_m = max_forward_m
        self.max_outward_m = max_outward_m
        self.min_step_width_m = min_step_width_m
        self.freeze_s = freeze_s
        self.learning_rate = learning_rate
        self.min_seen = min_seen
        self.recovery_steps = recovery_steps
        self._model = model
        self._torso = model.body(TORSO_BODY_NAME).id
        self._soles = [model.site(f"{MODEL_NAME}/{side}_sole").id for side in SIDES]
        self._dt = control_period_s
        self._bins = math.ceil(longest_step_s / control_period_s) + 1
        # Nominal capture point from the support foot, (support side, time-to-touch-down bin,
        # forward/left), and how many steps each bin has seen.
        self._nominal = np.zeros((len(SIDES), self._bins, 2))
        self._seen = np.zeros((len(SIDES), self._bins), dtype=int)
        self._learn_after_s = -math.inf
        self._adjusting_step_start_s: float | None = None
        self._offset = np.zeros(2)
        #: Number of steps whose adjustment has started so far.
        self.adjusted_steps = 0
        #: When the capture point first departed from its nominal pattern by ``trigger_m``,
        #: double support included but not in the last ``freeze_s`` of a step (where the
        #: nominal departure of turning in place comes close to it): a disturbance such as a
        #: push; None until then.
        self.disturbed_at_s: float | None = None
        #: The departure at that moment (m, forward and left in the support foot's frame), and
        #: whether the step was then in single support.
        self.disturbance_m: np.ndarray | None = None
        self.disturbed_in_single_support = False

    def recovering(self, now_s: float) -> bool:
        """Whether the robot is in the steps that follow an adjusted one."""
        return now_s < self._learn_after_s

    def measured_capture_point(self, data: mujoco.MjData) -> np.ndarray:
        """The robot's capture point (x, y) from MuJoCo's whole-body CoM and its velocity."""
        mujoco.mj_subtreeVel(self._model, data)
        return data.subtree_com[self._torso, :2] + data.subtree_linvel[self._torso, :2] / self.omega

    def capture_point_from_support(self, data: mujoco.MjData, planner: FootstepPlanner) -> np.ndarray:
        """The measured capture point relative to the support foot of the step under way
        (its sole's position on the floor), world x, y."""
        side = planner.current_step.support_side
        return self.measured_capture_point(data) - data.site_xpos[self._soles[side], :2]

    def update(self, now_s: float, data: mujoco.MjData, planner: FootstepPlanner) -> None:
        """Learn the nominal pattern, detect a disturbance, or adjust the step under way."""
        step = planner.current_step
        # The first step from standing and the steps that stop have their own pattern: neither
        # learnt nor adjusted.
        if (step is None or step.double_support_s != planner.double_support_s
                or not planner.walking_commanded):
            return
        support = planner.feet_landed[step.support_side]
        c, s = math.cos(support.yaw), math.sin(support.yaw)
        error = self.capture_point_from_support(data, planner)
        local = np.array([c * error[0] + s * error[1], -s * error[0] + c * error[1]])
        remaining_s = step.end_s - now_s
        key = (step.support_side, min(self._bins - 1, max(0, int(remaining_s / self._dt))))
        residual = local - self._nominal[key]
        if (self.disturbed_at_s is None and self._seen[key] >= self.min_seen
                and remaining_s >= self.freeze_s and math.hypot(*residual) >= self.trigger_m):
            self.disturbed_at_s = now_s
            self.disturbance_m = residual
            self.disturbed_in_single_support = now_s >= step.start_s + step.double_support_s
        if self._adjusting_step_start_s != step.start_s:
            single_support = now_s >= step.start_s + step.double_support_s
            # While recovering (the steps after an adjusted one) no new adjustment starts: the
            # robot lags its moved plan, and re-adjusting from that lag made the footsteps
            # alternate with growing amplitude.
            if (self._seen[key] < self.min_seen or not single_support or self.recovering(now_s)
                    or remaining_s < self.freeze_s or math.hypot(*residual) < self.trigger_m):
                if not self.recovering(now_s):
                    self._nominal[key] += (self.learning_rate if self._seen[key] else 1.0) * residual
                    self._seen[key] += 1
                return
            self._adjusting_step_start_s = step.start_s
            self._offset = np.zeros(2)
            self.adjusted_steps += 1
        self._learn_after_s = step.end_s + self.recovery_steps * planner.step_period_s
        if remaining_s < self.freeze_s:
            return
        wanted = self.gain * residual * math.exp(self.divergence_rate * remaining_s)
        offset = self._limited(wanted, step, planner, c, s)
        # The body follows the moved plan, which shrinks the departure: the move only grows
        # within a step, so that this feedback cannot undo it.
        if np.dot(offset, offset) > np.dot(self._offset, self._offset):
            self._offset = offset
            planner.adjust_current_step(offset, now_s + self._dt)

    def _limited(self, offset: np.ndarray, step: Step, planner: FootstepPlanner, c: float,
                 s: float) -> np.ndarray:
        """``offset`` (forward, left in the support foot's frame, whose heading has cosine
        ``c`` and sine ``s``) limited forward by ``max_forward_m``, outward by
        ``max_outward_m`` and inward by ``min_step_width_m``; returned in world x, y."""
        support = planner.feet_landed[step.support_side]
        forward = min(self.max_forward_m, max(-self.max_forward_m, offset[0]))
        side = SIDE_SIGN[step.swing_side]          # + towards the swing foot's side
        target = step.planned_swing_to
        width = side * (-s * (target.x - support.x) + c * (target.y - support.y))
        left = side * min(self.max_outward_m, max(self.min_step_width_m - width, side * offset[1]))
        return np.array([c * forward - s * left, s * forward + c * left])
