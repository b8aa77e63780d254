"""Office: a room with desks and chairs, shelves along the walls and boxes; the walk turns left
by 90 degrees in the middle of the room."""

from __future__ import annotations

from sim.world.scenes.parts import Scene, SceneBuilder, polyline

TURN_RADIUS_M = 0.8


def build(seed: int) -> Scene:
    b = SceneBuilder("office", seed, polyline(("line", 1.5), ("arc", TURN_RADIUS_M, 90),
                                              ("line", 1.5)))
    xmax, ymax = 2.3 + b.rng.uniform(1.8, 2.5), 2.3 + b.rng.uniform(1.8, 2.5)
    xmin, ymin = -1.2, -b.rng.uniform(1.5, 2.0)
    b.room(xmin, xmax, ymin, ymax)
    inside = (xmin + 0.2, xmax - 0.2, ymin + 0.2, ymax - 0.2)
    ahead_of_start = (2.0, xmax - 0.3, -1.2, 1.2)  # seen during the first, straight leg
    for _ in range(2):
        b.place_crates(ahead_of_start, (0.15, 0.15, 0.15), (0.35, 0.3, 0.35))
    for _ in range(int(b.rng.integers(3, 5))):
        b.place(b.shelf, (0.45, 0.18), inside)
    for _ in range(int(b.rng.integers(3, 5))):  # desks with a chair in front
        b.place(_desk_with_chair(b), (0.6, 0.7), inside)
    for _ in range(int(b.rng.integers(3, 6))):
        b.place_crates(inside, (0.12, 0.12, 0.1), (0.3, 0.25, 0.3))
    return b.finish("office with desks, chairs, shelves and boxes; a 90-degree left turn")


def _desk_with_chair(b: SceneBuilder):
    def build(xy, yaw):
        b.chair((0, -0.45), 90, parent=b.desk(xy, yaw))
    return build

