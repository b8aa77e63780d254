"""Running a sweep: the runs not yet done, on a local process pool or on Ray, then the table.

Runs go to a local process pool (``spawn`` start method: an EGL context made in a parent breaks
in forked children; docs/design.md, "Parallel runs") or, with ``backend="ray"``, to a Ray
cluster (the optional extra ``cluster``). On a cluster of several machines, ``out_dir`` must be
on a shared file system for the run files and for resuming; the table itself is built from the
metrics the runs return. A run that raises is reported in the table and does not stop the
others.
"""

from __future__ import annotations

import multiprocessing
import os
import signal
import threading
import time
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from pathlib import Path
from typing import Any, TypeVar

from sim.harness.cpu_paths import cpu_paths_in_effect
from sim.harness.interrupts import (STOP_SIGNALS, Interrupted, children_start_deaf_to_ctrl_c,
                                    handle, ignore_ctrl_c, signal_handlers_kept,
                                    stop_signals_interrupt, stops_held)
from sim.harness.report import METRICS_JSON
from sim.harness.runner import RunConfig, run
from sim.harness.sweep.plan import (DONE_STATUSES, RunOutcome, SweepRun, completed_metrics,
                                    plan_sweep, split_done)
from sim.harness.sweep.spec import SweepSpec
from sim.harness.sweep.tables import SweepResult, write_sweep_outputs
from sim.harness.threads import (check_local_workers, exit_with_parent, limit_threads,
                                 single_thread_environment, single_thread_environment_vars,
                                 worker_count)
from sim.harness.validation import is_int

BACKENDS = ("local", "ray")
T = TypeVar("T")
#: Seconds an interrupted sweep waits for its cancelled Ray runs to write their files.
RAY_CANCEL_WAIT_S = 60.0


def run_sweep(spec: SweepSpec, out_dir: str | os.PathLike, backend: str = "local",
              workers: int | None = None, ray_address: str | None = None,
              run_fn: Callable[[RunConfig], dict] = run, progress: bool = False) -> SweepResult:
    """Run every run of ``spec`` not yet complete, then write the table and the plots.

    Args:
        spec: from :func:`load_sweep`.
        out_dir: the sweep's folder (see the package docstring for its layout).
        backend, workers, ray_address, run_fn, progress: as for :func:`execute_plan`.

    Returns:
        A :class:`SweepResult`; runs that raised are in ``result.failed``, not raised here.
    """
    out_dir = Path(out_dir)
    return execute_plan(plan_sweep(spec, out_dir),
                        lambda outcomes: write_sweep_outputs(out_dir, spec, outcomes),
                        backend=backend, workers=workers, ray_address=ray_address,
                        run_fn=run_fn, progress=progress, label="sweep runs")


def execute_plan(plan: Sequence[SweepRun], write_outputs: Callable[[tuple[RunOutcome, ...]], T],
                 *, backend: str = "local", workers: int | None = None,
                 ray_address: str | None = None, run_fn: Callable[[RunConfig], dict] = run,
                 progress: bool = False, label: str = "runs") -> T:
    """Run the planned runs not yet done; then ``write_outputs`` of every outcome, in plan order.

    The outputs are written also when the runs are interrupted, from every finished run in the
    folder: those finished by then, and those finished before this call that it has not run
    anew yet (read back from their metrics.json; see :func:`_table_outcomes`).

    Args:
        plan: the planned runs (anything with ``.name``, ``.config``, ``.scored``, the
            methods a finished run must have scored, and ``.folders``, the folders it writes
            in; see ``plan_sweep``).
        write_outputs: writes the tables from the outcomes and returns the result.
        backend: ``"local"`` (a process pool on this machine, spawn start method) or ``"ray"``.
        workers: runs at a time; default: one per usable core locally, the cluster's free CPUs
            on Ray.
        ray_address: for Ray: ``"auto"`` joins a running cluster, an address such as
            ``"ray://head:10001"`` a remote one; None uses ``$RAY_ADDRESS`` if set, else starts
            a local instance. Ignored if Ray is already initialised in this process.
        run_fn: the run function, a picklable ``RunConfig -> metrics dict`` (tests pass a fake).
        progress: show a progress bar of finished runs, labelled ``label``.
    """
    if backend not in BACKENDS:
        raise ValueError(f"unknown backend {backend!r}; accepted: {', '.join(BACKENDS)}")
    if backend == "local":
        check_local_workers(workers)
    elif workers is not None and (not is_int(workers) or workers < 1):
        raise ValueError(f"workers must be an integer >= 1 (or None for every free CPU of "
                         f"the cluster); got {workers!r}")
    if backend == "ray":
        _import_ray()  # fail before anything is written if the extra is missing
    check_run_folders(plan)
    started = time.time()
    done, pending = split_done(plan)
    outcomes = {outcome.run.name: outcome for outcome in done}
    execute = _run_local if backend == "local" else _run_ray
    try:
        for outcome in _with_progress(execute(pending, run_fn, workers, ray_address),
                                      len(pending), progress, label):
            outcomes[outcome.run.name] = outcome
    finally:  # also on Ctrl-C: the tables show every finished run
        result = write_outputs(_table_outcomes(plan, outcomes, started))
    return result


