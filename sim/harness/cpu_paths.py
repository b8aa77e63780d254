"""The same SIMD code paths, hence the same results, on every Linux x86-64 machine of the
x86-64-v3 level (AVX2 and FMA: nearly every x86 server and desktop since 2015).

numpy, OpenBLAS and OpenCV pick their kernels by the CPU they find when they load, and kernels
for different instruction sets round differently: numpy's AVX-512 loops, OpenBLAS's Skylake-X
kernels and OpenCV's AVX-512 dispatch each gave other last bits than their AVX2 forms, which a
25-s walk grows into other frames (docs/design.md, "Determinism"). Pinning all three to their
x86-64-v3 paths makes a machine with AVX-512 compute what one without it computes. Nothing else
needed pinning: with OpenBLAS on the kernels of the machine that made a run, another machine
repeated that run bit for bit, and Mesa's renderer gave the same frames with its instruction set
restricted.

The variables are read once, when each library loads: :func:`pin_cpu_paths` must run before
numpy or OpenCV are imported. Importing ``sim`` calls it when neither is loaded yet (so the
``egostab`` command does first thing, and so does Python code that imports the harness first);
processes started afterwards inherit the variables. A value the user set is kept (an empty
one switches that library's pin off). Elsewhere (another OS or architecture, a CPU below
x86-64-v3) nothing is pinned and the results may differ from those of a pinned machine.
"""

from __future__ import annotations

import os
import platform
from collections.abc import Mapping, MutableMapping
from pathlib import Path

#: /proc/cpuinfo flags of the x86-64-v3 level (AVX2, FMA, BMI1/2, LZCNT = abm, MOVBE, F16C),
#: the level numpy's X86_V3 paths and OpenBLAS's Haswell kernels need.
X86_64_V3_FLAGS = frozenset({"avx", "avx2", "fma", "bmi1", "bmi2", "abm", "movbe", "f16c"})
#: numpy's dispatch levels above x86-64-v3 (numpy >= 2.4 names them so).
NUMPY_ABOVE_V3 = "X86_V4 AVX512_ICL AVX512_SPR"
#: The OpenBLAS core type of x86-64-v3 machines.
OPENBLAS_V3_CORE = "Haswell"
#: OpenCV's dispatch targets above AVX2 and the /proc/cpuinfo flags each needs. OpenCV prints a
#: line for every feature it is told to disable that the machine lacks: only those present are
#: named.
OPENCV_ABOVE_V3 = (
    ("AVX_VNNI", frozenset({"avx_vnni"})),
    ("AVX512-SKX", frozenset({"avx512f", "avx512cd", "avx512bw", "avx512dq", "avx512vl"})),
    ("AVX512-CLX", frozenset({"avx512f", "avx512cd", "avx512bw", "avx512dq", "avx512vl",
                              "avx512_vnni"})),
)
#: The environment variables the pin sets.
CPU_PATH_VARIABLES = ("NPY_DISABLE_CPU_FEATURES", "OPENBLAS_CORETYPE", "OPENCV_CPU_DISABLE")


def cpu_flags(cpuinfo: Path = Path("/proc/cpuinfo")) -> frozenset[str]:
    """The first processor's flags in Linux's ``/proc/cpuinfo``; empty when there is none (not
    Linux) or the machine is not x86-64."""
    if platform.machine().lower() not in ("x86_64", "amd64"):
        return frozenset()
    try:
        with open(cpuinfo, encoding="utf-8", errors="replace") as handle:
            for line in handle:
                key, _, value = line.partition(":")
                if key.strip() == "flags":
                    return frozenset(value.split())
    except OSError:
        pass
    return frozenset()


def pinned_paths(flags: frozenset[str] | None = None) -> dict[str, str]:
    """The environment that puts numpy, OpenBLAS and OpenCV on their x86-64-v3 paths on a
    machine with these ``flags`` (default: this machine's, :func:`cpu_flags`); empty below
    x86-64-v3 or off Linux x86-64."""
    flags = cpu_flags() if flags is None else flags
    if not X86_64_V3_FLAGS <= flags:
        return {}
    environment = {"NPY_DISABLE_CPU_FEATURES": NUMPY_ABOVE_V3,
                   "OPENBLAS_CORETYPE": OPENBLAS_V3_CORE}
    opencv = [name for name, needed in OPENCV_ABOVE_V3 if needed <= flags]
    if opencv:
        environment["OPENCV_CPU_DISABLE"] = ",".join(opencv)
    return environment


def pin_cpu_paths(environ: MutableMapping[str, str] | None = None) -> None:
    """Set :func:`pinned_paths` in ``environ`` (default ``os.environ``), keeping any value
    already set there."""
    environ = os.environ if environ is None else environ
    for name, value in pinned_paths().items():
        environ.setdefault(name, value)


def cpu_paths_in_effect(environ: Mapping[str, str] | None = None) -> dict[str, str]:
    """The pin's variables as set in ``environ`` (default ``os.environ``): what a process
    started with them runs on (for Ray workers and the provenance of a run)."""
    environ = os.environ if environ is None else environ
    return {name: environ[name] for name in CPU_PATH_VARIABLES if name in environ}
