"""How much the head camera swings over a gait cycle, in degrees and in SR4000 pixels.

For every control period of a steady forward walk, the camera's rotation relative to the first
frame of the current gait cycle (the paper's reference frame, docs/design.md) is split into pitch
(about the camera x axis), yaw (about y) and roll (about z, the optical axis). For a distant
scene these move the image by about x = fx tan(yaw), y = fy tan(pitch) pixels and rotate it by
the roll: the magnitudes the paper reports for its robot (x +-40 px, y 2-32 px, +-12 deg).

Run ``python -m sim.world.walking.camera_swing [gaits] [--seconds S]``; the figures of both
presets are in docs/walking.md, "Camera swing".
"""

from __future__ import annotations

import sys

import numpy as np
from scipy.spatial.transform import Rotation

from sim.command_line import OneLineParser, number_option, script_status
from sim.world.camera import SR4000_INTRINSICS
from sim.world.walking.gait import GAIT_PRESETS
from sim.world.walking.simulation import RobotSimulation
from sim.world.assembly import assemble, compile_world


def relative_camera_angles(reference_mats: np.ndarray, mats: np.ndarray) -> np.ndarray:
    """(N, 3) rotation vectors, degrees, of ``mats`` relative to ``reference_mats`` in the
    reference camera's frame: columns pitch (camera x), yaw (camera y), roll (camera z)."""
    relative = np.einsum("nji,njk->nik", reference_mats, mats)
    return np.degrees(Rotation.from_matrix(relative).as_rotvec())


def measure_camera_swing(gait: str = "default", walk_s: float = 12.0, settle_cycles: int = 2,
                         seed: int = 0) -> dict[str, float]:
    """Camera swing of a forward walk at the gait's top speed on a flat floor.

    Returns the extreme pitch/yaw/roll (deg) relative to each cycle's first frame over the
    cycles after ``settle_cycles``, the implied image shifts (px), and whether the robot fell.
    """
    sim = RobotSimulation(compile_world(assemble()), gait=gait, seed=seed)
    sim.run(1.0)
    sim.command(forward_speed_mps=sim.gait.max_forward_speed_mps)
    cycles, mats = [], []
    while sim.time < 1.0 + walk_s:
        sim.step()
        cycles.append(sim.gait_cycle)
        mats.append(sim.camera_pose()[1])
    cycles, mats = np.array(cycles), np.array(mats)
    first_of_cycle = np.searchsorted(cycles, cycles)      # cycles never decrease
    keep = cycles > cycles[0] + settle_cycles
    if not keep.any():
        raise ValueError(f"a walk of {walk_s:g} s ends within its first {settle_cycles + 1} gait "
                         f"cycles, which are not measured; accepted: a longer walk (the "
                         f"default is 12 s)")
    angles = relative_camera_angles(mats[first_of_cycle][keep], mats[keep])
    pitch, yaw, roll = angles.T
    k = SR4000_INTRINSICS
    return {
        "pitch_min_deg": pitch.min(), "pitch_max_deg": pitch.max(),
        "yaw_min_deg": yaw.min(), "yaw_max_deg": yaw.max(),
        "roll_min_deg": roll.min(), "roll_max_deg": roll.max(),
        "x_min_px": k.fx * np.tan(np.radians(yaw.min())), "x_max_px": k.fx * np.tan(np.radians(yaw.max())),
        "y_min_px": k.fy * np.tan(np.radians(pitch.min())), "y_max_px": k.fy * np.tan(np.radians(pitch.max())),
        "fell": sim.fall is not None,
    }


def main(argv: list[str] | None = None) -> int:
    parser = OneLineParser(prog="python -m sim.world.walking.camera_swing",
                           description=measure_camera_swing.__doc__.splitlines()[0])
    # Checked below: argparse checks an empty list of a positional against its choices.
    parser.add_argument("gaits", nargs="*", help=f"gait presets: {', '.join(GAIT_PRESETS)} "
                                                 f"(default: every one)")
    parser.add_argument("--seconds", type=number_option(0.0, 3600.0), default=12.0,
                        help="walking time (default 12 s)")
    args = parser.parse_args(argv)
    unknown = [gait for gait in args.gaits if gait not in GAIT_PRESETS]
    if unknown:
        parser.error(f"gait {unknown[0]!r}: accepted: {', '.join(GAIT_PRESETS)}")
    for gait in args.gaits or list(GAIT_PRESETS):
        try:
            s = measure_camera_swing(gait, args.seconds)
        except ValueError as error:  # a walk too short to measure
            parser.error(f"--seconds {args.seconds:g}: {error}")
        print(f"{gait}: pitch [{s['pitch_min_deg']:.1f}, {s['pitch_max_deg']:.1f}] deg, "
              f"yaw [{s['yaw_min_deg']:.1f}, {s['yaw_max_deg']:.1f}] deg, "
              f"roll [{s['roll_min_deg']:.1f}, {s['roll_max_deg']:.1f}] deg; image x "
              f"[{s['x_min_px']:.0f}, {s['x_max_px']:.0f}] px, y [{s['y_min_px']:.0f}, "
              f"{s['y_max_px']:.0f}] px; fell: {s['fell']}")
    return 0


if __name__ == "__main__":
    sys.exit(script_status(main))
