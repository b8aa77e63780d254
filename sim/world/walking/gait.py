"""Gait parameters of the walking controller, and the named presets."""

from __future__ import annotations

import math
from dataclasses import dataclass, fields


#: Shortest and longest step: ten control periods (0.01 s) at least, so that a step is a
#: trajectory the controller follows; a step of a minute is standing still.
MIN_STEP_PERIOD_S, MAX_STEP_PERIOD_S = 0.1, 60.0
#: Highest centre of mass the walking model takes: six times this 0.6 m robot's (0.33 m); far
#: higher, the preview controller's Riccati equation has no finite solution.
MAX_COM_HEIGHT_M = 2.0
#: The humanoid's leg from hip to ankle (thigh and shank 0.15 m each,
#: robot_models/humanoid/README.md): no step is longer, wider or higher.
LEG_LENGTH_M = 0.30
#: Half the width of the humanoid's sole (0.075 m): a ZMP reference beyond the sole's edge has no
#: support under it.
SOLE_HALF_WIDTH_M = 0.0375
#: Largest angle of the gait's joint motions and of a step's turn (deg), either way: a quarter
#: turn, beyond every waist and neck joint's range.
MAX_GAIT_ANGLE_DEG = 90.0
#: Largest ankle correction per radian of torso tilt: the CoM passes the sole's edge at a roll of
#: 6.5 deg (atan(0.0375 / 0.33)), for which a gain of 5 already asks for the ankle roll's whole
#: range (0.6 rad, robot_models/humanoid/README.md); a larger gain only drives it to its stop.
MAX_TILT_ANKLE_GAIN = 5.0
#: Largest ankle correction per unit torso rate (s): a robot tipping over the sole's edge turns
#: at about sqrt(g / z_c) times its tilt, 0.6 rad/s at 6.5 deg, for which 1 s already asks for
#: the ankle roll's whole range (in pitch the sole's 0.065 m half-length and the ankle's 1.2 rad
#: give about the same).
MAX_GYRO_ANKLE_GAIN_S = 1.0


#: The bounds of the fields the robot's build limits: (least, most, unit and why), checked after
#: the fields that must be positive are.
_RANGES = {
    **{name: (0.0, LEG_LENGTH_M, " m (the leg's length)")
       for name in ("step_length_max_m", "step_width_m", "step_height_m")},
    "lateral_sway_m": (-SOLE_HALF_WIDTH_M, SOLE_HALF_WIDTH_M, " m (half the sole's width)"),
    **{name: (-MAX_GAIT_ANGLE_DEG, MAX_GAIT_ANGLE_DEG, " deg")
       for name in ("step_yaw_max_deg", "torso_lean_deg", "waist_roll_amp_deg",
                    "waist_yaw_amp_deg", "head_nod_amp_deg", "arm_swing_deg")},
    # Negative gains turn the ankle with the tilt, which tips the robot further.
    **{name: (0.0, MAX_GYRO_ANKLE_GAIN_S, " s (the ankle's range at the tilt that tips the "
                                         "robot over)")
       for name in ("gyro_ankle_pitch_gain", "gyro_ankle_roll_gain")},
    "tilt_ankle_gain": (0.0, MAX_TILT_ANKLE_GAIN,
                        " (the ankle's range at the tilt that tips the robot over)"),
}


