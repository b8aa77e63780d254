"""Footstep planning: walking commands -> footsteps, ZMP reference and swing-foot paths.

A walking "centre" pose advances by (v T, omega T) per step; each step puts the swing foot
half a step width to its side of the new centre, so successive footprints are one step length
apart and the feet turn by omega T per step (in place when v = 0). A step starts with a
double-support phase in which the ZMP reference moves from the previous support foot to the new
one, then the other foot swings along a cycloid. With a zero command the next step puts the feet
side by side and the ZMP returns between them (docs/walking.md, "The standard recipe", steps 1-2).
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass, replace

import numpy as np

LEFT, RIGHT = 0, 1
#: Lateral sign of each side: the left foot is at +y of the centre, the right at -y.
SIDE_SIGN = (1.0, -1.0)


@dataclass(frozen=True)
class Pose2D:
    """A pose on the floor: position (m) and heading (rad, counter-clockwise from +x)."""

    x: float
    y: float
    yaw: float

    def moved(self, forward: float, left: float, turn: float = 0.0) -> Pose2D:
        """This pose moved by (forward, left) in its own frame, then turned by ``turn``."""
        c, s = math.cos(self.yaw), math.sin(self.yaw)
        return Pose2D(self.x + c * forward - s * left, self.y + s * forward + c * left,
                      self.yaw + turn)

    @property
    def xy(self) -> np.ndarray:
        return np.array([self.x, self.y])


@dataclass(frozen=True)
class Step:
    """One planned step: the ZMP moves onto ``support`` then the other foot swings.

    ``zmp_from`` is where the ZMP reference starts (the previous support foot or the middle of
    the feet); ``feet_after`` are both feet's poses (left, right) once the step is done and
    ``centre_after`` the walking centre then. ``centre_offset`` (world x, y) is how far step
    adjustments have moved that centre from the commanded path; ``planned_swing_to`` is the
    swing target before any adjustment of this step.
    """

    start_s: float
    double_support_s: float
    single_support_s: float
    support_side: int
    zmp_from: np.ndarray
    zmp_on: np.ndarray
    swing_from: Pose2D
    swing_to: Pose2D
    feet_after: tuple[Pose2D, Pose2D]
    centre_after: Pose2D
    centre_offset: tuple[float, float]
    planned_swing_to: Pose2D

    @property
    def end_s(self) -> float:
        return self.start_s + self.double_support_s + self.single_support_s

    @property
    def swing_side(self) -> int:
        return 1 - self.support_side


def mid_pose(a: Pose2D, b: Pose2D) -> Pose2D:
    """The pose half-way between ``a`` and ``b``, its yaw on the shorter arc between theirs."""
    yaw = b.yaw + math.remainder(a.yaw - b.yaw, 2 * math.pi) / 2.0
    return Pose2D((a.x + b.x) / 2.0, (a.y + b.y) / 2.0, yaw)


class FootstepPlanner:
    """Online footstep plan covering at least the ZMP preview horizon.

    The step under way can be moved (``adjust_current_step``, push recovery): the plan after
    it is then re-planned from the moved foot, and each later step brings the walking centre
    back towards the commanded path by at most ``path_return_m``.

    Args:
        step_period_s, double_support_ratio, step_width_m, step_height_m, lateral_sway_m:
            as in GaitParams.
        start_delay_s: double support before the first step from standing, so the body can
            shift over the first support foot.
        settle_s: time for the ZMP to return between the feet after the last step.
        path_return_m: largest move of the walking centre back towards the commanded path per
            step, after a step adjustment.
    """

    def __init__(self, centre: Pose2D, step_period_s: float, double_support_ratio: float,
                 step_width_m: float, step_height_m: float, lateral_sway_m: float,
                 start_delay_s: float = 0.5, settle_s: float = 0.5, path_return_m: float = 0.02):
        self.step_period_s = step_period_s
        self.double_support_s = double_support_ratio * step_period_s
        self.single_support_s = step_period_s - self.double_support_s
        self.step_width_m = step_width_m
        self.step_height_m = step_height_m
        self.lateral_sway_m = lateral_sway_m
        self.start_delay_s = start_delay_s
        self.settle_s = settle_s
        self.path_return_m = path_return_m
        self.steps: deque[Step] = deque()
        # Plan's end state (after the last planned step) and the state reached so far.
        self.centre = centre
        self.feet = (centre.moved(0.0, step_width_m / 2), centre.moved(0.0, -step_width_m / 2))
        self.feet_landed = self.feet
        self.centre_offset = (0.0, 0.0)        # of the plan's end state from the commanded path
        self._advance = (0.0, 0.0)            # forward m and turn rad per step
        #: Extra turn (rad) added to each newly planned step while walking: heading feedback.
        self.turn_correction_rad = 0.0
        self._finished: Step | None = None
        self._current: Step | None = None
        self.steps_started = 0
        self._breakpoints = None              # ZMP breakpoints cache, reset when the plan changes

    # -- commands -----------------------------------------------------------------------
    def set_command(self, forward_per_step_m: float, turn_per_step_rad: float, now_s: float) -> None:
        """Replan every step not yet started with the new per-step advance."""
        advance = (float(forward_per_step_m), float(turn_per_step_rad))
        if advance == self._advance:
            return
        self._advance = advance
        while self.steps and self.steps[-1].start_s > now_s:
            self.steps.pop()
        self._replan_from_last()

    def _replan_from_last(self) -> None:
        """Set the plan's end state to the last step kept (or the landed feet)."""
        self._breakpoints = None
        if self.steps:
            last = self.steps[-1]
            self.feet, self.centre, self.centre_offset = last.feet_after, last.centre_after, last.centre_offset
        else:
            self.feet = self.feet_landed

    @property
    def walking_commanded(self) -> bool:
        return self._advance != (0.0, 0.0)

    @property
    def current_step(self) -> Step | None:
        """The step in progress, None while standing."""
        return self._current

    # -- planning -----------------------------------------------------------------------
    def update(self, now_s: float, horizon_s: float) -> None:
        """Drop finished steps and plan new ones up to ``now_s + horizon_s``."""
        while self.steps and self.steps[0].end_s <= now_s:
            self._finished = self.steps.popleft()
            self.feet_landed = self._finished.feet_after
            self._breakpoints = None
        while not self.steps or self.steps[-1].end_s <= now_s + horizon_s:
            step = self._next_step(self.steps[-1].end_s if self.steps else now_s)
            if step is None:
                break
            self.steps.append(step)
            self.feet, self.centre, self.centre_offset = step.feet_after, step.centre_after, step.centre_offset
            self._breakpoints = None
        head = self.steps[0] if self.steps and self.steps[0].start_s <= now_s else None
        if head is not None and head is not self._current:
            self.steps_started += 1
        self._current = head

    def _feet_side_by_side(self) -> bool:
        expected = (self.centre.moved(0.0, self.step_width_m / 2),
                    self.centre.moved(0.0, -self.step_width_m / 2))
        return all(math.isclose(a, b, abs_tol=1e-9) for foot, goal in zip(self.feet, expected)
                   for a, b in ((foot.x, goal.x), (foot.y, goal.y), (foot.yaw, goal.yaw)))

    def _next_step(self, start_s: float) -> Step | None:
        forward, turn = self._advance
        if not self.walking_commanded and self._feet_side_by_side():
            return None
        previous = self.steps[-1] if self.steps else None
        if previous is None:
            # From standing, lead with the foot on the side of the turn (left by default).
            swing = RIGHT if turn < 0 else LEFT
        else:
            swing = previous.support_side
        support = 1 - swing
        if self.walking_commanded:
            turn += self.turn_correction_rad
        offset_x, offset_y = self.centre_offset
        on_path = Pose2D(self.centre.x - offset_x, self.centre.y - offset_y, self.centre.yaw)
        offset = _shrunk((offset_x, offset_y), self.path_return_m)
        centre = on_path.moved(forward, 0.0, turn)
        centre = Pose2D(centre.x + offset[0], centre.y + offset[1], centre.yaw)
        swing_to = centre.moved(0.0, SIDE_SIGN[swing] * self.step_width_m / 2)
        support_pose = self.feet[support]
        zmp_on = support_pose.moved(0.0, SIDE_SIGN[support] * self.lateral_sway_m).xy
        zmp_from = mid_pose(*self.feet).xy if previous is None else previous.zmp_on
        feet_after = (swing_to, support_pose) if swing == LEFT else (support_pose, swing_to)
        double = self.start_delay_s if previous is None else self.double_support_s
        return Step(start_s, double, self.single_support_s, support, zmp_from, zmp_on,
                    self.feet[swing], swing_to, feet_after, centre, offset, swing_to)

    def adjust_current_step(self, offset_xy, now_s: float) -> None:
        """Move the swing foot's target of the step under way to its planned target plus
        ``offset_xy`` (world, m), and re-plan the steps after it from there: the walking
        centre moves with the foot, then returns to the commanded path (``path_return_m`` per
        step). The swing path is re-anchored so the foot does not jump at ``now_s``. No-op
        while standing."""
        step = self._current
        if step is None:
            return
        target = step.planned_swing_to
        swing_to = Pose2D(target.x + float(offset_xy[0]), target.y + float(offset_xy[1]), target.yaw)
        if swing_to == step.swing_to:
            return
        shift = (swing_to.x - step.swing_to.x, swing_to.y - step.swing_to.y)
        # Keep the swing foot where it is now: a + s (b - a) = a' + s (b' - a').
        progress = _swing_progress(step, now_s)
        if progress >= 1.0:
            raise ValueError(f"adjust_current_step: the swing foot has landed at {now_s!r} s")
        a = step.swing_from
        swing_from = (a if progress <= 0.0 else
                      Pose2D(a.x - progress * shift[0] / (1.0 - progress),
                             a.y - progress * shift[1] / (1.0 - progress), a.yaw))
        centre = step.centre_after
        feet_after = ((swing_to, step.feet_after[1]) if step.swing_side == LEFT
                      else (step.feet_after[0], swing_to))
        moved = replace(step, swing_from=swing_from, swing_to=swing_to, feet_after=feet_after,
                        centre_after=Pose2D(centre.x + shift[0], centre.y + shift[1], centre.yaw),
                        centre_offset=(step.centre_offset[0] + shift[0], step.centre_offset[1] + shift[1]))
        while self.steps[-1] is not step:
            self.steps.pop()
        self.steps[-1] = moved
        self._current = moved
        self._replan_from_last()

    def translate(self, shift_xy) -> None:
        """Move the plan (feet, the step under way, ZMP reference) by ``shift_xy`` (world, m),
        keeping the commanded path where it is: the steps after the one under way are planned
        again and walk back to it (``path_return_m`` per step). Used when the real feet have
        slipped away from the plan (push recovery); the poses now, and so the joint targets,
        do not change."""
        dx, dy = float(shift_xy[0]), float(shift_xy[1])

        def moved(pose: Pose2D) -> Pose2D:
            return Pose2D(pose.x + dx, pose.y + dy, pose.yaw)

        def moved_step(step: Step) -> Step:
            return replace(step, zmp_from=step.zmp_from + (dx, dy), zmp_on=step.zmp_on + (dx, dy),
                           swing_from=moved(step.swing_from), swing_to=moved(step.swing_to),
                           feet_after=(moved(step.feet_after[0]), moved(step.feet_after[1])),
                           centre_after=moved(step.centre_after),
                           centre_offset=(step.centre_offset[0] + dx, step.centre_offset[1] + dy),
                           planned_swing_to=moved(step.planned_swing_to))

        # The steps not yet started are planned again from the moved ones.
        kept = [self._current] if self._current is not None else []
        self.steps = deque(moved_step(step) for step in kept)
        self._current = self.steps[0] if kept else None
        if self._finished is not None:
            self._finished = moved_step(self._finished)
        self.feet_landed = (moved(self.feet_landed[0]), moved(self.feet_landed[1]))
        self._replan_from_last()
        if not self.steps:
            self.centre = moved(self.centre)
            self.centre_offset = (self.centre_offset[0] + dx, self.centre_offset[1] + dy)

    # -- references ---------------------------------------------------------------------
    def zmp_reference(self, times_s: np.ndarray) -> np.ndarray:
        """ZMP reference at ``times_s``, shape (len, 2): linear between the plan's breakpoints,
        returning between the feet in ``settle_s`` after the last step."""
        if self._breakpoints is None:
            self._breakpoints = self._zmp_breakpoints()
        t, x, y = self._breakpoints
        reference = np.empty((len(times_s), 2))
        reference[:, 0] = np.interp(times_s, t, x)
        reference[:, 1] = np.interp(times_s, t, y)
        return reference

    def _zmp_breakpoints(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Times and (x, y) of the ZMP reference's corners."""
        points = []
        if self._finished is not None:
            points.append((self._finished.end_s, self._finished.zmp_on))
        for step in self.steps:
            points += [(step.start_s, step.zmp_from),
                       (step.start_s + step.double_support_s, step.zmp_on),
                       (step.end_s, step.zmp_on)]
        last_s = points[-1][0] if points else 0.0
        points.append((last_s + self.settle_s, mid_pose(*self.feet).xy))
        return (np.array([p[0] for p in points]), np.array([p[1][0] for p in points]),
                np.array([p[1][1] for p in points]))

    def feet_now(self, now_s: float) -> tuple[tuple[Pose2D, Pose2D], tuple[float, float]]:
        """Both feet's floor poses (left, right) and lifts (m) at ``now_s``: the swing foot
        follows a cycloid (zero velocity at lift-off and touch-down)."""
        step = self._current
        if step is None:
            return self.feet_landed, (0.0, 0.0)
        phase = _swing_phase(step, now_s)
        s = _swing_progress(step, now_s)
        a, b = step.swing_from, step.swing_to
        swing = Pose2D(a.x + s * (b.x - a.x), a.y + s * (b.y - a.y),
                       a.yaw + s * math.remainder(b.yaw - a.yaw, 2 * math.pi))
        lift = self.step_height_m * (1.0 - math.cos(2.0 * math.pi * phase)) / 2.0
        feet = [None, None]
        lifts = [0.0, 0.0]
        feet[step.support_side] = self.feet_landed[step.support_side]
        feet[step.swing_side] = swing
        lifts[step.swing_side] = lift
        return (feet[0], feet[1]), (lifts[0], lifts[1])


def _shrunk(vector: tuple[float, float], by: float) -> tuple[float, float]:
    """``vector`` shortened by ``by`` (zero if shorter)."""
    length = math.hypot(*vector)
    if length <= by:
        return (0.0, 0.0)
    scale = (length - by) / length
    return (vector[0] * scale, vector[1] * scale)


def _swing_phase(step: Step, now_s: float) -> float:
    """Fraction of the step's single support elapsed at ``now_s``, in [0, 1]."""
    phase = (now_s - step.start_s - step.double_support_s) / step.single_support_s
    return min(1.0, max(0.0, phase))


def _swing_progress(step: Step, now_s: float) -> float:
    """Fraction of the swing path covered at ``now_s``: a cycloid of the phase (zero velocity
    at lift-off and touch-down)."""
    phase = _swing_phase(step, now_s)
    return phase - math.sin(2.0 * math.pi * phase) / (2.0 * math.pi)
