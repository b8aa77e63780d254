"""ORB estimates of an egostab sequence, written as an estimates file by a program that does
not import egostab: what a stabilizer in any language does (docs/sequence-format.md).

    python orb_estimates.py SEQUENCE_FOLDER ESTIMATES.csv
    egostab score SEQUENCE_FOLDER --estimates orb=ESTIMATES.csv --check-estimates

Only the format's documentation is used, with numpy and OpenCV: ``sequence.json`` and
``truth.csv`` say which frames there are and each frame's reference; each depth PNG is decoded
to metres and turned into the 8-bit disparity-like image egostab hands its methods; ORB
keypoints on the valid pixels, cross-checked Hamming matches and ``cv2.estimateAffinePartial2D``
(RANSAC) give a similarity, whose scale is dropped and whose rotation and translation are
re-expressed in the Motion convention (docs/design.md): p_cur = R(a) (p_ref - c) + c + (dx, dy)
with c = ((W - 1) / 2, (H - 1) / 2) and R(a) = [[cos a, sin a], [-sin a, cos a]]. The estimator
is the one of examples/plugin (the same parameters), so scored from this file or as that plugin
it gives the same figures.

A frame the estimator cannot measure gets a row with a failure status (``too_few_keypoints``,
``too_few_matches``, ``too_few_inliers``) instead of numbers, which egostab counts as a failure
with that reason.
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import os
import sys
from pathlib import Path

import cv2
import numpy as np

FORMAT = "egostab-sequence/1"
#: The disparity-like image: g = rint(NEAR_M * 255 / d) for NEAR_M <= d <= FAR_M, at least 1.
NEAR_M, FAR_M = 0.5, 10.0
MIN_MATCHES = 6


def disparity_image(units: np.ndarray, depth_unit_m: float) -> np.ndarray:
    """The 8-bit disparity-like image of a depth PNG's units, as docs/sequence-format.md states
    it (float32 metres; rounded half to even; 0 = no measurement or out of range)."""
    depth = (units.astype(np.float64) * depth_unit_m).astype(np.float32)
    valid = np.isfinite(depth) & (depth >= NEAR_M) & (depth <= FAR_M)
    gray = np.where(valid, np.rint(255.0 * NEAR_M / np.where(valid, depth, 1.0)), 0)
    gray = np.clip(gray, 0, 255).astype(np.uint8)
    gray[valid & (gray == 0)] = 1
    return gray


class Orb:
    """Keypoints and descriptors of a frame's valid pixels; the similarity between two frames."""

    def __init__(self):
        # Small patches: the SR4000's 176 x 144 frames leave little room inside ORB's border.
        self._orb = cv2.ORB_create(nfeatures=500, fastThreshold=10, edgeThreshold=15,
                                   patchSize=15)
        self._matcher = cv2.BFMatcher(cv2.NORM_HAMMING, crossCheck=True)

    def features(self, image: np.ndarray):
        mask = np.where(image > 0, 255, 0).astype(np.uint8)
        keypoints, descriptors = self._orb.detectAndCompute(image, mask)
        points = np.array([keypoint.pt for keypoint in keypoints], np.float32).reshape(-1, 2)
        return points, descriptors

    def motion(self, reference, current, shape: tuple[int, int]) -> tuple[str, tuple]:
        """(status, (angle_deg, dx, dy)) of ``current`` against ``reference`` (features)."""
        (reference_points, reference_descriptors), (points, descriptors) = reference, current
        if min(len(reference_points), len(points)) < MIN_MATCHES:
            return "too_few_keypoints", ()
        matches = self._matcher.match(reference_descriptors, descriptors)
        if len(matches) < MIN_MATCHES:
            return "too_few_matches", ()
        source = reference_points[[match.queryIdx for match in matches]]
        target = points[[match.trainIdx for match in matches]]
        matrix, inliers = cv2.estimateAffinePartial2D(source, target, method=cv2.RANSAC,
                                                      ransacReprojThreshold=3.0)
        if matrix is None or int(inliers.sum()) < MIN_MATCHES:
            return "too_few_inliers", ()
        return "ok", motion_of(matrix, shape)


