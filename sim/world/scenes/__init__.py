"""Indoor scenes the robot walks through: a registry and ``build_scene(name, seed, **params)``.

Each scene is a class in the manner of dm_control's locomotion arenas: its constructor's
keyword arguments are its parameters (ranges drawn from the seeded generator, counts,
positions; documented, with defaults), and ``build(seed)`` draws one scene from them; the same
seed and parameters give the same scene. docs/scenes.md describes the scenes, their
parameters, the lane rule and how to add a scene. The modules:

- ``corridor``, ``office``, ``lab``, ``hall``: the scenes;
- ``variation``: parameter kinds, checks and draws (:class:`SceneLayout`, the scenes' base);
- ``builder``: the finished :class:`Scene` and the :class:`SceneBuilder` a scene is made with;
- ``floor``: the floor every scene can stand on: flat, sloped, bumpy (:class:`Floor`);
- ``arena``: the empty arena (floor, materials, lights, clip planes) and its primitives;
- ``structure``: walls, rooms, doors, stairs, pillars; ``furniture``: the furniture catalogue;
- ``placement``: rejection sampling of footprints off the lane; ``lane``: paths and the lane
  check on the compiled model.

Attach the robot with ``sim.world.assembly.assemble(scene.arena, scene.start_xy,
scene.start_yaw_deg)``.
"""

from __future__ import annotations

from typing import Any, Mapping

from sim.world.scenes.builder import Scene
from sim.world.scenes.corridor import Corridor
from sim.world.scenes.floor import FLAT, Floor, FloorParameterError
from sim.world.scenes.hall import Hall
from sim.world.scenes.lab import Lab
from sim.world.scenes.office import Office
from sim.world.scenes.variation import SceneLayout, SceneParameterError

#: Scene name -> its layout class: ``SCENES[name](**params).build(seed) -> Scene``.
SCENES: dict[str, type[SceneLayout]] = {
    layout.name: layout for layout in (Corridor, Office, Lab, Hall)
}


def scene_layout(name: str, **params: Any) -> SceneLayout:
    """The layout of scene ``name`` with ``params`` (the others at their defaults).

    Raises:
        ValueError: unknown scene.
        SceneParameterError: (a ValueError) unknown parameter or value out of range; the
            message names the scene, the parameter and what it accepts.
    """
    if name not in SCENES:
        raise ValueError(f"unknown scene {name!r}; accepted: {', '.join(SCENES)}")
    return SCENES[name].from_params(params)


def build_scene(name: str, seed: int = 0, floor: Floor | Mapping[str, Any] | None = None,
                **params: Any) -> Scene:
    """Build scene ``name`` with its random choices drawn from ``seed`` (same seed and
    parameters, same scene); ``params`` are the scene's parameters (docs/scenes.md).

    ``floor`` is the floor it stands on: a :class:`Floor`, or a mapping of its settings
    (``slope_deg``, ``slope_direction_deg``, ``bump_height_m``); None is the flat floor. The
    floor does not change the scene's layout; its bumps are drawn from ``seed`` too.

    Raises:
        FloorParameterError: (a ValueError) unknown floor setting or value out of range.
    """
    layout = scene_layout(name, **params)
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise ValueError(f"scene seed must be an integer >= 0; got {seed!r}")
    if floor is None:
        floor = FLAT
    elif isinstance(floor, Mapping):
        floor = Floor.from_params(floor)
    elif not isinstance(floor, Floor):
        raise FloorParameterError("floor", f"got {floor!r}", "a Floor, or a mapping of "
                                  "slope_deg, slope_direction_deg, bump_height_m")
    return layout.build(seed, floor)


__all__ = ["FLAT", "SCENES", "Floor", "FloorParameterError", "Scene", "SceneLayout",
           "SceneParameterError", "build_scene", "scene_layout"]
