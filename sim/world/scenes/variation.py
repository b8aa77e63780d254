"""Scene parameters: what a caller may vary in a scene, checked before it is built.

A scene is a frozen dataclass derived from :class:`SceneLayout`; its fields are its parameters,
declared with the helpers below, which record the bounds each value is checked against. The
kinds of parameter:

- a range (:func:`real_range`): a pair ``(low, high)`` of metres or degrees; each time the
  scene needs the value it draws it uniformly from its seeded generator (:func:`draw`).
  ``low == high`` fixes the value.
- a count range (:func:`integer_range`): a pair ``(low, high)`` of integers; the scene draws a
  count from ``low`` to ``high`` inclusive (:func:`draw_count`).
- a count (:func:`integer`): a fixed number of objects.
- positions (:func:`positions`): fixed places along a wall or the walk, metres.

This is the local, smaller counterpart of dm_control's ``composer.variation`` distributions:
the same seed and parameters always give the same scene, because a scene draws everything from
one generator seeded once, in a fixed order.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any, ClassVar, Mapping

import numpy as np


class SceneParameterError(ValueError):
    """A scene parameter that cannot be used: names the scene, the parameter, what is wrong
    and what is accepted."""

    def __init__(self, scene: str, parameter: str, problem: str, accepted: str):
        self.scene, self.parameter, self.problem, self.accepted = (scene, parameter, problem,
                                                                   accepted)
        super().__init__(f"scene {scene!r}: parameter {parameter!r}: {problem}; "
                         f"accepted: {accepted}")

    def __reduce__(self):  # picklable, so a process pool can report it
        return SceneParameterError, (self.scene, self.parameter, self.problem, self.accepted)


def real_range(default: tuple[float, float], within: tuple[float, float]):
    """A ``(low, high)`` range of reals, both ends inside ``within``."""
    return _parameter("real_range", default, within)


def integer_range(default: tuple[int, int], within: tuple[int, int]):
    """A ``(low, high)`` range of integers (inclusive), both ends inside ``within``."""
    return _parameter("integer_range", default, within)


def integer(default: int, within: tuple[int, int]):
    """A fixed integer inside ``within``."""
    return _parameter("integer", default, within)


def positions(default: tuple[float, ...], within: tuple[float, float]):
    """A non-empty list of reals, each inside ``within``."""
    return _parameter("positions", default, within)


def draw(rng: np.random.Generator, low_high: tuple[float, float]) -> float:
    """A real drawn uniformly from ``low`` to ``high``."""
    return rng.uniform(low_high[0], low_high[1])


def draw_count(rng: np.random.Generator, low_high: tuple[int, int]) -> int:
    """An integer drawn uniformly from ``low`` to ``high`` inclusive."""
    return int(rng.integers(low_high[0], low_high[1] + 1))


@dataclasses.dataclass(frozen=True)
class SceneLayout:
    """Base of the scenes: parameters as fields, checked on construction, and ``build(seed)``.

    A scene subclass sets ``name`` and ``description``, declares its parameters as fields with
    :func:`real_range`, :func:`integer_range`, :func:`integer` or :func:`positions`, and
    implements :meth:`build`. Values are stored in canonical form (tuples of floats or ints),
    so a layout read from a TOML file builds the same scene as one written in Python.
    """

    #: Scene name: its key in ``sim.world.scenes.SCENES``.
    name: ClassVar[str] = ""
    #: One line for reports.
    description: ClassVar[str] = ""

    def __post_init__(self):
        for spec in dataclasses.fields(self):
            object.__setattr__(self, spec.name, self._checked(spec, getattr(self, spec.name)))

    @classmethod
    def from_params(cls, params: Mapping[str, Any]) -> "SceneLayout":
        """The layout with ``params`` (parameter name -> value) and defaults for the rest."""
        names = cls.parameter_names()
        for parameter in params:
            if parameter not in names:
                raise SceneParameterError(cls.name, str(parameter), "unknown parameter",
                                          ", ".join(names))
        return cls(**params)

    @classmethod
    def parameter_names(cls) -> tuple[str, ...]:
        return tuple(spec.name for spec in dataclasses.fields(cls))

    @classmethod
    def accepted(cls, parameter: str) -> str:
        """What ``parameter`` accepts, in words."""
        spec = {spec.name: spec for spec in dataclasses.fields(cls)}[parameter]
        low, high = spec.metadata["within"]
        return {
            "real_range": f"a pair [low, high] with {low:g} <= low <= high <= {high:g}",
            "integer_range": f"a pair [low, high] of integers with {low} <= low <= high <= "
                             f"{high}",
            "integer": f"an integer from {low} to {high}",
            "positions": f"a non-empty list of numbers from {low:g} to {high:g}",
        }[spec.metadata["kind"]]

    def params(self) -> dict[str, Any]:
        """Parameter name -> value, every parameter (defaults included)."""
        return {name: getattr(self, name) for name in self.parameter_names()}

    def build(self, seed: int, floor=None):
        """The scene drawn from ``seed``, standing on ``floor`` (a
        :class:`sim.world.scenes.floor.Floor`; the subclasses default to the flat floor): a
        :class:`sim.world.scenes.builder.Scene`."""
        raise NotImplementedError

    def refuse(self, parameter: str, problem: str, accepted: str | None = None):
        """Raise the SceneParameterError of ``parameter`` (for checks across parameters)."""
        raise SceneParameterError(self.name, parameter, problem,
                                  accepted or self.accepted(parameter))

    def _checked(self, spec: dataclasses.Field, value):
        """``value`` in canonical form, or a SceneParameterError."""
        kind = spec.metadata["kind"]
        low, high = spec.metadata["within"]
        if kind == "integer":
            if not (_is_int(value) and low <= value <= high):
                self.refuse(spec.name, f"got {value!r}")
            return int(value)
        is_number = _is_int if kind == "integer_range" else _is_real
        number = int if kind == "integer_range" else float
        if not (isinstance(value, (list, tuple)) and value
                and (kind == "positions" or len(value) == 2)
                and all(is_number(v) and low <= v <= high for v in value)):
            self.refuse(spec.name, f"got {value!r}")
        if kind != "positions" and value[0] > value[1]:
            self.refuse(spec.name, f"{value!r}: low is above high")
        return tuple(number(v) for v in value)


def _parameter(kind: str, default, within):
    return dataclasses.field(default=default, metadata={"kind": kind, "within": within})


def _is_int(value) -> bool:
    return isinstance(value, (int, np.integer)) and not isinstance(value, bool)


def _is_real(value) -> bool:
    return (isinstance(value, (int, float, np.integer, np.floating))
            and not isinstance(value, bool) and math.isfinite(value))