def motion_of(matrix: np.ndarray, shape: tuple[int, int]) -> tuple[float, float, float]:
    """(angle_deg, dx, dy) of x' = M [x, y, 1] in the Motion convention: the angle read from
    the first row (a scale dropped), the translation t = b + R c - c for the image centre c."""
    angle = math.atan2(matrix[0, 1], matrix[0, 0])
    cos_a, sin_a = math.cos(angle), math.sin(angle)
    centre_x, centre_y = (shape[1] - 1) / 2.0, (shape[0] - 1) / 2.0
    dx = matrix[0, 2] - centre_x - (cos_a * -centre_x + sin_a * -centre_y)
    dy = matrix[1, 2] - centre_y - (-sin_a * -centre_x + cos_a * -centre_y)
    return math.degrees(angle), float(dx), float(dy)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("sequence", type=Path, help="a sequence folder (egostab record)")
    parser.add_argument("out", type=Path, help="the estimates file to write (CSV)")
    args = parser.parse_args(argv)
    refused = "accepted: a sequence folder written by `egostab record`"
    try:
        header = json.loads((args.sequence / "sequence.json").read_text(encoding="utf-8"))
        if not isinstance(header, dict) or header.get("format") != FORMAT:
            raise ValueError(f"sequence.json is not of the format {FORMAT}")
        shape = (int(header["intrinsics"]["height"]), int(header["intrinsics"]["width"]))
        depth_unit_m = float(header["depth_unit_m"])
        with open(args.sequence / "truth.csv", newline="", encoding="utf-8") as handle:
            rows = [(int(row["frame"]), int(row["reference_frame"]))
                    for row in csv.DictReader(handle)]
    except (OSError, ValueError, KeyError, TypeError) as error:
        print(f"orb_estimates: {args.sequence} is not a readable sequence folder ({error}); "
              f"{refused}", file=sys.stderr)
        return 2
    orb = Orb()

    def features(frame: int):
        path = args.sequence / "depth" / f"{frame:06d}.png"
        try:
            data = np.frombuffer(path.read_bytes(), np.uint8)
        except OSError:
            raise ValueError(f"{path} is missing") from None
        units = cv2.imdecode(data, cv2.IMREAD_UNCHANGED) if data.size else None
        if units is None or units.dtype != np.uint16 or units.shape != shape:
            raise ValueError(f"{path} is not a {shape[1]} x {shape[0]} 16-bit PNG")
        return orb.features(disparity_image(units, depth_unit_m))

    # Written under another name and renamed when complete: an interrupted run leaves no
    # half-written estimates file.
    partial = args.out.with_name(args.out.name + ".partial")
    reference_frame, reference = None, None
    try:
        with open(partial, "w", newline="", encoding="utf-8") as handle:
            writer = csv.writer(handle)
            writer.writerow(["frame", "angle_deg", "dx", "dy", "status"])
            for frame, frame_reference in rows:
                if frame_reference != reference_frame:  # each reference is analysed once
                    reference_frame, reference = frame_reference, features(frame_reference)
                status, motion = orb.motion(reference, features(frame), shape)
                # repr: the shortest decimal that reads back as the same double.
                writer.writerow([frame, *(repr(value) for value in motion), status]
                                if status == "ok" else [frame, "", "", "", status])
        os.replace(partial, args.out)
    except ValueError as error:
        print(f"orb_estimates: {error}; {refused}", file=sys.stderr)
        return 2
    except OSError as error:
        print(f"orb_estimates: cannot write {args.out} ({error.strerror}); accepted: a path in "
              f"a folder that exists and can be written", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("orb_estimates: interrupted; no estimates file written", file=sys.stderr)
        return 130
    finally:
        partial.unlink(missing_ok=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
