"""Running a suite: one run per sequence on the sweep's machinery, resumable, then the tables.

Each sequence is one ``sim.harness.runner.run`` scoring every method of the suite on the same
frames, in ``<out_dir>/runs/<sequence>/``. The runs go to the sweep's executors (a local
``spawn`` process pool, or Ray), and a run whose metrics.json says "complete" or "fell" is
skipped, by the sweep's rule, so an interrupted suite is resumed by running it again.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from sim.harness.runner import RunConfig, run
from sim.harness.suite.spec import SuiteSequence, SuiteSpec
from sim.harness.suite.tables import SuiteResult, write_suite_outputs
from sim.harness.sweep.execute import execute_plan
from sim.harness.sweep.plan import RUNS_FOLDER


@dataclass(frozen=True)
class SuiteRun:
    """One run of a suite: its folder name, its sequence and its RunConfig."""

    name: str
    sequence: SuiteSequence
    config: RunConfig


def plan_suite(spec: SuiteSpec, out_dir: str | os.PathLike) -> list[SuiteRun]:
    """The run of every sequence of ``spec``, in file order."""
    return [SuiteRun(sequence.name, sequence, RunConfig(
                scenario=sequence.scenario,
                out_dir=str(Path(out_dir) / RUNS_FOLDER / sequence.name),
                methods=spec.methods, record=spec.record, max_frames=spec.max_frames,
                overrides=dict(sequence.overrides)))
            for sequence in spec.sequences]


def default_suite_dir(spec: SuiteSpec, results: str | os.PathLike = "results") -> Path:
    """Where a suite writes unless told otherwise: ``results/suites/<name>``."""
    return Path(results) / "suites" / spec.name


def run_suite(spec: SuiteSpec, out_dir: str | os.PathLike, backend: str = "local",
              workers: int | None = None, ray_address: str | None = None,
              run_fn: Callable[[RunConfig], dict] = run, progress: bool = False) -> SuiteResult:
    """Run every sequence of ``spec`` not yet done, then write suite.md, suite.csv, suite.json.

    Args:
        spec: from :func:`sim.harness.suite.load_suite`.
        out_dir: the suite's folder (runs in ``runs/<sequence>/``, tables beside them).
        backend: ``"local"`` (a process pool, spawn start method) or ``"ray"``.
        workers: runs at a time; default: every core locally, the cluster's free CPUs on Ray.
        ray_address: for Ray, as in :func:`sim.harness.sweep.run_sweep`.
        run_fn: the run function, a picklable ``RunConfig -> metrics dict`` (tests pass a fake).
        progress: show a progress bar of finished runs.

    Returns:
        A :class:`SuiteResult`; runs that raised are in ``result.failed``, not raised here.
        The tables are written also when interrupted, from the runs finished by then.
    """
    out_dir = Path(out_dir)
    return execute_plan(plan_suite(spec, out_dir),
                        lambda outcomes: write_suite_outputs(out_dir, spec, outcomes),
                        backend=backend, workers=workers, ray_address=ray_address,
                        run_fn=run_fn, progress=progress, label="suite runs")
