"""The command line's conventions, shared by ``egostab`` and the developer tools (``python -m
sim.harness.bench``, ``python -m sim.world...``, ``benchmarks/``): one-line errors with exit
status 2, and the argparse types of their options, each refusing a bad value with what it
accepts."""

from __future__ import annotations

import argparse
import math
import os
import sys
from collections.abc import Callable
from pathlib import Path

#: Exit status when the reader of the output went away: 128 + SIGPIPE, as a shell reports a
#: command that SIGPIPE ended.
BROKEN_PIPE_STATUS = 141


class OneLineParser(argparse.ArgumentParser):
    """An argument parser whose errors are one line, as every other error of the command:
    what was wrong, what is accepted, and where the usage is (exit status 2)."""

    def error(self, message: str):
        self.exit(2, f"{self.prog}: error: {message} (usage: {self.prog} --help)\n")

    def parse_args(self, args=None, namespace=None):
        """As argparse's, but an argument no parser knows is refused by the subcommand's
        parser, whose --help lists what it accepts (argparse refuses it as the top level's)."""
        parsed, unknown = self.parse_known_args(args, namespace)
        if unknown:
            commands = getattr(self, "commands", None)
            chosen = commands.choices.get(getattr(parsed, "command", None)) if commands else None
            (chosen or self).error(f"unrecognized arguments: {' '.join(unknown)}")
        return parsed


def discard_output() -> None:
    """Send what is left of stdout to /dev/null, so that Python's own last flush of it does not
    fail again (with a second message and status 120)."""
    os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())


def script_status(main: Callable[[], int | None]) -> int | str:
    """The exit status of a developer tool's ``main()`` (None: 0; a ``SystemExit``'s code, as
    argparse's ``--help`` and errors end), its output written out; a reader that has gone
    (``python benchmarks/floor_walks.py | head``) ends it quietly with
    :data:`BROKEN_PIPE_STATUS`, as ``egostab`` does, not with a traceback."""
    try:
        try:
            status = main()
        except SystemExit as stop:
            status = stop.code
        sys.stdout.flush()
    except BrokenPipeError:
        discard_output()
        return BROKEN_PIPE_STATUS
    return status or 0


def integer_option(least: int, most: int | None = None) -> Callable[[str], int]:
    """An argparse ``type``: an integer of at least ``least`` (and at most ``most``); anything
    else is refused with the text given and what is accepted."""
    accepted = (f"an integer >= {least}" if most is None
                else f"an integer from {least} to {most}")

    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            value = None
        if value is None or value < least or (most is not None and value > most):
            raise argparse.ArgumentTypeError(f"{text!r}: accepted: {accepted}")
        return value

    return parse


def number_option(above: float, most: float) -> Callable[[str], float]:
    """An argparse ``type``: a number greater than ``above`` and at most ``most``; anything
    else (NaN, infinity too) is refused with the text given and what is accepted."""

    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            value = math.nan
        if not (above < value <= most):  # NaN fails every comparison
            raise argparse.ArgumentTypeError(f"{text!r}: accepted: a number greater than "
                                             f"{above:g} and at most {most:g}")
        return value

    return parse


def path_option(text: str) -> Path:
    """An argparse ``type`` for a path to write to or a folder to read: an empty value (an unset
    shell variable) is refused rather than taken for the working directory, and a leading ``~`` that the shell
    left (quoted, or ``--out=~/x``) is the home folder, as the printed path then says."""
    if not text.strip():
        raise argparse.ArgumentTypeError(f"{text!r}: accepted: a path (an empty one, such as an "
                                         "unset shell variable, is refused; '.' is the working "
                                         "directory)")
    return Path(text).expanduser()


#: The ``type`` of an option that counts something: workers, frames.
POSITIVE_INTEGER = integer_option(1)
#: The largest seed: seeds are stored and logged as signed 64-bit integers.
MAX_SEED = 2**63 - 1
