"""The robot's lane: paths on the floor and the check that nothing stands in the way.

A scene's path is a polyline sampled every 5 cm; its lane is the band of half-width
``CLEAR_HALF_WIDTH_M`` around it. Placement keeps furniture out of the lane
(:mod:`sim.world.scenes.placement`); :func:`lane_intrusions` checks the compiled model again.

Conventions: x, y on the floor, z up, metres; the path starts at the origin heading +x.
"""

from __future__ import annotations

import math

import mujoco
import numpy as np

#: Half-width of the robot's lane around the path: half the robot's width (~0.18 m with arms)
#: plus room for the sway and drift of an open-loop gait.
CLEAR_HALF_WIDTH_M = 0.35
#: Geoms whose lowest point is above this are overhead and cannot hit the 0.6 m robot.
ROBOT_HEIGHT_M = 0.75
#: Spacing of the points of a path, metres.
PATH_STEP_M = 0.05


def polyline(*segments) -> np.ndarray:
    """A path sampled every 5 cm, starting at the origin heading +x.

    Args:
        *segments: ``("line", length_m)`` runs straight ahead; ``("arc", radius_m, turn_deg)``
            turns on a circle, counter-clockwise for a positive ``turn_deg``.

    Returns:
        (N, 2) points on the floor, metres, from the start to the end of the path.
    """
    points, heading, step = [np.zeros(2)], 0.0, PATH_STEP_M
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


def start_heading_deg(path: np.ndarray) -> float:
    """Heading of a path's first segment, degrees counter-clockwise from +x."""
    direction = path[1] - path[0]
    return math.degrees(math.atan2(direction[1], direction[0]))


def path_distance(path: np.ndarray, boxes: np.ndarray) -> np.ndarray:
    """Distance from a polyline (N, 2) to each axis-aligned rectangle (M, 4: xmin ymin xmax ymax).

    The path is resampled every centimetre; the result is exact to that resolution.
    """
    dense = [path[:1]]
    for start, end in zip(path[:-1], path[1:]):
        n = max(1, int(math.ceil(np.linalg.norm(end - start) / 0.01)))
        dense.append(start + (end - start) * (np.arange(1, n + 1)[:, None] / n))
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
