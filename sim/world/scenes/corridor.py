"""Corridor: a straight hallway with closed side doors, clutter along the walls and an open door
with a doorsill at the far end, through which a room beyond the unambiguous range is seen."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

from sim.world.scenes.builder import Scene, SceneBuilder
from sim.world.scenes.floor import FLAT, Floor
from sim.world.scenes.lane import polyline
from sim.world.scenes.variation import (SceneLayout, draw, draw_count, integer_range,
                                        positions, real_range)

#: Length of the walk, straight ahead (+x) from the origin down the middle of the corridor.
WALK_M = 3.0
#: x of the corridor's back wall, behind the start.
BACK_WALL_X_M = -1.5
#: How much wider than the corridor the room behind the end door is, on each side.
END_ROOM_WIDENING_M = 1.5
#: Height of the corridor's ceiling and of its lights.
CEILING_HEIGHT_M, LIGHT_HEIGHT_M = 2.5, 2.3


@dataclass(frozen=True)
class Corridor(SceneLayout):
    """A straight corridor with doors on both sides and an open door at its far end.

    The robot walks 3 m along +x down the middle. The corridor runs from its back wall 1.5 m
    behind the start to the end wall past the end of the walk; the end wall has an open door
    (with a 2 cm sill) onto a wider room without a ceiling. Each side wall has closed doors at
    some of the door slots. Boxes, bins and low benches stand against the side walls.

    Args:
        half_width_m: half the corridor's width (wall centre lines at y = +-half width),
            metres; default (0.65, 0.85).
        end_wall_past_walk_m: distance from the end of the walk to the end wall and its open
            door, metres; default (2.0, 3.5).
        end_room_depth_m: depth of the room behind the end door, metres; default (2.5, 4.0).
        side_door_slots_m: places a side door may be centred at, metres along a side wall from
            the back wall; default (1.0, 2.5, 4.0).
        side_doors_per_wall: how many slots of each side wall get a door (different slots);
            default (1, 2).
        side_door_shift_m: shift of a side door from its slot along the wall, metres;
            default (-0.3, 0.3).
        end_door_shift_m: shift of the end door from the corridor's centre line, metres;
            default (-0.2, 0.2).
        end_door_open_deg: how far the end door's leaf is swung open, degrees;
            default (60, 100).
        clutter_count: how many boxes, bins and benches stand against the walls (fewer when
            no free place is found); default (4, 6).

    Ranges are (low, high) pairs, drawn uniformly each time they are used
    (:mod:`sim.world.scenes.variation`).
    """

    name: ClassVar[str] = "corridor"
    description: ClassVar[str] = ("straight corridor with side doors and an open end door with "
                                  "a sill")

    half_width_m: tuple = real_range((0.65, 0.85), within=(0.45, 2.0))
    end_wall_past_walk_m: tuple = real_range((2.0, 3.5), within=(1.5, 10.0))
    end_room_depth_m: tuple = real_range((2.5, 4.0), within=(1.0, 10.0))
    side_door_slots_m: tuple = positions((1.0, 2.5, 4.0), within=(0.6, 15.0))
    side_doors_per_wall: tuple = integer_range((1, 2), within=(0, 10))
    side_door_shift_m: tuple = real_range((-0.3, 0.3), within=(-1.0, 1.0))
    end_door_shift_m: tuple = real_range((-0.2, 0.2), within=(-1.0, 1.0))
    end_door_open_deg: tuple = real_range((60.0, 100.0), within=(0.0, 180.0))
    clutter_count: tuple = integer_range((4, 6), within=(0, 30))

    def __post_init__(self):
        super().__post_init__()
        if self.side_doors_per_wall[1] > len(self.side_door_slots_m):
            self.refuse("side_doors_per_wall", f"{self.side_doors_per_wall} asks for more doors "
                        f"than the {len(self.side_door_slots_m)} side_door_slots_m",
                        "at most as many doors as slots")

    def build(self, seed: int, floor: Floor = FLAT) -> Scene:
        builder = SceneBuilder(self.name, seed, polyline(("line", WALK_M)), floor=floor)
        rng, structure = builder.rng, builder.structure
        half_width = draw(rng, self.half_width_m)
        end_x = WALK_M + draw(rng, self.end_wall_past_walk_m)
        room_depth = draw(rng, self.end_room_depth_m)
        for side in (-1, 1):
            slots = sorted(rng.choice(self.side_door_slots_m,
                                      size=draw_count(rng, self.side_doors_per_wall),
                                      replace=False))
            structure.wall_with_doors((BACK_WALL_X_M, side * half_width),
                                      (end_x, side * half_width),
                                      [(slot + draw(rng, self.side_door_shift_m), None)
                                       for slot in slots])
        structure.wall((BACK_WALL_X_M, -half_width), (BACK_WALL_X_M, half_width))
        end_door_at = half_width + draw(rng, self.end_door_shift_m)
        structure.wall_with_doors((end_x, -half_width), (end_x, half_width),
                                  [(end_door_at, -draw(rng, self.end_door_open_deg))])
        self._end_room(builder, half_width, end_x, room_depth)
        structure.ceiling((BACK_WALL_X_M, end_x), (-half_width, half_width), CEILING_HEIGHT_M)
        builder.arena.ceiling_lights((0.0, end_x), (0.0, 0.0), LIGHT_HEIGHT_M, spacing=2.0)
        along_wall = (0.3, end_x - 0.3, -half_width + 0.06, half_width - 0.06)
        for _ in range(draw_count(rng, self.clutter_count)):
            self._place_clutter(builder, along_wall)
        return builder.finish(self.description, self.params())

    @staticmethod
    def _end_room(builder: SceneBuilder, half_width, end_x, room_depth):
        """The room behind the end wall: walls on three sides, the end wall's wings, a light."""
        far_x, room_half = end_x + room_depth, half_width + END_ROOM_WIDENING_M
        for start, end in [((end_x, -room_half), (far_x, -room_half)),
                           ((far_x, -room_half), (far_x, room_half)),
                           ((far_x, room_half), (end_x, room_half)),
                           ((end_x, -room_half), (end_x, -half_width)),
                           ((end_x, half_width), (end_x, room_half))]:
            builder.structure.wall(start, end)
        builder.arena.light([end_x + room_depth / 2, 0, LIGHT_HEIGHT_M])

    @staticmethod
    def _place_clutter(builder: SceneBuilder, zone):
        """A crate stack, a bin or a low bench, with even odds."""
        kind = builder.rng.integers(3)
        if kind == 0:
            builder.place_crates(zone, (0.1, 0.1, 0.1), (0.25, 0.2, 0.3), max_stack=2)
        elif kind == 1:
            builder.place_barrel(zone, (0.1, 0.18), (0.4, 0.7), "dark")
        else:
            builder.placement.place(
                lambda xy, yaw: builder.furniture.desk(xy, yaw, (1.0, 0.3), 0.45), (0.5, 0.15),
                zone, yaw_choices=(0,))
