"""Checks of values read from a TOML file, for validators that name the key and what is allowed.

The predicates say whether one value is acceptable; ``distinct_list`` checks a list item by item
and raises the error its caller builds (``fail(key, problem)``), naming the item as
``key[index]``. None of them knows about sweeps, so any file validator can use them.
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable
from typing import Any

#: A name usable as a file or folder name: letters, digits, '_', '-', '.'.
SAFE_NAME = re.compile(r"^[A-Za-z0-9_.-]+$")
#: A dotted key into nested tables, such as ``sensor.noise_scale``.
DOTTED_KEY = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*(\.[A-Za-z_][A-Za-z0-9_]*)*$")

#: Builds the error of a bad value from its key and the problem found.
Fail = Callable[[str, str], Exception]


def is_int(value: Any) -> bool:
    """True for an integer; False for a bool (TOML's ``true`` is not 1)."""
    return isinstance(value, int) and not isinstance(value, bool)


def is_finite_number(value: Any) -> bool:
    """True for a finite integer or float; False for a bool, NaN or infinity."""
    return isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)


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
