"""The scripts of benchmarks/ compute what the ``egostab`` command does: numpy and OpenCV load
on the SIMD paths its runs pin (sim/harness/cpu_paths.py), or not before the harness does."""

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from sim.harness.cpu_paths import CPU_PATH_VARIABLES, pinned_paths

ROOT = Path(__file__).resolve().parents[1]
SCRIPTS = sorted((ROOT / "benchmarks").glob("*.py"))

# Import the script as its command line does (not its main), then say which libraries are
# loaded and on which paths.
PROBE = """
import importlib.util, json, os, sys
spec = importlib.util.spec_from_file_location("script", sys.argv[1])
spec.loader.exec_module(importlib.util.module_from_spec(spec))
loaded = [name for name in ("numpy", "cv2") if name in sys.modules]
print(json.dumps({"loaded": loaded,
                  "paths": {name: os.environ.get(name) for name in json.loads(sys.argv[2])}}))
"""


@pytest.mark.skipif(not pinned_paths(), reason="below x86-64-v3 or off Linux x86-64: no pin")
@pytest.mark.parametrize("script", SCRIPTS, ids=[script.name for script in SCRIPTS])
def test_a_benchmark_loads_numpy_and_opencv_only_on_the_pinned_paths(script):
    # They loaded them first and ran on the machine's own paths: on a machine with AVX-512
    # their figures then differed from egostab's (one t2fuzzy frame in 15,120 of `rivals`).
    environment = {name: value for name, value in os.environ.items()
                   if name not in CPU_PATH_VARIABLES}
    done = subprocess.run([sys.executable, "-c", PROBE, str(script),
                           json.dumps(list(CPU_PATH_VARIABLES))], capture_output=True,
                          text=True, timeout=120, cwd=ROOT, env=environment)
    assert done.returncode == 0, done.stderr
    found = json.loads(done.stdout)
    if found["loaded"]:
        assert {name: value for name, value in found["paths"].items() if value} \
            == pinned_paths()
