"""Hall: a large hall with a flight of stairs ahead at the end of the walk, pillars and benches
at the sides."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

from sim.world.scenes.builder import Scene, SceneBuilder
from sim.world.scenes.floor import FLAT, Floor
from sim.world.scenes.lane import polyline
from sim.world.scenes.variation import (SceneLayout, draw, draw_count, integer_range,
                                        positions, real_range)

#: Length of the walk, straight ahead (+x) from the origin.
WALK_M = 2.0
#: x of the hall's back wall, behind the start; height of the hall and of its pillars.
BACK_WALL_X_M, HALL_HEIGHT_M = -1.5, 4.0
#: Depth of a step and of the landing at the top of the stairs.
TREAD_M, LANDING_M = 0.3, 2.0


@dataclass(frozen=True)
class Hall(SceneLayout):
    """A tall hall with a flight of stairs ahead, two rows of pillars and benches at the sides.

    The robot walks 2 m along +x towards the stairs, which rise along +x from their first step
    past the end of the walk to a 2 m landing against the far wall, with a rail of posts on
    both sides. Pillars stand in two rows along the walk; benches and concrete planters stand
    between the back wall and the stairs, off the lane.

    Args:
        stairs_past_walk_m: distance from the end of the walk to the first step, metres;
            default (1.0, 1.8).
        stair_steps: number of steps (0.3 m deep each); default (5, 8).
        stair_rise_m: height of a step, metres; default (0.14, 0.18).
        stair_width_m: width of the flight, metres; default (1.6, 2.4).
        stair_shift_m: sideways (y) shift of the flight from the walk's line, metres;
            default (-0.2, 0.2).
        half_width_m: half the hall's width (walls at y = +-half width), metres;
            default (3.5, 4.5).
        pillar_rows_x_m: x of the pillar pairs (one pillar each side of the walk), metres;
            default (0.5, 3.0, 5.5).
        pillar_shift_m: shift of each pillar along x from its place, metres;
            default (-0.3, 0.3).
        pillar_offset_m: distance of a pillar's centre from the walk's line, metres;
            default (1.3, 2.0).
        pillar_radius_m: radius of a pillar, metres; default (0.15, 0.3).
        bench_count: benches and planters (even odds), placed at the sides; default (2, 4).

    Ranges are (low, high) pairs, drawn uniformly each time they are used
    (:mod:`sim.world.scenes.variation`).
    """

    name: ClassVar[str] = "hall"
    description: ClassVar[str] = "hall with stairs ahead, pillars and benches"

    stairs_past_walk_m: tuple = real_range((1.0, 1.8), within=(0.6, 10.0))
    stair_steps: tuple = integer_range((5, 8), within=(1, 20))
    stair_rise_m: tuple = real_range((0.14, 0.18), within=(0.05, 0.3))
    stair_width_m: tuple = real_range((1.6, 2.4), within=(0.6, 5.0))
    stair_shift_m: tuple = real_range((-0.2, 0.2), within=(-2.0, 2.0))
    half_width_m: tuple = real_range((3.5, 4.5), within=(2.0, 10.0))
    pillar_rows_x_m: tuple = positions((0.5, 3.0, 5.5), within=(-1.0, 20.0))
    pillar_shift_m: tuple = real_range((-0.3, 0.3), within=(-1.0, 1.0))
    pillar_offset_m: tuple = real_range((1.3, 2.0), within=(0.8, 10.0))
    pillar_radius_m: tuple = real_range((0.15, 0.3), within=(0.05, 0.4))
    bench_count: tuple = integer_range((2, 4), within=(0, 20))

    def build(self, seed: int, floor: Floor = FLAT) -> Scene:
        builder = SceneBuilder(self.name, seed, polyline(("line", WALK_M)), floor=floor)
        rng, structure = builder.rng, builder.structure
        foot_x = WALK_M + draw(rng, self.stairs_past_walk_m)
        steps, rise = draw_count(rng, self.stair_steps), draw(rng, self.stair_rise_m)
        stair_width = draw(rng, self.stair_width_m)
        run = steps * TREAD_M + LANDING_M
        structure.stairs((foot_x, draw(rng, self.stair_shift_m)), 0.0, steps, rise, TREAD_M,
                         stair_width, LANDING_M)
        builder.placement.reserve((foot_x + run / 2, 0.0),
                                  (run / 2 + 0.1, stair_width / 2 + 0.3))
        xmax, half_width = foot_x + run, draw(rng, self.half_width_m)
        structure.room(BACK_WALL_X_M, xmax, -half_width, half_width, height=HALL_HEIGHT_M)
        for x in self.pillar_rows_x_m:
            for side in (-1, 1):
                structure.pillar((x + draw(rng, self.pillar_shift_m),
                                  side * draw(rng, self.pillar_offset_m)),
                                 radius=draw(rng, self.pillar_radius_m), height=HALL_HEIGHT_M)
        sides = (-1.0, foot_x, -half_width + 0.3, half_width - 0.3)
        for _ in range(draw_count(rng, self.bench_count)):
            if rng.random() < 0.5:
                builder.placement.place(
                    lambda xy, yaw: builder.furniture.desk(xy, yaw, (1.4, 0.4), 0.45),
                    (0.7, 0.2), sides)
            else:
                builder.place_barrel(sides, (0.2, 0.35), (0.4, 0.7), "concrete")
        return builder.finish(self.description, self.params())
