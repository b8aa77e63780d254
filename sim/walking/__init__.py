"""Walking of the humanoid under physics: gait parameters, controller and simulation."""

from sim.walking.benchmark import benchmark_realtime_factor
from sim.walking.falls import FallEvent
from sim.walking.gait import GAIT_PRESETS, GaitParams
from sim.walking.simulation import RobotSimulation

__all__ = ["GAIT_PRESETS", "FallEvent", "GaitParams", "RobotSimulation", "benchmark_realtime_factor"]
