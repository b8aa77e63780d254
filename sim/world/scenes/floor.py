"""The floor a scene stands on: flat (the default), sloped, bumpy, or both.

A :class:`Floor` is a scene option, not a scene parameter: any scene can be built on any floor
(``build_scene(name, seed, floor=Floor(...))``), and the floor never changes the scene's layout.

- **Slope**: the whole building (floor, walls, furniture, ceiling, lights) is tilted as one
  rigid body by ``slope_deg`` about a horizontal axis through the robot's start, rising along
  ``slope_direction_deg``; gravity stays along -z. So everything stands on the floor exactly
  and renders as it would on level ground, while the robot walks up, down or across a slope.
- **Bumps**: a MuJoCo height field (hfield) over the walk, from 0 to ``bump_height_m`` above
  the floor: Gaussian-smoothed white noise (standard deviation ``BUMP_SMOOTHING_M``) on a
  ``BUMP_CELL_M`` grid, scaled so its highest point is exactly ``bump_height_m``. It covers the
  path's bounding box plus ``BUMP_MARGIN_M`` and fades to 0 within ``BUMP_FADE_M`` of its
  border and around the start (flat within ``START_FLAT_RADIUS_M``, so the robot is placed
  standing on the floor itself). The noise is drawn from its own stream of the scene seed
  (:func:`bump_rng`), so bumps never change the scene's other draws. The height field is a
  level geom whose heights are the sloped floor's plus the bumps: MuJoCo's contacts of the
  feet with a *rotated* height field were found to be unreliable (a robot standing on a 3-degree
  rotated one rocked onto its heels and fell, on the same slope as a plane it stood on), while
  a level one with the slope in its heights walks as the plane does. The floor plane lies
  ``PLANE_BELOW_BUMPS_M`` below it, out of sight.

Conventions: x, y on the floor, z up, metres; directions in degrees counter-clockwise from +x.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any, Mapping

import numpy as np
from scipy.ndimage import gaussian_filter

#: Steepest slope accepted, degrees.
MAX_SLOPE_DEG = 3.0
#: Highest bumps accepted, metres.
MAX_BUMP_HEIGHT_M = 0.005
#: Grid spacing of the bump height field, metres (the sole is 13 x 7.5 cm).
BUMP_CELL_M = 0.02
#: Standard deviation of the Gaussian that smooths the bumps' white noise, metres.
BUMP_SMOOTHING_M = 0.05
#: How far the bump field reaches beyond the path's bounding box, metres.
BUMP_MARGIN_M = 1.0
#: Width of the band over which the bumps fade in from the field's border and the start, m.
BUMP_FADE_M = 0.25
#: Radius of the flat patch the robot starts on, metres.
START_FLAT_RADIUS_M = 0.2
#: Depth of the bump field's base below the floor, metres (hidden under the floor plane).
BUMP_BASE_M = 0.01
#: The floor plane lies this far below the bump field's zero level (in the floor's frame), so
#: that the two surfaces never coincide (which would flicker in colour renderings), metres.
PLANE_BELOW_BUMPS_M = 0.0005
#: Spawn key of the bumps' random stream of the scene seed.
BUMP_STREAM = 1


class FloorParameterError(ValueError):
    """A floor setting that cannot be used: names the setting, what is wrong and what is
    accepted, on one line."""

    def __init__(self, parameter: str, problem: str, accepted: str):
        self.parameter, self.problem, self.accepted = parameter, problem, accepted
        super().__init__(f"floor: parameter {parameter!r}: {problem}; accepted: {accepted}")

    def __reduce__(self):  # picklable, so a process pool can report it
        return FloorParameterError, (self.parameter, self.problem, self.accepted)


#: Setting -> (low, high, accepted in words).
FLOOR_BOUNDS = {
    "slope_deg": (0.0, MAX_SLOPE_DEG, f"a number of degrees from 0 to {MAX_SLOPE_DEG:g}"),
    "slope_direction_deg": (-360.0, 360.0, "a number of degrees from -360 to 360 (the uphill "
                            "direction, counter-clockwise from +x)"),
    "bump_height_m": (0.0, MAX_BUMP_HEIGHT_M,
                      f"a number of metres from 0 to {MAX_BUMP_HEIGHT_M:g}"),
}


@dataclasses.dataclass(frozen=True)
class Floor:
    """A scene's floor (docs/scenes.md, "Floors").

    Args:
        slope_deg: angle of the floor with the horizontal, degrees, 0-3; default 0 (level).
        slope_direction_deg: direction the floor rises towards, degrees counter-clockwise from
            +x (0: the robot starts walking uphill); default 0.
        bump_height_m: height of the highest bump above the floor, metres, 0-0.005; default 0
            (smooth).
    """

    slope_deg: float = 0.0
    slope_direction_deg: float = 0.0
    bump_height_m: float = 0.0

    def __post_init__(self):
        for name, (low, high, accepted) in FLOOR_BOUNDS.items():
            value = getattr(self, name)
            if not (isinstance(value, (int, float, np.integer, np.floating))
                    and not isinstance(value, bool) and math.isfinite(value)
                    and low <= value <= high):
                raise FloorParameterError(name, f"got {value!r}", accepted)
            object.__setattr__(self, name, float(value))

    @classmethod
    def from_params(cls, params: Mapping[str, Any]) -> "Floor":
        """The floor with ``params`` (setting -> value) and defaults for the rest."""
        for name in params:
            if name not in FLOOR_BOUNDS:
                raise FloorParameterError(str(name), "unknown parameter",
                                          ", ".join(FLOOR_BOUNDS))
        return cls(**params)

    @property
    def is_level(self) -> bool:
        return self.slope_deg == 0.0

    @property
    def is_flat(self) -> bool:
        """Level and smooth: the scenes' plain floor plane, nothing added."""
        return self.is_level and self.bump_height_m == 0.0

    def uphill(self) -> np.ndarray:
        """Unit vector (x, y) of the direction the floor rises towards."""
        direction = math.radians(self.slope_direction_deg)
        return np.array([math.cos(direction), math.sin(direction)])

    def tilt_quat(self) -> list[float]:
        """Quaternion (w, x, y, z) of the building's tilt: a turn by ``slope_deg`` about the
        horizontal axis ``uphill x z``, which lifts the uphill side."""
        half = math.radians(self.slope_deg) / 2.0
        axis_x, axis_y = self.uphill()[1], -self.uphill()[0]
        return [math.cos(half), axis_x * math.sin(half), axis_y * math.sin(half), 0.0]

    def height(self, xy) -> np.ndarray:
        """Height of the (tilted) floor plane above the world point(s) ``xy``, without bumps."""
        return np.tan(math.radians(self.slope_deg)) * (np.asarray(xy, float) @ self.uphill())


