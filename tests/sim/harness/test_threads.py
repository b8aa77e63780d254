"""One OpenCV and one BLAS thread where estimates run (sim/harness/threads.py)."""

import os
import signal
import subprocess
import sys
import time

import pytest

from sim.harness.threads import (THREAD_VARIABLES, WORKERS_PER_CORE, single_thread_pool,
                                 worker_count)

PROBE = ("import cv2, numpy, os, threadpoolctl; "
         "blas = [p['num_threads'] for p in threadpoolctl.threadpool_info()]; "
         "print(cv2.getNumThreads(), os.environ['OMP_NUM_THREADS'], max(blas))")


def _python(code: str, **env: str) -> str:
    clean = {k: v for k, v in os.environ.items() if k not in THREAD_VARIABLES}
    result = subprocess.run([sys.executable, "-c", code], env={**clean, **env},
                            capture_output=True, text=True, check=True, timeout=120)
    return result.stdout.split()


def test_limit_threads_pins_opencv_and_blas_before_they_load():
    assert _python("from sim.harness.threads import limit_threads; limit_threads(); " + PROBE) \
        == ["1", "1", "1"]


def test_a_thread_count_the_user_set_is_kept():
    cv2_threads, omp, _ = _python(
        "from sim.harness.threads import limit_threads; limit_threads(); " + PROBE,
        OMP_NUM_THREADS="2")
    assert (cv2_threads, omp) == ("1", "2")


def test_the_egostab_command_limits_threads_first():
    out = _python("import sys; from sim.harness.cli import main; main(['list']); " + PROBE)
    assert out[-3:] == ["1", "1", "1"]


def test_a_single_thread_pools_workers_run_one_opencv_and_one_blas_thread_and_ignore_ctrl_c():
    probe = ("(__import__('cv2').getNumThreads(), __import__('os').environ['OMP_NUM_THREADS'], "
             "max(p['num_threads'] for p in __import__('threadpoolctl').threadpool_info()), "
             "__import__('signal').getsignal(2) == __import__('signal').SIG_IGN, "
             "2 not in __import__('signal').pthread_sigmask(0, []))")  # ignored, not blocked
    out = _python("from sim.harness.threads import single_thread_pool\n"
                  "with single_thread_pool(1) as pool:\n"
                  f"    print(*pool.submit(eval, {probe!r}).result())")
    assert out == ["1", "1", "1", "True", "True"]


def test_a_worker_count_given_is_kept():
    assert worker_count(3, wanted=1) == 3
    assert worker_count(1, wanted=5) == 1


def test_a_pool_ends_its_workers_and_gives_the_environment_back_when_it_ends(monkeypatch):
    for name in THREAD_VARIABLES:
        monkeypatch.delenv(name, raising=False)
    with single_thread_pool(1) as pool:
        assert os.environ["OMP_NUM_THREADS"] == "1"  # what a starting worker reads
        worker = pool.submit(os.getpid).result()
    assert not {name for name in THREAD_VARIABLES if name in os.environ}
    with pytest.raises(ProcessLookupError):  # ended and reaped
        os.kill(worker, 0)


def test_no_worker_of_an_ended_pool_still_counts_as_running():
    # The executor's thread reaps the workers too; before the pool waited for it, a worker
    # still looked alive right after the pool ended in about one pool of six.
    import multiprocessing

    for _ in range(40):
        with single_thread_pool(2) as pool:
            assert list(pool.map(abs, range(-4, 0))) == [4, 3, 2, 1]
        assert multiprocessing.active_children() == []


@pytest.mark.parametrize("workers", [0, -1, True, 2.0, "2"])
def test_a_worker_count_that_is_no_whole_number_from_1_is_refused(workers):
    with pytest.raises(ValueError, match=r"workers \S+: accepted: an integer from 1 to \d+"):
        worker_count(workers, wanted=2)


def test_local_workers_are_at_most_a_few_per_core(monkeypatch):
    monkeypatch.setattr(os, "sched_getaffinity", lambda pid: {0, 1}, raising=False)
    most = 2 * WORKERS_PER_CORE
    assert worker_count(most, wanted=1) == most
    with pytest.raises(ValueError, match=rf"--workers {most + 1}: accepted: an integer from 1 to "
                                         rf"{most} \({WORKERS_PER_CORE} per core of the 2 "):
        worker_count(most + 1, wanted=1)


@pytest.mark.parametrize("cores, wanted, expected", [(2, 6, 2), (8, 6, 6), (2, 1, 1), (1, 6, 1),
                                                     (4, 0, 1)])
def test_the_default_worker_count_is_what_is_wanted_up_to_one_per_usable_core(
        monkeypatch, cores, wanted, expected):
    monkeypatch.setattr(os, "sched_getaffinity", lambda pid: set(range(cores)), raising=False)
    assert worker_count(None, wanted) == expected


def test_a_pool_that_cannot_start_leaves_the_environment_as_it_was(monkeypatch):
    for name in THREAD_VARIABLES:
        monkeypatch.delenv(name, raising=False)
    with pytest.raises(ValueError):
        single_thread_pool(0)
    assert not {name for name in THREAD_VARIABLES if name in os.environ}


def test_workers_end_when_their_parent_is_killed_outright():
    # SIGKILL cannot be handled: the pool's workers waited for work forever, holding the
    # command's output open.
    code = ("import os, time\n"
            "from sim.harness.threads import single_thread_pool\n"
            "pool = single_thread_pool(2)\n"
            "print(*{pool.submit(os.getpid).result() for _ in range(8)}, flush=True)\n"
            "time.sleep(60)\n")
    parent = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, text=True,
                              stderr=subprocess.DEVNULL)
    workers = [int(pid) for pid in parent.stdout.readline().split()]
    assert workers
    os.kill(parent.pid, signal.SIGKILL)
    parent.wait()
    deadline = time.monotonic() + 10
    while time.monotonic() < deadline and any(_running(pid) for pid in workers):
        time.sleep(0.2)
    assert not [pid for pid in workers if _running(pid)]


def _running(pid: int) -> bool:
    try:
        with open(f"/proc/{pid}/stat") as stat:
            return stat.read().rsplit(")", 1)[1].split()[0] != "Z"
    except FileNotFoundError:
        return False
