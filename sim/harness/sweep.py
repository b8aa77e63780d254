"""Sweeps: scenarios x seeds x noise levels, run in parallel, resumable, aggregated.

A sweep file (TOML) lists what to vary; every combination of scenario, seed and noise level is
one run of ``sim.harness.runner.run`` (each run scores all the sweep's methods on the same simulated
frames, so methods are not a run dimension). Example (``scenarios/sweeps/noise_sweep.toml``)::

    name = "noise_sweep"                      # default: the file's stem
    description = "error against sensor noise"
    scenarios = ["corridor_straight", "lab_clutter"]  # shipped names, or TOML paths
                                              # (relative paths: from the sweep file's folder)
    seeds = [0, 1]                            # integers >= 0, distinct
    noise_levels = [0.5, 1.0, 2.0, 4.0]       # numbers, distinct; each is written to noise_key
    noise_key = "sensor.noise_scale"          # default; any dotted scenario key
    methods = ["t2fuzzy", "sift"]             # default: each scenario's own list
    max_frames = 90                           # default: the scenario's whole duration
    record = false                            # rerun recordings; default false

    [overrides]                               # optional: dotted scenario keys for every run
    "evaluation.reference" = "previous"

Unknown keys, wrong types and out-of-range values raise :class:`SweepError` (a ValueError)
naming the file, the key and what is allowed. Every (scenario, noise level) is also loaded
through ``sim.harness.scenario.load_scenario`` before anything runs, so a noise level the scenario
rejects fails at once, not after hours of other runs.

Output folder of a sweep (``run_sweep(spec, out_dir)``)::

    <out_dir>/runs/<scenario>__seed<seed>__noise<level>/   one run's files (metrics.json, ...)
    <out_dir>/sweep.md, sweep.csv                          one row per run and method
    <out_dir>/error_vs_noise__<scenario>.png               |error| and failures vs noise level

A run whose metrics.json says ``"status": "complete"`` (or ``"fell"``) is skipped, so an
interrupted sweep is resumed by running it again. A run that raises is reported in the table
and does not stop the others. Runs go to a local process pool (``spawn`` start method: an
EGL context made in a parent breaks in forked children; docs/design.md, "Parallel runs") or, with
``backend="ray"``, to a Ray cluster (the optional extra ``cluster``). On a cluster of several
machines, ``out_dir`` must be on a shared file system for the run files and for resuming; the
table itself is built from the metrics the runs return.
"""

from __future__ import annotations

import csv
import io
import math
import multiprocessing
import os
import re
import tomllib
from collections import defaultdict
from collections.abc import Callable, Iterator, Mapping, Sequence
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.figure import Figure

from sim.harness.atomic import write_text_atomic
from sim.harness.report import (AXIS_TITLES, METRICS_JSON, markdown_table, format_number, safe_name,
                        save_figure, read_metrics)
from sim.harness.runner import COMPLETE, FELL, RunConfig, run, scenario_name
from sim.harness.scenario import ScenarioError, load_scenario, resolve_scenario_path
from sim.harness.scoring import AXES, AXIS_UNITS
from stabilizer.api import available_methods

#: Run statuses (metrics.json "status") that count as done: such runs are not run again (a
#: fall is as final as a complete run: the same seed falls again).
DONE_STATUSES = (COMPLETE, FELL)
BACKENDS = ("local", "ray")
DEFAULT_NOISE_KEY = "sensor.noise_scale"
RUNS_FOLDER = "runs"
TABLE_MD = "sweep.md"
TABLE_CSV = "sweep.csv"
#: Columns of the runs' mean absolute errors, per axis.
ERROR_COLUMNS = {axis: f"{axis}_mean_abs_error_{AXIS_UNITS[axis]}" for axis in AXES}
#: Columns of sweep.csv (sweep.md shows the same, formatted).
COLUMNS = ("run", "scenario", "seed", "noise_level", "run_status", "method", "frames",
           *ERROR_COLUMNS.values(), "failure_rate", "ms_per_frame")
