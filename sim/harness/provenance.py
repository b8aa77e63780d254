"""How a run was made: package versions, Python, and the git commit of the harness.

docs/design.md: "Each run stores its resolved scenario, seed, package versions and git commit beside
its metrics and in its recording." Versions come from the installed distributions' metadata (no
heavy imports); the commit from ``git rev-parse HEAD`` when the code lives in a git work tree,
and is None otherwise (an installed wheel, no git on the machine).
"""

from __future__ import annotations

import platform
import subprocess
from functools import lru_cache
from importlib import metadata
from pathlib import Path

#: Reported name -> distributions that provide it (the first installed one is reported).
PACKAGES = {
    "numpy": ("numpy",),
    "opencv": ("opencv-python-headless", "opencv-python", "opencv-contrib-python-headless",
               "opencv-contrib-python"),
    "pywt": ("PyWavelets",),
    "scipy": ("scipy",),
    "mujoco": ("mujoco",),
    "dm_control": ("dm-control",),
    "rerun": ("rerun-sdk",),
    "matplotlib": ("matplotlib",),
}
#: The folder whose git commit identifies the harness (the repository root in a checkout).
SOURCE_ROOT = Path(__file__).resolve().parents[2]


@lru_cache(maxsize=1)
def _installed_versions() -> tuple[tuple[str, str | None], ...]:
    versions = []
    for name, distributions in PACKAGES.items():
        version = None
        for distribution in distributions:
            try:
                version = metadata.version(distribution)
                break
            except metadata.PackageNotFoundError:
                continue
        versions.append((name, version))
    return tuple(versions)


def package_versions() -> dict[str, str | None]:
    """Reported name -> installed version (None when not installed), plus Python's version.

    Read once per process: the installed packages do not change under a running job."""
    return {"python": platform.python_version(), **dict(_installed_versions())}


def _git(*args: str, cwd: Path) -> str | None:
    try:
        completed = subprocess.run(["git", *args], cwd=cwd, capture_output=True, text=True,
                                   timeout=10, check=False)
    except (OSError, subprocess.SubprocessError):
        return None
    return completed.stdout.strip() if completed.returncode == 0 else None


#: Outputs, not code: a change there leaves the work tree's code at its commit.
OUTPUT_FOLDER = "results"


@lru_cache(maxsize=4)
def git_state(root: Path = SOURCE_ROOT) -> dict[str, str | bool | None]:
    """``{"commit": sha or None, "dirty": bool or None}`` of the work tree at ``root``; dirty
    when a tracked file outside ``results/`` differs from the commit (a run rewriting the
    committed results leaves the next run's code as clean as it was)."""
    commit = _git("rev-parse", "HEAD", cwd=root)
    if not commit:
        return {"commit": None, "dirty": None}
    status = _git("status", "--porcelain", "--untracked-files=no", "--", ".",
                  f":(top,exclude){OUTPUT_FOLDER}", cwd=root)
    return {"commit": commit, "dirty": None if status is None else bool(status)}


def provenance() -> dict:
    """Versions, git state, the platform and the SIMD code paths the libraries were pinned to
    (sim.harness.cpu_paths; empty: not pinned), as stored in metrics.json and in the
    recording."""
    from sim.harness.cpu_paths import cpu_paths_in_effect

    state = git_state()
    return {"versions": package_versions(), "git_commit": state["commit"],
            "git_dirty": state["dirty"], "platform": platform.platform(),
            "cpu_paths": cpu_paths_in_effect()}
