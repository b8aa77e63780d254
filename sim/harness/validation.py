"""Validation of the harness's input files (scenarios, sweeps): the error and the value checks.

Every file validator reports a bad value the same way, with :class:`FileValueError`: the file,
the key, what is wrong and what is allowed, on one line. The predicates say whether one value is
acceptable; ``distinct_list`` checks a list item by item and raises the error its caller builds
(``fail(key, problem)``), naming the item as ``key[index]``.
"""

from __future__ import annotations

import math
import re
import tomllib
from collections.abc import Callable
from pathlib import Path
from typing import Any

from sim.command_line import MAX_SEED

#: A name usable as a file or folder name: letters, digits, '_', '-', '.'.
SAFE_NAME = re.compile(r"^[A-Za-z0-9_.-]+$")
#: A dotted key into nested tables, such as ``sensor.noise_scale``.
DOTTED_KEY = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*(\.[A-Za-z_][A-Za-z0-9_]*)*$")

#: Builds the error of a bad value from its key and the problem found.
Fail = Callable[[str, str], Exception]


class FileValueError(ValueError):
    """A value in an input file that cannot be used: names the file, the key and what is allowed."""

    def __init__(self, source: str, key: str, problem: str, allowed: str):
        self.source, self.key, self.problem, self.allowed = source, key, problem, allowed
        super().__init__(f"{source}: {key}: {problem}; allowed: {allowed}")

    def __reduce__(self):  # picklable, so a process pool can report it
        return type(self), (self.source, self.key, self.problem, self.allowed)


def is_int(value: Any) -> bool:
    """True for an integer; False for a bool (TOML's ``true`` is not 1)."""
    return isinstance(value, int) and not isinstance(value, bool)


def is_finite_number(value: Any) -> bool:
    """True for a finite integer or float; False for a bool, NaN or infinity."""
    return isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)


def is_seed(value: Any) -> bool:
    """True for an integer from 0 to ``MAX_SEED`` (what a scenario's seeds accept)."""
    return is_int(value) and 0 <= value <= MAX_SEED


def is_safe_name(value: Any) -> bool:
    """True for a non-empty string of ``SAFE_NAME`` characters."""
    return isinstance(value, str) and SAFE_NAME.match(value) is not None


def is_dotted_key(value: Any) -> bool:
    """True for a string such as ``sensor.noise_scale`` (``DOTTED_KEY``)."""
    return isinstance(value, str) and DOTTED_KEY.match(value) is not None


def distinct_list(value: Any, key: str, fail: Fail, check: Callable[[Any], bool]) -> tuple:
    """``value`` as a tuple, if it is a non-empty list of distinct items that pass ``check``.

    Raises:
        The error ``fail`` builds: for ``key`` if ``value`` is not a non-empty list, for
        ``key[index]`` if an item fails ``check`` or repeats an earlier one.
    """
    if not isinstance(value, list) or not value:
        raise fail(key, f"got {value!r}")
    for index, item in enumerate(value):
        if not check(item):
            raise fail(f"{key}[{index}]", f"got {item!r}")
        if item in value[:index]:
            raise fail(f"{key}[{index}]", f"{item!r} is listed twice")
    return tuple(value)


def read_toml(path: Path, error: type[FileValueError] = FileValueError) -> dict:
    """The tables of the TOML file ``path``; a file that is not UTF-8 TOML raises ``error``."""
    try:
        # utf-8-sig, as the CSVs: some editors (Notepad, PowerShell) start UTF-8 with a
        # byte-order mark, which TOML does not allow.
        return tomllib.loads(Path(path).read_bytes().decode("utf-8-sig"))
    except tomllib.TOMLDecodeError as problem:
        raise error(str(path), "(file)", f"not valid TOML ({problem})", "TOML 1.0") from None
    except UnicodeDecodeError:
        raise error(str(path), "(file)", "not UTF-8 text", "a TOML 1.0 file") from None


