"""The harness: world assembly, gait control, SR4000 emulation, ground truth, scoring,
recordings, runner and CLI (docs/design.md).

Rendering is headless by default: MuJoCo reads ``MUJOCO_GL`` when it is first imported, so it is
set here, before any submodule imports mujoco, unless the user chose a backend.
"""

import os

os.environ.setdefault("MUJOCO_GL", "egl")
