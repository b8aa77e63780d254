"""Placement of furniture by rejection sampling: random poses in a zone until the footprint
keeps out of the robot's lane and off everything placed before.

Footprints are axis-aligned rectangles on the floor around each (turned) object; fixed
structures (walls, doors, stairs, pillars) reserve theirs so furniture keeps off them too.
"""

from __future__ import annotations

import math

import numpy as np

from sim.world.scenes.lane import CLEAR_HALF_WIDTH_M, path_distance

#: Extra clearance between a footprint and the lane, metres.
LANE_MARGIN_M = 0.02
#: Smallest gap between two footprints, metres.
FOOTPRINT_GAP_M = 0.05
#: Random turn added to each placed object's heading, degrees (at most, either way).
YAW_JITTER_DEG = 8.0


class Placement:
    """The floor of one scene: the lane to keep free and the footprints taken so far.

    Args:
        path: the robot's path (N, 2).
        rng: the scene's random generator (poses are drawn from it).
        clear_half_width_m: half-width of the lane kept free around ``path``.
    """

    def __init__(self, path: np.ndarray, rng: np.random.Generator,
                 clear_half_width_m: float = CLEAR_HALF_WIDTH_M):
        self.path = path
        self.rng = rng
        self.clear_half_width_m = clear_half_width_m
        self._footprints: list[np.ndarray] = []

    def fits(self, xy, half_extents, yaw_deg: float) -> bool:
        """True if a footprint keeps out of the lane and off the footprints taken so far."""
        box = footprint_box(xy, half_extents, yaw_deg)
        if path_distance(self.path, box)[0] < self.clear_half_width_m + LANE_MARGIN_M:
            return False
        return all(not _overlap(box, other, FOOTPRINT_GAP_M) for other in self._footprints)

    def place(self, build, half_extents, zone, yaw_choices=(0, 90, 180, 270),
              tries: int = 200):
        """Call ``build(xy, yaw_deg)`` at the first random pose in ``zone`` where the footprint
        fits.

        Args:
            build: makes the object at a pose (a furniture method, for instance).
            half_extents: half-sizes (x, y) of the object's footprint in its own frame.
            zone: (xmin, xmax, ymin, ymax) where the object's centre may go.
            yaw_choices: headings to choose from, degrees; each gets a random turn of up to
                ``YAW_JITTER_DEG`` either way.
            tries: poses drawn before giving up.

        Returns:
            The pose ``(xy, yaw_deg)``, or None when no pose fitted (nothing is built).
        """
        for _ in range(tries):
            xy = (self.rng.uniform(zone[0], zone[1]), self.rng.uniform(zone[2], zone[3]))
            yaw = float(self.rng.choice(yaw_choices)) + self.rng.uniform(-YAW_JITTER_DEG,
                                                                         YAW_JITTER_DEG)
            if self.fits(xy, half_extents, yaw):
                self._footprints.append(footprint_box(xy, half_extents, yaw))
                build(xy, yaw)
                return xy, yaw
        return None

    def reserve(self, xy, half_extents, yaw_deg: float = 0.0) -> None:
        """Mark a footprint as taken (fixed structures such as walls and stairs)."""
        self._footprints.append(footprint_box(xy, half_extents, yaw_deg))


def footprint_box(xy, half_extents, yaw_deg) -> np.ndarray:
    """Axis-aligned box (xmin, ymin, xmax, ymax) around a rectangle turned by ``yaw_deg``."""
    c, s = abs(math.cos(math.radians(yaw_deg))), abs(math.sin(math.radians(yaw_deg)))
    hx = c * half_extents[0] + s * half_extents[1]
    hy = s * half_extents[0] + c * half_extents[1]
    return np.array([xy[0] - hx, xy[1] - hy, xy[0] + hx, xy[1] + hy])


def _overlap(a, b, gap) -> bool:
    return not (a[2] + gap <= b[0] or b[2] + gap <= a[0] or a[3] + gap <= b[1]
                or b[3] + gap <= a[1])
