"""Assemble a world: an arena (any dm_control MJCF) plus the free-standing humanoid.

The robot is attached through an attachment frame that carries a free joint, so it stands on
the arena's floor and moves only under physics (docs/walking.md, "Composing scenes").
"""

from __future__ import annotations

import math

import mujoco
import numpy as np
from dm_control import mjcf

from sim.world.humanoid import TORSO_BODY_NAME, humanoid_mjcf

#: Physics settings the walking controller is tuned for (docs/walking.md recipe, step 6).
PHYSICS_TIMESTEP_S = 0.0025
#: Rendered depth range, metres: the SR4000's 0.1-10 m with margin. MuJoCo takes it as clip
#: planes in fractions of the model extent (:func:`clip_plane_fractions`).
DEPTH_NEAR_M = 0.05
#: Farthest rendered depth of an assembled world (:func:`compile_world`).
DEPTH_FAR_M = 20.0
#: Farthest rendered depth of a scene compiled on its own, without the robot
#: (``sim.world.scenes.Scene.compile``: probe cameras in tests, the render benchmark); the
#: scenes' MJCF carries it, and pixels that see no surface read it.
SCENE_DEPTH_FAR_M = 30.0


def clip_plane_fractions(extent_m: float, near_m: float = DEPTH_NEAR_M,
                         far_m: float = DEPTH_FAR_M) -> tuple[float, float]:
    """MuJoCo's clip planes ``(znear, zfar)`` for a depth range in metres.

    MuJoCo expresses ``visual/map`` znear and zfar as fractions of the model extent
    (``statistic/extent``, or the compiled ``model.stat.extent``).
    """
    if not (extent_m > 0 and 0 < near_m < far_m):
        raise ValueError(f"need extent_m > 0 and 0 < near_m < far_m; got extent_m={extent_m}, "
                         f"near_m={near_m}, far_m={far_m}")
    return near_m / extent_m, far_m / extent_m


def floor_arena() -> mjcf.RootElement:
    """A plain lit floor, 20 m x 20 m, with a checker texture."""
    arena = mjcf.RootElement(model="floor_arena")
    arena.asset.add(
        "texture", name="grid", type="2d", builtin="checker", width=300, height=300,
        rgb1=(0.2, 0.3, 0.4), rgb2=(0.1, 0.2, 0.3), mark="edge", markrgb=(0.8, 0.8, 0.8),
    )
    arena.asset.add("material", name="grid", texture="grid", texrepeat=(20, 20), texuniform=True)
    arena.worldbody.add("light", pos=(0, 0, 3), dir=(0, 0, -1), directional=True)
    arena.worldbody.add("geom", name="floor", type="plane", size=(10, 10, 0.05), material="grid")
    return arena


def assemble(arena: mjcf.RootElement | None = None, start_xy=(0.0, 0.0),
             start_yaw_deg: float = 0.0) -> mjcf.RootElement:
    """Attach the humanoid to ``arena`` standing at ``start_xy`` facing ``start_yaw_deg``.

    Args:
        arena: an MJCF root with a floor at z = 0 (a plain floor when None). It is modified in
            place: the robot is attached and the physics options are set to the controller's.
        start_xy: (x, y) of the robot's torso on the floor, metres.
        start_yaw_deg: heading, degrees counter-clockwise from the world +x axis.

    Returns:
        The world's MJCF root (``arena``).
    """
    if len(start_xy) != 2 or not all(math.isfinite(float(v)) for v in start_xy):
        raise ValueError(f"start_xy must be two finite numbers (x, y) in metres, got {start_xy!r}")
    if not math.isfinite(float(start_yaw_deg)):
        raise ValueError(f"start_yaw_deg must be a finite number of degrees, got {start_yaw_deg!r}")
    world = floor_arena() if arena is None else arena
    half_yaw = math.radians(float(start_yaw_deg)) / 2.0
    robot = humanoid_mjcf()
    # The free joint then moves the torso itself: its pose is the attachment frame's.
    torso = robot.find("body", "torso")
    straight_leg_height = float(torso.pos[2])
    torso.pos = (0.0, 0.0, 0.0)
    frame = world.attach(robot)
    frame.pos = (float(start_xy[0]), float(start_xy[1]), straight_leg_height)
    frame.quat = (math.cos(half_yaw), 0.0, 0.0, math.sin(half_yaw))
    frame.add("freejoint")
    world.option.timestep = PHYSICS_TIMESTEP_S
    world.option.integrator = "implicitfast"
    world.option.iterations = 20
    world.option.ls_iterations = 8
    return world


def compile_world(world_mjcf: mjcf.RootElement) -> mujoco.MjModel:
    """Compile an assembled world (with its assets) into an MjModel.

    The depth clipping planes are set on the compiled model so the camera renders depth from
    ``DEPTH_NEAR_M`` to ``DEPTH_FAR_M`` whatever the world's size: the model extent they are
    fractions of is known only after compiling.
    """
    model = mujoco.MjModel.from_xml_string(world_mjcf.to_xml_string(), world_mjcf.get_assets())
    model.vis.map.znear, model.vis.map.zfar = clip_plane_fractions(model.stat.extent)
    return model


def free_joint_qpos_address(model: mujoco.MjModel) -> int:
    """Index in qpos of the robot's free joint: the torso's position xyz, then quaternion wxyz."""
    frame_body = model.body_parentid[model.body(TORSO_BODY_NAME).id]
    for joint in np.flatnonzero(model.jnt_type == mujoco.mjtJoint.mjJNT_FREE):
        if model.jnt_bodyid[joint] == frame_body:
            return int(model.jnt_qposadr[joint])
    raise ValueError("the model has no free joint carrying the humanoid; build it with "
                     "sim.world.assembly.assemble")
