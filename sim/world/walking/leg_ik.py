"""Analytic inverse kinematics of a 6-DOF leg (Kajita et al., "Introduction to Humanoid
Robotics", 2014, section 2.5: hip yaw-roll-pitch meeting at one point, knee pitch, ankle
pitch-roll meeting at one point)."""

from __future__ import annotations

import math

import numpy as np


def rot_x(angle: float) -> np.ndarray:
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def rot_y(angle: float) -> np.ndarray:
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def rot_z(angle: float) -> np.ndarray:
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


class LegIK:
    """Joint angles that put the ankle at a pose, given the hip joint's pose.

    Args:
        thigh_m: hip-to-knee length.
        shank_m: knee-to-ankle length.
    """

    def __init__(self, thigh_m: float, shank_m: float):
        if thigh_m <= 0 or shank_m <= 0:
            raise ValueError(f"leg segment lengths must be > 0, got {thigh_m}, {shank_m}")
        self.thigh_m = thigh_m
        self.shank_m = shank_m

    def solve(self, hip_pos: np.ndarray, body_rot: np.ndarray, ankle_pos: np.ndarray,
              foot_rot: np.ndarray) -> tuple[float, float, float, float, float, float]:
        """(hip yaw, hip roll, hip pitch, knee, ankle pitch, ankle roll), radians.

        ``hip_pos``/``ankle_pos`` are the joint centres in any common frame and
        ``body_rot``/``foot_rot`` the torso's and the foot's orientations in it. Out-of-reach
        targets give the straight leg pointing at the target.
        """
        a, b = self.thigh_m, self.shank_m
        r = foot_rot.T @ (hip_pos - ankle_pos)               # hip seen from the ankle frame
        rx, ry, rz = float(r[0]), float(r[1]), float(r[2])
        reach = math.sqrt(rx * rx + ry * ry + rz * rz)
        cos_knee = (reach * reach - a * a - b * b) / (2.0 * a * b)
        knee = math.acos(min(1.0, max(-1.0, cos_knee)))
        ankle_pitch_offset = math.asin(min(1.0, a / reach * math.sin(math.pi - knee)))
        ankle_roll = math.atan2(ry, rz)
        if ankle_roll > math.pi / 2:
            ankle_roll -= math.pi
        elif ankle_roll < -math.pi / 2:
            ankle_roll += math.pi
        ankle_pitch = (-math.atan2(rx, math.copysign(math.sqrt(ry * ry + rz * rz), rz))
                       - ankle_pitch_offset)
        # Hip rotation = body^T foot Rx(-ankle_roll) Ry(-ankle_pitch - knee); only the
        # entries the angles need are formed (scalar maths: this runs every control period).
        m = (body_rot.T @ foot_rot).tolist()
        ca, sa = math.cos(-ankle_roll), math.sin(-ankle_roll)
        b = -ankle_pitch - knee
        cb, sb = math.cos(b), math.sin(b)
        col0 = (cb, sa * sb, -ca * sb)                  # columns of Rx(a) Ry(b)
        col1 = (0.0, ca, sa)
        col2 = (sb, -sa * cb, ca * cb)
        h01 = m[0][1] * col1[1] + m[0][2] * col1[2]
        h11 = m[1][1] * col1[1] + m[1][2] * col1[2]
        h21 = m[2][1] * col1[1] + m[2][2] * col1[2]
        h20 = m[2][0] * col0[0] + m[2][1] * col0[1] + m[2][2] * col0[2]
        h22 = m[2][0] * col2[0] + m[2][1] * col2[1] + m[2][2] * col2[2]
        hip_yaw = math.atan2(-h01, h11)
        cz, sz = math.cos(hip_yaw), math.sin(hip_yaw)
        hip_roll = math.atan2(h21, -h01 * sz + h11 * cz)
        hip_pitch = math.atan2(-h20, h22)
        return hip_yaw, hip_roll, hip_pitch, knee, ankle_pitch, ankle_roll
