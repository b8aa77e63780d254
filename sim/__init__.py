"""The harness: world assembly, gait control, SR4000 emulation, ground truth, scoring,
recordings, runner and CLI (docs/design.md).

Set here, before any submodule loads the libraries that read them, unless the user chose
otherwise: rendering is headless (MuJoCo reads ``MUJOCO_GL`` when it is first imported), and
numpy, OpenBLAS and OpenCV take the SIMD paths of every run (sim/harness/cpu_paths.py), so that
Python code importing the harness computes what the ``egostab`` command does. Only if neither
numpy nor OpenCV is loaded yet: pinning one library after another has loaded would mix paths.
"""

import os
import sys

os.environ.setdefault("MUJOCO_GL", "egl")

from sim.harness.cpu_paths import pin_cpu_paths  # noqa: E402  (loads no numpy)

if "numpy" not in sys.modules and "cv2" not in sys.modules:
    pin_cpu_paths()
