"""The humanoid robot as a dm_control MJCF element, ready to attach to an arena.

The robot itself lives in ``robot_models/humanoid/humanoid.xml`` (see its README for the DOF
split, masses and the SR4000's intrinsics). This module only loads it and names the parts the
rest of the harness looks up.
"""

from __future__ import annotations

import mujoco
import numpy as np
from dm_control import mjcf

from robot_models import humanoid_path

#: Model name dm_control prefixes to every element name once the robot is attached.
MODEL_NAME = "humanoid"
#: Name of the SR4000 camera inside the robot's MJCF, and its full name after attachment.
CAMERA_LOCAL_NAME = "sr4000"
CAMERA_NAME = f"{MODEL_NAME}/{CAMERA_LOCAL_NAME}"
#: Site on the camera's optical frame (same pose as the camera).
CAMERA_SITE_NAME = f"{MODEL_NAME}/sr4000_frame"
#: The root body of the robot (carries the IMU) after attachment.
TORSO_BODY_NAME = f"{MODEL_NAME}/torso"
#: Leg joint names in actuator order, per side (hip yaw, hip roll, hip pitch, knee, ankle pitch,
#: ankle roll): the order the leg inverse kinematics returns its angles in.
LEG_JOINTS = ("hip_yaw", "hip_roll", "hip_pitch", "knee", "ankle_pitch", "ankle_roll")
SIDES = ("l", "r")


def humanoid_mjcf() -> mjcf.RootElement:
    """The robot's MJCF without its free joint, ready for ``arena.attach``
    (sim.world.assembly.assemble adds the free joint to the attachment frame)."""
    robot = mjcf.from_path(str(humanoid_path("humanoid.xml")))
    robot.model = MODEL_NAME
    # The standalone file carries a free joint so scene.xml works alone; once attached, the
    # attachment frame carries the free joint instead.
    robot.find("body", "torso").freejoint.remove()
    return robot


def robot_body_ids(model: mujoco.MjModel) -> np.ndarray:
    """Ids of the robot's bodies in a compiled world: the torso and all its descendants."""
    root = model.body(TORSO_BODY_NAME).id
    inside = np.zeros(model.nbody, dtype=bool)
    inside[root] = True
    for body in range(root + 1, model.nbody):        # MuJoCo lists parents before children
        inside[body] = inside[model.body_parentid[body]]
    return np.flatnonzero(inside)
