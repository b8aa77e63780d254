"""Office: a room with desks and chairs, shelves along the walls and boxes; the walk turns left
by 90 degrees in the middle of the room."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

from sim.world.scenes.builder import Scene, SceneBuilder
from sim.world.scenes.floor import FLAT, Floor
from sim.world.scenes.lane import polyline
from sim.world.scenes.variation import (SceneLayout, draw, draw_count, integer, integer_range,
                                        real_range)

#: The walk: a straight leg, a 90-degree left turn of this radius, a second straight leg.
LEG_M = 1.5
TURN_RADIUS_M = 0.8
#: x of the room's back wall, behind the start.
BACK_WALL_X_M = -1.2


@dataclass(frozen=True)
class Office(SceneLayout):
    """A room with shelves, desks with chairs and boxes, and a walk that turns left.

    The robot walks 1.5 m along +x, turns left on a 0.8 m radius and walks 1.5 m along +y.
    The room's back wall is 1.2 m behind the start; its other walls are drawn around the walk.
    Crates stand ahead of the start, in view during the first leg; shelves, desks with a chair
    in front and more crates stand anywhere in the room off the lane.

    Args:
        room_past_second_leg_m: distance from the second leg (x = 2.3 m) to the +x wall,
            metres; default (1.8, 2.5).
        room_past_walk_end_m: distance from the end of the walk (y = 2.3 m) to the +y wall,
            metres; default (1.8, 2.5).
        room_right_m: distance from the first leg (y = 0) to the -y wall, metres;
            default (1.5, 2.0).
        crates_ahead: crate stacks in view ahead of the start; default 2.
        shelf_count: shelves; default (3, 4).
        desk_count: desks, each with a chair; default (3, 4).
        crate_count: crate stacks anywhere in the room; default (3, 5).

    Counts are of the pieces placed: a piece with no free place left is skipped. Ranges are
    (low, high) pairs, drawn uniformly each time they are used (:mod:`sim.world.scenes.variation`).
    """

    name: ClassVar[str] = "office"
    description: ClassVar[str] = ("office with desks, chairs, shelves and boxes; a 90-degree "
                                  "left turn")

    room_past_second_leg_m: tuple = real_range((1.8, 2.5), within=(0.8, 10.0))
    room_past_walk_end_m: tuple = real_range((1.8, 2.5), within=(0.8, 10.0))
    room_right_m: tuple = real_range((1.5, 2.0), within=(0.8, 10.0))
    crates_ahead: int = integer(2, within=(0, 10))
    shelf_count: tuple = integer_range((3, 4), within=(0, 20))
    desk_count: tuple = integer_range((3, 4), within=(0, 20))
    crate_count: tuple = integer_range((3, 5), within=(0, 30))

    def build(self, seed: int, floor: Floor = FLAT) -> Scene:
        builder = SceneBuilder(self.name, seed, polyline(
            ("line", LEG_M), ("arc", TURN_RADIUS_M, 90), ("line", LEG_M)), floor=floor)
        rng, furniture, placement = builder.rng, builder.furniture, builder.placement
        second_leg_x, walk_end_y = LEG_M + TURN_RADIUS_M, TURN_RADIUS_M + LEG_M
        xmax = second_leg_x + draw(rng, self.room_past_second_leg_m)
        ymax = walk_end_y + draw(rng, self.room_past_walk_end_m)
        xmin, ymin = BACK_WALL_X_M, -draw(rng, self.room_right_m)
        builder.structure.room(xmin, xmax, ymin, ymax)
        inside = (xmin + 0.2, xmax - 0.2, ymin + 0.2, ymax - 0.2)
        ahead_of_start = (2.0, xmax - 0.3, -1.2, 1.2)  # seen during the first, straight leg
        for _ in range(self.crates_ahead):
            builder.place_crates(ahead_of_start, (0.15, 0.15, 0.15), (0.35, 0.3, 0.35))
        for _ in range(draw_count(rng, self.shelf_count)):
            placement.place(furniture.shelf, (0.45, 0.18), inside)
        for _ in range(draw_count(rng, self.desk_count)):
            placement.place(furniture.desk_with_chair, (0.6, 0.7), inside)
        for _ in range(draw_count(rng, self.crate_count)):
            builder.place_crates(inside, (0.12, 0.12, 0.1), (0.3, 0.25, 0.3))
        return builder.finish(self.description, self.params())
