"""The methods the harness scores: built-in stabilizers, entry points and import paths.

A method name is one of three forms (docs/plugins.md):

- a built-in name of ``stabilizer.available_methods()``, built as
  ``stabilizer.Stabilizer(reference, name)``;
- ``package.module:Name``, an import path to a class built as ``Name(reference, **params)``
  with ``.estimate(current) -> Motion``, or to a function ``(reference, current) -> Motion``
  or ``-> (angle_deg, dx, dy)``; the module is imported from ``sys.path`` (installed, or on
  ``PYTHONPATH``) or else from the working directory, as ``python -m`` would find it;
- the name of an entry point of the group ``egostab.stabilizers`` that an installed
  distribution declares; it loads one of the objects above.

A built-in name wins over an entry point of the same name. Outputs name a method by the string
given. A plugin method is held to the Motion contract frame by frame (:class:`PluginStabilizer`):
what it raises, a non-finite estimate or a result of the wrong type is a failed frame whose
status says why; the run goes on.
"""

from __future__ import annotations

import contextlib
import functools
import importlib
import importlib.machinery
import importlib.metadata
import inspect
import math
import numbers
import os
import re
import sys
import warnings
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np

from sim.harness.interrupts import stops_the_job
from stabilizer import Stabilizer, available_methods
from stabilizer.inputs import as_disparity, check_same_shape
from stabilizer.motion import OK, Motion
from stabilizer.verification import VerificationParams, shared_verifier

#: Entry-point group under which installed distributions register methods.
ENTRY_POINT_GROUP = "egostab.stabilizers"
#: ``package.module:Name`` (the attribute may be dotted, as in ``module:Outer.Estimator``).
IMPORT_PATH = re.compile(r"^[A-Za-z_]\w*(\.[A-Za-z_]\w*)*:[A-Za-z_]\w*(\.[A-Za-z_]\w*)*$")
#: The accepted forms, for messages.
ACCEPTED_FORMS = (f"a built-in method ({', '.join(available_methods())}), an entry point of "
                  f"group {ENTRY_POINT_GROUP} (egostab methods lists them), or an import path "
                  "package.module:Name (a class Name(reference, **params) with "
                  ".estimate(current), or a function (reference, current); its module "
                  "installed, on PYTHONPATH or under the working directory)")


class Estimator(Protocol):
    """What the harness calls: the motion of a current frame against the analysed reference."""

    def estimate(self, current: np.ndarray) -> Motion: ...


class MethodError(ValueError):
    """A method name that cannot be resolved: one line naming it and the accepted forms."""

    def __init__(self, name: str, problem: str):
        self.name, self.problem = name, problem
        super().__init__(f"method {name!r}: {problem}; accepted: {ACCEPTED_FORMS}")

    def __reduce__(self):  # picklable, so a process pool can report it
        return type(self), (self.name, self.problem)


#: What ``--methods`` on the command line reads as every built-in method.
ALL_BUILT_INS = "all"


@dataclass(frozen=True)
class MethodInfo:
    """An available method and where it comes from (``egostab methods``)."""

    name: str
    origin: str


def list_methods() -> list[MethodInfo]:
    """The built-in methods, then the installed entry points, in the order found.

    Entry points are listed without being loaded; one that a built-in name shadows, or an
    earlier entry point of the same name, says so.
    """
    found = [MethodInfo(name, "built-in") for name in available_methods()]
    seen = set(available_methods())
    for entry_point in importlib.metadata.entry_points(group=ENTRY_POINT_GROUP):
        origin = f"entry point {entry_point.name} -> {entry_point.value}" \
                 f"{_distribution_text(entry_point)}"
        if entry_point.name in seen:
            origin += " (shadowed: an earlier method has this name)"
        elif entry_point.name == ALL_BUILT_INS:
            origin += (f" (not on the command line, where --methods {ALL_BUILT_INS} means every "
                       f"built-in method; in scenario and sweep files)")
        seen.add(entry_point.name)
        found.append(MethodInfo(entry_point.name, origin))
    return found


def method_factory(name: str) -> Callable[..., Estimator]:
    """``factory(reference, **params)``: the estimator of method ``name`` for one reference.

    A built-in name gives ``functools.partial(Stabilizer, method=name)``; any other name is
    loaded now (entry point or import path) and wrapped in :class:`PluginStabilizer`.

    Raises:
        MethodError: ``name`` is not a built-in, an installed entry point or an importable
            class or function.
    """
    if name in available_methods():
        return functools.partial(Stabilizer, method=name)
    target = _load(name)
    if inspect.isclass(target):
        if not callable(getattr(target, "estimate", None)):
            raise MethodError(name, f"class {target.__qualname__} has no estimate(current) "
                                    "method")
    elif not callable(target):
        raise MethodError(name, f"{type(target).__name__} object is not callable")
    return functools.partial(PluginStabilizer, name, target)


