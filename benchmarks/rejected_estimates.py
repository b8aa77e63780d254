"""How far off the truth were the estimates the trust check rejected?

    python benchmarks/rejected_estimates.py RUN_OR_SUITE_DIR...
    python benchmarks/rejected_estimates.py SUITE_DIR --where-ok ecc   # frames ECC got "ok"

A method's ``"unverified"`` frame is an estimate the trust check could not confirm
(docs/method.md, section 11); its failures.jsonl keeps the estimate as ``unverified_motion``.
Against the frame's ground truth (frames.csv), each such estimate is either accurate (within
1 degree and 2 px on each axis: a rejection that cost an estimate) or off (a rejection that was
right). Per method, over the run folders given (a suite folder stands for its ``runs/*``): the
rejected estimates, how many were accurate and which of the check's tests failed them, the
median rotation and shift errors, and how many were off by more than 5 degrees or 10 px.
Frames whose ground truth failed are left out. ``--where-ok M`` keeps only the frames method M
called ``"ok"``: where one method fails and another succeeds, is the failure honest?
docs/suites.md quotes it for the maintainers' checks.
"""

from __future__ import annotations

import csv
import json
import statistics
import sys
from collections import Counter, defaultdict
from pathlib import Path

#: An estimate within these of the truth (deg, px on each axis) counts as accurate.
ACCURATE_DEG, ACCURATE_PX = 1.0, 2.0
#: And beyond either of these as far off, as the suites' "ok but off" column counts it.
FAR_DEG, FAR_PX = 5.0, 10.0


def run_folders(paths: list[Path]) -> list[Path]:
    """The run folders named, a suite folder standing for its ``runs/*``."""
    from sim.harness.suite.tables import TABLE_JSON
    from sim.harness.sweep import RUNS_FOLDER

    folders = []
    for path in paths:
        folders += sorted(p for p in (path / RUNS_FOLDER).iterdir() if p.is_dir()) \
            if (path / TABLE_JSON).is_file() else [path]
    return folders


def rejected(folders: list[Path], where_ok: str | None = None) -> dict[str, dict]:
    """Per method, the figures of its rejected estimates over the run folders (see the
    module's docstring)."""
    from sim.harness.report import FAILURES_JSONL, FRAMES_CSV

    errors: dict[str, list[tuple[float, float]]] = defaultdict(list)
    accurate_by_test: dict[str, Counter] = defaultdict(Counter)
    for folder in folders:
        truth, ok_frames = {}, set()
        with open(folder / FRAMES_CSV, newline="", encoding="utf-8") as frames:
            for row in csv.DictReader(frames):
                index = int(row["frame_index"])
                if row["truth_status"] == "ok":
                    truth[index] = tuple(float(row[key]) for key in
                                         ("true_angle_deg", "true_dx_px", "true_dy_px"))
                if row["method"] == where_ok and row["status"] == "ok":
                    ok_frames.add(index)
        with open(folder / FAILURES_JSONL, encoding="utf-8") as failures:
            for line in failures:
                failure = json.loads(line)
                index, motion = failure["frame_index"], failure["diagnostics"].get(
                    "unverified_motion")
                if (failure["status"] != "unverified" or motion is None or index not in truth
                        or (where_ok is not None and index not in ok_frames)):
                    continue
                rotation = abs(motion[0] - truth[index][0])
                shift = max(abs(motion[1] - truth[index][1]), abs(motion[2] - truth[index][2]))
                errors[failure["method"]].append((rotation, shift))
                if rotation <= ACCURATE_DEG and shift <= ACCURATE_PX:
                    accurate_by_test[failure["method"]][
                        failure["diagnostics"].get("verify_failed", "?")] += 1
    return {method: {"rejected": len(found),
                     "accurate": sum(accurate_by_test[method].values()),
                     "accurate_by_test": dict(accurate_by_test[method]),
                     "median_rotation_deg": statistics.median(r for r, _ in found),
                     "median_shift_px": statistics.median(s for _, s in found),
                     "far_off": sum(r > FAR_DEG or s > FAR_PX for r, s in found)}
            for method, found in sorted(errors.items())}


def table(figures: dict[str, dict]) -> str:
    """:func:`rejected`'s figures as a Markdown table."""
    from sim.harness.report import markdown_table

    header = ["Method", "Rejected", f"Accurate (<= {ACCURATE_DEG:g}° and {ACCURATE_PX:g} px)",
              "Accurate, by the test that failed", "Median error (deg / px)",
              f"Off by > {FAR_DEG:g}° or {FAR_PX:g} px"]
    rows = [[method, f"{f['rejected']:,}", f"{f['accurate']:,}",
             ", ".join(f"{test} {n}" for test, n in sorted(f["accurate_by_test"].items())),
             f"{f['median_rotation_deg']:.2f} / {f['median_shift_px']:.2f}",
             f"{f['far_off']:,} ({f['far_off'] / f['rejected']:.0%})"]
            for method, f in figures.items()]
    return markdown_table(header, rows)


def main(argv: list[str] | None = None) -> int:
    from sim.command_line import OneLineParser, path_option
    from sim.harness.report import FAILURES_JSONL, FRAMES_CSV

    parser = OneLineParser(prog="rejected_estimates.py", description=__doc__.splitlines()[0])
    parser.add_argument("folders", type=path_option, nargs="+",
                        help="run folders (frames.csv, failures.jsonl) or suite folders")
    parser.add_argument("--where-ok", metavar="METHOD", default=None,
                        help="only the frames this method called ok")
    args = parser.parse_args(argv)
    folders = run_folders(args.folders)
    for folder in folders:
        if not ((folder / FRAMES_CSV).is_file() and (folder / FAILURES_JSONL).is_file()):
            parser.error(f"{folder}: no {FRAMES_CSV} and {FAILURES_JSONL}; accepted: run "
                         f"folders or suite folders that egostab wrote")
    print(table(rejected(folders, args.where_ok)))
    return 0


if __name__ == "__main__":
    from sim.command_line import script_status

    sys.exit(script_status(main))
