"""Synthetic depth scenes with a known answer, for the stabilizer's tests and benchmarks.

A scene is a float32 depth image (metres, 0 = no measurement) of a back wall with a few objects
in front of it at different depths: boxes (rotated rectangles), cylinders seen end-on
(ellipses) and slanted planes (quadrilaterals whose depth varies across them). Everything is
drawn with OpenCV and is a pure function of the seed.

:func:`make_depth_scene` is the tests' scene. The varied corpus (:data:`CORPUS_GENERATORS`,
:func:`corpus_frames`) widens it for the speed and accuracy figures: few and many objects,
floor and ceiling gradients, clutter, depth noise and invalid pixels, each a named generator,
so that a figure measured on the tests' scenes alone does not stand for every scene.
"""

from __future__ import annotations

import cv2
import numpy as np

from stabilizer.motion import Motion

SR4000_SHAPE = (144, 176)


def make_depth_scene(seed: int, shape: tuple[int, int] = SR4000_SHAPE, n_objects: int = 4,
                     wall_m: float = 4.5, floor: bool = False) -> np.ndarray:
    """A depth image of a wall with objects in front of it, a pure function of ``seed``.

    Objects keep clear of the image border by 15% so that moderate motions keep them in view.

    Parameters
    ----------
    seed : int
        Seed of the scene's random layout.
    shape : (int, int), optional
        (H, W). Default the SR4000's 144 x 176.
    n_objects : int, optional
        Objects at 0.8-3.5 m, each a box, an end-on cylinder or a slanted plane. Default 4.
    wall_m : float, optional
        Depth of the back wall in metres. Default 4.5.
    floor : bool, optional
        The lower quarter is a floor plane whose depth grows toward the wall. Default False.

    Returns
    -------
    (H, W) ndarray of float32
        Depth in metres.
    """
    rng = np.random.default_rng(seed)
    height, width = shape
    depth = np.full(shape, wall_m, np.float32)
    if floor:
        rows = np.arange(height * 3 // 4, height)
        ramp = np.linspace(wall_m, 1.2, rows.size, dtype=np.float32)
        depth[rows, :] = ramp[:, None]
    object_depths = np.sort(rng.uniform(0.8, 3.5, n_objects))[::-1]  # far ones drawn first
    for kind, object_depth in zip(rng.integers(0, 3, n_objects), object_depths):
        cx = rng.uniform(0.25, 0.75) * width
        cy = rng.uniform(0.25, 0.75) * height
        half_w = rng.uniform(0.08, 0.18) * width
        half_h = rng.uniform(0.08, 0.2) * height
        angle = rng.uniform(0.0, 180.0)
        mask = np.zeros(shape, np.uint8)
        if kind == 1:  # cylinder seen end-on
            cv2.ellipse(mask, (int(cx), int(cy)), (int(half_w), int(half_h)), angle, 0, 360, 1, -1)
        else:  # box face or slanted plane
            corners = cv2.boxPoints(((cx, cy), (2 * half_w, 2 * half_h), angle))
            cv2.fillPoly(mask, [np.rint(corners).astype(np.int32)], 1)
        inside = mask.astype(bool)
        if kind == 2:  # slanted plane: depth changes by up to 0.3 m across it
            ys, xs = np.nonzero(inside)
            tilt = rng.uniform(-0.3, 0.3) * (xs - cx) / max(half_w, 1.0)
            depth[ys, xs] = object_depth + tilt.astype(np.float32)
        else:
            depth[inside] = object_depth
    return depth


def random_motion(rng: np.random.Generator, max_angle_deg: float = 15.0,
                  max_shift_px: float = 40.0) -> Motion:
    """A rigid motion with angle and shifts drawn uniformly within the given bounds.

    Parameters
    ----------
    rng : numpy.random.Generator
        Source of the draws.
    max_angle_deg : float, optional
        Angles in [-max, max]. Default 15, beyond the +-12 degrees of a walking camera (Kang et
        al. 2009, section III-B).
    max_shift_px : float, optional
        Shifts in [-max, max] along each axis. Default 40, the paper's walking peaks.

    Returns
    -------
    Motion
    """
    return Motion(float(rng.uniform(-max_angle_deg, max_angle_deg)),
                  float(rng.uniform(-max_shift_px, max_shift_px)),
                  float(rng.uniform(-max_shift_px, max_shift_px)))


def _draw_object(depth: np.ndarray, rng: np.random.Generator, object_depth: float,
                 size_range: tuple[float, float], kinds: tuple[int, ...] = (0, 1, 2)) -> None:
    """One object of :func:`make_depth_scene`'s kinds (box, end-on cylinder, slanted plane)
    drawn over ``depth`` in place, its half-sides ``size_range`` fractions of the image's."""
    height, width = depth.shape
    kind = kinds[int(rng.integers(0, len(kinds)))]
    cx = rng.uniform(0.1, 0.9) * width
    cy = rng.uniform(0.1, 0.9) * height
    half_w = rng.uniform(*size_range) * width
    half_h = rng.uniform(*size_range) * height
    angle = rng.uniform(0.0, 180.0)
    mask = np.zeros(depth.shape, np.uint8)
    if kind == 1:
        cv2.ellipse(mask, (int(cx), int(cy)), (max(int(half_w), 1), max(int(half_h), 1)), angle,
                    0, 360, 1, -1)
    else:
        corners = cv2.boxPoints(((cx, cy), (2 * half_w, 2 * half_h), angle))
        cv2.fillPoly(mask, [np.rint(corners).astype(np.int32)], 1)
    ys, xs = np.nonzero(mask)
    if kind == 2:  # slanted plane: depth changes by up to 0.3 m across it
        tilt = rng.uniform(-0.3, 0.3) * (xs - cx) / max(half_w, 1.0)
        depth[ys, xs] = (object_depth + tilt).astype(np.float32)
    else:
        depth[ys, xs] = object_depth


def _room(shape: tuple[int, int], rng: np.random.Generator, wall_m: float,
          ceiling: bool) -> np.ndarray:
    """A back wall at ``wall_m`` with a floor (and optionally a ceiling) whose depth falls
    linearly from the wall to 1-1.5 m at the image edge, as a room seen level."""
    height, width = shape
    depth = np.full(shape, wall_m, np.float32)
    horizon = int(rng.uniform(0.45, 0.65) * height)
    depth[horizon:] = np.linspace(wall_m, rng.uniform(1.0, 1.5), height - horizon,
                                  dtype=np.float32)[:, None]
    if ceiling:
        top = int(rng.uniform(0.15, 0.3) * height)
        depth[:top] = np.linspace(rng.uniform(1.5, 2.5), wall_m, top, dtype=np.float32)[:, None]
    return depth


def few_objects_scene(seed: int, shape: tuple[int, int] = SR4000_SHAPE) -> np.ndarray:
    """A wall at 3.5-6 m with one or two large objects: few clusters, large regions."""
    rng = np.random.default_rng(seed)
    depth = np.full(shape, rng.uniform(3.5, 6.0), np.float32)
    for object_depth in np.sort(rng.uniform(0.8, 3.0, int(rng.integers(1, 3))))[::-1]:
        _draw_object(depth, rng, object_depth, (0.12, 0.25))
    return depth


def many_objects_scene(seed: int, shape: tuple[int, int] = SR4000_SHAPE) -> np.ndarray:
    """A wall at 4-6 m with 8-12 objects at 0.7-3.8 m: many clusters and point sets."""
    rng = np.random.default_rng(seed)
    depth = np.full(shape, rng.uniform(4.0, 6.0), np.float32)
    for object_depth in np.sort(rng.uniform(0.7, 3.8, int(rng.integers(8, 13))))[::-1]:
        _draw_object(depth, rng, object_depth, (0.05, 0.14))
    return depth


def gradient_floor_scene(seed: int, shape: tuple[int, int] = SR4000_SHAPE) -> np.ndarray:
    """3-5 boxes and end-on cylinders on a floor whose depth grows toward the wall: the floor
    spreads the histogram over many gray levels."""
    rng = np.random.default_rng(seed)
    depth = _room(shape, rng, rng.uniform(4.0, 6.0), ceiling=False)
    for object_depth in np.sort(rng.uniform(0.9, 3.5, int(rng.integers(3, 6))))[::-1]:
        _draw_object(depth, rng, object_depth, (0.07, 0.18), kinds=(0, 1))
    return depth


def clutter_scene(seed: int, shape: tuple[int, int] = SR4000_SHAPE) -> np.ndarray:
    """A room (floor and ceiling gradients) with 15-30 small objects of every kind, many of
    them slanted: crowded histograms, many small and cut regions."""
    rng = np.random.default_rng(seed)
    depth = _room(shape, rng, rng.uniform(4.5, 7.0), ceiling=True)
    for object_depth in np.sort(rng.uniform(0.7, 4.0, int(rng.integers(15, 31))))[::-1]:
        _draw_object(depth, rng, object_depth, (0.03, 0.09))
    return depth


def noisy_scene(seed: int, shape: tuple[int, int] = SR4000_SHAPE) -> np.ndarray:
    """:func:`gradient_floor_scene`'s layout; :func:`corpus_frames` adds 2% depth noise to
    each of its frames (see :data:`CORPUS_GENERATORS`)."""
    return gradient_floor_scene(seed, shape)


def invalid_pixels_scene(seed: int, shape: tuple[int, int] = SR4000_SHAPE) -> np.ndarray:
    """A room with 3-5 objects and the invalid pixels of a time-of-flight camera: an
    out-of-range far region (a doorway beyond 10 m), one or two dark objects that return no
    measurement, and thin lines of no measurement along some depth edges (mixed pixels);
    :func:`corpus_frames` adds 0.5% scattered dropouts to each frame."""
    rng = np.random.default_rng(seed)
    height, width = shape
    depth = _room(shape, rng, rng.uniform(4.0, 6.0), ceiling=True)
    door_w, door_h = rng.uniform(0.12, 0.25) * width, rng.uniform(0.25, 0.45) * height
    door_x, door_y = rng.uniform(0.1, 0.9) * width - door_w / 2, rng.uniform(0.15, 0.4) * height
    depth[int(door_y):int(door_y + door_h), int(max(door_x, 0)):int(door_x + door_w)] = 0.0
    for object_depth in np.sort(rng.uniform(0.9, 3.5, int(rng.integers(3, 6))))[::-1]:
        _draw_object(depth, rng, object_depth, (0.07, 0.18))
    for _ in range(int(rng.integers(1, 3))):  # dark surfaces: no measurement
        _draw_object(depth, rng, 0.0, (0.04, 0.08), kinds=(0, 1))
    # Mixed pixels: no measurement on one pixel of some strong depth edges.
    edges = cv2.morphologyEx(depth, cv2.MORPH_GRADIENT, np.ones((3, 3), np.uint8)) > 0.8
    edges &= rng.random(shape) < 0.5
    depth[edges] = 0.0
    return depth


#: The varied corpus: name -> (scene generator(seed, shape), relative depth noise sigma,
#: fraction of dropout pixels), the noise and dropouts drawn anew for every frame.
CORPUS_GENERATORS = {
    "tests": (make_depth_scene, 0.0, 0.0),
    "few_objects": (few_objects_scene, 0.0, 0.0),
    "many_objects": (many_objects_scene, 0.0, 0.0),
    "gradient_floor": (gradient_floor_scene, 0.0, 0.0),
    "clutter": (clutter_scene, 0.0, 0.0),
    "noisy": (noisy_scene, 0.02, 0.0),
    "invalid_pixels": (invalid_pixels_scene, 0.0, 0.005),
}


def corrupt_depth(depth: np.ndarray, rng: np.random.Generator, noise: float = 0.0,
                  dropouts: float = 0.0) -> np.ndarray:
    """``depth`` with Gaussian noise of ``noise`` times the depth (a range sensor's error
    grows with the distance) and a ``dropouts`` fraction of measured pixels set to 0."""
    measured = depth > 0
    out = depth.copy()
    if noise > 0:
        out += (noise * depth * rng.standard_normal(depth.shape)).astype(np.float32)
    if dropouts > 0:
        out[measured & (rng.random(depth.shape) < dropouts)] = 0.0
    out[~measured] = 0.0
    return out


def corpus_frames(generator: str, seed: int, n_frames: int,
                  shape: tuple[int, int] = SR4000_SHAPE, max_angle_deg: float = 15.0,
                  max_shift_px: float = 40.0) -> tuple[np.ndarray, list[np.ndarray],
                                                       list[Motion]]:
    """A reference and ``n_frames`` moved copies of one scene of a corpus generator, as the
    stabilizer's uint8 disparity input; a pure function of its arguments.

    The depth scene is moved by :func:`random_motion` (nearest-neighbour warp, uncovered pixels
    unmeasured), then the generator's noise and dropouts are drawn for each frame, the
    reference's too.

    Parameters
    ----------
    generator : str
        A key of :data:`CORPUS_GENERATORS`.
    seed : int
        Seed of the scene and of the motions and noise.
    n_frames : int
        Moved frames, >= 0.
    shape : (int, int), optional
        (H, W); default the SR4000's.
    max_angle_deg, max_shift_px : float, optional
        Bounds of the motions (:func:`random_motion`).

    Returns
    -------
    reference : (H, W) ndarray of uint8
    frames : list of (H, W) ndarray of uint8
    motions : list of Motion
        The true motion of each frame relative to the reference.
    """
    from stabilizer.inputs import depth_to_disparity
    from stabilizer.motion import apply_motion

    if generator not in CORPUS_GENERATORS:
        raise ValueError(f"unknown corpus generator {generator!r}; accepted: "
                         f"{', '.join(CORPUS_GENERATORS)}")
    if n_frames < 0:
        raise ValueError(f"n_frames must be >= 0; got {n_frames}")
    make_scene, noise, dropouts = CORPUS_GENERATORS[generator]
    depth = make_scene(seed, shape)
    rng = np.random.default_rng([seed, 1])
    reference = depth_to_disparity(corrupt_depth(depth, rng, noise, dropouts))
    motions = [random_motion(rng, max_angle_deg, max_shift_px) for _ in range(n_frames)]
    frames = [depth_to_disparity(corrupt_depth(apply_motion(depth, motion), rng, noise,
                                               dropouts)) for motion in motions]
    return reference, frames, motions
