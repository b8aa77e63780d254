"""The simulated world: indoor scenes, the humanoid and its walking, the SR4000 on its head.

Nothing here knows about stabilizers or scoring; :mod:`sim.harness` builds on it.
"""
