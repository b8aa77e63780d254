"""Stopping a job cleanly on Ctrl-C, SIGTERM or SIGHUP.

Python turns only SIGINT (Ctrl-C) into ``KeyboardInterrupt``; batch systems (Slurm, Docker,
``timeout``, Ray) stop a job with SIGTERM, and a closing terminal sends SIGHUP, both of which
would otherwise kill the process where it stands and leave temporary files and no metrics.
Within :func:`stop_signals_interrupt`, SIGTERM and SIGHUP raise :class:`Interrupted`, a
``KeyboardInterrupt``, so every job ends on them as it ends on Ctrl-C: what it finished is
written out completely, with the status "interrupted" and the signal that stopped it.
"""

from __future__ import annotations

import signal
import threading
from collections.abc import Iterator
from contextlib import contextmanager

#: The signals that stop a job like Ctrl-C does.
STOP_SIGNALS = (signal.SIGTERM, signal.SIGHUP)
STOP_SIGNAL_NAMES = tuple(number.name for number in STOP_SIGNALS)


class Interrupted(KeyboardInterrupt):
    """A stop requested by a signal other than SIGINT; ``signal_name`` says which."""

    def __init__(self, signal_name: str):
        super().__init__(signal_name)
        self.signal_name = signal_name


#: The names of the stop signals received within :func:`stop_signals_interrupt`, in order.
_received: list[str] = []


def interrupt_reason(interrupt: KeyboardInterrupt) -> str:
    """One line saying what stopped the job: Ctrl-C, or the signal's name. A library may raise
    the interrupt again with a message of its own (MuJoCo's model compiler does, or drops the
    signal's name): the last stop signal received then names it."""
    name = getattr(interrupt, "signal_name", None)
    if name not in STOP_SIGNAL_NAMES:
        name = _received[-1] if _received else None
    return f"interrupted by {name}" if name else "interrupted by the user (Ctrl-C)"


def _raise_interrupted(signum: int, frame) -> None:
    name = signal.Signals(signum).name
    _received.append(name)
    raise Interrupted(name)


@contextmanager
def stop_signals_interrupt() -> Iterator[None]:
    """Within the block, SIGTERM and SIGHUP raise :class:`Interrupted`; restored afterwards.

    Signal handlers belong to the main thread: elsewhere the block runs unchanged.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    _received.clear()
    previous = {number: signal.signal(number, _raise_interrupted) for number in STOP_SIGNALS}
    try:
        yield
    finally:
        for number, handler in previous.items():
            signal.signal(number, handler)
