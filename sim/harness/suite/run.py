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
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path

from sim.harness.runner import RunConfig, frame_count
from sim.harness.score import file_sha256, read_estimates
from sim.harness.suite.spec import SuiteSequence, SuiteSpec
from sim.harness.suite.tables import SuiteResult, write_suite_outputs
from sim.harness.sweep.execute import execute_plan
from sim.harness.sweep.plan import RUNS_FOLDER, planned_scenario


#: Sub-folder of a sequence's run folder that holds its recorded sequence.
SEQUENCE_FOLDER = "sequence"


#: What stands for the sequence's folder name in the path of an estimates file.
SEQUENCE_FIELD = "{sequence}"


@dataclass(frozen=True)
class SuiteJob(RunConfig):
    """The RunConfig of one sequence of a suite, and the estimates files of other programs
    scored beside its methods (name -> this sequence's CSV; docs/sequence-format.md), through
    the trust check with ``check_estimates`` (``sim.harness.score.ScoreConfig``)."""

    estimates: Mapping[str, str] = field(default_factory=dict)
    check_estimates: bool = False


def record_then_score(config: RunConfig) -> dict:
    """One sequence of a suite: record it (unless a recording of this configuration, finished
    and readable, is there), then score ``config.methods`` (and a :class:`SuiteJob`'s
    estimates files) on it; returns the run's metrics, as ``sim.harness.runner.run`` would.

    A recording that was interrupted is not scored: the stop is raised again
    (``KeyboardInterrupt``), and running the suite again records it anew. A recording found
    damaged when scored (a frame's file unreadable) is recorded again, once; so is one whose
    sequence.json is lost or unreadable (what the recording left there is removed first).
    """
    from sim.harness.runner import RecordConfig, record
    from sim.harness.score import ScoreConfig, score
    from sim.harness.sequence import holds_sequence, remove_recording
    from sim.harness.validation import FileValueError

    sequence = Path(config.out_dir) / SEQUENCE_FOLDER
    estimates = dict(config.estimates) if isinstance(config, SuiteJob) else {}
    checked = isinstance(config, SuiteJob) and config.check_estimates

    def record_it() -> None:
        if not holds_sequence(sequence):  # its own folder: what a recording there left goes
            remove_recording(sequence)
        header = record(RecordConfig(config.scenario, str(sequence),
                                     max_frames=config.max_frames, seed=config.seed,
                                     overrides=config.overrides))
        if header["ended"] == "interrupted":
            raise KeyboardInterrupt(header["message"])

    recorded_now = not _recorded_as_planned(sequence, config)
    if recorded_now:
        record_it()
    try:
        return score(ScoreConfig(str(sequence), config.out_dir, methods=config.methods,
                                 estimates=estimates, check_estimates=checked,
                                 record=config.record))
    except FileValueError as error:
        if recorded_now or not Path(error.source).resolve().is_relative_to(sequence.resolve()):
            raise
        record_it()
        return score(ScoreConfig(str(sequence), config.out_dir, methods=config.methods,
                                 estimates=estimates, check_estimates=checked,
                                 record=config.record))


def _recorded_as_planned(sequence: Path, config: RunConfig) -> bool:
    """Whether ``sequence`` holds a readable recording, finished ("complete" or "fell"), of the
    scenario ``config`` asks for (with its seed and overrides) and of its number of frames
    (fewer after a fall). A change to the suite file's ``max_frames`` or overrides is
    recorded anew."""
    from sim.harness.runner import frame_count
    from sim.harness.sequence import load_sequence
    from sim.harness.validation import FileValueError

    try:
        recorded = load_sequence(sequence)
    except (FileValueError, FileNotFoundError):
        return False
    if recorded.ended not in ("complete", "fell"):
        return False
    scenario, stored = planned_scenario(config)
    planned = {k: v for k, v in stored.items() if k != "source"}
    frames = frame_count(scenario, config.max_frames)
    return (recorded.scenario == planned
            and (recorded.n_frames == frames
                 or (recorded.ended == "fell" and recorded.n_frames <= frames)))


@dataclass(frozen=True)
class SuiteRun:
    """One run of a suite: its folder name, its sequence and its :class:`SuiteJob`."""

    name: str
    sequence: SuiteSequence
    config: SuiteJob

    @property
    def scored(self) -> tuple[str, ...]:
        """The names a finished run must have scored: the methods, then the estimates."""
        return (*self.config.methods, *self.config.estimates)

    @property
    def folders(self) -> tuple[Path, ...]:
        """The folders the run writes in: its run folder and its sequence's."""
        return (Path(self.config.out_dir), Path(self.config.out_dir) / SEQUENCE_FOLDER)

    def made_by_this_plan(self, metrics: dict) -> bool:
        """Whether a finished run's metrics come from this run's configuration: its sequence
        recorded as planned now (:func:`_recorded_as_planned`) and its estimates files read
        from the paths given now, with the contents they have now, checked or not as asked now.
        A suite file, command or estimates file changed since is run again."""
        run = metrics.get("run") or {}
        paths, digests = run.get("estimates") or {}, run.get("estimates_sha256") or {}
        checked = bool(run.get("estimates_checked", False))
        return (all(paths.get(name) == path and digests.get(name) == _sha256_or_none(path)
                    for name, path in self.config.estimates.items())
                and (not self.config.estimates or checked == self.config.check_estimates)
                and _recorded_as_planned(Path(self.config.out_dir) / SEQUENCE_FOLDER,
                                         self.config))


