"""Building blocks of the indoor scenes: arena set-up, furniture, placement rules, clearance.

Every scene is an ``mjcf.RootElement`` built by a :class:`SceneBuilder`: a floor, lights, clip
planes that cover the SR4000's 0.1-10 m, and static furniture (geoms in bodies without joints).
Furniture is placed by rejection sampling so that nothing enters the robot's lane: the band of
half-width ``clear_half_width_m`` around the scene's path (checked again on the compiled model
by :func:`lane_intrusions`).

Conventions: x, y on the floor, z up, metres; yaw in degrees about z, counter-clockwise.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field


import mujoco  # noqa: E402
import numpy as np  # noqa: E402
from dm_control import mjcf  # noqa: E402

#: Half-width of the robot's lane around the path: half the robot's width (~0.18 m with arms)
#: plus room for the sway and drift of an open-loop gait.
CLEAR_HALF_WIDTH_M = 0.35
#: Geoms whose lowest point is above this are overhead and cannot hit the 0.6 m robot.
ROBOT_HEIGHT_M = 0.75
#: Model extent and clip planes: 0.05-30 m rendered (SR4000 needs 0.1-10 m).
MODEL_EXTENT_M = 10.0
ZNEAR, ZFAR = 0.005, 3.0

_MATERIALS = {  # name: rgba
    "wall": (0.82, 0.80, 0.74, 1), "door": (0.55, 0.38, 0.22, 1), "wood": (0.62, 0.46, 0.30, 1),
    "metal": (0.55, 0.57, 0.60, 1), "plastic": (0.20, 0.35, 0.60, 1), "cardboard": (0.70, 0.55,
    0.35, 1), "fabric": (0.35, 0.20, 0.25, 1), "concrete": (0.60, 0.60, 0.58, 1),
    "dark": (0.15, 0.15, 0.17, 1),
}


def yaw_quat(yaw_deg: float) -> list[float]:
    half = math.radians(yaw_deg) / 2.0
    return [math.cos(half), 0.0, 0.0, math.sin(half)]


def polyline(*segments) -> np.ndarray:
    """Densely sampled path (every 5 cm) from ("line", length) and ("arc", radius, turn_deg)
    segments, starting at the origin heading +x."""
    points, heading, step = [np.zeros(2)], 0.0, 0.05
    for segment in segments:
        if segment[0] == "line":
            n = max(1, int(math.ceil(segment[1] / step)))
            for _ in range(n):
                points.append(points[-1] + segment[1] / n * np.array(
                    [math.cos(heading), math.sin(heading)]))
        elif segment[0] == "arc":
            radius, turn = segment[1], math.radians(segment[2])
            n = max(1, int(math.ceil(abs(turn) * radius / step)))
            for _ in range(n):
                chord_heading = heading + turn / n / 2
                chord = 2 * radius * math.sin(abs(turn) / n / 2)
                points.append(points[-1] + chord * np.array(
                    [math.cos(chord_heading), math.sin(chord_heading)]))
                heading += turn / n
        else:
            raise ValueError(f"unknown path segment {segment!r}; accepted: line, arc")
    return np.array(points)


def path_distance(path: np.ndarray, boxes: np.ndarray) -> np.ndarray:
    """Distance from a polyline (N, 2) to each axis-aligned rectangle (M, 4: xmin ymin xmax ymax).

    The path is resampled every centimetre; the result is exact to that resolution.
    """
    dense = [path[:1]]
    for a, b in zip(path[:-1], path[1:]):
        n = max(1, int(math.ceil(np.linalg.norm(b - a) / 0.01)))
        dense.append(a + (b - a) * (np.arange(1, n + 1)[:, None] / n))
    points = np.concatenate(dense)[:, None, :]
    boxes = np.asarray(boxes, dtype=float).reshape(-1, 4)[None]
    dx = np.maximum(np.maximum(boxes[..., 0] - points[..., 0], 0.0),
                    points[..., 0] - boxes[..., 2])
    dy = np.maximum(np.maximum(boxes[..., 1] - points[..., 1], 0.0),
                    points[..., 1] - boxes[..., 3])
    return np.hypot(dx, dy).min(axis=0)


def compiled_geom_boxes(model: mujoco.MjModel) -> tuple[np.ndarray, np.ndarray]:
    """World axis-aligned boxes (G, 6: xmin ymin zmin xmax ymax zmax) of the non-plane geoms of
    a compiled model at its initial pose, and their geom ids."""
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    ids = np.flatnonzero(model.geom_type != mujoco.mjtGeom.mjGEOM_PLANE)
    corners = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)])
    boxes = []
    for gid in ids:
        centre, half = model.geom_aabb[gid, :3], model.geom_aabb[gid, 3:]
        local = centre + corners * half
        world = data.geom_xpos[gid] + local @ data.geom_xmat[gid].reshape(3, 3).T
        boxes.append(np.concatenate([world.min(axis=0), world.max(axis=0)]))
    return np.array(boxes).reshape(-1, 6), ids


def lane_intrusions(model: mujoco.MjModel, path: np.ndarray,
                    half_width_m: float = CLEAR_HALF_WIDTH_M) -> list[str]:
    """Names of geoms below the robot's height that reach into the lane around ``path``."""
    boxes, ids = compiled_geom_boxes(model)
    low = boxes[:, 2] < ROBOT_HEIGHT_M
    distance = path_distance(path, boxes[:, [0, 1, 3, 4]])
    return [model.geom(int(g)).name for g in ids[low & (distance < half_width_m)]]


