"""Stopping a job cleanly on Ctrl-C, SIGTERM or SIGHUP.

Python turns only SIGINT (Ctrl-C) into ``KeyboardInterrupt``; batch systems (Slurm, Docker,
``timeout``, Ray) stop a job with SIGTERM, and a closing terminal sends SIGHUP, both of which
would otherwise kill the process where it stands and leave temporary files and no metrics.
Within :func:`stop_signals_interrupt`, SIGTERM and SIGHUP raise :class:`Interrupted`, a
``KeyboardInterrupt``, so every job ends on them as it ends on Ctrl-C: what it finished is
written out completely, with the status "interrupted" and the signal that stopped it.

Outside a job, in an ``egostab`` process's start-up (its imports take a second) and clean-up,
:class:`ProcessStops` ends the process at once on a stop signal, with the same one line.
"""

from __future__ import annotations

import os
import signal
import sys
import threading
from collections.abc import Iterable, Iterator
from contextlib import contextmanager, suppress
from typing import NoReturn

#: The signals that stop a job like Ctrl-C does.
STOP_SIGNALS = (signal.SIGTERM, signal.SIGHUP)
STOP_SIGNAL_NAMES = tuple(number.name for number in STOP_SIGNALS)


class Interrupted(KeyboardInterrupt):
    """A stop requested by a signal other than SIGINT; ``signal_name`` says which."""

    def __init__(self, signal_name: str):
        super().__init__(signal_name)
        self.signal_name = signal_name

    @staticmethod
    def named_in(message: str) -> KeyboardInterrupt:
        """The stop a run's message names ("interrupted by SIGTERM"), or Ctrl-C's."""
        name = message.removeprefix("interrupted by ")
        return Interrupted(name) if name in STOP_SIGNAL_NAMES else KeyboardInterrupt()


#: The names of the stop signals received within :func:`stop_signals_interrupt`, in order.
_received: list[str] = []


def interrupt_reason(interrupt: KeyboardInterrupt) -> str:
    """One line saying what stopped the job: Ctrl-C, or the signal's name, and whether it came
    during the job's final write, which it let finish (:func:`stops_held`). A library may raise
    the interrupt again with a message of its own (MuJoCo's model compiler does, or drops the
    signal's name): the last stop signal received then names it."""
    name = getattr(interrupt, "signal_name", None)
    if name not in STOP_SIGNAL_NAMES:
        name = _received[-1] if _received else None
    after = (" during its final write, which it finished (its files are complete and say how "
             "it ended)" if getattr(interrupt, "files_complete", False) else "")
    return _reason(name) + after


def _reason(signal_name: str | None) -> str:
    """"interrupted by" the signal named, or by Ctrl-C (None)."""
    return f"interrupted by {signal_name}" if signal_name else "interrupted by the user (Ctrl-C)"


def _raise_interrupted(signum: int, frame) -> None:
    name = signal.Signals(signum).name
    _received.append(name)
    raise Interrupted(name)


