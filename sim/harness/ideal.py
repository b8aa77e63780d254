"""The paper's "ideal environment" experiment (Kang, Zhang & Park 2009, section III-A).

One disparity/depth image is moved along a known trajectory of rigid motions; every method
estimates each moved frame against the original; the errors against the known motions give the
paper's Table I layout, its Fig. 8 (estimate against truth) and a per-frame CSV.

Images accepted (``load_image``):
- an 8-bit PNG: a disparity-like image (brighter = closer, 0 = no measurement);
- a 16-bit PNG: depth in millimetres (0 = no measurement), as depth cameras export it;
- a ``.npy`` file: float depth in metres;
- a scene name of ``sim.world.scenes.SCENES``: the noise-free SR4000 frame seen by the standing
  robot at the scene's start (rendered with the "noiseless" sensor preset).

Trajectories (``load_trajectory``): ``"paper_cycle"`` (default) is one gait cycle with the
magnitudes the paper saw on its walking robot (section III-B: x peaks near +-40 px, y between 2
and 32 px, rotation near +-12 deg): rotation 12 sin(p), x 40 sin(p + pi/3), y 17 - 15 cos(2p),
p = 2 pi k / n; or a frames.csv of a walking run, whose ground-truth motions are replayed.
"""

from __future__ import annotations

import csv
import math
import time
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from sim.harness.methods import method_factory
from sim.harness.sequence import decode_image
from stabilizer import apply_motion, available_methods, depth_to_disparity
from stabilizer.motion import Motion

#: Name of the default trajectory.
PAPER_CYCLE = "paper_cycle"
#: Frame rate that puts the trajectory's frames on a time axis (the SR4000's default).
IDEAL_FPS = 30.0
#: Largest image the experiment takes as it is (1280 x 1024): every method's time and memory
#: grow with the pixel count (a 4000 x 3000 image took 3.8 GB and 140 s for 3 frames).
MAX_IMAGE_PIXELS = 1280 * 1024


@dataclass(frozen=True)
class IdealConfig:
    """One ideal experiment.

    Attributes:
        image: PNG/.npy path or a scene name (see the module docstring).
        out_dir: folder for frames.csv, metrics.json, summary.md and the plots.
        trajectory: ``"paper_cycle"`` or the path of a walking run's frames.csv.
        methods: methods to score; None = all available.
        n_frames: frames of the paper cycle (ignored for a frames.csv trajectory).
        scene_seed: seed of the scene when ``image`` is a scene name.
        resize: scale an image larger than ``MAX_IMAGE_PIXELS`` down to fit (nearest
            neighbour, so no disparity value is invented); refused otherwise.
    """

    image: str
    out_dir: str
    trajectory: str = PAPER_CYCLE
    methods: tuple[str, ...] | None = None
    n_frames: int = 30
    scene_seed: int = 0
    resize: bool = False


def paper_cycle(n_frames: int = 30) -> list[Motion]:
    """One gait cycle of the paper's magnitudes (see the module docstring)."""
    if n_frames < 2:
        raise ValueError(f"n_frames must be >= 2; got {n_frames}")
    phase = 2.0 * np.pi * np.arange(n_frames) / n_frames
    return [Motion(12.0 * math.sin(p), 40.0 * math.sin(p + math.pi / 3),
                   17.0 - 15.0 * math.cos(2.0 * p)) for p in phase]


def trajectory_from_run(frames_csv: str | Path) -> list[Motion]:
    """The ground-truth motions of a walking run's frames.csv, one per frame, in order."""
    from sim.harness.validation import FileValueError

    columns = ("frame_index", "truth_status", "true_angle_deg", "true_dx_px", "true_dy_px")
    motions: dict[int, Motion] = {}
    try:
        with open(frames_csv, newline="", encoding="utf-8-sig") as handle:
            reader = csv.DictReader(handle)
            missing = [name for name in columns if name not in (reader.fieldnames or ())]
            if missing:
                raise FileValueError(str(frames_csv), "header",
                                     f"lacks column(s) {', '.join(missing)}",
                                     "the frames.csv of a walking run")
            for line, row in enumerate(reader, start=2):
                if row["truth_status"] != "ok":
                    continue
                try:
                    index = int(row["frame_index"])
                    values = [float(row[name]) for name in columns[2:]]
                    if not all(map(math.isfinite, values)):
                        raise ValueError("a truth that is not finite")
                except (TypeError, ValueError):
                    raise FileValueError(f"{frames_csv}:{line}", "row", "holds a value that is "
                                         "not a finite number", "the frames.csv of a walking "
                                         "run") from None
                motions.setdefault(index, Motion(*values))
    except (UnicodeDecodeError, csv.Error) as error:
        raise FileValueError(str(frames_csv), "content", f"is not a CSV table ({error})",
                             "the frames.csv of a walking run (UTF-8)") from None
    if not motions:
        raise ValueError(f"{frames_csv}: no frame with a ground truth (truth_status ok); "
                         "give the frames.csv of a walking run")
    return [motions[index] for index in sorted(motions)]


def load_trajectory(trajectory: str, n_frames: int = 30) -> list[Motion]:
    if trajectory == PAPER_CYCLE:
        return paper_cycle(n_frames)
    if Path(trajectory).suffix.lower() == ".csv" and Path(trajectory).is_file():
        return trajectory_from_run(trajectory)
    raise ValueError(f"unknown trajectory {trajectory!r}; accepted: {PAPER_CYCLE!r} or the "
                     "path of a walking run's frames.csv")


