"""Fall detection and foot contacts of the humanoid, from MuJoCo's state and contacts."""

from __future__ import annotations

import math
from dataclasses import dataclass

import mujoco
import numpy as np

from sim.world.humanoid import MODEL_NAME, SIDES, robot_body_ids


@dataclass(frozen=True)
class FallEvent:
    """The robot fell at ``time_s``: ``reason`` is "torso_low", "torso_tilt" or
    "contact:<body>" (a body other than the feet touched the world)."""

    time_s: float
    reason: str


class FallDetector:
    """Checks the torso's height and tilt and which robot bodies touch the world.

    Args:
        model: a world built by sim.world.assembly.assemble.
        min_torso_height_m: the torso origin less than this above the lower foot's origin is
            a fall (standing: ~0.30 m; the foot's origin is 0.035 m above its sole, so the
            default is 0.2 m above a flat floor). Measured from the feet, not from z = 0, so a
            walk down a sloped floor is not taken for a fall.
        max_tilt_deg: the torso's z axis further than this from vertical is a fall.
    """

    def __init__(self, model: mujoco.MjModel, min_torso_height_m: float = 0.165,
                 max_tilt_deg: float = 45.0):
        self.min_torso_height_m = min_torso_height_m
        self.min_cos_tilt = math.cos(math.radians(max_tilt_deg))
        self._torso_id = model.body(f"{MODEL_NAME}/torso").id
        self._robot_geom = np.isin(model.geom_bodyid, robot_body_ids(model))
        self._foot_body = [model.body(f"{MODEL_NAME}/{s}_foot").id for s in SIDES]
        self._non_foot_geom = self._robot_geom & ~np.isin(model.geom_bodyid, self._foot_body)
        self._geom_body = model.geom_bodyid
        self._model = model

    def _world_contacts(self, data: mujoco.MjData) -> tuple[np.ndarray, np.ndarray]:
        """Robot geoms touching a non-robot geom: (robot geom ids, count)."""
        pairs = data.contact.geom[: data.ncon]
        robot = self._robot_geom[pairs]
        touching = robot[:, 0] != robot[:, 1]
        return np.where(robot[touching, 0], pairs[touching, 0], pairs[touching, 1])

    def check(self, data: mujoco.MjData) -> FallEvent | None:
        """A FallEvent if the robot is down now, else None."""
        torso_height = data.xpos[self._torso_id, 2] - data.xpos[self._foot_body, 2].min()
        if torso_height < self.min_torso_height_m:
            return FallEvent(float(data.time), "torso_low")
        if data.xmat[self._torso_id, 8] < self.min_cos_tilt:
            return FallEvent(float(data.time), "torso_tilt")
        for geom in self._world_contacts(data):
            if self._non_foot_geom[geom]:
                name = self._model.body(self._geom_body[geom]).name
                return FallEvent(float(data.time), f"contact:{name}")
        return None

    def foot_contacts(self, data: mujoco.MjData) -> tuple[bool, bool]:
        """(left, right): whether each foot touches the world."""
        bodies = self._geom_body[self._world_contacts(data)]
        return tuple(bool(np.any(bodies == foot)) for foot in self._foot_body)

