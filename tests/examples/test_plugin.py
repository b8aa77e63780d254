"""examples/plugin: installed as a package, its stabilizer is scored by import path and by name.

The package is installed with pip into a temporary folder (no network, no build isolation, the
site-packages untouched) and put on PYTHONPATH of the ``egostab`` subprocesses.
"""

from __future__ import annotations

import csv
import math
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
PLUGIN = ROOT / "examples" / "plugin"
SCENARIO = ROOT / "scenarios" / "ci" / "ci_corridor.toml"
IMPORT_PATH = "egostab_orb:OrbEstimator"


@pytest.fixture(scope="module")
def plugin_path(tmp_path_factory) -> str:
    """A folder holding the installed plugin (module and dist-info with its entry point)."""
    work = tmp_path_factory.mktemp("plugin")
    source = shutil.copytree(PLUGIN, work / "source")  # the build leaves files beside it
    target = work / "site"
    install = subprocess.run(
        [sys.executable, "-m", "pip", "install", "--quiet", "--no-deps", "--no-build-isolation",
         "--no-index", "--target", str(target), str(source)],
        capture_output=True, text=True)
    assert install.returncode == 0, install.stdout + install.stderr
    return str(target)


def egostab(plugin_path: str, *args: str) -> subprocess.CompletedProcess:
    env = {**os.environ, "PYTHONPATH": plugin_path, "OMP_NUM_THREADS": "1"}
    result = subprocess.run([sys.executable, "-m", "sim.harness.cli", *args], cwd=ROOT, env=env,
                            capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stdout + result.stderr
    return result


def run_rows(plugin_path: str, out_dir: Path, methods: str) -> list[dict]:
    egostab(plugin_path, "run", str(SCENARIO), "--max-frames", "6", "--no-record", "--quiet",
            "--methods", methods, "--out", str(out_dir))
    with open(out_dir / "frames.csv", newline="") as handle:
        return list(csv.DictReader(handle))


def estimates(rows: list[dict], method: str) -> list[tuple[float, float, float]]:
    return [tuple(float(row[key]) for key in ("est_angle_deg", "est_dx_px", "est_dy_px"))
            for row in rows if row["method"] == method]


def test_the_plugin_is_listed_with_its_distribution(plugin_path):
    out = egostab(plugin_path, "methods").stdout
    assert (f"orb             entry point orb -> {IMPORT_PATH} from distribution egostab-orb "
            "0.1.0") in out


def test_the_plugin_is_scored_by_import_path_and_by_entry_point(plugin_path, tmp_path):
    by_path = run_rows(plugin_path, tmp_path / "by_path", f"{IMPORT_PATH},ecc")
    by_name = run_rows(plugin_path, tmp_path / "by_name", "orb")
    assert {row["method"] for row in by_path} == {IMPORT_PATH, "ecc"}
    plugin_rows = [row for row in by_path if row["method"] == IMPORT_PATH]
    assert len(plugin_rows) == 6
    # ORB's "ok" passes the trust check of every method, or becomes "unverified" (standing
    # frames, where its few keypoints invent a degree or two).
    assert {row["status"] for row in plugin_rows} <= {"ok", "unverified"}
    ok = [row for row in plugin_rows if row["status"] == "ok"]
    assert ok and all(math.isfinite(value) for row in estimates(ok, IMPORT_PATH) for value in row)
    by_name_rows = [row for row in by_name if row["method"] == "orb"]
    assert [row["status"] for row in by_name_rows] == [row["status"] for row in plugin_rows]
    assert estimates(ok, IMPORT_PATH) == estimates(  # the same class on the same frames
        [row for row in by_name_rows if row["status"] == "ok"], "orb")
    assert (tmp_path / "by_path" / "estimates_egostab_orb_OrbEstimator.png").is_file()
