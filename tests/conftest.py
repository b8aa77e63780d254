"""Test session setup, before any test module imports numpy, OpenCV or MuJoCo: importing
``sim`` makes rendering headless and puts numpy, OpenBLAS and OpenCV on the SIMD paths of the
``egostab`` command (sim/__init__.py, sim/harness/cpu_paths.py), so that a test's own runs and
the command's compute alike.
"""

import sys
import warnings

if "numpy" in sys.modules:  # a pytest plugin loaded it: the tests run on its own paths
    warnings.warn("numpy was loaded before the tests' conftest: the SIMD paths of the egostab "
                  "command could not be pinned (sim/harness/cpu_paths.py)")

import sim  # noqa: E402,F401
