"""What the trust check saw on the ``"ok"`` estimates a suite found off by more than 5° or 10 px.

    python benchmarks/ok_but_off.py SUITE_DIR        # a folder `egostab suite` wrote
    python benchmarks/ok_but_off.py SUITE_DIR --figures DIR   # and a picture of each frame

For every frame under "Ok but off" in the suite's tables (suite.json, ``large_errors``), the
trust check runs again on that frame and its reference, for the method's estimate and for the
rigid truth, twice: on the sensor's depth, which the methods saw, and on the exact depth of the
sequence's ``exact/`` folder (no noise, every surface measured). One row per frame: the errors,
the truth's residual, the estimate's end-point error against the floor the rigid truth leaves
(the run's frames.csv), then for each depth the check's verdict on the estimate and on the truth
(``ok`` or the test that failed) and how far, in rotation, the optimum of the depth edges that
the check climbed to from the estimate lies from the truth. A truth that fails where the
estimate passes says the check's edges do not line up at the truth; the exact depth tells
whether the sensor (noise, unmeasured surfaces) is why. docs/suites.md reports it for the
maintainers' checks. With ``--figures DIR``, one picture per frame (:func:`picture`).
"""

from __future__ import annotations

import csv
import json
import sys
from pathlib import Path

# First: importing sim puts numpy and OpenCV on the SIMD paths of egostab's runs, and
# limit_threads gives them one thread each, as where egostab estimates, before they load.
from sim.harness.threads import limit_threads

limit_threads()

import cv2
import numpy as np


def _verdict(motion) -> str:
    return "ok" if motion.ok else motion.diagnostics.get("verify_failed", motion.status)


def _turn_between(optimum: tuple[float, float, float], truth_deg: float) -> float:
    from stabilizer.motion import wrap_angle_deg

    return abs(float(wrap_angle_deg(optimum[0] - truth_deg)))


def _exact_disparity(frame) -> np.ndarray:
    from stabilizer import depth_to_disparity

    return depth_to_disparity(frame.true_depth_m)  # no surface (0, beyond 10 m): 0


def looked_at(suite_dir: Path) -> list[dict]:
    """One dict per "ok but off" frame of the suite in ``suite_dir``: the suite's figures and
    the check's verdicts on the sensor's and the exact depth."""
    from sim.harness.sequence import load_sequence
    from sim.harness.suite.run import SEQUENCE_FOLDER
    from sim.harness.suite.tables import TABLE_JSON
    from sim.harness.sweep import RUNS_FOLDER
    from stabilizer import Motion
    from stabilizer.verification import Verifier

    listed = json.loads((suite_dir / TABLE_JSON).read_text(encoding="utf-8"))["large_errors"]
    found = []
    for method, errors in listed.items():
        for entry in errors["frames"]:
            run = suite_dir / RUNS_FOLDER / entry["sequence"]
            with open(run / "frames.csv", newline="", encoding="utf-8") as frames:
                row = next(row for row in csv.DictReader(frames) if row["method"] == method
                           and int(row["frame_index"]) == entry["frame"])
            sequence = load_sequence(run / SEQUENCE_FOLDER)
            reference = sequence.frame(int(row["reference_index"]))
            current = sequence.frame(entry["frame"])
            estimate = Motion(*(float(row[key]) for key in ("est_angle_deg", "est_dx_px",
                                                            "est_dy_px")))
            truth = Motion(*(float(row[key]) for key in ("true_angle_deg", "true_dx_px",
                                                         "true_dy_px")))
            result = dict(entry, method=method, residual_px=float(row["truth_residual_px"]),
                          epe_px=float(row["epe_px"]), floor_px=float(row["truth_epe_px"]),
                          reference_frame=int(row["reference_index"]),
                          estimate=estimate.as_tuple(), truth=truth.as_tuple())
            for depth, image in (("sensor", lambda frame: frame.disparity8),
                                 ("exact", _exact_disparity)):
                check = Verifier(image(reference))
                on_estimate = check(image(current), estimate)
                on_truth = check(image(current), truth)
                result[depth] = {
                    "estimate": _verdict(on_estimate), "truth": _verdict(on_truth),
                    "optimum_off_truth_deg": _turn_between(
                        on_estimate.diagnostics["verify_optimum"], truth.angle_deg)}
            found.append(result)
    return found


