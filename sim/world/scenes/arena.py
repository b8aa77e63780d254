"""The arena every indoor scene is built in: an MJCF root with a floor, materials, lighting and
depth clip planes, and the primitives (bodies, boxes, cylinders, lights) with unique names.

Conventions: x, y on the floor, z up, metres; yaw in degrees about z, counter-clockwise.
"""

from __future__ import annotations

import math

import numpy as np
from dm_control import mjcf

from sim.world.assembly import SCENE_DEPTH_FAR_M, DEPTH_NEAR_M, clip_plane_fractions
from sim.world.scenes.floor import (BUMP_BASE_M, FLAT, PLANE_BELOW_BUMPS_M, BumpField, Floor,
                                    bump_field)

#: Model extent of every scene, metres (``statistic/extent``): the unit of its clip planes.
MODEL_EXTENT_M = 10.0
#: Half-size of the floor plane, metres.
FLOOR_HALF_SIZE_M = 20.0
#: Elevations of the bump height field are whole numbers from 0 to this (MuJoCo rescales).
ELEVATION_STEPS = 1_000_000

#: The scenes' flat-coloured materials (name: rgba); the floor has its own checker texture.
MATERIALS = {
    "wall": (0.82, 0.80, 0.74, 1), "door": (0.55, 0.38, 0.22, 1), "wood": (0.62, 0.46, 0.30, 1),
    "metal": (0.55, 0.57, 0.60, 1), "plastic": (0.20, 0.35, 0.60, 1), "cardboard": (0.70, 0.55,
    0.35, 1), "fabric": (0.35, 0.20, 0.25, 1), "concrete": (0.60, 0.60, 0.58, 1),
    "dark": (0.15, 0.15, 0.17, 1),
}


def yaw_quat(yaw_deg: float) -> list[float]:
    """Quaternion (w, x, y, z) of a turn by ``yaw_deg`` about z."""
    half = math.radians(yaw_deg) / 2.0
    return [math.cos(half), 0.0, 0.0, math.sin(half)]


class Arena:
    """An empty lit floor in an MJCF model, and the primitives scenes are made of.

    The model renders depth from ``DEPTH_NEAR_M`` to ``SCENE_DEPTH_FAR_M``
    (:mod:`sim.world.assembly`), lit by a soft headlight plus the lights the scene adds.
    Every body, geom and light gets a name made of its kind and a counter (``box12``), so a
    scene built with the same draws has the same names.

    On a flat floor everything is placed in the world body. Otherwise it goes into one body,
    ``floor_frame``, which :meth:`lay_floor` tilts by the floor's slope before it adds the
    bumps (:mod:`sim.world.scenes.floor`); until then the scene is built and checked level.

    Args:
        name: model name of the arena (the scene's name).
        floor: the floor the scene stands on.
    """

    def __init__(self, name: str, floor: Floor = FLAT):
        root = mjcf.RootElement(model=name)
        root.statistic.extent = MODEL_EXTENT_M
        root.visual.map.znear, root.visual.map.zfar = clip_plane_fractions(
            MODEL_EXTENT_M, DEPTH_NEAR_M, SCENE_DEPTH_FAR_M)
        root.visual.headlight.ambient = [0.35, 0.35, 0.35]
        root.visual.headlight.diffuse = [0.4, 0.4, 0.4]
        root.asset.add("texture", name="floor", type="2d", builtin="checker", width=256,
                       height=256, rgb1=[0.45, 0.42, 0.38], rgb2=[0.38, 0.35, 0.32])
        root.asset.add("material", name="floor", texture="floor", texrepeat=[2, 2],
                       texuniform=True, reflectance=0.05)
        for material, rgba in MATERIALS.items():
            root.asset.add("material", name=material, rgba=rgba)
        self.floor = floor
        self.base = root.worldbody if floor.is_flat else root.worldbody.add(
            "body", name="floor_frame")
        plane = self.base.add("geom", name="floor", type="plane",
                              size=[FLOOR_HALF_SIZE_M, FLOOR_HALF_SIZE_M, 0.1], material="floor")
        if floor.bump_height_m > 0:
            plane.pos = [0.0, 0.0, -PLANE_BELOW_BUMPS_M]
        self.root = root
        self._counts: dict[str, int] = {}

    def unique_name(self, kind: str) -> str:
        """``kind`` followed by how many of that kind the arena has had so far (``desk3``)."""
        self._counts[kind] = self._counts.get(kind, 0) + 1
        return f"{kind}{self._counts[kind]}"

    def body(self, kind: str, xy, yaw_deg: float = 0.0, z: float = 0.0, parent=None):
        """A static body at ``xy`` (in ``parent``'s frame; default the floor's), turned by
        yaw."""
        parent = self.base if parent is None else parent
        return parent.add("body", name=self.unique_name(kind), pos=[xy[0], xy[1], z],
                          quat=yaw_quat(yaw_deg))

    def box(self, parent, half_size, pos, material: str):
        """A box geom of half-sizes (x, y, z) centred at ``pos`` in ``parent``'s frame."""
        return parent.add("geom", name=self.unique_name("box"), type="box",
                          size=list(half_size), pos=list(pos), material=material)

    def cylinder(self, parent, radius: float, half_height: float, pos, material: str):
        """An upright cylinder geom centred at ``pos`` in ``parent``'s frame."""
        return parent.add("geom", name=self.unique_name("cyl"), type="cylinder",
                          size=[radius, half_height], pos=list(pos), material=material)

    def light(self, xyz, cast_shadow: bool = False):
        """A spot light at ``xyz`` shining straight down."""
        self.base.add("light", name=self.unique_name("light"), pos=list(xyz), dir=[0, 0, -1],
                      diffuse=[0.5, 0.5, 0.5], castshadow=cast_shadow)

    def ceiling_lights(self, x_range, y_range, height: float, spacing: float = 3.0):
        """A grid of lights ``spacing`` apart over the rectangle ``x_range`` x ``y_range``."""
        for x in np.arange(x_range[0], x_range[1] + 1e-9, spacing):
            for y in np.arange(y_range[0], y_range[1] + 1e-9, spacing):
                self.light([x, y, height])

    def lay_floor(self, path: np.ndarray, seed: int) -> BumpField | None:
        """Finish the floor: tilt the building, then add the bumps around ``path`` (drawn from
        ``seed``) as a level height field following the slope (:mod:`sim.world.scenes.floor`).
        Returns the bumps (None on a smooth floor)."""
        if not self.floor.is_level:
            self.base.quat = self.floor.tilt_quat()
        if self.floor.bump_height_m == 0:
            return None
        bumps = bump_field(path, seed, self.floor.bump_height_m)
        x, y = bumps.grid_xy()
        surface = (self.floor.height(np.stack(np.meshgrid(x, y), axis=-1))
                   + bumps.height_m * bumps.heights)
        bottom, rise = surface.min(), surface.max() - surface.min()
        rows, cols = surface.shape
        # MuJoCo scales the elevations to 0-1 itself: whole millionths of the rise (about
        # 0.3 m at most, on a 3-degree slope: 0.3 um) keep the MJCF short. MJCF lists the rows
        # from the top (+y) down.
        self.root.asset.add(
            "hfield", name="floor_bumps", nrow=rows, ncol=cols,
            size=[*bumps.half_size_xy, rise, BUMP_BASE_M],
            elevation=np.rint((surface[::-1] - bottom) / rise * ELEVATION_STEPS).ravel())
        self.root.worldbody.add("geom", name="floor_bumps", type="hfield", hfield="floor_bumps",
                                pos=[*bumps.centre_xy, bottom], material="floor")
        return bumps
