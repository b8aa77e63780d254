"""A run's estimates made ahead in worker processes (``egostab run --workers N``).

In a run, one thread simulates and renders ahead (``runner.PrefetchedFrames``) while the main
thread estimates, scores and records each frame; the six methods' estimates are most of that
work, so with one estimating thread the run uses little more than one core. With workers, each
frame is handed to a pool of spawn processes (one OpenCV and one BLAS thread each,
``threads.single_thread_pool``) as soon as it is rendered, one task per frame that runs every
method (one message each way per frame: fewer and larger messages cost the main process less
than one per method), and the scoring loop takes the estimates in frame order a few frames
later, while the workers estimate the next frames. An estimate depends on its reference and
frame alone, so the results equal those of one process; only the timings differ (and a
reference is analysed once per method in each worker that gets one of its frames).
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass
from typing import Any

import numpy as np

#: Frames started per worker before the scoring loop takes the first of them: each worker has
#: a frame queued behind the one it estimates while the main thread scores and records.
AHEAD_PER_WORKER = 2


@dataclass(frozen=True)
class _Image:
    """What a worker needs of a frame: its index and its disparity image."""

    index: int
    disparity8: np.ndarray


# In a worker process: each method's estimation, which keeps its last reference's analysis.
_WORKER_ESTIMATIONS: dict[str, Any] = {}


def _estimate(methods: tuple[str, ...], reference: _Image, frame: _Image, keep_images: bool):
    """In a worker: each method's estimate of ``frame`` against ``reference`` (without its
    diagnostic images unless ``keep_images``) and the milliseconds of the reference analyses
    it took."""
    from sim.harness.runner import MethodEstimation

    results = {}
    for method in methods:
        if method not in _WORKER_ESTIMATIONS:
            _WORKER_ESTIMATIONS[method] = MethodEstimation(method)
        estimation = _WORKER_ESTIMATIONS[method]
        analysed = len(estimation.analysis_ms)
        estimate = estimation.estimate(reference, frame)
        results[method] = (estimate if keep_images else estimate.without_images(),
                           estimation.analysis_ms[analysed:])
    return results


class PipelinedFrames:
    """The frames of ``source`` (a frame source of the scoring loop, see
    ``runner.SimulatedFrames``), each with every method's estimate started in ``pool`` as soon
    as it comes, ``AHEAD_PER_WORKER`` frames per worker before the scoring loop takes it.

    Entering and leaving it enters and leaves ``source``; ``fall`` and ``sim_time_s`` are the
    source's as they were when the frame now given came from it. ``estimations`` are the
    methods' estimations for the scoring loop. The reference of each frame is chosen by the
    ``reference_policy`` the scoring loop uses (``runner.ReferencePolicy``); the loop's own
    choice is checked against it.

    Args:
        source: the frames.
        methods: the methods to run.
        pool: a pool of worker processes (``threads.single_thread_pool``), left open.
        workers: its processes.
        reference_policy: the scenario's ``evaluation.reference``.
        keep_images: send back the estimates' diagnostic images (a recording shows them).
    """

    def __init__(self, source, methods: tuple[str, ...], pool, workers: int,
                 reference_policy: str, keep_images: bool):
        from sim.harness.runner import ReferencePolicy

        self.source, self.methods, self.pool = source, methods, pool
        self.keep_images = keep_images
        self.ahead = AHEAD_PER_WORKER * workers
        self.n_frames = source.n_frames
        self.intrinsics = None
        self.fall, self.sim_time_s = None, 0.0
        self.references = ReferencePolicy(reference_policy)
        # Frame index -> (reference index, the worker's result, or its methods' estimates
        # once taken).
        self._started: dict[int, tuple[int, Any]] = {}
        self.analysis_ms: dict[str, list[float]] = {method: [] for method in methods}
        self.estimations = {method: PooledMethod(self, method) for method in methods}

    def __enter__(self) -> "PipelinedFrames":
        self.source.__enter__()
        self.intrinsics = self.source.intrinsics
        return self

    def __exit__(self, *exc_info) -> None:
        self.source.__exit__(*exc_info)

    def __iter__(self):
        waiting: deque = deque()
        for item in self.source:
            reference = self.references.reference_for(item.frame, item.gait_cycle)
            reference_image = _Image(reference.index, reference.disparity8)
            frame_image = _Image(item.frame.index, item.frame.disparity8)
            self._started[frame_image.index] = (reference.index, self.pool.submit(
                _estimate, self.methods, reference_image, frame_image, self.keep_images))
            waiting.append((item, self.source.fall, self.source.sim_time_s))
            if len(waiting) > self.ahead:
                yield self._take(waiting)
        while waiting:
            yield self._take(waiting)
        self.sim_time_s = self.source.sim_time_s

    def _take(self, waiting: deque):
        item, self.fall, self.sim_time_s = waiting.popleft()
        return item

    def estimate(self, method: str, reference, frame):
        """``method``'s estimate of ``frame``, waiting for its worker if need be."""
        reference_index, result = self._started[frame.index]
        if reference_index != reference.index:
            raise RuntimeError(f"frame {frame.index}: estimated against frame "
                               f"{reference_index}, scored against frame {reference.index}")
        if not isinstance(result, dict):
            result = result.result()
            self._started[frame.index] = (reference_index, result)
        estimate, analysis_ms = result.pop(method)
        if not result:
            del self._started[frame.index]
        self.analysis_ms[method].extend(analysis_ms)
        return estimate


class PooledMethod:
    """One method's view of a pool of worker processes, as the scoring loop wants it: the
    pool's ``estimate(method, reference, frame)`` and ``analysis_ms[method]`` (the pools of
    ``run --workers``, :class:`PipelinedFrames`, and of ``score --workers``)."""

    def __init__(self, pool, method: str):
        self.pool, self.method = pool, method

    @property
    def analysis_ms(self) -> list[float]:
        return self.pool.analysis_ms[self.method]

    def estimate(self, reference, frame):
        return self.pool.estimate(self.method, reference, frame)
