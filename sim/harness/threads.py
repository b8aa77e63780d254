"""One OpenCV and one BLAS/OpenMP thread per process where estimates run.

Parallelism comes from processes (``run --workers``, ``score --workers``, sweeps, suites, Ray;
:func:`single_thread_pool` starts local ones); a library's own
thread pool on top of them oversubscribes the cores. On the 2-core machine of issue 13, pinning
both made a six-method run 1.5-2x faster with 44 % less CPU and identical estimates.

BLAS and OpenMP read their thread count once, when they load: :func:`limit_threads` must run
before numpy or OpenCV are imported to take effect on them (the ``egostab`` command calls it
first thing); OpenCV's own pool is set at run time. Processes started afterwards inherit the
environment.
"""

from __future__ import annotations

import os
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager

from sim.harness.interrupts import children_start_deaf_to_ctrl_c, ignore_ctrl_c

#: Environment variables that set a BLAS / OpenMP library's thread count.
THREAD_VARIABLES = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS",
                    "NUMEXPR_NUM_THREADS", "VECLIB_MAXIMUM_THREADS")


def limit_threads() -> None:
    """One BLAS/OpenMP thread in this process and the ones it starts (a value the user set in
    the environment is kept), and one OpenCV thread."""
    for name in THREAD_VARIABLES:
        os.environ.setdefault(name, "1")
    import cv2

    cv2.setNumThreads(1)


def single_thread_environment_vars() -> dict[str, str]:
    """The environment that gives a new process one BLAS/OpenMP thread (for Ray workers)."""
    return {name: "1" for name in THREAD_VARIABLES}


@contextmanager
def single_thread_environment() -> Iterator[None]:
    """One BLAS/OpenMP thread in processes started inside (they read it before any import)."""
    saved = {name: os.environ.get(name) for name in THREAD_VARIABLES}
    os.environ.update(single_thread_environment_vars())
    try:
        yield
    finally:
        for name, value in saved.items():
            if value is None:
                os.environ.pop(name, None)
            else:
                os.environ[name] = value


#: Local worker processes allowed per core: more only share the cores, each with its own
#: copy of the simulator and the methods (hundreds of MB), until memory runs out.
WORKERS_PER_CORE = 4


def usable_cores() -> int:
    """The cores this process may run on (at least 1)."""
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    return max(1, cores or 1)


def check_local_workers(workers: int | None) -> None:
    """A ValueError unless ``workers`` is None or an integer from 1 to :data:`WORKERS_PER_CORE`
    times :func:`usable_cores`: the number of local worker processes asked for."""
    if workers is None:
        return
    cores = usable_cores()
    most = WORKERS_PER_CORE * cores
    if isinstance(workers, bool) or not isinstance(workers, int) or not 1 <= workers <= most:
        raise ValueError(f"--workers {workers!r}: accepted: an integer from 1 to {most} "
                         f"({WORKERS_PER_CORE} per core of the {cores} this process may run "
                         f"on; more local processes only share the cores and add memory)")


def worker_count(workers: int | None, wanted: int) -> int:
    """``workers`` when given (checked by :func:`check_local_workers`); else ``wanted``
    processes, at most one per core this process may run on, at least 1."""
    check_local_workers(workers)
    if workers is not None:
        return workers
    return max(1, min(wanted, usable_cores()))


def single_thread_pool(processes: int) -> "WorkerPool":
    """A :class:`WorkerPool` of ``processes`` spawn processes."""
    return WorkerPool(processes)


class WorkerPool:
    """Spawn worker processes, each on one OpenCV and one BLAS/OpenMP thread and deaf to Ctrl-C
    from its start (it reaches the whole process group: the parent ends the work and terminates
    the pool; :func:`~sim.harness.interrupts.children_start_deaf_to_ctrl_c`).

    ``submit(fn, *args)`` gives a future; ``map(fn, items)`` the results in order. A worker
    that dies (a method's segfault, an ``os._exit``) fails every pending result with
    ``concurrent.futures.process.BrokenProcessPool`` instead of leaving its task to wait for
    ever (``multiprocessing.Pool`` replaces the worker and loses the task). Workers start on
    demand, so the single-thread environment is kept while the pool lives: a worker's BLAS
    reads it before anything in the worker loads numpy. A context manager that terminates the
    pool on exit.
    """

    def __init__(self, processes: int):
        import multiprocessing
        from concurrent.futures import ProcessPoolExecutor

        self._environment = single_thread_environment()
        self._environment.__enter__()
        try:
            self._executor = ProcessPoolExecutor(processes,
                                                 mp_context=multiprocessing.get_context("spawn"),
                                                 initializer=_init_single_thread_worker)
        except BaseException:  # a bad process count, say: the environment as it was
            self._environment.__exit__(None, None, None)
            raise

    def submit(self, fn, /, *args):
        with children_start_deaf_to_ctrl_c():  # a submit may start a worker
            return self._executor.submit(fn, *args)

    def map(self, fn, items):
        with children_start_deaf_to_ctrl_c():
            return self._executor.map(fn, items)

    def terminate(self) -> None:
        """Drop the pending work, end the workers at once, restore the environment."""
        if self._environment is None:
            return
        processes = list((self._executor._processes or {}).values())  # no public handle
        manager = self._executor._executor_manager_thread
        self._executor.shutdown(wait=False, cancel_futures=True)
        for process in processes:
            process.terminate()
        # The executor's own thread reaps the workers too: a join here can return on the
        # other's reaping before the exit status is stored, and the worker still looks alive.
        if manager is not None:
            manager.join()
        for process in processes:
            process.join()
        self._environment.__exit__(None, None, None)
        self._environment = None

    def __enter__(self) -> "WorkerPool":
        return self

    def __exit__(self, *exc_info) -> None:
        self.terminate()


def _init_single_thread_worker() -> None:
    ignore_ctrl_c()
    limit_threads()
    exit_with_parent()


#: How often a worker looks whether its parent is still there, seconds.
PARENT_POLL_S = 1.0


def exit_with_parent() -> None:
    """In a worker process: end it once its parent has gone. A parent killed outright
    (SIGKILL: a batch system's hard limit, the out-of-memory killer) cannot stop its pool, whose
    workers then waited for work forever, holding the command's output open; a daemon thread
    sees the parent change (the worker is re-parented) and ends the worker."""
    parent = os.getppid()

    def watch() -> None:
        while os.getppid() == parent:
            time.sleep(PARENT_POLL_S)
        os._exit(1)

    threading.Thread(target=watch, name="exit-with-parent", daemon=True).start()
