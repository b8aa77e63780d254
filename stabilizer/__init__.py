"""Ego-motion stabilizers for depth streams: Kang, Zhang & Park (2009) and its peers.

Pure image algorithms: imports only numpy, scipy, OpenCV and PyWavelets.
"""

from stabilizer.api import Stabilizer, available_methods, estimate
from stabilizer.inputs import as_disparity, depth_to_disparity
from stabilizer.motion import Motion, apply_motion, compensate, motion_matrix

__all__ = [
    "Motion", "Stabilizer", "apply_motion", "as_disparity", "available_methods", "compensate",
    "depth_to_disparity", "estimate", "motion_matrix",
]
