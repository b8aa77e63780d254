"""Hall: a large hall with a flight of stairs ahead at the end of the walk, pillars and benches
at the sides."""

from __future__ import annotations

from sim.world.scenes.parts import Scene, SceneBuilder, polyline

WALK_M = 2.0


def build(seed: int) -> Scene:
    b = SceneBuilder("hall", seed, polyline(("line", WALK_M)))
    foot_x = WALK_M + b.rng.uniform(1.0, 1.8)  # the first step, ahead of the end of the walk
    steps, rise, tread = int(b.rng.integers(5, 9)), b.rng.uniform(0.14, 0.18), 0.3
    stair_width, landing = b.rng.uniform(1.6, 2.4), 2.0
    run = steps * tread + landing
    b.stairs((foot_x, b.rng.uniform(-0.2, 0.2)), 0.0, steps, rise, tread, stair_width, landing)
    b.reserve((foot_x + run / 2, 0.0), (run / 2 + 0.1, stair_width / 2 + 0.3))
    xmax, half_width = foot_x + run, b.rng.uniform(3.5, 4.5)
    b.room(-1.5, xmax, -half_width, half_width, height=4.0)
    for x in (0.5, 3.0, 5.5):  # two rows of pillars
        for side in (-1, 1):
            b.pillar((x + b.rng.uniform(-0.3, 0.3), side * b.rng.uniform(1.3, 2.0)),
                     radius=b.rng.uniform(0.15, 0.3), height=4.0)
    sides = (-1.0, foot_x, -half_width + 0.3, half_width - 0.3)
    for _ in range(int(b.rng.integers(2, 5))):  # benches and planters
        if b.rng.random() < 0.5:
            b.place(lambda xy, yaw: b.desk(xy, yaw, (1.4, 0.4), 0.45), (0.7, 0.2), sides)
        else:
            b.place_barrel(sides, (0.2, 0.35), (0.4, 0.7), "concrete")
    return b.finish("hall with stairs ahead, pillars and benches")