#: Keys of a sweep file -> what is allowed (the module docstring shows them in use).
ALLOWED = {
    "name": "a non-empty name of letters, digits, '_', '-', '.' (default: the file's stem)",
    "description": "free text",
    "scenarios": "a non-empty list of distinct shipped scenario names or TOML paths",
    "seeds": "a non-empty list of distinct integers >= 0",
    "noise_levels": "a non-empty list of distinct finite numbers",
    "noise_key": "a dotted scenario key such as sensor.noise_scale",
    "methods": f"a non-empty list of distinct names from {', '.join(available_methods())}",
    "max_frames": "an integer >= 1",
    "record": "true or false",
    "overrides": "a table of dotted scenario keys -> single values (not seed, not the noise "
                 "key)",
}
_REQUIRED = ("scenarios", "seeds", "noise_levels")
_SAFE_NAME = re.compile(r"^[A-Za-z0-9_.-]+$")
_DOTTED_KEY = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*(\.[A-Za-z_][A-Za-z0-9_]*)*$")


class SweepError(ScenarioError):
    """A sweep file that cannot run: names the file, the key and what is allowed."""


@dataclass(frozen=True)
class SweepSpec:
    """A validated sweep (see the module docstring for the file layout).

    Attributes:
        name: the sweep's name.
        scenarios: scenario names (shipped) or absolute TOML paths, in the file's order.
        seeds, noise_levels: the values swept, in the file's order.
        noise_key: the dotted scenario key each noise level is written to.
        methods: methods every run scores; None = each scenario's own list.
        max_frames: frames per run; None = the scenario's duration.
        record: write rerun recordings.
        overrides: dotted scenario keys -> values applied to every run.
        description, source: free text; the file the spec came from.
    """

    name: str
    scenarios: tuple[str, ...]
    seeds: tuple[int, ...]
    noise_levels: tuple[float, ...]
    noise_key: str = DEFAULT_NOISE_KEY
    methods: tuple[str, ...] | None = None
    max_frames: int | None = None
    record: bool = False
    overrides: Mapping[str, Any] = field(default_factory=dict)
    description: str = ""
    source: str = "<dict>"

    @property
    def n_runs(self) -> int:
        return len(self.scenarios) * len(self.seeds) * len(self.noise_levels)


# ----------------------------------------------------------------------------- loading
def load_sweep(path: str | os.PathLike) -> SweepSpec:
    """Read and validate a sweep file; relative scenario paths are taken from its folder."""
    path = Path(path)
    try:
        with open(path, "rb") as handle:
            raw = tomllib.load(handle)
    except FileNotFoundError:
        raise FileNotFoundError(f"no sweep file {path}") from None
    except tomllib.TOMLDecodeError as error:
        raise SweepError(str(path), "(file)", f"not valid TOML ({error})", "TOML 1.0") from None
    raw.setdefault("name", safe_name(path.stem))
    return sweep_from_dict(raw, source=str(path), base_dir=path.parent)


