"""Walking of the humanoid under physics: gait parameters, controller and simulation."""

from sim.world.walking.falls import FallEvent
from sim.world.walking.gait import GAIT_PRESETS, GaitParams
from sim.world.walking.simulation import RobotSimulation

__all__ = ["GAIT_PRESETS", "FallEvent", "GaitParams", "RobotSimulation"]
