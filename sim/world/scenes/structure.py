"""The building: walls, rooms, doorways, stairs and pillars.

These are fixed structures; each reserves its footprint in the scene's
:class:`~sim.world.scenes.placement.Placement` so that furniture keeps off it. They draw nothing
at random: a scene draws their sizes and positions and passes them in.
"""

from __future__ import annotations

import math

import numpy as np

from sim.world.scenes.arena import Arena
from sim.world.scenes.placement import Placement

#: Wall height and thickness, metres.
WALL_HEIGHT_M = 2.5
WALL_THICKNESS_M = 0.12
#: Door opening width and the width of each jamb, metres.
DOOR_WIDTH_M = 0.9
DOOR_JAMB_M = 0.08


class Structure:
    """Builds walls, rooms, doors, stairs and pillars in an arena, reserving their footprints.

    Args:
        arena: the arena the structures are added to.
        placement: where their footprints are reserved.
    """

    def __init__(self, arena: Arena, placement: Placement):
        self.arena = arena
        self.placement = placement

    def wall(self, start_xy, end_xy, height: float = WALL_HEIGHT_M,
             thickness: float = WALL_THICKNESS_M, material: str = "wall"):
        """A straight wall whose centre line runs from ``start_xy`` to ``end_xy``."""
        start, end = np.asarray(start_xy, float), np.asarray(end_xy, float)
        delta = end - start
        yaw = math.degrees(math.atan2(delta[1], delta[0]))
        body = self.arena.body("wall", (start + end) / 2, yaw)
        self.placement.reserve((start + end) / 2, (np.linalg.norm(delta) / 2, thickness / 2), yaw)
        self.arena.box(body, [np.linalg.norm(delta) / 2, thickness / 2, height / 2],
                       [0, 0, height / 2], material)
        return body

    def room(self, xmin, xmax, ymin, ymax, height=2.6, ceiling=True):
        """Four walls (and a ceiling) around a rectangle, with lights 3 m apart under the
        ceiling, 1 m in from the walls."""
        for start, end in [((xmin, ymin), (xmax, ymin)), ((xmax, ymin), (xmax, ymax)),
                           ((xmax, ymax), (xmin, ymax)), ((xmin, ymax), (xmin, ymin))]:
            self.wall(start, end, height)
        if ceiling:
            self.ceiling((xmin, xmax), (ymin, ymax), height)
        self.arena.ceiling_lights((xmin + 1, xmax - 1), (ymin + 1, ymax - 1), height - 0.2)

    def ceiling(self, x_range, y_range, height):
        """A 10 cm slab over the rectangle ``x_range`` x ``y_range``, its underside at
        ``height``."""
        body = self.arena.body("ceiling", ((x_range[0] + x_range[1]) / 2,
                                           (y_range[0] + y_range[1]) / 2), z=height)
        self.arena.box(body, [(x_range[1] - x_range[0]) / 2, (y_range[1] - y_range[0]) / 2, 0.05],
                       [0, 0, 0.05], "wall")
        return body

    def doorway(self, xy, yaw_deg, width=DOOR_WIDTH_M, height=2.05, wall=WALL_THICKNESS_M,
                leaf_open_deg=None, sill_height=0.02):
        """A door frame across a wall gap: jambs, lintel, a sill on the floor and the leaf.

        The frame's local x runs along the wall, y through it. ``leaf_open_deg`` None keeps the
        leaf closed at the back of the frame; an angle swings it open about its hinge.
        """
        arena = self.arena
        body = arena.body("door", xy, yaw_deg)
        self.placement.reserve(xy, (width / 2 + DOOR_JAMB_M, wall / 2 + 0.02), yaw_deg)
        for sx in (-1, 1):
            arena.box(body, [DOOR_JAMB_M / 2, wall / 2 + 0.02, height / 2],
                      [sx * (width / 2 + DOOR_JAMB_M / 2), 0, height / 2], "door")
        arena.box(body, [width / 2 + DOOR_JAMB_M, wall / 2 + 0.02, 0.05],
                  [0, 0, height + 0.05], "door")
        arena.box(body, [width / 2, wall / 2 + 0.02, sill_height / 2], [0, 0, sill_height / 2],
                  "concrete")
        leaf_half_size = [width / 2 - 0.01, 0.02, (height - sill_height) / 2 - 0.005]
        if leaf_open_deg is None:
            arena.box(body, leaf_half_size,
                      [0, wall / 2 - 0.02, sill_height + (height - sill_height) / 2], "door")
        else:
            hinge = arena.body("hinge", (-width / 2, wall / 2), leaf_open_deg, parent=body)
            arena.box(hinge, leaf_half_size,
                      [width / 2, 0.02, sill_height + (height - sill_height) / 2], "door")
        return body

    def wall_with_doors(self, start_xy, end_xy, doors, height=WALL_HEIGHT_M,
                        thickness=WALL_THICKNESS_M):
        """A wall from ``start_xy`` to ``end_xy`` with door openings centred at the distances
        ``doors`` (each (metres from the start, leaf_open_deg or None))."""
        start, end = np.asarray(start_xy, float), np.asarray(end_xy, float)
        length = np.linalg.norm(end - start)
        unit = (end - start) / length
        yaw = math.degrees(math.atan2(unit[1], unit[0]))
        cursor = 0.0
        for distance, leaf in sorted(doors, key=lambda door: door[0]):
            self.wall(start + unit * cursor,
                      start + unit * (distance - DOOR_WIDTH_M / 2 - DOOR_JAMB_M),
                      height, thickness)
            self.doorway(start + unit * distance, yaw, DOOR_WIDTH_M, wall=thickness,
                         leaf_open_deg=leaf)
            cursor = distance + DOOR_WIDTH_M / 2 + DOOR_JAMB_M
        self.wall(start + unit * cursor, end, height, thickness)

    def stairs(self, xy, yaw_deg, steps=6, rise=0.16, tread=0.3, width=2.0, landing=2.0,
               rail=True):
        """A straight flight rising along local +x from ``xy`` (the foot of the first step),
        a landing of depth ``landing`` at the top, and a rail of posts on both sides."""
        arena = self.arena
        body = arena.body("stairs", xy, yaw_deg)
        for i in range(steps):
            top = (i + 1) * rise
            arena.box(body, [tread / 2, width / 2, top / 2], [(i + 0.5) * tread, 0, top / 2],
                      "concrete")
        top = steps * rise
        arena.box(body, [landing / 2, width / 2, top / 2],
                  [steps * tread + landing / 2, 0, top / 2], "concrete")
        if rail:
            run = steps * tread + landing
            for sy in (-1, 1):
                for x in np.linspace(0.1, run - 0.1, 5):
                    z0 = min(x / tread, steps) * rise
                    arena.cylinder(body, 0.02, 0.45, [x, sy * (width / 2 - 0.03), z0 + 0.45],
                                   "metal")
        return body

    def pillar(self, xy, radius=0.2, height=3.0):
        """A round concrete pillar."""
        body = self.arena.body("pillar", xy)
        self.placement.reserve(xy, (radius, radius))
        self.arena.cylinder(body, radius, height / 2, [0, 0, height / 2], "concrete")
        return body
