"""Test session setup, before any test module imports numpy, OpenCV or MuJoCo: headless
rendering, and the SIMD code paths of the ``egostab`` command (sim/harness/cpu_paths.py), so
that a test's own runs and the command's compute alike.

MuJoCo reads MUJOCO_GL once, when it is first imported; a test module that imports mujoco
before ``sim`` would otherwise fall back to GLFW, which needs a display.
"""

import os
import sys
import warnings

os.environ.setdefault("MUJOCO_GL", "egl")

from sim.harness.cpu_paths import pin_cpu_paths  # noqa: E402  (after MUJOCO_GL, no numpy)

if "numpy" in sys.modules:  # a pytest plugin loaded it: the tests run on its own paths
    warnings.warn("numpy was loaded before the tests' conftest: the SIMD paths of the egostab "
                  "command could not be pinned (sim/harness/cpu_paths.py)")
pin_cpu_paths()
