"""Fixtures of the harness tests."""

from __future__ import annotations

import pytest


@pytest.fixture
def interrupt_ground_truth(monkeypatch):
    """``interrupt_ground_truth(n)``: the n-th ground truth computed from then on raises
    KeyboardInterrupt, as Ctrl-C (or SIGTERM, which the harness turns into it) would arrive
    there; the ones before it are computed."""
    import sim.harness.ground_truth

    def arm(n: int) -> None:
        real = sim.harness.ground_truth.ground_truth
        calls = []

        def interrupting(*args, **kwargs):
            calls.append(1)
            if len(calls) == n:
                raise KeyboardInterrupt
            return real(*args, **kwargs)

        monkeypatch.setattr(sim.harness.ground_truth, "ground_truth", interrupting)

    return arm
