"""Test session setup: headless rendering, whatever a test module imports first.

MuJoCo reads MUJOCO_GL once, when it is first imported; a test module that imports mujoco
before ``sim`` would otherwise fall back to GLFW, which needs a display.
"""

import os

os.environ.setdefault("MUJOCO_GL", "egl")