def check_methods(names) -> None:
    """Load every method of ``names`` once, so that one that cannot be loaded is reported
    before any work (worker processes load them only at their first frame).

    Raises:
        MethodError: the first name that is not a method (see :func:`method_factory`).
    """
    for name in names:
        method_factory(name)


def _load(name: str) -> Any:
    """The object a non-built-in name refers to: an import path's, or an entry point's."""
    if ":" in name:
        if not IMPORT_PATH.match(name):
            raise MethodError(name, "not an import path of the form package.module:Name")
        module_name, attribute = name.split(":")
        try:
            with _as_it_was():
                target = _import_module(module_name)
        # A plugin's own import error (a sys.exit() or another BaseException on import too)
        # is the user's to read; Ctrl-C still stops the command.
        except BaseException as error:
            if stops_the_job(error):
                raise
            raise MethodError(name, f"cannot import module {module_name} "
                                    f"({_one_line(error)})") from None
        for part in attribute.split("."):
            if not hasattr(target, part):
                raise MethodError(name, f"{getattr(target, '__name__', module_name)} has no "
                                        f"attribute {part}")
            target = getattr(target, part)
        return target
    entry_points = importlib.metadata.entry_points(group=ENTRY_POINT_GROUP, name=name)
    if not entry_points:
        raise MethodError(name, "unknown: not a built-in method, not an installed entry point "
                                "and not an import path")
    entry_point = next(iter(entry_points))
    try:
        with _as_it_was():
            return entry_point.load()
    except BaseException as error:
        if stops_the_job(error):
            raise
        raise MethodError(name, f"entry point {entry_point.value}"
                                f"{_distribution_text(entry_point)} cannot be loaded "
                                f"({_one_line(error)})") from None


def _import_module(module_name: str) -> Any:
    """``importlib.import_module``, from the working directory too: an ``egostab`` command,
    unlike ``python -m``, does not search it, yet that is where a user's module usually is.
    The directory joins the end of ``sys.path`` (installed modules keep precedence) only when
    the module's top-level package is found nowhere else but there; worker processes inherit
    it."""
    try:
        return importlib.import_module(module_name)
    except ModuleNotFoundError as error:
        top = module_name.split(".")[0]
        cwd = os.getcwd()
        if error.name != top or importlib.machinery.PathFinder.find_spec(top, [cwd]) is None:
            raise
        sys.path.append(cwd)
        return importlib.import_module(module_name)


def _distribution_text(entry_point: importlib.metadata.EntryPoint) -> str:
    dist = entry_point.dist
    return "" if dist is None else f" from distribution {dist.name} {dist.version}"


def exception_text(error: BaseException) -> str:
    """What ``error`` says (``str(error)``), as text any file takes; a word about it when its
    own ``__str__`` fails."""
    try:
        return encodable_text(str(error))
    except Exception as unreadable:
        return f"(its message could not be read: {type(unreadable).__name__})"


def _one_line(error: BaseException) -> str:
    text = exception_text(error).strip().splitlines()
    return f"{type(error).__name__}: {text[0]}" if text else type(error).__name__


