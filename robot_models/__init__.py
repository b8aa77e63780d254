"""MJCF robot models shipped with the harness (MuJoCo Menagerie layout)."""

from __future__ import annotations

from pathlib import Path

#: Folder of the 0.6 m, 24-DOF humanoid carrying the SR4000: humanoid.xml, scene.xml, README.md,
#: CHANGELOG.md and humanoid.png (the README's picture, ``python -m sim.world.render_robot``).
HUMANOID_DIR = Path(__file__).resolve().parent / "humanoid"


def humanoid_path(name: str = "humanoid.xml") -> Path:
    """Path of a file in the humanoid's folder ("humanoid.xml" the robot, "scene.xml" robot + floor)."""
    path = HUMANOID_DIR / name
    if not path.is_file():
        available = sorted(p.name for p in HUMANOID_DIR.iterdir())
        raise ValueError(f"no file {name!r} in {HUMANOID_DIR}; available: {available}")
    return path
