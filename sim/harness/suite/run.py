"""Running a suite: one job per sequence on the sweep's machinery, resumable, then the tables.

Each sequence is recorded once as a sequence folder (``<out_dir>/runs/<sequence>/sequence/``,
docs/sequence-format.md), then every method of the suite is scored on it
(``<out_dir>/runs/<sequence>/``: the run folder of ``egostab score``, with the figures
``egostab run`` would give); anyone can score more methods on the same sequences later with
``egostab score``. The jobs go to the sweep's executors (a local ``spawn`` process pool, or
Ray), and a job whose metrics.json says "complete" or "fell" and that scored every method of
the suite is skipped, by the sweep's rule, so an interrupted suite is resumed by running it
again (a sequence already recorded to its end is not recorded again), and a method added to
the suite file is scored by running it again: the recorded sequences are scored anew with
every method of the file (the same figures for the methods scored before).
"""

from __future__ import annotations

import os
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from sim.harness.runner import RunConfig
from sim.harness.suite.spec import SuiteSequence, SuiteSpec
from sim.harness.suite.tables import SuiteResult, write_suite_outputs
from sim.harness.sweep.execute import execute_plan
from sim.harness.sweep.plan import RUNS_FOLDER


#: Sub-folder of a sequence's run folder that holds its recorded sequence.
SEQUENCE_FOLDER = "sequence"


def record_then_score(config: RunConfig) -> dict:
    """One sequence of a suite: record it (unless a finished recording is there), then score
    ``config.methods`` on it; returns the run's metrics, as ``sim.harness.runner.run`` would."""
    from sim.harness.runner import RecordConfig, record
    from sim.harness.score import ScoreConfig, score
    from sim.harness.sequence import SEQUENCE_JSON

    sequence = Path(config.out_dir) / SEQUENCE_FOLDER
    if not _recorded_to_its_end(sequence / SEQUENCE_JSON):
        record(RecordConfig(config.scenario, str(sequence), max_frames=config.max_frames,
                            seed=config.seed, overrides=config.overrides))
    return score(ScoreConfig(str(sequence), config.out_dir, methods=config.methods,
                             record=config.record))


def _recorded_to_its_end(sequence_json: Path) -> bool:
    import json

    try:
        return json.loads(sequence_json.read_text(encoding="utf-8")).get("ended") in (
            "complete", "fell")
    except (OSError, ValueError):
        return False


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
              run_fn: Callable[[RunConfig], dict] = record_then_score,
              progress: bool = False) -> SuiteResult:
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
