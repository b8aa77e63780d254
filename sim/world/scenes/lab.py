"""Lab: a room cluttered with benches, crates, barrels and stacked boxes at several depths
(about 1-5 m) in the camera's view; the walk goes straight through the clutter."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

from sim.world.scenes.builder import Scene, SceneBuilder
from sim.world.scenes.floor import FLAT, Floor
from sim.world.scenes.lane import polyline
from sim.world.scenes.variation import (SceneLayout, draw, draw_count, integer, integer_range,
                                        real_range)

#: Length of the walk, straight ahead (+x) from the origin.
WALK_M = 2.5
#: x of the room's back wall, behind the start; height of the room.
BACK_WALL_X_M, ROOM_HEIGHT_M = -1.2, 3.0
#: Half the SR4000's horizontal field of view: objects are put where the start pose sees them.
HALF_HFOV_DEG = 21.8


@dataclass(frozen=True)
class Lab(SceneLayout):
    """A room full of benches, crates, barrels and small shelves at every depth in view.

    The robot walks 2.5 m along +x through the middle of the room. In each 1 m depth band
    from x = 1 m to the last whole metre but one before the far wall, objects are placed at
    least partly inside the start pose's field of view; more clutter goes anywhere off the
    lane. Each object is, with even odds, a crate
    stack, a barrel, a bench with equipment or a small shelf.

    Args:
        room_past_walk_m: distance from the end of the walk to the far (+x) wall, metres;
            default (3.0, 4.0).
        half_width_m: half the room's width (walls at y = +-half width), metres;
            default (2.5, 3.2).
        objects_per_depth_band: objects placed in each 1 m depth band of the view; default 2.
        extra_clutter_count: objects placed anywhere in the room; default (4, 7).

    Counts are of the objects tried: one with no free place left is skipped. Ranges are
    (low, high) pairs, drawn uniformly each time they are used (:mod:`sim.world.scenes.variation`).
    """

    name: ClassVar[str] = "lab"
    description: ClassVar[str] = "lab cluttered with benches, crates and barrels at 1-5 m"

    room_past_walk_m: tuple = real_range((3.0, 4.0), within=(1.5, 10.0))
    half_width_m: tuple = real_range((2.5, 3.2), within=(1.0, 10.0))
    objects_per_depth_band: int = integer(2, within=(0, 10))
    extra_clutter_count: tuple = integer_range((4, 7), within=(0, 30))

    def build(self, seed: int, floor: Floor = FLAT) -> Scene:
        builder = SceneBuilder(self.name, seed, polyline(("line", WALK_M)), floor=floor)
        rng = builder.rng
        xmax = WALK_M + draw(rng, self.room_past_walk_m)
        half_width = draw(rng, self.half_width_m)
        builder.structure.room(BACK_WALL_X_M, xmax, -half_width, half_width,
                               height=ROOM_HEIGHT_M)
        for near in range(1, int(xmax) - 1):
            half_view = math.tan(math.radians(HALF_HFOV_DEG)) * (near + 1.0) + 0.3
            zone = (near, near + 1.0, -half_view, half_view)
            for _ in range(self.objects_per_depth_band):
                _place_random_object(builder, zone)
        anywhere = (0.0, xmax - 0.3, -half_width + 0.3, half_width - 0.3)
        for _ in range(draw_count(rng, self.extra_clutter_count)):
            _place_random_object(builder, anywhere)
        return builder.finish(self.description, self.params())


def _place_random_object(builder: SceneBuilder, zone):
    """A crate stack, a barrel, a bench or a small shelf, with even odds, at a free pose."""
    kind = int(builder.rng.integers(4))
    furniture = builder.furniture
    if kind == 0:
        builder.place_crates(zone, (0.1, 0.1, 0.1), (0.35, 0.3, 0.4))
    elif kind == 1:
        builder.place_barrel(zone, (0.12, 0.3), (0.5, 1.1))
    elif kind == 2:
        builder.placement.place(furniture.table, (0.75, 0.375), zone)
    else:
        builder.placement.place(
            lambda xy, yaw: furniture.shelf(xy, yaw, width=0.7, height=1.4, levels=3),
            (0.35, 0.18), zone)
