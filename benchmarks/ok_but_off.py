"""What the trust check saw on the ``"ok"`` estimates a suite found off by more than 5° or 10 px.

    python benchmarks/ok_but_off.py SUITE_DIR        # a folder `egostab suite` wrote

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
maintainers' checks.
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
    from stabilizer import Motion
    from stabilizer.verification import Verifier

    listed = json.loads((suite_dir / "suite.json").read_text(encoding="utf-8"))["large_errors"]
    found = []
    for method, errors in listed.items():
        for entry in errors["frames"]:
            run = suite_dir / "runs" / entry["sequence"]
            with open(run / "frames.csv", newline="", encoding="utf-8") as frames:
                row = next(row for row in csv.DictReader(frames) if row["method"] == method
                           and int(row["frame_index"]) == entry["frame"])
            sequence = load_sequence(run / "sequence")
            reference = sequence.frame(int(row["reference_index"]))
            current = sequence.frame(entry["frame"])
            estimate = Motion(*(float(row[key]) for key in ("est_angle_deg", "est_dx_px",
                                                            "est_dy_px")))
            truth = Motion(*(float(row[key]) for key in ("true_angle_deg", "true_dx_px",
                                                         "true_dy_px")))
            result = dict(entry, method=method, residual_px=float(row["truth_residual_px"]),
                          epe_px=float(row["epe_px"]), floor_px=float(row["truth_epe_px"]))
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
    args = parser.parse_args(argv)
    if not (args.suite_dir / "suite.json").is_file():
        parser.error(f"{args.suite_dir}: no suite.json; accepted: a folder `egostab suite` "
                     f"wrote")
    cv2.setNumThreads(1)
    found = looked_at(args.suite_dir)
    print(table(found) if found else "no ok estimate off by more than 5 deg or 10 px")
    return 0


if __name__ == "__main__":
    from sim.command_line import script_status

    sys.exit(script_status(main))