@contextmanager
def stop_signals_interrupt() -> Iterator[None]:
    """Within the block, SIGTERM and SIGHUP raise :class:`Interrupted`; restored afterwards.

    A signal the process ignores stays ignored: ``nohup egostab suite ...`` must outlive the
    terminal's SIGHUP. Signal handlers belong to the main thread: elsewhere the block runs
    unchanged.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    _received.clear()
    with signal_handlers_kept():
        handle(STOP_SIGNALS, _raise_interrupted)
        yield


def handle(numbers: Iterable[int], handler) -> None:
    """Install ``handler`` for the signals ``numbers``, but for one the process was started
    ignoring (``nohup``'s SIGHUP, Ctrl-C of a background job), which stays ignored."""
    for number in numbers:
        if signal.getsignal(number) is not signal.SIG_IGN:
            signal.signal(number, handler)


@contextmanager
def signal_handlers_kept() -> Iterator[None]:
    """Ctrl-C's and the stop signals' handlers after the block as they were before it, whatever
    the block installs (as ``ray.init`` does). Only the main thread has handlers: elsewhere the
    block runs unchanged."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    handlers = {number: signal.getsignal(number) for number in (signal.SIGINT, *STOP_SIGNALS)}
    try:
        yield
    finally:
        for number, kept in handlers.items():
            if kept is not None:  # None: installed outside Python, left as it is
                signal.signal(number, kept)


@contextmanager
def stops_held(final_write: bool = False) -> Iterator[None]:
    """Within the block, Ctrl-C, SIGTERM and SIGHUP are held, and the first one received is
    delivered again once the block ends (to the handler in place then): a run's final write is
    not cut short, so its files say how it ended. A signal the process ignores stays ignored.
    Main thread only; elsewhere the block runs unchanged.

    With ``final_write`` (the block writes the job's last files), the stop it then raises is
    marked ``files_complete``: :func:`interrupt_reason` says the files were written whole, as
    they say how the job ended (a job that had done all its work says "complete")."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    held: list[int] = []
    with signal_handlers_kept():
        handle((signal.SIGINT, *STOP_SIGNALS), lambda signum, frame: held.append(signum))
        yield
    if held:
        try:
            signal.raise_signal(held[0])  # the handler in place runs before this returns
        except KeyboardInterrupt as interrupt:
            interrupt.files_complete = final_write
            raise


@contextmanager
def children_start_deaf_to_ctrl_c() -> Iterator[None]:
    """Processes started within the block ignore Ctrl-C from their first instruction; this
    process still gets a Ctrl-C pressed meanwhile, once the block ends.

    Ctrl-C reaches the terminal's whole process group: a spawned worker still importing its
    modules (a second or more) would print a traceback of its own beside the job's one line.
    A disposition of "ignore" is the one a new program inherits, so this process ignores
    SIGINT while it starts them, and holds it blocked meanwhile so that a Ctrl-C pressed then
    stays pending for it (Linux keeps a blocked signal even when it is ignored). A child may
    start with SIGINT blocked too, and with a Ctrl-C of its start-up pending: a worker's
    initializer drops it (:func:`ignore_ctrl_c`). One gap remains: another thread
    of this process, not blocking SIGINT, may take a Ctrl-C pressed during a start (a few
    milliseconds) and drop it. Main thread only; elsewhere, and when SIGINT is handled outside
    Python or already ignored, the block runs unchanged.
    """
    handler = signal.getsignal(signal.SIGINT)
    if (threading.current_thread() is not threading.main_thread() or handler is None
            or handler is signal.SIG_IGN):
        yield
        return
    blocked = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, handler)
        signal.pthread_sigmask(signal.SIG_SETMASK, blocked)


def ignore_ctrl_c() -> None:
    """Ignore Ctrl-C in this process from now on, and drop one pending since its start
    (:func:`children_start_deaf_to_ctrl_c`): a worker's initializer."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})  # ignored: dropped


#: Exit status of a process a stop ended: 128 + SIGINT, as shells report Ctrl-C.
INTERRUPTED_STATUS = 130


class ProcessStops:
    """The stop signals of a whole command-line process (``egostab``), outside its job.

    Before the job (Python's start-up, the imports) and after it (the clean-up), no work is
    under way and every file the job wrote is complete, but a stop signal there would print a
    traceback (Ctrl-C) or kill the process without a word (SIGTERM, SIGHUP: status 143, 129).
    Installed for a signal, this ends the process at once instead, with one line on stderr,
    ``<job>: interrupted by <signal>``, and status :data:`INTERRUPTED_STATUS`, as a stopped
    job ends. The job itself runs within :func:`stop_signals_interrupt`, which restores this
    handler after it.

    :meth:`exit` ends the process once the job is done, as Python ends it: the ``atexit``
    callbacks run with this handler in place, then Python's teardown of the modules, in which
    Python restores the default handlers (a stop in those last tenths of a second ends the
    process with the signal's own status and no line; the files are complete then too).
    """

    def __init__(self, job: str):
        self.job = job  # what the line names; the command's name once it is known
        self._status: int | None = None  # set by exit(): the job is done

    def install(self, numbers: Iterable[int]) -> None:
        """Handle the signals ``numbers`` from now on (:func:`handle`)."""
        handle(numbers, self.stop)

    def stop(self, signum: int, frame=None) -> NoReturn:
        """End the process now, saying which signal stopped it (and, once the job is done,
        that its files are complete)."""
        reason = _reason(None if signum == signal.SIGINT else signal.Signals(signum).name)
        after = ", while exiting (its files are complete)" if self._status is not None else ""
        _flush_standard_streams()
        with suppress(OSError):  # stderr closed: the status still says it
            os.write(2, f"{self.job}: {reason}{after}\n".encode())
        os._exit(INTERRUPTED_STATUS)

    def exit(self, status: int) -> NoReturn:
        """End the process with ``status`` (raises SystemExit; see the class docstring)."""
        self._status = status
        sys.exit(status)


def _flush_standard_streams() -> None:
    for stream in (sys.stdout, sys.stderr):
        # Closed, a broken pipe, or a signal handled in the middle of a write to it.
        with suppress(OSError, ValueError, RuntimeError, AttributeError):
            stream.flush()


def stops_the_job(error: BaseException) -> bool:
    """Whether an exception caught around a method's code stops the whole job rather than
    failing a frame: a stop signal's :class:`Interrupted`, or a KeyboardInterrupt where it may be
    the user's Ctrl-C. Where SIGINT is ignored (a worker process, ``threads.single_thread_pool``;
    a job started in the background or by a batch system) only code can raise a bare one."""
    if isinstance(error, Interrupted):
        return True
    return (isinstance(error, KeyboardInterrupt)
            and signal.getsignal(signal.SIGINT) is not signal.SIG_IGN)