def check_run_folders(plan: Sequence[SweepRun]) -> None:
    """A ValueError of one line when a file stands where a planned run keeps a folder (the
    folder of the runs, a run's folder, or one a run writes in): each of those runs would
    fail at its first write."""
    for planned in plan:
        for folder in (Path(planned.config.out_dir).parent, *planned.folders):
            if folder.exists() and not folder.is_dir():
                raise ValueError(f"{folder}: is a file where run {planned.name} keeps a folder; "
                                 f"accepted: a folder there, or nothing (move the file away)")


def _table_outcomes(plan: Sequence[SweepRun], outcomes: dict[str, RunOutcome],
                    started: float) -> tuple[RunOutcome, ...]:
    """The outcome the tables show of each planned run, in plan order: its outcome in this
    call, unless it has none (not run yet: interrupted first; or its result never came back,
    as from a Ray task that finished while the interrupt cancelled it) or was interrupted, and
    its folder holds a finished run; that one is shown then, read back from its metrics.json,
    as done before this call if its metrics.json is older than the call (``started``, a
    time.time()). A run over a finished one (a method added to the file) replaces it only once
    finished too, so an interrupt leaves the finished one there, and the tables keep it too."""
    shown = []
    for sweep_run in plan:
        outcome = outcomes.get(sweep_run.name)
        if outcome is None or not (outcome.error or outcome.status in DONE_STATUSES):
            earlier = completed_metrics(sweep_run.config.out_dir)
            if earlier is not None:
                written = (Path(sweep_run.config.out_dir) / METRICS_JSON).stat().st_mtime
                outcome = RunOutcome(sweep_run, earlier, skipped=written < started)
        if outcome is not None:
            shown.append(outcome)
    return tuple(shown)


def _with_progress(outcomes: Iterator[RunOutcome], total: int, progress: bool, label: str):
    if not progress:
        return outcomes
    from tqdm import tqdm

    return tqdm(outcomes, total=total, desc=label, unit="run")


def _describe(error: BaseException) -> str:
    return f"{type(error).__name__}: {error}".splitlines()[0]


def _run_local(pending: Sequence[SweepRun], run_fn, workers: int | None,
               ray_address: str | None) -> Iterator[RunOutcome]:
    """Runs in a spawn process pool; yields outcomes as runs finish.

    A run whose worker process dies (a method's crash in native code, an ``os._exit``) breaks
    the pool, and every run under way or queued in it fails with it: those runs are run again
    one at a time, each in a pool of its own, so that only the run that crashes ends with the
    error.
    """
    broken: list[SweepRun] = []
    yield from _run_pool(pending, run_fn, min(worker_count(workers, len(pending)), len(pending)),
                         broken)
    for sweep_run in broken:
        yield from _run_pool([sweep_run], run_fn, 1, None)


def _run_pool(pending: Sequence[SweepRun], run_fn, workers: int,
              broken: list[SweepRun] | None) -> Iterator[RunOutcome]:
    """Runs in one spawn process pool of ``workers``; the runs a broken pool failed go to
    ``broken`` if given, else are reported with the error."""
    if not pending:
        return
    context = multiprocessing.get_context("spawn")
    stopping = context.Event()
    # A worker hears Ctrl-C while it runs a run (which then ends with complete files), and
    # only if this process does.
    ctrl_c = signal.getsignal(signal.SIGINT) is not signal.SIG_IGN
    pool = ProcessPoolExecutor(max_workers=workers, mp_context=context,
                               initializer=_start_worker, initargs=(stopping, ctrl_c))
    try:
        # The submits start the workers, which read their BLAS threads as numpy loads.
        with children_start_deaf_to_ctrl_c(), single_thread_environment():
            futures = {pool.submit(_run_unless_stopped, run_fn, sweep_run.config): sweep_run
                       for sweep_run in pending}
        remaining = set(futures)
        while remaining:
            done, remaining = wait(remaining, return_when=FIRST_COMPLETED)
            for future in done:
                error = future.exception()
                if isinstance(error, BrokenProcessPool) and broken is not None:
                    broken.append(futures[future])
                    continue
                yield (RunOutcome(futures[future], None, error=_describe(error)) if error
                       else RunOutcome(futures[future], future.result()))
    except BaseException as error:
        stopping.set()  # no worker starts another run
        # Ctrl-C reaches the workers from the terminal; SIGTERM and SIGHUP reach only this
        # process, so pass those on: each started run then ends with complete files (a worker
        # between runs outlives them). Passed on after a Ctrl-C, a signal would reach each run
        # a second time (held through its final write, then raised from it).
        if not isinstance(error, KeyboardInterrupt) or isinstance(error, Interrupted):
            for worker in list((pool._processes or {}).values()):  # no public handle
                worker.terminate()
        raise
    finally:  # also for an abandoned generator: drop queued runs, let started ones end
        _shut_down(pool)