def render_scene_still(scene_name: str, seed: int = 0) -> np.ndarray:
    """Noise-free SR4000 depth (metres) seen by the standing robot at the scene's start."""
    from sim.harness.runner import build_robot
    from sim.world.sensor.sr4000 import SR4000
    from sim.world.sensor.tof_model import TOF_PRESETS

    robot = build_robot(scene_name, seed, seed=seed)
    with SR4000(robot.model, robot.camera_name, TOF_PRESETS["noiseless"]) as sensor:
        return sensor.capture_still(robot.data).depth_m


def load_image(image: str, scene_seed: int = 0, resize: bool = False) -> np.ndarray:
    """The uint8 disparity-like image of ``image`` (see the module docstring).

    An image of more than ``MAX_IMAGE_PIXELS`` is refused, or scaled down to fit when
    ``resize`` is true.
    """
    from sim.world.scenes import SCENES

    if image in SCENES:
        return depth_to_disparity(render_scene_still(image, scene_seed))
    path = Path(image)
    if not path.is_file():
        raise ValueError(f"{image!r} is neither a file nor a scene name; accepted: an 8-bit "
                         f"or 16-bit PNG, a .npy depth in metres, or one of {', '.join(SCENES)}")
    if path.suffix.lower() == ".npy":
        try:
            depth = np.load(path)  # never pickles: an object array is refused
        except (ValueError, OSError, EOFError) as error:
            raise ValueError(f"{image}: cannot read it as a .npy array ({error}); accepted: "
                             f"a 2-D numeric array of depths in metres (numpy.save)") from None
        if depth.ndim != 2 or not np.issubdtype(depth.dtype, np.number):
            raise ValueError(f"{image}: need a 2-D array of depths in metres; got "
                             f"{depth.dtype} with shape {depth.shape}")
        return _within_size_limit(depth_to_disparity(depth.astype(np.float64)), image, resize)
    try:
        pixels = decode_image(path.read_bytes())
    except OSError:
        pixels = None
    if pixels is None or pixels.ndim != 2 or pixels.dtype not in (np.uint8, np.uint16):
        raise ValueError(f"{image}: need a single-channel 8-bit (disparity) or 16-bit "
                         f"(depth in mm) PNG; got "
                         f"{'an unreadable file' if pixels is None else pixels.dtype}"
                         f"{'' if pixels is None else f' with shape {pixels.shape}'}")
    if pixels.dtype == np.uint16:
        pixels = depth_to_disparity(np.where(pixels > 0, pixels / 1000.0, np.nan))
    return _within_size_limit(pixels, image, resize)


def _within_size_limit(disparity: np.ndarray, image: str, resize: bool) -> np.ndarray:
    height, width = disparity.shape
    if height * width <= MAX_IMAGE_PIXELS:
        return disparity
    if not resize:
        raise ValueError(f"{image}: {width} x {height} pixels is larger than the ideal "
                         f"experiment accepts ({MAX_IMAGE_PIXELS:,} pixels, e.g. 1280 x 1024); "
                         "pass --resize to scale it down")
    scale = math.sqrt(MAX_IMAGE_PIXELS / (height * width))
    size = (max(1, int(width * scale)), max(1, int(height * scale)))
    return cv2.resize(disparity, size, interpolation=cv2.INTER_NEAREST)


def run_ideal(config: IdealConfig) -> dict:
    """Run the ideal experiment; write and return the metrics (metrics.json)."""
    from sim.harness.atomic import prepare_output_dir
    from sim.harness.ground_truth import GroundTruth
    from sim.harness.report import write_run_outputs
    from sim.harness.runner import timed_estimate
    from sim.harness.scoring import RAW_STREAM, FrameRecord, ItfAccumulator, summarize
    from stabilizer import compensate

    methods = tuple(config.methods or available_methods())
    reference = load_image(config.image, config.scene_seed, config.resize)
    motions = load_trajectory(config.trajectory, config.n_frames)
    stabilizers = {method: method_factory(method)(reference) for method in methods}
    prepare_output_dir(config.out_dir)  # after the inputs: a refused one leaves no folder
    rows, cols = np.nonzero(reference[::2, ::2])  # the walking truth's stride-2 sample
    source = np.stack([2 * cols, 2 * rows], axis=1)
    records = []
    itf = ItfAccumulator()
    for index, truth_motion in enumerate(motions):
        current = apply_motion(reference, truth_motion)
        truth = GroundTruth.exact(truth_motion, source, reference.shape)
        itf.add(RAW_STREAM, current, gait_cycle=0, reference_index=-1)
        for method in methods:
            motion, ms = timed_estimate(stabilizers[method], current)
            itf.add(method, compensate(current, motion), gait_cycle=0, reference_index=-1)
            records.append(FrameRecord.score(
                frame_index=index, time_s=index / IDEAL_FPS, gait_cycle=0, reference_index=-1,
                method=method, estimate=motion, truth=truth, ms=ms))
    scenario = {"name": f"ideal:{Path(config.image).stem}", "mode": "ideal",
                "image": config.image, "trajectory": config.trajectory,
                "n_frames": len(motions), "scene_seed": config.scene_seed}
    files = write_run_outputs(config.out_dir, scenario=scenario, records=records,
                              summary=summarize(records, itf), status="complete",
                              meta={"seed": config.scene_seed, "methods": list(methods),
                                    "created": time.strftime("%Y-%m-%d")})
    return files.metrics