def sweep_from_dict(raw: Mapping[str, Any], source: str = "<dict>",
                    base_dir: str | os.PathLike = ".") -> SweepSpec:
    """Validate a sweep given as a (TOML-like) dict; ``source`` names it in errors."""
    def fail(key: str, problem: str) -> SweepError:
        return SweepError(source, key, problem, ALLOWED[key.split("[")[0]])

    for key in raw:
        if key not in ALLOWED:
            raise SweepError(source, str(key), "unknown key", f"keys {', '.join(ALLOWED)}")
    for key in _REQUIRED:
        if key not in raw:
            raise fail(key, "missing")
    name = raw.get("name", "sweep")
    if not isinstance(name, str) or not _SAFE_NAME.match(name):
        raise fail("name", f"got {name!r}")
    description = raw.get("description", "")
    if not isinstance(description, str):
        raise fail("description", f"got {description!r}")
    noise_key = raw.get("noise_key", DEFAULT_NOISE_KEY)
    if not isinstance(noise_key, str) or not _DOTTED_KEY.match(noise_key) or noise_key == "seed":
        raise fail("noise_key", f"got {noise_key!r}")
    max_frames = raw.get("max_frames")
    if max_frames is not None and not (_is_int(max_frames) and max_frames >= 1):
        raise fail("max_frames", f"got {max_frames!r}")
    record = raw.get("record", False)
    if not isinstance(record, bool):
        raise fail("record", f"got {record!r}")
    overrides = raw.get("overrides", {})
    if not isinstance(overrides, Mapping):
        raise fail("overrides", f"got {overrides!r}")
    for key, value in overrides.items():
        if key in ("seed", noise_key) or not _DOTTED_KEY.match(str(key)):
            raise fail("overrides", f"key {key!r} is not allowed here (seed and {noise_key} "
                                    "come from the sweep's lists)")
        if isinstance(value, Mapping):  # it would replace the scenario's whole table
            raise fail("overrides", f"{key!r} is a table; write one dotted key per value, "
                                    f"e.g. \"{key}.{next(iter(value), 'field')}\" = ...")

    scenarios = _distinct_list(raw["scenarios"], "scenarios", fail,
                               lambda v: isinstance(v, str) and bool(v.strip()))
    seeds = _distinct_list(raw["seeds"], "seeds", fail, lambda v: _is_int(v) and v >= 0)
    noise_levels = tuple(float(v) for v in _distinct_list(
        raw["noise_levels"], "noise_levels", fail,
        lambda v: isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)))
    methods = raw.get("methods")
    if methods is not None:
        methods = _distinct_list(methods, "methods", fail,
                                 lambda v: isinstance(v, str) and v in available_methods())

    resolved = tuple(_resolve_scenario(entry, index, Path(base_dir), fail)
                     for index, entry in enumerate(scenarios))
    spec = SweepSpec(name=name, scenarios=resolved, seeds=seeds, noise_levels=noise_levels,
                     noise_key=noise_key, methods=methods, max_frames=max_frames,
                     record=record, overrides=dict(overrides), description=description,
                     source=source)
    _check_runs_load(spec)
    return spec


def _is_int(value) -> bool:
    return isinstance(value, int) and not isinstance(value, bool)


def _distinct_list(value, key: str, fail, check: Callable[[Any], bool]) -> tuple:
    if not isinstance(value, list) or not value:
        raise fail(key, f"got {value!r}")
    for index, item in enumerate(value):
        if not check(item):
            raise fail(f"{key}[{index}]", f"got {item!r}")
        if item in value[:index]:
            raise fail(f"{key}[{index}]", f"{item!r} is listed twice")
    return tuple(value)


def _resolve_scenario(entry: str, index: int, base_dir: Path, fail) -> str:
    """A shipped name stays a name; a path becomes absolute (from the sweep file's folder)."""
    is_path = entry.endswith(".toml") or "/" in entry or os.sep in entry
    target = Path(entry) if Path(entry).is_absolute() or not is_path else base_dir / entry
    try:
        found = resolve_scenario_path(str(target))
    except FileNotFoundError as error:
        raise fail(f"scenarios[{index}]", str(error)) from None
    return str(found.resolve()) if is_path else entry


def _check_runs_load(spec: SweepSpec) -> None:
    """Load every (scenario, noise level) now, so a bad combination fails before any run."""
    for scenario in spec.scenarios:
        for index, level in enumerate(spec.noise_levels):
            try:
                load_scenario(scenario, {**spec.overrides, spec.noise_key: level})
            except ScenarioError as error:
                key = (f"noise_levels[{index}]" if error.key == spec.noise_key
                       else "overrides" if error.key in spec.overrides
                       else f"scenarios[{spec.scenarios.index(scenario)}]")
                raise SweepError(spec.source, key, f"scenario {scenario_label(scenario)} with "
                                 f"{spec.noise_key} = {level!r} is refused ({error})",
                                 "values every scenario of the sweep accepts") from None


# ----------------------------------------------------------------------------- expansion
def scenario_label(scenario: str) -> str:
    """Short name of a scenario entry: a shipped name, or a TOML file's stem."""
    return safe_name(scenario_name(scenario))