def picture(reference: np.ndarray, current: np.ndarray, estimate, truth,
            scale: int = 3) -> np.ndarray:
    """Four panels side by side, each ``scale`` times the frame's size (BGR, uint8): the
    reference, the current frame, and the reference (magenta) over the current frame compensated
    by the estimate (green), then by the truth: where the two line up they make gray, where they
    do not, magenta and green fringes. Disparities (uint8, 0 = unmeasured, black) are stretched
    to the reference's 1st-99th percentile."""
    from stabilizer.motion import motion_matrix

    measured = reference[reference > 0]
    low, high = np.percentile(measured, (1, 99)) if measured.size else (0.0, 255.0)

    def stretched(image: np.ndarray) -> np.ndarray:
        shown = np.clip((image.astype(np.float32) - low) * (235.0 / max(high - low, 1.0)) + 20.0,
                        20.0, 255.0).astype(np.uint8)
        shown[image == 0] = 0
        return shown

    def compensated(motion) -> np.ndarray:
        height, width = current.shape
        return cv2.warpAffine(current, motion_matrix(motion, current.shape), (width, height),
                              flags=cv2.INTER_NEAREST | cv2.WARP_INVERSE_MAP)

    shown = stretched(reference)
    panels = [cv2.cvtColor(shown, cv2.COLOR_GRAY2BGR),
              cv2.cvtColor(stretched(current), cv2.COLOR_GRAY2BGR)]
    panels += [cv2.merge([shown, stretched(compensated(motion)), shown])
               for motion in (estimate, truth)]
    labels = ("reference", "current", "estimate", "truth")
    row = []
    for panel, label in zip(panels, labels):
        panel = cv2.resize(panel, None, fx=scale, fy=scale, interpolation=cv2.INTER_NEAREST)
        cv2.putText(panel, label, (8, 24), cv2.FONT_HERSHEY_SIMPLEX, 0.7, (255, 255, 255), 2)
        row.append(panel)
    return np.hstack(row)


def write_pictures(found: list[dict], suite_dir: Path, out: Path) -> list[Path]:
    """:func:`picture` of every row of :func:`looked_at`, on the sensor's depth, as
    ``out/<method>__<sequence>__<frame>.png`` (each written whole or not at all)."""
    from sim.atomic import atomic_path
    from sim.harness.sequence import load_sequence
    from sim.harness.suite.run import SEQUENCE_FOLDER
    from sim.harness.sweep import RUNS_FOLDER
    from stabilizer import Motion

    written = []
    for row in found:
        sequence = load_sequence(suite_dir / RUNS_FOLDER / row["sequence"] / SEQUENCE_FOLDER)
        path = out / f"{row['method']}__{row['sequence']}__{row['frame']}.png"
        image = picture(sequence.frame(row["reference_frame"]).disparity8,
                        sequence.frame(row["frame"]).disparity8,
                        Motion(*row["estimate"]), Motion(*row["truth"]))
        encoded, png = cv2.imencode(".png", image)
        if not encoded:
            raise OSError(f"{path}: OpenCV could not encode the picture as PNG")
        with atomic_path(path) as temporary:
            temporary.write_bytes(png.tobytes())
        written.append(path)
    return written


def table(found: list[dict]) -> str:
    """The rows of :func:`looked_at` as a Markdown table."""
    from sim.harness.report import markdown_table

    header = ["Method", "Sequence", "Frame", "Error (deg / px / px)", "Truth residual (px)",
              "End-point error / floor (px)"]
    for depth in ("Sensor", "Exact"):
        header += [f"{depth}: estimate", f"{depth}: truth",
                   f"{depth}: edges' optimum off the truth (deg)"]
    rows = []
    for row in found:
        cells = [row["method"], row["sequence"], str(row["frame"]),
                 f"{row['rotation_deg']:.2f} / {row['x_px']:.2f} / {row['y_px']:.2f}",
                 f"{row['residual_px']:.2f}", f"{row['epe_px']:.2f} / {row['floor_px']:.2f}"]
        for depth in ("sensor", "exact"):
            cells += [row[depth]["estimate"], row[depth]["truth"],
                      f"{row[depth]['optimum_off_truth_deg']:.1f}"]
        rows.append(cells)
    return markdown_table(header, rows)


def main(argv: list[str] | None = None) -> int:
    from sim.command_line import OneLineParser, path_option

    parser = OneLineParser(prog="ok_but_off.py", description=__doc__.splitlines()[0])
    parser.add_argument("suite_dir", type=path_option,
                        help="a suite folder (`egostab suite ... --out DIR`)")
    parser.add_argument("--figures", type=path_option, metavar="DIR",
                        help="also draw each frame (reference, current, compensated by the "
                             "estimate and by the truth) into DIR")
    args = parser.parse_args(argv)
    from sim.atomic import check_output_path, prepare_output_dir
    from sim.harness.suite.tables import TABLE_JSON

    try:
        if args.figures is not None:  # checked before anything is made
            check_output_path(args.figures, "--figures")
        if not (args.suite_dir / TABLE_JSON).is_file():
            raise ValueError(f"{args.suite_dir}: no suite.json; accepted: a folder `egostab "
                             f"suite` wrote")
        if args.figures is not None:
            prepare_output_dir(args.figures, "--figures")
    except ValueError as error:
        parser.error(str(error))
    cv2.setNumThreads(1)
    found = looked_at(args.suite_dir)
    print(table(found) if found else "no ok estimate off by more than 5 deg or 10 px")
    if args.figures is not None:
        for path in write_pictures(found, args.suite_dir, args.figures):
            print(path)
    return 0


if __name__ == "__main__":
    from sim.command_line import script_status

    sys.exit(script_status(main))
