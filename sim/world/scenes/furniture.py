"""The furniture catalogue: desks, chairs, shelves, crates, barrels and lab benches.

Each piece is a static body with its origin on the floor at the centre of its footprint, built
at a pose ``(xy, yaw_deg)`` so that :meth:`sim.world.scenes.placement.Placement.place` can put
it. Details (a monitor on a desk, books on a shelf, the turn of stacked crates) are drawn from
the scene's random generator.
"""

from __future__ import annotations

import numpy as np

from sim.world.scenes.arena import Arena


class Furniture:
    """Builds furniture in an arena, its details drawn from ``rng``.

    Args:
        arena: the arena the pieces are added to.
        rng: the scene's random generator.
    """

    def __init__(self, arena: Arena, rng: np.random.Generator):
        self.arena = arena
        self.rng = rng

    def desk(self, xy, yaw_deg, size=(1.2, 0.6), height=0.74):
        """A wooden top of ``size`` (x, y) on four metal legs; 70 % carry a monitor or a box."""
        arena = self.arena
        body = arena.body("desk", xy, yaw_deg)
        hx, hy = size[0] / 2, size[1] / 2
        arena.box(body, [hx, hy, 0.015], [0, 0, height - 0.015], "wood")
        for sx in (-1, 1):
            for sy in (-1, 1):
                arena.box(body, [0.025, 0.025, (height - 0.03) / 2],
                          [sx * (hx - 0.05), sy * (hy - 0.05), (height - 0.03) / 2], "metal")
        if self.rng.random() < 0.7:
            w = self.rng.uniform(0.15, 0.3)
            arena.box(body, [w, 0.03 + 0.1 * self.rng.random(), w * 0.7],
                      [0, 0.05, height + w * 0.7], "dark")
        return body

    def chair(self, xy, yaw_deg, seat=0.45, height=0.45, parent=None):
        """A chair facing local +x (backrest at -x), in ``parent``'s frame (default the world)."""
        arena = self.arena
        body = arena.body("chair", xy, yaw_deg, parent=parent)
        h = seat / 2
        arena.box(body, [h, h, 0.03], [0, 0, height], "fabric")
        arena.box(body, [0.03, h, 0.22], [-h + 0.03, 0, height + 0.25], "fabric")
        arena.cylinder(body, 0.03, (height - 0.03) / 2, [0, 0, (height - 0.03) / 2], "metal")
        return body

    def desk_with_chair(self, xy, yaw_deg):
        """A desk with a chair in front of it (at local -y, facing the desk)."""
        self.chair((0, -0.45), 90, parent=self.desk(xy, yaw_deg))

    def shelf(self, xy, yaw_deg, width=0.9, depth=0.35, height=1.8, levels=4):
        """A wooden shelf open at local -y; 80 % of its boards below the top carry books or
        boxes of random width and height."""
        arena = self.arena
        body = arena.body("shelf", xy, yaw_deg)
        for sx in (-1, 1):
            arena.box(body, [0.015, depth / 2, height / 2],
                      [sx * (width / 2 - 0.015), 0, height / 2], "wood")
        arena.box(body, [width / 2, 0.01, height / 2], [0, depth / 2 - 0.01, height / 2], "wood")
        for level in range(levels):
            z = 0.05 + level * (height - 0.1) / (levels - 1)
            arena.box(body, [width / 2 - 0.03, depth / 2, 0.012], [0, 0, z], "wood")
            if level < levels - 1 and self.rng.random() < 0.8:
                w = self.rng.uniform(0.08, width / 2 - 0.05)
                hz = self.rng.uniform(0.06, 0.15)
                arena.box(body, [w, depth / 2 - 0.04, hz],
                          [self.rng.uniform(-1, 1) * (width / 2 - 0.05 - w), 0, z + hz],
                          "cardboard")
        return body

    def crate(self, xy, yaw_deg, half_size, material="cardboard", stack=1):
        """A stack of ``stack`` boxes, the lowest of ``half_size``, each next one 20 % narrower,
        10 % lower and turned by up to 15 degrees."""
        arena = self.arena
        body = arena.body("crate", xy, yaw_deg)
        z, hs = 0.0, np.asarray(half_size, float)
        for level in range(stack):
            yaw = self.rng.uniform(-15, 15) if level else 0.0
            top = arena.body("crate_part", (0, 0), yaw, z, parent=body)
            arena.box(top, hs, [0, 0, hs[2]], material)
            z += 2 * hs[2]
            hs = hs * [0.8, 0.8, 0.9]
        return body

    def barrel(self, xy, yaw_deg, radius=0.25, height=0.9, material="plastic"):
        """An upright cylinder (a bin, a barrel, a planter)."""
        body = self.arena.body("barrel", xy, yaw_deg)
        self.arena.cylinder(body, radius, height / 2, [0, 0, height / 2], material)
        return body

    def table(self, xy, yaw_deg, size=(1.5, 0.75), height=0.9):
        """A lab bench: a desk with one to three equipment boxes on it."""
        body = self.desk(xy, yaw_deg, size, height)
        for _ in range(int(self.rng.integers(1, 4))):
            hs = self.rng.uniform([0.08, 0.08, 0.05], [0.2, 0.15, 0.2])
            self.arena.box(body, hs, [self.rng.uniform(-1, 1) * (size[0] / 2 - hs[0]),
                                      self.rng.uniform(-1, 1) * (size[1] / 2 - hs[1]),
                                      height + hs[2]], "metal")
        return body