@dataclass(frozen=True)
class SweepRun:
    """One run of a sweep: its folder name, what it varies, and its RunConfig."""

    name: str
    scenario: str
    seed: int
    noise_level: float
    config: RunConfig


def plan_sweep(spec: SweepSpec, out_dir: str | os.PathLike) -> list[SweepRun]:
    """Every run of ``spec``, in file order (scenario, then seed, then noise level)."""
    runs = []
    for scenario in spec.scenarios:
        for seed in spec.seeds:
            for level in spec.noise_levels:
                name = f"{scenario_label(scenario)}__seed{seed}__noise{level!r}"
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


# ----------------------------------------------------------------------------- running
def completed_metrics(run_dir: str | os.PathLike) -> dict | None:
    """The metrics of a finished run in ``run_dir``, or None if it must (re)run."""
    path = Path(run_dir) / METRICS_JSON
    if not path.is_file():
        return None
    try:
        document = read_metrics(path)
    except ValueError:  # unreadable or foreign: run it again
        return None
    return document if document.get("status") in DONE_STATUSES else None


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


@dataclass(frozen=True)
class SweepResult:
    """The outcome of a sweep: per-run outcomes, the table and the files written."""

    outcomes: tuple[RunOutcome, ...]
    rows: tuple[dict, ...]
    markdown: str
    files: tuple[Path, ...]

    @property
    def failed(self) -> tuple[RunOutcome, ...]:
        return tuple(outcome for outcome in self.outcomes if outcome.error)


def run_sweep(spec: SweepSpec, out_dir: str | os.PathLike, backend: str = "local",
              workers: int | None = None, ray_address: str | None = None,
              run_fn: Callable[[RunConfig], dict] = run, progress: bool = False) -> SweepResult:
    """Run every run of ``spec`` not yet complete, then write the table and the plots.

    Args:
        spec: from :func:`load_sweep`.
        out_dir: the sweep's folder (see the module docstring for its layout).
        backend: ``"local"`` (a process pool on this machine, spawn start method) or ``"ray"``.
        workers: runs at a time; default: ``os.cpu_count()`` locally, the cluster's free CPUs
            on Ray.
        ray_address: for Ray: ``"auto"`` joins a running cluster, an address such as
            ``"ray://head:10001"`` a remote one; None uses ``$RAY_ADDRESS`` if set, else starts
            a local instance. Ignored if Ray is already initialised in this process.
        run_fn: the run function, a picklable ``RunConfig -> metrics dict`` (tests pass a fake).
        progress: show a progress bar of finished runs.

    Returns:
        A :class:`SweepResult`; runs that raised are in ``result.failed``, not raised here.
    """
    if backend not in BACKENDS:
        raise ValueError(f"unknown sweep backend {backend!r}; accepted: {', '.join(BACKENDS)}")
    if workers is not None and (not _is_int(workers) or workers < 1):
        raise ValueError(f"workers must be an integer >= 1 (or None for every core); "
                         f"got {workers!r}")
    if backend == "ray":
        _import_ray()  # fail before anything is written if the extra is missing
    out_dir = Path(out_dir)
    plan = plan_sweep(spec, out_dir)
    outcomes: dict[str, RunOutcome] = {}
    pending = []
    for sweep_run in plan:
        metrics = completed_metrics(sweep_run.config.out_dir)
        if metrics is None:
            pending.append(sweep_run)
        else:
            outcomes[sweep_run.name] = RunOutcome(sweep_run, metrics, skipped=True)
    execute = _run_local if backend == "local" else _run_ray
    try:
        for outcome in _with_progress(execute(pending, run_fn, workers, ray_address),
                                      len(pending), progress):
            outcomes[outcome.run.name] = outcome
    finally:  # also on Ctrl-C: the table shows what finished
        ordered = tuple(outcomes[r.name] for r in plan if r.name in outcomes)
        result = write_sweep_outputs(out_dir, spec, ordered)
    return result