@dataclass(frozen=True)
class GaitParams:
    """Parameters of the ZMP-preview walking gait.

    Each parameter's role and the presets' values: docs/walking.md, "Gait parameters and presets".

    Attributes:
        step_period_s: duration of one step (a gait cycle is two steps), seconds.
        double_support_ratio: fraction of a step with both feet on the floor (the ZMP moves
            from one foot to the other during it).
        step_length_max_m: largest forward advance per step; a forward speed command is
            clipped to ``step_length_max_m / step_period_s``.
        step_yaw_max_deg: largest heading change per step; a yaw-rate command is clipped to
            ``step_yaw_max_deg / step_period_s``.
        step_height_m: swing foot lift at mid-swing.
        step_width_m: lateral distance between the feet centres.
        lateral_sway_m: lateral offset of the ZMP reference from the support foot's centre,
            towards its outside: above 0 it widens the body's side-to-side sway, below 0 it
            keeps the body nearer the other foot. Default -0.01: single support then starts
            with room on the support foot's outer side for a push towards it
            (docs/walking.md, "Push recovery"). Above 0 the CoM feedback is on even in the
            controller that feeds back only after a push: without it the real body overshoots
            the wider sway and falls.
        com_height_m: height of the centre of mass above the soles, the LIPM's z_c.
        torso_lean_deg: forward pitch of the torso while walking; the neck tilts the head back
            by the same angle so the camera stays level on average.
        waist_roll_amp_deg: waist roll towards the swing side at mid-step, alternating with
            the support foot (camera roll at the cycle frequency).
        waist_yaw_amp_deg: waist yaw following the leading foot (camera yaw at the cycle
            frequency), like a walker's shoulder counter-rotation.
        head_nod_amp_deg: neck pitch at the top of each foot lift (camera pitch at the step
            frequency); positive pitches the head down.
        arm_swing_deg: shoulder pitch swing, opposite to the legs.
        gyro_ankle_pitch_gain: ankle pitch correction per unit torso pitch rate, s
            (IMU balance feedback as in the OP3/Darwin walking modules).
        gyro_ankle_roll_gain: ankle roll correction per unit torso roll rate, s.
        tilt_ankle_gain: ankle pitch/roll correction per radian of torso tilt away from its
            planned attitude (IMU attitude feedback, pushes the body back over the feet).
    """

    step_period_s: float = 0.5
    double_support_ratio: float = 0.2
    step_length_max_m: float = 0.06
    step_yaw_max_deg: float = 12.0
    step_height_m: float = 0.03
    step_width_m: float = 0.09
    lateral_sway_m: float = -0.01
    com_height_m: float = 0.33
    torso_lean_deg: float = 3.0
    waist_roll_amp_deg: float = 2.0
    waist_yaw_amp_deg: float = 3.0
    head_nod_amp_deg: float = 1.0
    arm_swing_deg: float = 10.0
    gyro_ankle_pitch_gain: float = 0.0
    gyro_ankle_roll_gain: float = 0.03
    tilt_ankle_gain: float = 0.3

    def __post_init__(self):
        for f in fields(self):
            if not math.isfinite(getattr(self, f.name)):
                raise ValueError(f"GaitParams.{f.name} must be finite, got {getattr(self, f.name)!r}")
        positive = ("step_period_s", "step_length_max_m", "step_yaw_max_deg", "step_height_m",
                    "step_width_m", "com_height_m")
        for name in positive:
            if getattr(self, name) <= 0:
                raise ValueError(f"GaitParams.{name} must be > 0, got {getattr(self, name)!r}")
        for name, (low, high, unit) in _RANGES.items():
            if not low <= getattr(self, name) <= high:
                raise ValueError(f"GaitParams.{name}={getattr(self, name)!r} is out of range; "
                                 f"allowed: {low:g} to {high:g}{unit}")
        if self.com_height_m > MAX_COM_HEIGHT_M:
            raise ValueError(f"GaitParams.com_height_m={self.com_height_m!r} is out of range; "
                             f"allowed: 0 to {MAX_COM_HEIGHT_M} m")
        if not MIN_STEP_PERIOD_S <= self.step_period_s <= MAX_STEP_PERIOD_S:
            raise ValueError(f"GaitParams.step_period_s={self.step_period_s!r} is out of "
                             f"range; allowed: {MIN_STEP_PERIOD_S} to {MAX_STEP_PERIOD_S} s")
        if not 0.0 < self.double_support_ratio < 1.0:
            raise ValueError("GaitParams.double_support_ratio must be in (0, 1), "
                             f"got {self.double_support_ratio!r}")

    @property
    def max_forward_speed_mps(self) -> float:
        return self.step_length_max_m / self.step_period_s

    @property
    def max_yaw_rate_dps(self) -> float:
        return self.step_yaw_max_deg / self.step_period_s


#: "default": a steady, moderate gait. "paper_like": the sway-heavy gait of the paper's robot,
#: whose head camera moves by about +-40 px in x, 2-32 px in y and +-12 deg in rotation over a
#: gait cycle (Kang, Zhang & Park 2009, section III-B); its amplitudes were tuned against the
#: measured camera swing (docs/walking.md, "Camera swing").
GAIT_PRESETS: dict[str, GaitParams] = {
    "default": GaitParams(),
    "paper_like": GaitParams(
        step_period_s=0.5,
        step_length_max_m=0.06,
        waist_roll_amp_deg=10.0,
        waist_yaw_amp_deg=9.0,
        head_nod_amp_deg=3.0,
        arm_swing_deg=20.0,
    ),
}


def resolve_gait(gait: GaitParams | str) -> GaitParams:
    """A GaitParams from itself or from a preset name."""
    if isinstance(gait, GaitParams):
        return gait
    if gait not in GAIT_PRESETS:
        raise ValueError(f"unknown gait {gait!r}; presets: {sorted(GAIT_PRESETS)} or a GaitParams")
    return GAIT_PRESETS[gait]
