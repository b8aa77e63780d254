"""Corridor: a straight hallway with closed side doors, clutter along the walls and an open door
with a doorsill at the far end, through which a room beyond the unambiguous range is seen."""

from __future__ import annotations

from sim.world.scenes.parts import Scene, SceneBuilder, polyline

WALK_M = 3.0


def build(seed: int) -> Scene:
    b = SceneBuilder("corridor", seed, polyline(("line", WALK_M)))
    half_width = b.rng.uniform(0.65, 0.85)
    end_x = WALK_M + b.rng.uniform(2.0, 3.5)  # the end door 2-3.5 m past the end of the walk
    room_depth = b.rng.uniform(2.5, 4.0)
    # Side walls with 1-2 closed doors each, away from the ends.
    for side in (-1, 1):
        doors = sorted(b.rng.choice(
            [1.0, 2.5, 4.0], size=int(b.rng.integers(1, 3)), replace=False))
        b.wall_with_doors((-1.5, side * half_width), (end_x, side * half_width),
                          [(d + b.rng.uniform(-0.3, 0.3), None) for d in doors])
    b.wall((-1.5, -half_width), (-1.5, half_width))
    # End wall with an open door (and its sill) onto a deeper room.
    b.wall_with_doors((end_x, -half_width), (end_x, half_width),
                      [(half_width + b.rng.uniform(-0.2, 0.2), -b.rng.uniform(60, 100))])
    far_x, room_half = end_x + room_depth, half_width + 1.5
    for a, c in [((end_x, -room_half), (far_x, -room_half)), ((far_x, -room_half),
                 (far_x, room_half)), ((far_x, room_half), (end_x, room_half)),
                 ((end_x, -room_half), (end_x, -half_width)),
                 ((end_x, half_width), (end_x, room_half))]:
        b.wall(a, c)
    b.light([end_x + room_depth / 2, 0, 2.3])
    ceiling = b.body("ceiling", ((end_x - 1.5) / 2, 0), z=2.5)
    b.box(ceiling, [(end_x + 1.5) / 2, half_width, 0.05], [0, 0, 0.05], "wall")
    b.ceiling_lights((0.0, end_x), (0.0, 0.0), 2.3, spacing=2.0)
    # Clutter against the walls: boxes, bins, a bench, several sizes and depths.
    along_wall = (0.3, end_x - 0.3, -half_width + 0.06, half_width - 0.06)
    for _ in range(int(b.rng.integers(4, 7))):
        kind = b.rng.integers(3)
        if kind == 0:
            b.place_crates(along_wall, (0.1, 0.1, 0.1), (0.25, 0.2, 0.3), max_stack=2)
        elif kind == 1:
            b.place_barrel(along_wall, (0.1, 0.18), (0.4, 0.7), "dark")
        else:  # a bench
            b.place(lambda xy, yaw: b.desk(xy, yaw, (1.0, 0.3), 0.45), (0.5, 0.15), along_wall,
                    yaw_choices=(0,))
    return b.finish("straight corridor with side doors and an open end door with a sill")