def _with_progress(outcomes: Iterator[RunOutcome], total: int, progress: bool):
    if not progress:
        return outcomes
    from tqdm import tqdm

    return tqdm(outcomes, total=total, desc="sweep runs", unit="run")


def _describe(error: BaseException) -> str:
    return f"{type(error).__name__}: {error}".splitlines()[0]


def _run_local(pending: Sequence[SweepRun], run_fn, workers: int | None,
               ray_address: str | None) -> Iterator[RunOutcome]:
    """Runs in a spawn process pool; yields outcomes as runs finish."""
    if not pending:
        return
    workers = min(workers or os.cpu_count() or 1, len(pending))
    pool = ProcessPoolExecutor(max_workers=workers,
                               mp_context=multiprocessing.get_context("spawn"))
    try:
        futures = {pool.submit(run_fn, sweep_run.config): sweep_run for sweep_run in pending}
        remaining = set(futures)
        while remaining:
            done, remaining = wait(remaining, return_when=FIRST_COMPLETED)
            for future in done:
                error = future.exception()
                yield (RunOutcome(futures[future], None, error=_describe(error)) if error
                       else RunOutcome(futures[future], future.result()))
    finally:  # on Ctrl-C or an abandoned generator: drop queued runs, let started ones end
        pool.shutdown(wait=True, cancel_futures=True)


def _import_ray():
    try:
        import ray
    except ImportError as error:
        raise ImportError("the Ray backend needs Ray, an optional extra: "
                          "pip install -e \".[cluster]\" (or pip install \"ray>=2.9\")") from error
    return ray


def _run_ray(pending: Sequence[SweepRun], run_fn, workers: int | None,
             ray_address: str | None) -> Iterator[RunOutcome]:
    """Runs as Ray tasks (one CPU each), at most ``workers`` at a time if given."""
    ray = _import_ray()
    if not pending:
        return
    started_here = not ray.is_initialized()
    if started_here:
        ray.init(address=ray_address, include_dashboard=False)
    try:
        remote_run = ray.remote(num_cpus=1, max_retries=0)(run_fn)
        queue = list(pending)
        in_flight: dict[Any, SweepRun] = {}
        while queue or in_flight:
            while queue and (workers is None or len(in_flight) < workers):
                sweep_run = queue.pop(0)
                in_flight[remote_run.remote(sweep_run.config)] = sweep_run
            [ready], _ = ray.wait(list(in_flight), num_returns=1)
            sweep_run = in_flight.pop(ready)
            try:
                yield RunOutcome(sweep_run, ray.get(ready))
            except ray.exceptions.RayError as error:
                cause = getattr(error, "cause", None) or error
                yield RunOutcome(sweep_run, None, error=_describe(cause))
    finally:
        if started_here:
            ray.shutdown()


# ----------------------------------------------------------------------------- aggregation
def _float(value) -> float:
    return math.nan if value is None else float(value)


def table_rows(outcomes: Sequence[RunOutcome]) -> list[dict]:
    """One row per run and method (a run with no method scores gets one row with its status)."""
    rows = []
    for outcome in outcomes:
        sweep_run = outcome.run
        head = {"run": sweep_run.name, "scenario": sweep_run.scenario, "seed": sweep_run.seed,
                "noise_level": sweep_run.noise_level, "run_status": outcome.status}
        scores = ((outcome.metrics or {}).get("summary") or {}).get("run") or {}
        if not scores:
            rows.append({**head, **{column: "" for column in COLUMNS if column not in head}})
        for method, score in scores.items():
            errors = [_float(score["errors"][axis]["mean"]) for axis in AXES]
            rows.append({**head, "method": method, "frames": score["n_frames"],
                         **dict(zip(ERROR_COLUMNS.values(), errors)),
                         "failure_rate": _float(score["failure_rate"]),
                         "ms_per_frame": _float(score["ms_mean"])})
    return rows


def _csv_value(value) -> str:
    if isinstance(value, float):
        return "" if math.isnan(value) else repr(value)
    return str(value)


def table_csv(rows: Sequence[dict]) -> str:
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(COLUMNS)
    writer.writerows([_csv_value(row[column]) for column in COLUMNS] for row in rows)
    return buffer.getvalue()


