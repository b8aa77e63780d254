"""Methods from outside ``stabilizer``, one of each form the plugin contract accepts and of each
way a method can go wrong; tests refer to them by import path
(``tests.sim.harness.plugin_methods:Name``, docs/plugins.md)."""

from __future__ import annotations

import math
import os
import signal
import sys
import time
import warnings

import numpy as np

from stabilizer.motion import Motion

#: What every well-behaved method here returns, whatever the frames.
FIXED = (1.5, -2.0, 3.25)


class FixedEstimator:
    """A class ``FixedEstimator(reference, **params)``: the reference is kept, ``offset_px``
    is added to dx."""

    def __init__(self, reference: np.ndarray, offset_px: float = 0.0):
        self.shape = reference.shape
        self.offset_px = offset_px

    def estimate(self, current: np.ndarray) -> Motion:
        angle, dx, dy = FIXED
        return Motion(angle, dx + self.offset_px, dy, diagnostics={"shape": self.shape})


def fixed_motion(reference: np.ndarray, current: np.ndarray) -> Motion:
    return Motion(*FIXED)


def fixed_tuple(reference: np.ndarray, current: np.ndarray) -> tuple[float, float, float]:
    return FIXED


def fixed_array(reference: np.ndarray, current: np.ndarray) -> np.ndarray:
    return np.array(FIXED, np.float32)


def reported_failure(reference: np.ndarray, current: np.ndarray) -> Motion:
    return Motion.failed("no_structure")


def raising(reference: np.ndarray, current: np.ndarray) -> Motion:
    raise ValueError("this method always fails")


class UnreadableError(Exception):
    def __str__(self) -> str:
        raise RuntimeError("no message")


def raises_unreadable(reference: np.ndarray, current: np.ndarray) -> Motion:
    """Raises an exception whose message cannot be read."""
    raise UnreadableError


def exits(reference: np.ndarray, current: np.ndarray) -> Motion:
    sys.exit("a library that ends the program")


def ends_its_process(reference: np.ndarray, current: np.ndarray) -> Motion:
    """Ends the process at once, as a crash in native code would (only in a worker process)."""
    os._exit(70)


def raises_keyboard_interrupt(reference: np.ndarray, current: np.ndarray) -> Motion:
    raise KeyboardInterrupt("a library that raises KeyboardInterrupt itself")


class ExitsOnReference:
    """Its constructor calls sys.exit(): every frame against that reference fails."""

    def __init__(self, reference: np.ndarray):
        sys.exit(3)

    def estimate(self, current: np.ndarray) -> Motion:
        return Motion(*FIXED)


class OwnBaseException(BaseException):
    """Not an Exception: a plugin's own, as some frameworks raise."""


def raises_its_own_base_exception(reference: np.ndarray, current: np.ndarray) -> Motion:
    raise OwnBaseException("not an Exception")


def unwrites_its_input(reference: np.ndarray, current: np.ndarray) -> Motion:
    """Makes the frames it is given writable again (numpy allows it for an array that owns
    its memory, or a view of a writable one) and zeroes them."""
    for image in (reference, current):
        image.flags.writeable = True
        image[...] = 0
    return Motion(*FIXED)


class ZeroesItsReference:
    """Makes its reference writable again and zeroes it."""

    def __init__(self, reference: np.ndarray):
        reference.flags.writeable = True
        reference[...] = 0

    def estimate(self, current: np.ndarray) -> Motion:
        return Motion(*FIXED)


def changes_global_settings(reference: np.ndarray, current: np.ndarray) -> Motion:
    np.seterr(all="raise")
    warnings.simplefilter("error")
    os.chdir("/")
    return Motion(*FIXED)


def odd_diagnostics(reference: np.ndarray, current: np.ndarray) -> Motion:
    return Motion(*FIXED, diagnostics={"n": np.int64(4), "pair": (1.5, "a"),
                                       "callback": lambda: 1, "labels": "not an image"})


def list_diagnostics(reference: np.ndarray, current: np.ndarray) -> Motion:
    return Motion(*FIXED, diagnostics=[1, 2])


def huge_integer(reference: np.ndarray, current: np.ndarray) -> tuple:
    return (10**400, 0, 0)


def huger_integer(reference: np.ndarray, current: np.ndarray) -> tuple:
    """An integer of more than the 4300 digits Python converts to text."""
    return (0, 10**5000, 0)


def far_out(reference: np.ndarray, current: np.ndarray) -> tuple:
    """1e308, a "no value" of C programs, as an estimate."""
    return (0.0, 1e308, 0.0)


def at_the_bound(reference: np.ndarray, current: np.ndarray) -> tuple:
    """Shifts right at the documented bound, +-1,000,000: still estimates."""
    return (0.0, 1e6, -1e6)


def far_below(reference: np.ndarray, current: np.ndarray) -> tuple:
    """A shift just beyond the documented bound (docs/plugins.md: +-1,000,000) on the
    negative side."""
    return (0.0, 0.0, -1_000_001.0)


def unwritable_failure(reference: np.ndarray, current: np.ndarray) -> Motion:
    """A failure whose status and diagnostics no JSON or UTF-8 file can take as they are."""
    return Motion.failed("bad\ud800name", big=10**5000, path="\udcff.png", count=3)


def nan_motion(reference: np.ndarray, current: np.ndarray) -> Motion:
    return Motion(math.nan, 0.0, 0.0)


def infinite_tuple(reference: np.ndarray, current: np.ndarray) -> tuple[float, float, float]:
    return (0.0, math.inf, 0.0)


def wrong_type(reference: np.ndarray, current: np.ndarray) -> str:
    return "1.5, -2.0, 3.25"


def wrong_length(reference: np.ndarray, current: np.ndarray) -> tuple[float, float]:
    return (1.0, 2.0)


def wrong_value_type(reference: np.ndarray, current: np.ndarray) -> tuple:
    return (1.0, "2.0", 3.0)


def writes_its_input(reference: np.ndarray, current: np.ndarray) -> Motion:
    current[0, 0] = 7
    return Motion(*FIXED)


class FailsOnReference:
    """Its constructor raises: every frame against that reference fails."""

    def __init__(self, reference: np.ndarray):
        raise RuntimeError("cannot analyse this reference")

    def estimate(self, current: np.ndarray) -> Motion:
        return Motion(*FIXED)


class NoEstimate:
    """A class without ``estimate``: refused."""

    def __init__(self, reference: np.ndarray):
        pass


NOT_CALLABLE = 3.0


def sends_itself_sigterm(reference: np.ndarray, current: np.ndarray) -> Motion:
    """A batch system's stop arriving while the method runs: the signal reaches the process
    inside the estimate, where the harness's handler raises its stop."""
    os.kill(os.getpid(), signal.SIGTERM)
    time.sleep(5)  # the handler raises before this returns
    return Motion(0.0, 0.0, 0.0)
