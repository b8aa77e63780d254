"""Counterbalance of a push towards the support foot: the waist rolls the upper body into the
push, the swing leg swings away from it.

In single support, a sideways push towards the support foot's side drives the centre of mass
over the support foot's outer edge, where no step can go (the swing foot is on the other side;
docs/walking.md, "Known limits"). What is left are whole-body moves of the hip-strategy
family (Horak & Nashner, "Central programming of postural movements", J. Neurophysiol. 1986;
for humanoids, Stephens, "Humanoid push recovery", Humanoids 2007), here as position targets:

- the waist rolls the upper body (half the robot's mass) quickly towards the push, so that the
  reaction at the waist turns the legs and pelvis back against the fall (rolling it away from
  the push toppled the robot at smaller pushes: docs/walking.md, "Push recovery");
- the swing leg abducts away from the push, its mass a counterweight on the other side, and
  comes back to its planned landing before touch-down.

The moves start when the capture point's departure from its learnt pattern (push detection,
capture_point.py) points outwards of the support foot, more than forwards or backwards, in
single support; they ramp in over ``ramp_in_s`` and end after the step: the swing leg is back
on its plan ``swing_return_s`` before touch-down, the waist ``waist_hold_s`` after touch-down,
then returns over ``waist_return_s``. Unpushed walking never detects a push, so it never
moves.
"""

from __future__ import annotations

from dataclasses import dataclass

from sim.world.walking.footsteps import SIDE_SIGN


@dataclass(frozen=True)
class Counterbalance:
    """One counterbalance move after a push towards the support foot's side.

    Angles are radians; ``support_side`` indexes SIDES (the swing leg is the other one).
    """

    support_side: int
    start_s: float
    touchdown_s: float
    waist_roll_rad: float = 0.3
    swing_hip_roll_rad: float = 0.4
    ramp_in_s: float = 0.05
    swing_return_s: float = 0.1
    waist_hold_s: float = 0.2
    waist_return_s: float = 0.3

    @property
    def swing_side(self) -> int:
        return 1 - self.support_side

    def offsets(self, now_s: float) -> tuple[float, float]:
        """(waist roll, swing hip roll) to add to the targets at ``now_s``."""
        ramp_in = min(1.0, max(0.0, (now_s - self.start_s) / self.ramp_in_s))
        swing = min(ramp_in, max(0.0, (self.touchdown_s - now_s) / self.swing_return_s))
        waist = min(ramp_in, max(0.0, 1.0 - (now_s - self.touchdown_s - self.waist_hold_s)
                                 / self.waist_return_s))
        # A positive roll (about +x) tilts the upper body's top towards -y and moves a hanging
        # foot towards +y; the push goes towards +y times SIDE_SIGN[support]: both moves
        # are negative rolls for a push to +y.
        towards_push = SIDE_SIGN[self.support_side]
        return (-towards_push * self.waist_roll_rad * waist,
                -towards_push * self.swing_hip_roll_rad * swing)

    def finished(self, now_s: float) -> bool:
        return now_s >= self.touchdown_s + self.waist_hold_s + self.waist_return_s
