"""A finished :class:`Scene`, and the :class:`SceneBuilder` a scene is made with."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import mujoco
import numpy as np
from dm_control import mjcf

from sim.world.scenes.arena import Arena
from sim.world.scenes.floor import FLAT, BumpField, Floor
from sim.world.scenes.furniture import Furniture
from sim.world.scenes.lane import CLEAR_HALF_WIDTH_M, lane_intrusions, start_heading_deg
from sim.world.scenes.placement import Placement
from sim.world.scenes.structure import Structure


@dataclass(frozen=True)
class Scene:
    """An indoor scene: the arena (no robot yet) and the path the robot walks.

    Attributes:
        name: scene name (a key of ``sim.world.scenes.SCENES``).
        seed: the seed its random choices were drawn from.
        arena: the MJCF root; attach the robot with ``sim.world.assembly.assemble``.
        path: (N, 2) waypoints on the floor, from the start to the end of the walk.
        start_xy: where the robot stands at the start (path[0]).
        start_yaw_deg: its heading at the start (direction of the path's first segment).
        clear_half_width_m: half-width of the obstacle-free lane around the path.
        description: one line for reports.
        params: the scene's parameters (name -> value, defaults included).
        floor: the floor it stands on (:mod:`sim.world.scenes.floor`).
        bumps: the floor's bumps over the world's x, y (None on a smooth floor).
    """

    name: str
    seed: int
    arena: mjcf.RootElement
    path: np.ndarray
    start_xy: np.ndarray
    start_yaw_deg: float
    clear_half_width_m: float = CLEAR_HALF_WIDTH_M
    description: str = ""
    params: dict[str, Any] = field(default_factory=dict)
    floor: Floor = FLAT
    bumps: BumpField | None = None

    def compile(self) -> mujoco.MjModel:
        """The arena alone compiled, with its own clip planes (no robot)."""
        return mujoco.MjModel.from_xml_string(self.arena.to_xml_string(),
                                              self.arena.get_assets())


class SceneBuilder:
    """The parts one scene is built with, sharing one random generator seeded once.

    Attributes:
        rng: the generator every random choice of the scene is drawn from, in order.
        arena: the MJCF model and its primitives (:class:`~sim.world.scenes.arena.Arena`).
        placement: the lane to keep free and the footprints taken
            (:class:`~sim.world.scenes.placement.Placement`).
        structure: walls, rooms, doors, stairs, pillars
            (:class:`~sim.world.scenes.structure.Structure`).
        furniture: the furniture catalogue (:class:`~sim.world.scenes.furniture.Furniture`).

    Args:
        name: the scene's name (also the model's).
        seed: seed of the random generator.
        path: the robot's path (N, 2); nothing is placed within ``clear_half_width_m`` of it.
        clear_half_width_m: half-width of the lane kept free.
        floor: the floor the scene stands on; it is laid (bumps, tilt) by :meth:`finish`.
    """

    def __init__(self, name: str, seed: int, path: np.ndarray,
                 clear_half_width_m: float = CLEAR_HALF_WIDTH_M, floor: Floor = FLAT):
        self.name, self.seed, self.path = name, seed, path
        self.rng = np.random.default_rng(seed)
        self.arena = Arena(name, floor)
        self.placement = Placement(path, self.rng, clear_half_width_m)
        self.structure = Structure(self.arena, self.placement)
        self.furniture = Furniture(self.arena, self.rng)

    def place_crates(self, zone, smallest, largest, max_stack: int = 3):
        """A stack of 1 to ``max_stack`` crates, the lowest with half-sizes drawn between
        ``smallest`` and ``largest`` (x, y, z), at a free pose in ``zone``."""
        half = self.rng.uniform(smallest, largest)
        stack = int(self.rng.integers(1, max_stack + 1))
        return self.placement.place(
            lambda xy, yaw: self.furniture.crate(xy, yaw, half, stack=stack), half[:2], zone)

    def place_barrel(self, zone, radii, heights, material="plastic"):
        """An upright cylinder, radius and height drawn from the (low, high) ranges, at a free
        pose in ``zone``."""
        radius, height = self.rng.uniform(*radii), self.rng.uniform(*heights)
        return self.placement.place(
            lambda xy, yaw: self.furniture.barrel(xy, yaw, radius, height, material),
            (radius, radius), zone)

    def finish(self, description: str, params: dict[str, Any]) -> Scene:
        """The finished Scene, its floor laid; raises if anything reaches into the lane (checked
        on the level, smooth floor, where the lane is flat)."""
        clear = self.placement.clear_half_width_m
        intruders = lane_intrusions(mujoco.MjModel.from_xml_string(
            self.arena.root.to_xml_string(), self.arena.root.get_assets()), self.path, clear)
        if intruders:
            raise RuntimeError(f"scene {self.name!r} seed {self.seed}: {intruders} reach into "
                               f"the robot's lane (parameters {params})")
        bumps = self.arena.lay_floor(self.path, self.seed)
        return Scene(self.name, self.seed, self.arena.root, self.path.copy(),
                     self.path[0].copy(), start_heading_deg(self.path), clear, description,
                     dict(params), self.arena.floor, bumps)