def table_markdown(rows: Sequence[dict]) -> str:
    """The sweep table: |error| means per axis, failure rate and time per frame."""
    def cell(column: str, value) -> str:
        if not isinstance(value, float):
            return str(value)
        if column == "noise_level":
            return f"{value:g}"
        return f"{format_number(100 * value, 1)}%" if column == "failure_rate" else format_number(value)

    header = ("Run", "Scenario", "Seed", "Noise", "Status", "Method", "Frames",
              *(f"{AXIS_TITLES[a].split()[0]} mean abs error ({AXIS_UNITS[a]})" for a in AXES),
              "Failure rate", "ms/frame")
    return markdown_table(header, ([cell(c, row[c]) for c in COLUMNS] for row in rows))


def plot_error_vs_noise(path: Path, rows: Sequence[dict], scenario: str,
                        noise_key: str) -> Path:
    """Mean |error| per axis and the failure rate against the noise level, a line per method.

    Each point is the mean over the seeds of the runs' mean |error|; the band spans the
    seeds' smallest to largest value.
    """
    series: dict[str, dict[float, list[dict]]] = defaultdict(lambda: defaultdict(list))
    for row in rows:
        if row["scenario"] == scenario and row["method"]:
            series[row["method"]][row["noise_level"]].append(row)
    figure = Figure(figsize=(12, 8), layout="constrained")
    panels = figure.subplots(2, 2).ravel()
    quantities = [(column, f"mean |error| {AXIS_TITLES[axis].split()[0].lower()} "
                           f"({AXIS_UNITS[axis]})") for axis, column in ERROR_COLUMNS.items()]
    quantities.append(("failure_rate", "failure rate"))
    for ax, (column, label) in zip(panels, quantities):
        for method, by_level in series.items():
            levels = sorted(by_level)
            values = [np.array([r[column] for r in by_level[level]], float) for level in levels]
            finite = [v[np.isfinite(v)] for v in values]
            mean = [v.mean() if v.size else math.nan for v in finite]
            line, = ax.plot(levels, mean, marker="o", label=method)
            low = [v.min() if v.size else math.nan for v in finite]
            high = [v.max() if v.size else math.nan for v in finite]
            ax.fill_between(levels, low, high, color=line.get_color(), alpha=0.15)
        ax.set_xlabel(f"noise level ({noise_key})")
        ax.set_ylabel(label)
        ax.grid(True, alpha=0.3)
    if series:
        panels[0].legend(fontsize="small")
    figure.suptitle(f"{scenario}: error against noise level (mean over seeds, band = range)")
    return save_figure(figure, path)


def write_sweep_outputs(out_dir: str | os.PathLike, spec: SweepSpec,
                        outcomes: Sequence[RunOutcome]) -> SweepResult:
    """Write sweep.md, sweep.csv and one error-vs-noise plot per scenario (atomically)."""
    out_dir = Path(out_dir)
    rows = table_rows(outcomes)
    skipped = sum(outcome.skipped for outcome in outcomes)
    failed = [outcome for outcome in outcomes if outcome.error]
    markdown = "\n".join([
        f"# Sweep {spec.name}", "", *([spec.description, ""] if spec.description else []),
        f"Runs: {spec.n_runs} planned, {len(outcomes)} finished "
        f"({skipped} already complete before this call), {len(failed)} failed. "
        f"Noise levels are values of `{spec.noise_key}`. Errors are the runs' mean absolute "
        "errors against the ground truth.", "", table_markdown(rows), ""])
    files = [write_text_atomic(out_dir / TABLE_MD, markdown),
             write_text_atomic(out_dir / TABLE_CSV, table_csv(rows))]
    for scenario in dict.fromkeys(scenario_label(s) for s in spec.scenarios):
        files.append(plot_error_vs_noise(out_dir / f"error_vs_noise__{scenario}.png", rows,
                                         scenario, spec.noise_key))
    return SweepResult(tuple(outcomes), tuple(rows), markdown, tuple(files))