@dataclass(frozen=True)
class Scene:
    """An indoor scene: the arena (no robot yet) and the path the robot walks.

    Attributes:
        name: scene name (a key of ``sim.world.scenes.SCENES``).
        seed: the seed its placement was drawn from.
        arena: the MJCF root; attach the robot with ``sim.world.assembly.assemble``.
        path: (N, 2) waypoints on the floor, from the start to the end of the walk.
        start_xy: where the robot stands at the start (path[0]).
        start_yaw_deg: its heading at the start (direction of the path's first segment).
        clear_half_width_m: half-width of the obstacle-free lane around the path.
        description: one line for reports.
    """

    name: str
    seed: int
    arena: mjcf.RootElement
    path: np.ndarray
    start_xy: np.ndarray
    start_yaw_deg: float
    clear_half_width_m: float = CLEAR_HALF_WIDTH_M
    description: str = ""

    def compile(self) -> mujoco.MjModel:
        return mujoco.MjModel.from_xml_string(self.arena.to_xml_string(),
                                              self.arena.get_assets())


@dataclass
class SceneBuilder:
    """Builds one scene: a seeded rng, unique names, furniture that keeps out of the lane.

    Args:
        name: model name of the arena.
        seed: seed of every random choice of the scene.
        path: the robot's path (N, 2); furniture never comes within ``clear_half_width_m``.
        floor_material: material of the floor.
    """

    name: str
    seed: int
    path: np.ndarray
    floor_material: str = "floor"
    clear_half_width_m: float = CLEAR_HALF_WIDTH_M
    rng: np.random.Generator = field(init=False)
    arena: mjcf.RootElement = field(init=False)
    _footprints: list = field(init=False, default_factory=list)
    _counts: dict = field(init=False, default_factory=dict)

    def __post_init__(self):
        self.rng = np.random.default_rng(self.seed)
        arena = mjcf.RootElement(model=self.name)
        arena.statistic.extent = MODEL_EXTENT_M
        arena.visual.map.znear, arena.visual.map.zfar = ZNEAR, ZFAR
        arena.visual.headlight.ambient = [0.35, 0.35, 0.35]
        arena.visual.headlight.diffuse = [0.4, 0.4, 0.4]
        arena.asset.add("texture", name="floor", type="2d", builtin="checker", width=256,
                        height=256, rgb1=[0.45, 0.42, 0.38], rgb2=[0.38, 0.35, 0.32])
        arena.asset.add("material", name="floor", texture="floor", texrepeat=[2, 2],
                        texuniform=True, reflectance=0.05)
        for material, rgba in _MATERIALS.items():
            arena.asset.add("material", name=material, rgba=rgba)
        arena.worldbody.add("geom", name="floor", type="plane", size=[20, 20, 0.1],
                            material=self.floor_material)
        self.arena = arena

    def finish(self, description: str) -> Scene:
        """The finished Scene; raises if anything reached into the lane (a bug in the rules)."""
        scene = Scene(self.name, self.seed, self.arena, self.path.copy(),
                      self.path[0].copy(), self._start_yaw(), self.clear_half_width_m,
                      description)
        intruders = lane_intrusions(scene.compile(), self.path, self.clear_half_width_m)
        if intruders:
            raise RuntimeError(f"scene {self.name!r} seed {self.seed}: {intruders} in the lane")
        return scene

    def _start_yaw(self) -> float:
        direction = self.path[1] - self.path[0]
        return math.degrees(math.atan2(direction[1], direction[0]))

    def _name(self, kind: str) -> str:
        self._counts[kind] = self._counts.get(kind, 0) + 1
        return f"{kind}{self._counts[kind]}"

    # -- primitives -------------------------------------------------------------------------
    def body(self, kind: str, xy, yaw_deg: float = 0.0, z: float = 0.0, parent=None):
        """A static body at ``xy`` (in ``parent``'s frame; default the world), turned by yaw."""
        parent = self.arena.worldbody if parent is None else parent
        return parent.add("body", name=self._name(kind), pos=[xy[0], xy[1], z],
                          quat=yaw_quat(yaw_deg))

    def box(self, parent, half_size, pos, material: str):
        """A box geom of half-sizes (x, y, z) centred at ``pos`` in ``parent``'s frame."""
        return parent.add("geom", name=self._name("box"), type="box", size=list(half_size),
                          pos=list(pos), material=material)

    def cylinder(self, parent, radius: float, half_height: float, pos, material: str):
        return parent.add("geom", name=self._name("cyl"), type="cylinder",
                          size=[radius, half_height], pos=list(pos), material=material)

    def light(self, xyz, cast_shadow: bool = False):
        self.arena.worldbody.add("light", name=self._name("light"), pos=list(xyz),
                                 dir=[0, 0, -1], diffuse=[0.5, 0.5, 0.5],
                                 castshadow=cast_shadow)

    def ceiling_lights(self, x_range, y_range, height: float, spacing: float = 3.0):
        for x in np.arange(x_range[0], x_range[1] + 1e-9, spacing):
            for y in np.arange(y_range[0], y_range[1] + 1e-9, spacing):
                self.light([x, y, height])

    def wall(self, start_xy, end_xy, height: float = 2.5, thickness: float = 0.12,
             material: str = "wall"):
        """A straight wall whose centre line runs from ``start_xy`` to ``end_xy``."""
        start, end = np.asarray(start_xy, float), np.asarray(end_xy, float)
        delta = end - start
        yaw = math.degrees(math.atan2(delta[1], delta[0]))
        body = self.body("wall", (start + end) / 2, yaw)
        self.reserve((start + end) / 2, (np.linalg.norm(delta) / 2, thickness / 2), yaw)
        self.box(body, [np.linalg.norm(delta) / 2, thickness / 2, height / 2],
                 [0, 0, height / 2], material)
        return body

    def room(self, xmin, xmax, ymin, ymax, height=2.6, ceiling=True):
        """Four walls (and a ceiling) around a rectangle, with lights under the ceiling."""
        for a, b in [((xmin, ymin), (xmax, ymin)), ((xmax, ymin), (xmax, ymax)),
                     ((xmax, ymax), (xmin, ymax)), ((xmin, ymax), (xmin, ymin))]:
            self.wall(a, b, height)
        if ceiling:
            body = self.body("ceiling", ((xmin + xmax) / 2, (ymin + ymax) / 2), z=height)
            self.box(body, [(xmax - xmin) / 2, (ymax - ymin) / 2, 0.05], [0, 0, 0.05], "wall")
        self.ceiling_lights((xmin + 1, xmax - 1), (ymin + 1, ymax - 1), height - 0.2)

    # -- placement --------------------------------------------------------------------------
    def fits(self, xy, half_extents, yaw_deg: float, gap: float = 0.05) -> bool:
        """True if a footprint keeps out of the lane and off the footprints placed so far."""
        box = _footprint_box(xy, half_extents, yaw_deg)
        if path_distance(self.path, box)[0] < self.clear_half_width_m + 0.02:
            return False
        return all(not _overlap(box, other, gap) for other in self._footprints)

    def place(self, builder, half_extents, zone, yaw_choices=(0, 90, 180, 270),
              tries: int = 200):
        """Call ``builder(xy, yaw_deg)`` at a random pose in ``zone`` (xmin, xmax, ymin, ymax)
        where the footprint fits; returns the pose, or None when no pose fits."""
        for _ in range(tries):
            xy = (self.rng.uniform(zone[0], zone[1]), self.rng.uniform(zone[2], zone[3]))
            yaw = float(self.rng.choice(yaw_choices)) + self.rng.uniform(-8, 8)
            if self.fits(xy, half_extents, yaw):
                self._footprints.append(_footprint_box(xy, half_extents, yaw))
                builder(xy, yaw)
                return xy, yaw
        return None

    def place_crates(self, zone, smallest, largest, max_stack: int = 3):
        """A stack of 1 to ``max_stack`` boxes, half-sizes between ``smallest`` and
        ``largest``, at a free pose in ``zone``."""
        half = self.rng.uniform(smallest, largest)
        stack = int(self.rng.integers(1, max_stack + 1))
        return self.place(lambda xy, yaw: self.crate(xy, yaw, half, stack=stack), half[:2], zone)

    def place_barrel(self, zone, radii, heights, material="plastic"):
        """An upright cylinder, radius and height drawn from the (low, high) ranges."""
        radius, height = self.rng.uniform(*radii), self.rng.uniform(*heights)
        return self.place(lambda xy, yaw: self.barrel(xy, yaw, radius, height, material),
                          (radius, radius), zone)

    def reserve(self, xy, half_extents, yaw_deg=0.0):
        """Mark a footprint as occupied (fixed structures such as stairs)."""
        self._footprints.append(_footprint_box(xy, half_extents, yaw_deg))

    # -- furniture (origin at the floor, centre of the footprint) -----------------------------
    def desk(self, xy, yaw_deg, size=(1.2, 0.6), height=0.74):
        body = self.body("desk", xy, yaw_deg)
        hx, hy = size[0] / 2, size[1] / 2
        self.box(body, [hx, hy, 0.015], [0, 0, height - 0.015], "wood")
        for sx in (-1, 1):
            for sy in (-1, 1):
                self.box(body, [0.025, 0.025, (height - 0.03) / 2],
                         [sx * (hx - 0.05), sy * (hy - 0.05), (height - 0.03) / 2], "metal")
        if self.rng.random() < 0.7:  # something on the desk: a monitor or a box
            w = self.rng.uniform(0.15, 0.3)
            self.box(body, [w, 0.03 + 0.1 * self.rng.random(), w * 0.7],
                     [0, 0.05, height + w * 0.7], "dark")
        return body

    def chair(self, xy, yaw_deg, seat=0.45, height=0.45, parent=None):
        """A chair facing local +x (backrest at -x)."""
        body = self.body("chair", xy, yaw_deg, parent=parent)
        h = seat / 2
        self.box(body, [h, h, 0.03], [0, 0, height], "fabric")
        self.box(body, [0.03, h, 0.22], [-h + 0.03, 0, height + 0.25], "fabric")
        self.cylinder(body, 0.03, (height - 0.03) / 2, [0, 0, (height - 0.03) / 2], "metal")
        return body

    def shelf(self, xy, yaw_deg, width=0.9, depth=0.35, height=1.8, levels=4):
        body = self.body("shelf", xy, yaw_deg)
        for sx in (-1, 1):
            self.box(body, [0.015, depth / 2, height / 2], [sx * (width / 2 - 0.015), 0,
                                                             height / 2], "wood")
        self.box(body, [width / 2, 0.01, height / 2], [0, depth / 2 - 0.01, height / 2], "wood")
        for level in range(levels):
            z = 0.05 + level * (height - 0.1) / (levels - 1)
            self.box(body, [width / 2 - 0.03, depth / 2, 0.012], [0, 0, z], "wood")
            if level < levels - 1 and self.rng.random() < 0.8:  # books / boxes on the board
                w = self.rng.uniform(0.08, width / 2 - 0.05)
                hz = self.rng.uniform(0.06, 0.15)
                self.box(body, [w, depth / 2 - 0.04, hz],
                         [self.rng.uniform(-1, 1) * (width / 2 - 0.05 - w), 0, z + hz],
                         "cardboard")
        return body

    def crate(self, xy, yaw_deg, half_size, material="cardboard", stack=1):
        """A stack of ``stack`` boxes, each a little smaller and turned."""
        body = self.body("crate", xy, yaw_deg)
        z, hs = 0.0, np.asarray(half_size, float)
        for level in range(stack):
            yaw = self.rng.uniform(-15, 15) if level else 0.0
            top = self.body("crate_part", (0, 0), yaw, z, parent=body)
            self.box(top, hs, [0, 0, hs[2]], material)
            z += 2 * hs[2]
            hs = hs * [0.8, 0.8, 0.9]
        return body

    def barrel(self, xy, yaw_deg, radius=0.25, height=0.9, material="plastic"):
        body = self.body("barrel", xy, yaw_deg)
        self.cylinder(body, radius, height / 2, [0, 0, height / 2], material)
        return body

    def table(self, xy, yaw_deg, size=(1.5, 0.75), height=0.9):
        """A lab bench: a desk with equipment boxes on it."""
        body = self.desk(xy, yaw_deg, size, height)
        for _ in range(int(self.rng.integers(1, 4))):
            hs = self.rng.uniform([0.08, 0.08, 0.05], [0.2, 0.15, 0.2])
            self.box(body, hs, [self.rng.uniform(-1, 1) * (size[0] / 2 - hs[0]),
                                self.rng.uniform(-1, 1) * (size[1] / 2 - hs[1]),
                                height + hs[2]], "metal")
        return body

    def pillar(self, xy, yaw_deg=0.0, radius=0.2, height=3.0):
        body = self.body("pillar", xy, yaw_deg)
        self.reserve(xy, (radius, radius))
        self.cylinder(body, radius, height / 2, [0, 0, height / 2], "concrete")
        return body

    def doorway(self, xy, yaw_deg, width=0.9, height=2.05, wall=0.12, leaf_open_deg=None,
                sill_height=0.02):
        """A door frame across a wall gap: jambs, lintel, a sill on the floor and the leaf.

        The frame's local x runs along the wall, y through it. ``leaf_open_deg`` None keeps the
        leaf closed at the back of the frame; an angle swings it open about its hinge.
        """
        body = self.body("door", xy, yaw_deg)
        self.reserve(xy, (width / 2 + 0.08, wall / 2 + 0.02), yaw_deg)
        for sx in (-1, 1):
            self.box(body, [0.04, wall / 2 + 0.02, height / 2],
                     [sx * (width / 2 + 0.04), 0, height / 2], "door")
        self.box(body, [width / 2 + 0.08, wall / 2 + 0.02, 0.05], [0, 0, height + 0.05], "door")
        self.box(body, [width / 2, wall / 2 + 0.02, sill_height / 2], [0, 0, sill_height / 2],
                 "concrete")
        if leaf_open_deg is None:
            self.box(body, [width / 2 - 0.01, 0.02, (height - sill_height) / 2 - 0.005],
                     [0, wall / 2 - 0.02, sill_height + (height - sill_height) / 2], "door")
        else:
            hinge = self.body("hinge", (-width / 2, wall / 2), leaf_open_deg, parent=body)
            self.box(hinge, [width / 2 - 0.01, 0.02, (height - sill_height) / 2 - 0.005],
                     [width / 2, 0.02, sill_height + (height - sill_height) / 2], "door")
        return body

    def wall_with_doors(self, start_xy, end_xy, doors, height=2.5, thickness=0.12, **door_kw):
        """A wall from ``start_xy`` to ``end_xy`` with door openings centred at the distances
        ``doors`` (metres from the start, each (distance, leaf_open_deg or None))."""
        start, end = np.asarray(start_xy, float), np.asarray(end_xy, float)
        length = np.linalg.norm(end - start)
        unit = (end - start) / length
        yaw = math.degrees(math.atan2(unit[1], unit[0]))
        width = door_kw.pop("width", 0.9)
        cursor = 0.0
        for distance, leaf in sorted(doors, key=lambda d: d[0]):
            self.wall(start + unit * cursor, start + unit * (distance - width / 2 - 0.08),
                      height, thickness)
            self.doorway(start + unit * distance, yaw, width, wall=thickness,
                         leaf_open_deg=leaf, **door_kw)
            cursor = distance + width / 2 + 0.08
        self.wall(start + unit * cursor, end, height, thickness)

    def stairs(self, xy, yaw_deg, steps=6, rise=0.16, tread=0.3, width=2.0, landing=2.0,
               rail=True):
        """A straight flight rising along local +x from ``xy`` (the foot of the first step),
        a landing of depth ``landing`` at the top, and a rail of posts on both sides."""
        body = self.body("stairs", xy, yaw_deg)
        for i in range(steps):
            top = (i + 1) * rise
            self.box(body, [tread / 2, width / 2, top / 2], [(i + 0.5) * tread, 0, top / 2],
                     "concrete")
        top = steps * rise
        self.box(body, [landing / 2, width / 2, top / 2],
                 [steps * tread + landing / 2, 0, top / 2], "concrete")
        if rail:
            run = steps * tread + landing
            for sy in (-1, 1):
                for x in np.linspace(0.1, run - 0.1, 5):
                    z0 = min(x / tread, steps) * rise
                    self.cylinder(body, 0.02, 0.45, [x, sy * (width / 2 - 0.03), z0 + 0.45],
                                  "metal")
        return body


def _footprint_box(xy, half_extents, yaw_deg) -> np.ndarray:
    """Axis-aligned box (xmin, ymin, xmax, ymax) around a rotated rectangle."""
    c, s = abs(math.cos(math.radians(yaw_deg))), abs(math.sin(math.radians(yaw_deg)))
    hx = c * half_extents[0] + s * half_extents[1]
    hy = s * half_extents[0] + c * half_extents[1]
    return np.array([xy[0] - hx, xy[1] - hy, xy[0] + hx, xy[1] + hy])


def _overlap(a, b, gap) -> bool:
    return not (a[2] + gap <= b[0] or b[2] + gap <= a[0] or a[3] + gap <= b[1]
                or b[3] + gap <= a[1])