#: The default floor: level and smooth.
FLAT = Floor()


def bump_rng(seed: int) -> np.random.Generator:
    """The bumps' generator: a stream of the scene seed separate from the scene's own."""
    return np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(BUMP_STREAM,)))


@dataclasses.dataclass(frozen=True)
class BumpField:
    """Bumps on a grid over a rectangle of the world's x, y (the floor's slope not included).

    Attributes:
        heights: (rows along y, columns along x) heights from 0 to 1 (times ``height_m``),
            row 0 at the lowest y; its maximum is 1.
        centre_xy: centre of the rectangle, metres.
        half_size_xy: half its size along x and y, metres (the grid's outer points lie on it).
        height_m: height of the highest bump, metres.
    """

    heights: np.ndarray
    centre_xy: np.ndarray
    half_size_xy: np.ndarray
    height_m: float

    def grid_xy(self) -> tuple[np.ndarray, np.ndarray]:
        """x of the columns and y of the rows of the grid, metres."""
        rows, cols = self.heights.shape
        low = self.centre_xy - self.half_size_xy
        return (low[0] + np.linspace(0, 2 * self.half_size_xy[0], cols),
                low[1] + np.linspace(0, 2 * self.half_size_xy[1], rows))

    def height_at(self, xy) -> np.ndarray:
        """Bump height (m) at point(s) ``xy``; 0 outside the field. Exact at the grid points;
        between them bilinear, where MuJoCo's two triangles per cell differ by a fraction of
        the cell's own height variation."""
        xy = np.atleast_2d(np.asarray(xy, float))
        rows, cols = self.heights.shape
        grid = (xy - (self.centre_xy - self.half_size_xy)) / (2 * self.half_size_xy) \
            * [cols - 1, rows - 1]
        inside = np.all((grid >= 0) & (grid <= [cols - 1, rows - 1]), axis=1)
        col = np.clip(grid[:, 0], 0, cols - 1)
        row = np.clip(grid[:, 1], 0, rows - 1)
        c0, r0 = np.minimum(col.astype(int), cols - 2), np.minimum(row.astype(int), rows - 2)
        fc, fr = col - c0, row - r0
        h = self.heights
        value = ((1 - fr) * ((1 - fc) * h[r0, c0] + fc * h[r0, c0 + 1])
                 + fr * ((1 - fc) * h[r0 + 1, c0] + fc * h[r0 + 1, c0 + 1]))
        return np.where(inside, value * self.height_m, 0.0)


def bump_field(path: np.ndarray, seed: int, height_m: float) -> BumpField:
    """The bumps around ``path`` (N, 2) drawn from ``seed`` (see the module docstring)."""
    low = path.min(axis=0) - BUMP_MARGIN_M
    high = path.max(axis=0) + BUMP_MARGIN_M
    cols, rows = (np.ceil((high - low) / BUMP_CELL_M).astype(int) + 1)
    half_size = BUMP_CELL_M * (np.array([cols, rows]) - 1) / 2.0
    centre = low + half_size
    x = low[0] + BUMP_CELL_M * np.arange(cols)
    y = low[1] + BUMP_CELL_M * np.arange(rows)
    noise = gaussian_filter(bump_rng(seed).standard_normal((rows, cols)),
                            BUMP_SMOOTHING_M / BUMP_CELL_M, mode="reflect")
    noise = (noise - noise.min()) / (noise.max() - noise.min())
    to_border = np.minimum.outer(np.minimum(y - low[1], low[1] + 2 * half_size[1] - y),
                                 np.minimum(x - low[0], low[0] + 2 * half_size[0] - x))
    grid_x, grid_y = np.meshgrid(x, y)
    to_start = np.hypot(grid_x - path[0, 0], grid_y - path[0, 1]) - START_FLAT_RADIUS_M
    window = _fade_in(to_border) * _fade_in(to_start)
    heights = noise * window
    return BumpField(heights / heights.max(), centre, half_size, float(height_m))


def _fade_in(distance: np.ndarray) -> np.ndarray:
    """0 at distance <= 0, rising smoothly (raised cosine) to 1 at ``BUMP_FADE_M``."""
    ramp = np.clip(distance / BUMP_FADE_M, 0.0, 1.0)
    return 0.5 - 0.5 * np.cos(math.pi * ramp)