class PluginStabilizer:
    """A method from outside ``stabilizer`` behind the ``Stabilizer`` interface.

    The reference and every current frame reach the method as ``Stabilizer`` passes them
    (uint8 disparity-like images of one shape, 0 = invalid), each as a read-only copy of its
    own: writing into it fails the frame, and a method that makes it writable again changes
    only its copy, never the frames the other methods and the trust check see. Its result
    becomes a :class:`Motion` (:func:`as_motion`), and an ``"ok"`` result passes the same
    trust check as a built-in method's (the verifier of
    :func:`stabilizer.verification.shared_verifier`; ``"unverified"`` when it fails), so
    ``"ok"`` means the same for every method scored. If
    building the estimator raises, every frame against this reference fails with
    ``"exception:<type>"``; what ``estimate`` raises is left to the caller (the harness's
    ``timed_estimate`` records it the same way as for a built-in method).

    Args:
        method: the name the method was given by (kept as ``self.method``).
        target: a class ``target(reference, **params)`` with ``.estimate(current)``, or a
            function ``target(reference, current, **params)``.
        reference: the reference frame (uint8 disparity-like or float depth in metres).
        verification: the trust check's thresholds, as for ``Stabilizer``; None: no check.
        **params: the method's own keyword parameters.
    """

    def __init__(self, method: str, target: Any, reference: np.ndarray, *,
                 verification: VerificationParams | None = VerificationParams(), **params: Any):
        self.method = method
        self.reference = as_disparity(reference, "reference")
        self._verifier = shared_verifier(self.reference, verification) if verification else None
        self._failure: Motion | None = None
        if inspect.isclass(target):
            try:
                with _as_it_was():
                    self._estimate = target(_read_only_copy(self.reference), **params).estimate
            # A plugin's bug (a sys.exit() too, and a KeyboardInterrupt where the user cannot
            # have pressed Ctrl-C) fails its frames, not the run.
            except BaseException as error:
                if stops_the_job(error):
                    raise
                self._failure = Motion.failed(f"exception:{type(error).__name__}",
                                              message=exception_text(error),
                                              stage="reference")
        else:
            self._estimate = functools.partial(target, _read_only_copy(self.reference), **params)

    def estimate(self, current: np.ndarray) -> Motion:
        if self._failure is not None:
            return self._failure
        current = as_disparity(current, "current")
        check_same_shape(self.reference, current)
        with _as_it_was():
            result = self._estimate(_read_only_copy(current))
        motion = as_motion(result)
        return self._verifier(current, motion) if self._verifier is not None else motion


@contextlib.contextmanager
def _as_it_was() -> Iterator[None]:
    """numpy's floating-point error settings, the warning filters and the working directory
    restored after the block: a plugin that sets them (``np.seterr(all="raise")``,
    ``warnings.simplefilter("error")``, ``os.chdir``) changes them for itself, not for the
    other methods and the scoring (whose output paths may be relative)."""
    cwd = os.getcwd()
    try:
        with np.errstate(), warnings.catch_warnings():
            yield
    finally:
        if os.getcwd() != cwd:
            os.chdir(cwd)


def _read_only_copy(image: np.ndarray) -> np.ndarray:
    copy = image.copy()
    copy.flags.writeable = False
    return copy


def as_motion(result: Any) -> Motion:
    """A plugin's result as a Motion: a Motion, or three real numbers (angle_deg, dx, dy).

    A failed Motion keeps its status, which must be non-empty text (``"wrong_type:status"``
    otherwise). Anything else is a failed Motion whose status says why: ``"nan"`` for an
    estimate that is not finite (NaN, infinite, or an integer too large for a float),
    ``"wrong_type:<type>"`` for a result, or a value inside it, that is not of the accepted
    types, ``"wrong_type:diagnostics"`` for diagnostics that are not a dict. Of the
    diagnostics, only plain values are kept (:func:`plain_diagnostics`).
    """
    if isinstance(result, Motion):
        if not isinstance(result.diagnostics, dict):
            return Motion.failed("wrong_type:diagnostics",
                                 message=f"diagnostics must be a dict; got "
                                         f"{type(result.diagnostics).__name__}")
        diagnostics = plain_diagnostics(result.diagnostics)
        if not result.ok:
            if not (isinstance(result.status, str) and result.status.strip()
                    and result.status.strip().lower() != OK):
                return Motion.failed("wrong_type:status", status=_short_repr(result.status),
                                     message="a failure's status must be non-empty text other "
                                             "than 'ok' in any case")
            return Motion.failed(status_text(result.status), **diagnostics)
        values = result.as_tuple()
    elif (isinstance(result, (tuple, list)) and len(result) == 3
          or isinstance(result, np.ndarray) and result.shape == (3,)):
        values, diagnostics = tuple(result), {}
    else:
        return Motion.failed(f"wrong_type:{type(result).__name__}",
                             message="expected a Motion or (angle_deg, dx, dy)")
    for value in values:
        if not isinstance(value, numbers.Real) or isinstance(value, (bool, np.bool_)):
            return Motion.failed(f"wrong_type:{type(value).__name__}",
                                 message="angle_deg, dx and dy must be real numbers")
    try:
        floats = [float(value) for value in values]
    except OverflowError:  # an integer beyond any float
        return Motion.failed("nan", values=[_number_text(value) for value in values])
    if not all(math.isfinite(value) for value in floats):
        return Motion.failed("nan", values=floats)
    if max(abs(value) for value in floats) > MAX_ESTIMATE:
        return Motion.failed(OUT_OF_RANGE, values=floats,
                             message=f"|angle_deg|, |dx| and |dy| must be at most "
                                     f"{MAX_ESTIMATE:g}")
    return Motion(*floats, diagnostics=diagnostics)