def _sha256_or_none(path: str) -> str | None:
    try:
        return file_sha256(path)
    except OSError:  # gone or unreadable: the run scores it again, and says what is wrong
        return None


def plan_suite(spec: SuiteSpec, out_dir: str | os.PathLike,
               estimates: Mapping[str, str] | None = None,
               check_estimates: bool = False) -> list[SuiteRun]:
    """The run of every sequence of ``spec``, in file order; ``estimates``: name -> path of
    each sequence's estimates file, with :data:`SEQUENCE_FIELD` for the sequence's name,
    through the trust check with ``check_estimates``."""
    return [SuiteRun(sequence.name, sequence, SuiteJob(
                scenario=sequence.scenario,
                out_dir=str(Path(out_dir) / RUNS_FOLDER / sequence.name),
                methods=spec.methods, record=spec.record, max_frames=spec.max_frames,
                overrides=dict(sequence.overrides),
                estimates={name: _estimates_file(pattern, sequence.name)
                           for name, pattern in (estimates or {}).items()},
                check_estimates=check_estimates))
            for sequence in spec.sequences]


def _estimates_file(pattern: str, sequence_name: str) -> str:
    return pattern.replace(SEQUENCE_FIELD, sequence_name)


def check_estimates_files(spec: SuiteSpec, estimates: Mapping[str, str],
                          check_estimates: bool = False) -> None:
    """A ValueError naming the first estimates file that cannot be scored, or
    ``check_estimates`` without any file to check: a name that is
    also a method of the suite, a path without :data:`SEQUENCE_FIELD`, a sequence without
    its file (every sequence needs one), or a file whose content is refused
    (``sim.harness.score.read_estimates``, against the frames the sequence's scenario plans:
    a duplicate, unknown or non-numeric frame, with its line). Checked before any run, so that
    one bad file does not fail its sequence's run and with it every method's figures there."""
    if check_estimates and not estimates:
        raise ValueError("--check-estimates: no estimates file to check; accepted: with "
                         "--estimates NAME=PATH")
    for name, pattern in estimates.items():
        if name in spec.methods:
            raise ValueError(f"--estimates {name}: {name} is also a method of the suite; "
                             f"accepted: a name no method of the suite has")
        if SEQUENCE_FIELD not in pattern:
            raise ValueError(f"--estimates {name}={pattern}: the path has no {SEQUENCE_FIELD}; "
                             f"accepted: a path in which {SEQUENCE_FIELD} stands for each "
                             f"sequence's folder name, e.g. mine/{SEQUENCE_FIELD}.csv")
        missing = [sequence.name for sequence in spec.sequences
                   if not Path(_estimates_file(pattern, sequence.name)).is_file()]
        if missing:
            raise ValueError(f"--estimates {name}: no file "
                             f"{_estimates_file(pattern, missing[0])} ({len(missing)} of the "
                             f"suite's {len(spec.sequences)} sequences have none); accepted: one "
                             f"CSV per sequence (docs/suites.md, \"Your own estimates\")")
    if not estimates:
        return
    for run in plan_suite(spec, ".", estimates):
        scenario, _ = planned_scenario(run.config)
        for path in run.config.estimates.values():
            read_estimates(Path(path), frame_count(scenario, run.config.max_frames))


def default_suite_dir(spec: SuiteSpec, results: str | os.PathLike = "results") -> Path:
    """Where a suite writes unless told otherwise: ``results/suites/<name>``."""
    return Path(results) / "suites" / spec.name


def run_suite(spec: SuiteSpec, out_dir: str | os.PathLike, backend: str = "local",
              workers: int | None = None, ray_address: str | None = None,
              run_fn: Callable[[RunConfig], dict] = record_then_score,
              progress: bool = False,
              estimates: Mapping[str, str] | None = None,
              check_estimates: bool = False) -> SuiteResult:
    """Run every sequence of ``spec`` not yet done, then write suite.md, suite.csv, suite.json.

    Args:
        spec: from :func:`sim.harness.suite.load_suite`.
        out_dir: the suite's folder (runs in ``runs/<sequence>/``, tables beside them).
        estimates: name -> path of each sequence's estimates file made by another program,
            :data:`SEQUENCE_FIELD` standing for the sequence's folder name; each is scored
            like a method and compared with the suite's methods (:func:`check_estimates_files`).
        check_estimates: pass the estimates files' "ok" rows through the trust check every
            method's "ok" passes (``sim.harness.score.ScoreConfig``).
        backend: ``"local"`` (a process pool, spawn start method) or ``"ray"``.
        workers: runs at a time; default: every core locally, the cluster's free CPUs on Ray.
        ray_address: for Ray, as in :func:`sim.harness.sweep.run_sweep`.
        run_fn: the run function, a picklable ``RunConfig -> metrics dict`` (tests pass a fake).
        progress: show a progress bar of finished runs.

    Returns:
        A :class:`SuiteResult`; runs that raised are in ``result.failed``, not raised here.
        The tables are written also when interrupted, from every finished run in the
        folder (those finished before this call too: ``execute_plan``).
    """
    out_dir = Path(out_dir)
    estimates = dict(estimates or {})
    check_estimates_files(spec, estimates, check_estimates)
    return execute_plan(plan_suite(spec, out_dir, estimates, check_estimates),
                        lambda outcomes: write_suite_outputs(out_dir, spec, outcomes, estimates,
                                                             check_estimates),
                        backend=backend, workers=workers, ray_address=ray_address,
                        run_fn=run_fn, progress=progress, label="suite runs")
