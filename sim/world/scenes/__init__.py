"""Indoor scenes the robot walks through: a registry and ``build_scene(name, seed)``.

Each scene module has ``build(seed) -> Scene``; the shared building blocks are in
:mod:`sim.world.scenes.parts`. Attach the robot with ``sim.world.assembly.assemble(scene.arena,
scene.start_xy, scene.start_yaw_deg)``.
"""

from __future__ import annotations

from sim.world.scenes import corridor, hall, lab, office
from sim.world.scenes.parts import Scene

#: Scene name -> builder ``build(seed) -> Scene``.
SCENES = {
    "corridor": corridor.build,
    "office": office.build,
    "lab": lab.build,
    "hall": hall.build,
}


def build_scene(name: str, seed: int = 0) -> Scene:
    """Build scene ``name`` with its furniture placed from ``seed`` (same seed, same scene)."""
    if name not in SCENES:
        raise ValueError(f"unknown scene {name!r}; accepted: {', '.join(SCENES)}")
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise ValueError(f"scene seed must be an integer >= 0; got {seed!r}")
    return SCENES[name](seed)


__all__ = ["SCENES", "Scene", "build_scene"]