#: Largest |angle_deg|, |dx| (px), |dy| (px) of an estimate that is scored: far beyond any
#: motion in view, small enough that no error statistic overflows (a plugin's or a file's 1e308
#: meaning "no value" turned every mean and variance into n/a or a 300-digit number).
MAX_ESTIMATE = 1e6
#: Status of an estimate beyond MAX_ESTIMATE.
OUT_OF_RANGE = "out_of_range"
#: Diagnostics keys the recording draws for the built-in methods (segmentation, ellipses).
RECORDING_KEYS = ("labels", "ellipses")
#: The key under which the harness names the diagnostics it left out.
DROPPED_KEY = "dropped_diagnostics"
#: Bounds of a plain diagnostic value: list and tuple nesting, items in one list or tuple, and
#: bits of an integer. Beyond them a value is left out: one failed frame's line in
#: failures.jsonl stays small (a million-item list per frame made 157 MB for 20 frames, rewritten
#: at every checkpoint), and every integer can be written as JSON text (Python refuses integers
#: of more than 4300 digits).
MAX_DIAGNOSTIC_DEPTH = 8
MAX_DIAGNOSTIC_ITEMS = 1000
MAX_DIAGNOSTIC_INT_BITS = 1024


def _short_repr(value: Any, most: int = 200) -> str:
    """``repr(value)``, cut to ``most`` characters; its type's name if it has none."""
    try:
        text = repr(value)
    except Exception:  # a repr that raises, or an integer of more than 4300 digits
        return f"a {type(value).__name__}"
    return encodable_text(text if len(text) <= most else text[:most] + "...")


def _number_text(value: numbers.Real) -> float | str:
    """``value`` as a float, or, for an integer beyond any float, what it is in a few words."""
    try:
        return float(value)
    except OverflowError:
        return f"an integer of {abs(int(value)).bit_length()} bits"


def plain_diagnostics(diagnostics: dict) -> dict:
    """The entries of a plugin's diagnostics that every part of the harness can carry (worker
    processes pickle them, metrics and recordings write them): text keys with None, bool,
    numbers (numpy's as Python's), text, or lists and tuples of these (a namedtuple as a plain
    tuple), within the bounds above, except the keys the recording draws for the built-in
    methods (:data:`RECORDING_KEYS`) and the harness's own :data:`DROPPED_KEY`. Text that UTF-8
    cannot encode (lone surrogates) is kept with those characters escaped. The names of the
    entries left out are kept as ``dropped_diagnostics``."""
    kept, dropped = {}, []
    for key, value in diagnostics.items():
        plain = (_plain(value) if isinstance(key, str)
                 and key not in (*RECORDING_KEYS, DROPPED_KEY) else _NOT_PLAIN)
        if plain is _NOT_PLAIN:
            dropped.append(encodable_text(str(key)))
        else:
            kept[encodable_text(key)] = plain
    if dropped:
        kept[DROPPED_KEY] = dropped
    return kept


def status_text(status: str) -> str:
    """A failure's status as one line of text: ``encodable_text``, with control characters
    (line breaks, tabs) written as escapes, so that frames.csv keeps one line per row."""
    text = encodable_text(str(status))
    if text.isprintable():
        return text
    return "".join(char if char.isprintable() else char.encode("unicode_escape").decode("ascii")
                   for char in text)


def encodable_text(text: str) -> str:
    """``text`` with the characters UTF-8 cannot encode (lone surrogates, as ``os.fsdecode``
    makes of undecodable bytes) written as backslash escapes."""
    try:
        text.encode("utf-8")
    except UnicodeEncodeError:
        return text.encode("utf-8", "backslashreplace").decode("utf-8")
    return text


_NOT_PLAIN = object()


def _plain(value: Any, depth: int = 0) -> Any:
    """``value`` as plain Python data, or ``_NOT_PLAIN``."""
    if isinstance(value, np.generic):
        value = value.item()
    if value is None or isinstance(value, (bool, float)):
        return value
    if isinstance(value, int):
        return int(value) if abs(value).bit_length() <= MAX_DIAGNOSTIC_INT_BITS else _NOT_PLAIN
    if isinstance(value, str):
        return encodable_text(str(value))
    if isinstance(value, (list, tuple)):
        if depth >= MAX_DIAGNOSTIC_DEPTH or len(value) > MAX_DIAGNOSTIC_ITEMS:
            return _NOT_PLAIN
        items = [_plain(item, depth + 1) for item in value]
        if any(item is _NOT_PLAIN for item in items):
            return _NOT_PLAIN
        return items if isinstance(value, list) else tuple(items)
    return _NOT_PLAIN
