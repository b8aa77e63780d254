"""The same SIMD code paths on every x86-64-v3 machine (sim/harness/cpu_paths.py)."""

import json
import os
import platform
import subprocess
import sys

import pytest

from sim.harness import cpu_paths
from sim.harness.cpu_paths import (CPU_PATH_VARIABLES, X86_64_V3_FLAGS, cpu_flags,
                                   cpu_paths_in_effect, pin_cpu_paths, pinned_paths)

AVX512_SKX = frozenset({"avx512f", "avx512cd", "avx512bw", "avx512dq", "avx512vl"})


def test_below_x86_64_v3_nothing_is_pinned():
    assert pinned_paths(frozenset()) == {}
    assert pinned_paths(X86_64_V3_FLAGS - {"avx2"}) == {}


def test_an_avx2_machine_pins_numpy_and_openblas_and_names_no_opencv_feature_it_lacks():
    assert pinned_paths(X86_64_V3_FLAGS | {"sse4_2"}) == {
        "NPY_DISABLE_CPU_FEATURES": "X86_V4 AVX512_ICL AVX512_SPR",
        "OPENBLAS_CORETYPE": "Haswell"}


@pytest.mark.parametrize("extra, opencv", [
    (AVX512_SKX, "AVX512-SKX"),
    (AVX512_SKX | {"avx512_vnni"}, "AVX512-SKX,AVX512-CLX"),
    (AVX512_SKX | {"avx512_vnni", "avx_vnni"}, "AVX_VNNI,AVX512-SKX,AVX512-CLX"),
    ({"avx_vnni"}, "AVX_VNNI"),
    ({"avx512f", "avx512_vnni"}, None),  # not the whole of OpenCV's AVX512-SKX
])
def test_opencv_is_kept_off_exactly_the_targets_above_avx2_the_machine_has(extra, opencv):
    assert pinned_paths(X86_64_V3_FLAGS | extra).get("OPENCV_CPU_DISABLE") == opencv


def test_a_value_the_user_set_is_kept(monkeypatch):
    monkeypatch.setattr(cpu_paths, "cpu_flags", lambda: X86_64_V3_FLAGS | AVX512_SKX)
    environ = {"OPENBLAS_CORETYPE": "", "UNRELATED": "1"}
    pin_cpu_paths(environ)
    assert environ == {"OPENBLAS_CORETYPE": "", "UNRELATED": "1",
                       "NPY_DISABLE_CPU_FEATURES": "X86_V4 AVX512_ICL AVX512_SPR",
                       "OPENCV_CPU_DISABLE": "AVX512-SKX"}
    assert cpu_paths_in_effect(environ) == {name: environ[name] for name in CPU_PATH_VARIABLES}


def test_the_flags_are_read_from_cpuinfo_on_x86_64_only(tmp_path, monkeypatch):
    cpuinfo = tmp_path / "cpuinfo"
    cpuinfo.write_text("processor\t: 0\nvendor_id\t: AuthenticAMD\nflags\t\t: fpu avx avx2 fma\n"
                       "processor\t: 1\nflags\t\t: fpu\n")
    monkeypatch.setattr(platform, "machine", lambda: "x86_64")
    assert cpu_flags(cpuinfo) == {"fpu", "avx", "avx2", "fma"}
    assert cpu_flags(tmp_path / "missing") == frozenset()
    monkeypatch.setattr(platform, "machine", lambda: "aarch64")
    assert cpu_flags(cpuinfo) == frozenset()


PROBE = """
import json, os, cv2, numpy, threadpoolctl
from numpy._core._multiarray_umath import __cpu_dispatch__, __cpu_features__
print(json.dumps({
    "environ": {name: os.environ.get(name) for name in %r},
    "numpy": [name for name in __cpu_dispatch__ if __cpu_features__.get(name)],
    "blas": [info.get("architecture") for info in threadpoolctl.threadpool_info()
             if info.get("internal_api") == "openblas"],
    "opencv": cv2.getCPUFeaturesLine()}))
""" % (CPU_PATH_VARIABLES,)


@pytest.mark.skipif(not pinned_paths(), reason="this machine is not Linux x86-64-v3: no pin")
def test_the_egostab_command_puts_numpy_openblas_and_opencv_on_their_avx2_paths():
    clean = {name: value for name, value in os.environ.items()
             if name not in CPU_PATH_VARIABLES}
    code = "from sim.harness.cli import main; main(['list'])\n" + PROBE
    out = subprocess.run([sys.executable, "-c", code], env=clean, capture_output=True,
                         text=True, check=True, timeout=120)
    assert "OPENCV" not in out.stderr  # no feature it was told to disable was unknown to it
    found = json.loads(out.stdout.splitlines()[-1])
    assert found["environ"] == {name: pinned_paths().get(name) for name in CPU_PATH_VARIABLES}
    assert "X86_V3" in found["numpy"] and not {"X86_V4", "AVX512_ICL"} & set(found["numpy"])
    assert found["blas"] and set(found["blas"]) == {"Haswell"}
    # OpenCV marks a target it does not use with "?"; every AVX-512 one is unused.
    assert "*AVX2" in found["opencv"].split()
    assert not [name for name in found["opencv"].split()
                if name.startswith("*AVX512") and not name.endswith("?")]


def _environment_after(code: str) -> dict:
    clean = {name: value for name, value in os.environ.items()
             if name not in CPU_PATH_VARIABLES}
    out = subprocess.run([sys.executable, "-c", code + "\n" + PROBE], env=clean,
                         capture_output=True, text=True, check=True, timeout=120)
    return json.loads(out.stdout.splitlines()[-1])["environ"]


@pytest.mark.skipif(not pinned_paths(), reason="this machine is not Linux x86-64-v3: no pin")
def test_python_code_importing_the_harness_first_is_pinned_and_after_numpy_not_at_all():
    pinned = {name: pinned_paths().get(name) for name in CPU_PATH_VARIABLES}
    assert _environment_after("from sim.harness.runner import RunConfig, run") == pinned
    # numpy already on its own paths: pinning OpenCV alone would mix them.
    assert _environment_after("import numpy\nimport sim.harness.runner") == {
        name: None for name in CPU_PATH_VARIABLES}
