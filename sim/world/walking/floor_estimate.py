"""The floor's slope as the feet measure it, for planning the feet on sloped floors.

The footstep planner plans on a level floor. On a sloped one the support foot lies flat on the
floor, so a leg planned for a level floor holds the torso square to the floor, tilted by the
slope: downhill of the foot by about z_c tan(slope) (1.7 cm at 3 degrees), which is where the
robot tips over (docs/walking.md, Sloped floors), and the swing foot lands on its heel or toe,
early or late. :class:`FloorEstimate` measures the slope from the footholds and gives the
plane the feet are planned on, so the legs tilt the feet with the floor and keep the torso
upright.

Each step, half-way through it (in single support, when the support foot lies flattest), the
support foot's sole is measured: its normal gives the floor's gradient there. On a real robot that
is the torso's attitude from the IMU composed with the support leg's forward kinematics; here
it is MuJoCo's pose of the sole site, the same quantity without sensor noise. The estimate is
the median gradient of the last ``footholds`` footholds (bumps tilt single soles, and a push
can leave a foot on its edge half-way through a step: the median ignores up to two such
footholds of five). A sole tilted by more than ``max_slope_deg`` is taken for a foot on its
edge, not for the floor, and ignored: a strong push rolls the support foot by 10-30 degrees
for several steps, while on the roughest floors of docs/scenes.md (3 degrees, 5 mm bumps)
all but one or two footholds of a 20 s walk tilt by at most 4.1 degrees. The estimate is adopted
only when it departs from the current one by more than ``tilt_tolerance_deg``, so that the
soles' small rocking on a level floor leaves the level plan exactly as it was. The plane the
feet are planned on then follows the adopted gradient with a first-order lag of
``time_constant_s``, so the ankles do not jump. Only the gradient matters: the leg IK uses
the feet's heights relative to the torso, which is placed at a constant height above the
plane under the planned centre of mass.
"""

from __future__ import annotations

import math
from collections import deque

import numpy as np


class FloorEstimate:
    """Gradient (dz/dx, dz/dy) of the floor plane the feet are planned on.

    Args:
        control_period_s: period of ``advance``.
        footholds: number of latest footholds whose median is the estimate.
        tilt_tolerance_deg: a measured slope within this of the current one changes nothing.
        time_constant_s: lag of the planned plane behind the adopted estimate.
        max_slope_deg: footholds tilted more than this are ignored (a foot on its edge).
    """

    def __init__(self, control_period_s: float, footholds: int = 5,
                 tilt_tolerance_deg: float = 1.0, time_constant_s: float = 0.2,
                 max_slope_deg: float = 6.0):
        if (footholds < 1 or tilt_tolerance_deg < 0 or time_constant_s <= 0
                or not 0 < max_slope_deg < 90):
            raise ValueError(f"FloorEstimate: footholds must be >= 1, tilt_tolerance_deg >= 0, "
                             f"time_constant_s > 0 and max_slope_deg in (0, 90), got {footholds}, "
                             f"{tilt_tolerance_deg}, {time_constant_s}, {max_slope_deg}")
        self._gradients: deque[tuple[float, float]] = deque(maxlen=footholds)
        self._tolerance = math.tan(math.radians(tilt_tolerance_deg))
        self._max_gradient = math.tan(math.radians(max_slope_deg))
        self._blend = min(1.0, control_period_s / time_constant_s)
        #: The adopted estimate, (dz/dx, dz/dy).
        self.estimate = (0.0, 0.0)
        #: The plane the feet are planned on now, (dz/dx, dz/dy).
        self.gradient = (0.0, 0.0)

    @property
    def is_level(self) -> bool:
        return self.gradient == (0.0, 0.0)

    def measure(self, sole_rot: np.ndarray) -> None:
        """Record a foothold: the support sole's orientation (3x3, world frame; its z axis is
        the floor's normal there)."""
        nx, ny, nz = float(sole_rot[0, 2]), float(sole_rot[1, 2]), float(sole_rot[2, 2])
        if nz <= 0.0 or math.hypot(nx, ny) > self._max_gradient * nz:
            return
        self._gradients.append((-nx / nz, -ny / nz))
        gx, gy = np.median(np.array(self._gradients), axis=0)
        if math.hypot(gx - self.estimate[0], gy - self.estimate[1]) > self._tolerance:
            self.estimate = (float(gx), float(gy))

    def advance(self) -> None:
        """One control period: the planned plane moves towards the estimate."""
        if self.gradient != self.estimate:
            gx, gy = self.gradient
            self.gradient = (gx + self._blend * (self.estimate[0] - gx),
                             gy + self._blend * (self.estimate[1] - gy))

    def height(self, x: float, y: float, origin_x: float, origin_y: float) -> float:
        """Height of the planned plane at (x, y) relative to (origin_x, origin_y)."""
        return self.gradient[0] * (x - origin_x) + self.gradient[1] * (y - origin_y)

    def tilt(self) -> np.ndarray:
        """The rotation (3x3) that takes the world's z axis onto the plane's normal by the
        shortest way: a foot turned by ``tilt() @ rot_z(yaw)`` lies flat on the plane."""
        gx, gy = self.gradient
        normal = np.array([-gx, -gy, 1.0]) / math.sqrt(gx * gx + gy * gy + 1.0)
        axis = np.array([-normal[1], normal[0], 0.0])           # z x normal
        sin = math.hypot(axis[0], axis[1])
        if sin == 0.0:
            return np.eye(3)
        axis /= sin
        cos = normal[2]
        k = np.array([[0.0, -axis[2], axis[1]], [axis[2], 0.0, -axis[0]],
                      [-axis[1], axis[0], 0.0]])
        return np.eye(3) + sin * k + (1.0 - cos) * (k @ k)     # Rodrigues' formula
