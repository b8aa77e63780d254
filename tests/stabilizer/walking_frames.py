"""Disparity frames of recorded walks, kept in ``data/`` for tests of cases found on them."""

from pathlib import Path

import cv2
import numpy as np

DATA = Path(__file__).parent / "data"


def walking_frames(walk: str, *indices: int) -> list[np.ndarray]:
    """The 8-bit disparity frames ``data/<walk>_frame<index>.png``, in the order given."""
    return [cv2.imread(str(DATA / f"{walk}_frame{index:03d}.png"), cv2.IMREAD_UNCHANGED)
            for index in indices]