def _shut_down(pool: ProcessPoolExecutor) -> None:
    """Drop the pool's queued runs and wait for its started ones to end, a stop signal held
    meanwhile (``timeout`` and batch systems signal the process and then its whole group): a
    shutdown cut short left the interpreter's exit waiting forever for workers never told to
    end (CPython issue 83386)."""
    with stops_held():
        pool.shutdown(wait=True, cancel_futures=True)


#: In a worker process: set when the sweep is stopping (its parent was interrupted).
_stopping = None
#: In a worker process: whether its runs hear Ctrl-C.
_ctrl_c = False


def _start_worker(stopping, ctrl_c: bool) -> None:
    """A pool worker's initializer: one thread per library, the parent's stop event, and
    whether its runs hear Ctrl-C. Between runs the worker outlives every stop signal: Ctrl-C
    while it imports would print a traceback of its own, and a worker that a SIGTERM ended
    while idle broke the pool, which then stopped the other workers with a second SIGTERM
    that cut their runs' final writes short (a run left "incomplete"). A signal the sweep
    ignores (``nohup``'s SIGHUP) stays ignored."""
    global _stopping, _ctrl_c
    ignore_ctrl_c()
    handle(STOP_SIGNALS, _between_runs)
    limit_threads()
    exit_with_parent()
    _stopping, _ctrl_c = stopping, ctrl_c


def _between_runs(signum: int, frame) -> None:
    """A stop signal between a worker's runs: nothing to stop (the sweep stops its queue)."""


def _run_unless_stopped(run_fn: Callable[[RunConfig], dict], config: RunConfig) -> dict:
    """``run_fn(config)`` in a pool's worker, unless the sweep is stopping: the pool hands a
    worker one more queued run than it can cancel, and a stopped sweep must not start it.
    Within the run, a stop signal ends it as it ends a run anywhere (complete files)."""
    if _stopping is not None and _stopping.is_set():
        raise KeyboardInterrupt("not started: the runs were interrupted")
    if _ctrl_c:
        signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        with stop_signals_interrupt():
            return run_fn(config)
    finally:
        signal.signal(signal.SIGINT, signal.SIG_IGN)


def _run_as_ray_task(run_fn: Callable[[RunConfig], dict], config: RunConfig) -> dict:
    """``run_fn(config)`` in a Ray worker, on one OpenCV thread (the BLAS and OpenMP ones come
    from the task's ``runtime_env``, set as Ray starts the worker), and which a cancel can
    interrupt: Ray cancels a running task by a Ctrl-C of its worker, which a worker started
    with Ctrl-C ignored (a sweep started in the background: ``&``, ``nohup``, a batch job)
    never felt, so its run went on to the end."""
    limit_threads()
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGINT, signal.default_int_handler)
    return run_fn(config)


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
        with signal_handlers_kept():
            ray.init(address=ray_address, include_dashboard=False)
    in_flight: dict[Any, SweepRun] = {}
    try:
        # The task's own environment, not the job's: a caller may have started Ray without it.
        remote_run = ray.remote(num_cpus=1, max_retries=0, runtime_env={"env_vars": {
            **single_thread_environment_vars(), **cpu_paths_in_effect()}})(_run_as_ray_task)
        queue = list(pending)
        while queue or in_flight:
            while queue and (workers is None or len(in_flight) < workers):
                sweep_run = queue.pop(0)
                in_flight[remote_run.remote(run_fn, sweep_run.config)] = sweep_run
            [ready], _ = ray.wait(list(in_flight), num_returns=1)
            sweep_run = in_flight.pop(ready)
            try:
                yield RunOutcome(sweep_run, ray.get(ready))
            except ray.exceptions.RayError as error:
                cause = getattr(error, "cause", None) or error
                yield RunOutcome(sweep_run, None, error=_describe(cause))
    except BaseException:
        # A cancelled task gets a KeyboardInterrupt: its run ends with complete files.
        for reference in in_flight:
            ray.cancel(reference)
        if in_flight:
            ray.wait(list(in_flight), num_returns=len(in_flight), timeout=RAY_CANCEL_WAIT_S)
        raise
    finally:
        if started_here:
            ray.shutdown()
