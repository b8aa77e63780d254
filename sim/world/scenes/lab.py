"""Lab: a room cluttered with benches, crates, barrels and stacked boxes at several depths
(about 1-5 m) in the camera's view; the walk goes straight through the clutter."""

from __future__ import annotations

import math

from sim.world.scenes.parts import Scene, SceneBuilder, polyline

WALK_M = 2.5
#: Half the SR4000's horizontal field of view: objects are put where the start pose sees them.
HALF_HFOV_DEG = 21.8


def build(seed: int) -> Scene:
    b = SceneBuilder("lab", seed, polyline(("line", WALK_M)))
    xmax = WALK_M + b.rng.uniform(3.0, 4.0)
    half_width = b.rng.uniform(2.5, 3.2)
    b.room(-1.2, xmax, -half_width, half_width, height=3.0)
    # Two objects per 1 m depth band, at least partly inside the start view, out of the lane.
    for near in range(1, int(xmax) - 1):
        half_view = math.tan(math.radians(HALF_HFOV_DEG)) * (near + 1.0) + 0.3
        zone = (near, near + 1.0, -half_view, half_view)
        for _ in range(2):
            _place_random_object(b, zone)
    side_zone = (0.0, xmax - 0.3, -half_width + 0.3, half_width - 0.3)
    for _ in range(int(b.rng.integers(4, 8))):  # more clutter anywhere in the room
        _place_random_object(b, side_zone)
    return b.finish("lab cluttered with benches, crates and barrels at 1-5 m")


def _place_random_object(b: SceneBuilder, zone):
    kind = int(b.rng.integers(4))
    if kind == 0:
        b.place_crates(zone, (0.1, 0.1, 0.1), (0.35, 0.3, 0.4))
    elif kind == 1:
        b.place_barrel(zone, (0.12, 0.3), (0.5, 1.1))
    elif kind == 2:
        b.place(b.table, (0.75, 0.375), zone)
    else:
        b.place(lambda xy, yaw: b.shelf(xy, yaw, width=0.7, height=1.4, levels=3),
                (0.35, 0.18), zone)
