"""A sweep's runs: one RunConfig per (scenario, seed, noise level), and which are done already.

Each run writes to ``<out_dir>/runs/<scenario>__seed<seed>__noise<level>/``. A run whose
metrics.json says ``"status": "complete"`` (or ``"fell"``) is done and is not run again, so an
interrupted sweep is resumed by running it again.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from sim.harness.report import FRAMES_CSV, METRICS_JSON, read_metrics
from sim.harness.runner import COMPLETE, FELL, RunConfig
from sim.harness.sweep.spec import SweepError, SweepSpec, scenario_label

#: Run statuses (metrics.json "status") that count as done: such runs are not run again (a
#: fall is as final as a complete run: the same seed falls again).
DONE_STATUSES = (COMPLETE, FELL)
RUNS_FOLDER = "runs"


@dataclass(frozen=True)
class SweepRun:
    """One run of a sweep: its folder name, what it varies, and its RunConfig."""

    name: str
    scenario: str
    seed: int
    noise_level: int | float
    config: RunConfig

    @property
    def scored(self) -> tuple[str, ...] | None:
        """The methods a finished run must have scored (None: the scenario's)."""
        return self.config.methods

    @property
    def folders(self) -> tuple[Path, ...]:
        """The folders the run writes in: its run folder."""
        return (Path(self.config.out_dir),)

    def made_by_this_plan(self, metrics: dict) -> bool:
        """Whether a finished run's metrics come from this run's configuration: the scenario
        as resolved now (with its seed and overrides) and ``max_frames``. A sweep file changed
        since is run again."""
        return (metrics.get("scenario") == planned_scenario(self.config)[1]
                and (metrics.get("run") or {}).get("max_frames") == self.config.max_frames)


@dataclass(frozen=True)
class RunOutcome:
    """What became of one run: its metrics (None if it raised), and how it went."""

    run: SweepRun
    metrics: dict | None
    skipped: bool = False
    error: str = ""

    @property
    def status(self) -> str:
        if self.error:
            return f"error: {self.error}"
        return str((self.metrics or {}).get("status", "unknown"))


def planned_scenario(config: RunConfig):
    """The scenario ``config`` runs, resolved (seed and overrides applied), and its dict as
    metrics.json and sequence.json hold it (through JSON)."""
    import json

    from sim.harness.runner import _configured_scenario

    scenario = _configured_scenario(config.scenario, config.seed, config.overrides)
    return scenario, json.loads(json.dumps(scenario.to_dict()))


def plan_sweep(spec: SweepSpec, out_dir: str | os.PathLike) -> list[SweepRun]:
    """Every run of ``spec``, in file order (scenario, then seed, then noise level)."""
    runs = []
    for scenario in spec.scenarios:
        for seed in spec.seeds:
            for level in spec.noise_levels:
                name = f"{scenario_label(scenario)}__seed{seed}__noise{_level_label(level)}"
                config = RunConfig(
                    scenario=scenario, out_dir=str(Path(out_dir) / RUNS_FOLDER / name),
                    methods=spec.methods, record=spec.record, max_frames=spec.max_frames,
                    seed=seed, overrides={**spec.overrides, spec.noise_key: level})
                runs.append(SweepRun(name, scenario_label(scenario), seed, level, config))
    names = [r.name for r in runs]
    duplicates = sorted({n for n in names if names.count(n) > 1})
    if duplicates:
        raise SweepError(spec.source, "scenarios", f"two scenarios share the name(s) "
                         f"{', '.join(duplicates)}", "scenarios with distinct file names")
    return runs


def expand_sweep(spec: SweepSpec, out_dir: str | os.PathLike) -> list[RunConfig]:
    """The RunConfig of every run of ``spec``; run folders are ``<out_dir>/runs/<name>``."""
    return [sweep_run.config for sweep_run in plan_sweep(spec, out_dir)]


def default_sweep_dir(spec: SweepSpec, results: str | os.PathLike = "results") -> Path:
    """Where a sweep writes unless told otherwise: ``results/sweeps/<name>``."""
    return Path(results) / "sweeps" / spec.name


def completed_metrics(run_dir: str | os.PathLike,
                      methods: Sequence[str] | None = None) -> dict | None:
    """The metrics of a finished run in ``run_dir`` (its metrics.json and frames.csv there)
    that holds the figures of every method of ``methods`` (None: whichever it scored), or None
    if it must (re)run: a method added to a sweep or suite file after its runs finished is
    scored when it is run again."""
    path = Path(run_dir) / METRICS_JSON
    # metrics.json is written last; a run folder that lost its per-frame table is not done.
    if not (path.is_file() and (Path(run_dir) / FRAMES_CSV).is_file()):
        return None
    try:
        document = read_metrics(path)
    except ValueError:  # unreadable or foreign: run it again
        return None
    if document.get("status") not in DONE_STATUSES:
        return None
    # summary.run holds the figures the tables read: a method named without them is not done.
    scored = set(document["summary"]["run"])
    return document if methods is None or scored.issuperset(methods) else None


def split_done(plan: Sequence[SweepRun]) -> tuple[list[RunOutcome], list[SweepRun]]:
    """The runs of ``plan`` already done (as skipped outcomes) and those still to run: a run
    is done when it finished, scored every method asked for, and was made by the plan as it is
    now (``made_by_this_plan``)."""
    done, pending = [], []
    for sweep_run in plan:
        metrics = completed_metrics(sweep_run.config.out_dir, sweep_run.scored)
        if metrics is None or not sweep_run.made_by_this_plan(metrics):
            pending.append(sweep_run)
        else:
            done.append(RunOutcome(sweep_run, metrics, skipped=True))
    return done, pending


def _level_label(level: int | float) -> str:
    """A level in a run's folder name: as a float (an integer 2 is "2.0", as a 2.0 written in
    the file), unless the float would round the integer (a scene seed beyond 2**53)."""
    return repr(float(level)) if float(level) == level else repr(level)
