"""What sweep and suite files share: the file itself, the header keys, the methods, the
overrides table and the scenario entries, each checked the same way.

A sweep (sim/harness/sweep/spec.py) and a suite (sim/harness/suite/spec.py) both describe a set
of walking runs; they differ in how they vary the runs, and share the rest.
"""

from __future__ import annotations

import os
import sys
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from sim.harness.methods import MethodError, method_factory
from sim.harness.report import safe_name
from sim.harness.scenario import list_scenarios, resolve_scenario_path
from sim.harness.validation import (Fail, FileValueError, is_dotted_key, is_int, is_safe_name,
                                    read_toml)


def read_runset_file(path: str | os.PathLike, error: type[FileValueError], kind: str) -> dict:
    """The tables of a ``kind`` file ("sweep", "suite"), named after the file unless it says."""
    path = Path(path)
    if not path.is_file():
        problem = (f"{path} is a folder, not a {kind} file" if path.is_dir() else
                   f"{path} is not a regular file" if path.exists() else f"no {kind} file {path}")
        raise FileNotFoundError(f"{problem}; accepted: a {kind} TOML file (see "
                                f"scenarios/{kind}s/)")
    raw = read_toml(path, error)
    raw.setdefault("name", safe_name(path.stem))
    return raw


@dataclass(frozen=True)
class RunsetHeader:
    """The keys every sweep and suite file has: its name and description, the frames each run
    walks at most (None: the scenario's duration), whether runs write a recording."""

    name: str
    description: str
    max_frames: int | None
    record: bool


def check_header(raw: Mapping[str, Any], allowed: Mapping[str, str], required: tuple[str, ...],
                 error: type[FileValueError], source: str, fail: Fail,
                 default_name: str) -> RunsetHeader:
    """Refuse unknown and missing keys; check name, description, max_frames and record."""
    for key in raw:
        if key not in allowed:
            raise error(source, str(key), "unknown key", f"keys {', '.join(allowed)}")
    for key in required:
        if key not in raw:
            raise fail(key, "missing")
    name = raw.get("name", default_name)
    # The name is a folder's (results/<kind>s/<name>): "." or ".." would be another folder.
    if not is_safe_name(name) or not name.strip("."):
        raise fail("name", f"got {name!r}")
    description = raw.get("description", "")
    if not isinstance(description, str):
        raise fail("description", f"got {description!r}")
    max_frames = raw.get("max_frames")
    if max_frames is not None and not (is_int(max_frames) and max_frames >= 1):
        raise fail("max_frames", f"got {max_frames!r}")
    record = raw.get("record", False)
    if not isinstance(record, bool):
        raise fail("record", f"got {record!r}")
    return RunsetHeader(name, description, max_frames, record)


def check_methods(methods: tuple[str, ...], fail: Fail) -> None:
    """Every method resolves now (built-in, entry point or import path), before any run."""
    for index, name in enumerate(methods):
        try:
            method_factory(name)
        except MethodError as problem:
            raise fail(f"methods[{index}]", f"method {name!r}: {problem.problem}") from None


def checked_overrides(overrides: Any, key: str, varied: tuple[str, ...], fail: Fail) -> dict:
    """An overrides table as a dict: single values under dotted keys, none of the ``varied``
    keys (those come from the file's lists)."""
    if not isinstance(overrides, Mapping):
        raise fail(key, f"got {overrides!r}")
    for dotted, value in overrides.items():
        # Nor a key within a varied one or holding it: the varied value would replace it.
        if not is_dotted_key(str(dotted)) or any(
                f"{dotted}.".startswith(f"{other}.") or f"{other}.".startswith(f"{dotted}.")
                for other in varied):
            raise fail(key, f"key {dotted!r} is not allowed here ({', '.join(varied)} come "
                            "from the file's lists)")
        if isinstance(value, Mapping):  # it would replace the scenario's whole table
            raise fail(key, f"{dotted!r} is a table; write one dotted key per value, "
                            f"e.g. \"{dotted}.{next(iter(value), 'field')}\" = ...")
    return dict(overrides)


def set_by(key: str | None, overrides: Mapping[str, Any]) -> bool:
    """Whether the scenario key ``key`` a refusal names is one of ``overrides``, lies within
    one (``pushes[0].impulse_ns`` within ``pushes``, ``sensor.fps`` within ``sensor``) or holds
    one (``gait.overrides`` holds ``gait.overrides.step_period_s``)."""
    return key is not None and any(
        key == name or key.startswith((f"{name}.", f"{name}[")) or name.startswith(f"{key}.")
        for name in overrides)


def resolve_scenario_entry(entry: Any, key: str, base_dir: Path, fail: Fail) -> str:
    """A shipped scenario name stays a name; a path becomes absolute (from the file's folder)."""
    if not isinstance(entry, str) or not entry.strip():
        raise fail(key, f"got {entry!r}")
    is_path = entry.endswith(".toml") or "/" in entry or os.sep in entry
    target = Path(entry) if Path(entry).is_absolute() or not is_path else base_dir / entry
    try:
        found = resolve_scenario_path(str(target))
    except FileNotFoundError as problem:
        # Its "accepted" part is the file's allowed values, which ``fail`` adds.
        text = str(problem).split("; accepted: ")[0]
        if not is_path:
            text += f" (shipped: {', '.join(path.stem for path in list_scenarios())})"
        raise fail(key, text) from None
    return str(found.resolve()) if is_path else entry


def command_line_backend(ray: bool, ray_address: str | None, workers: int | None) -> str:
    """The backend of ``--ray`` ("ray" or "local"); a ValueError for ``--ray-address`` without
    ``--ray``, which would otherwise go unused while the runs stay on this machine, and for
    more local ``--workers`` than :func:`~sim.harness.threads.check_local_workers` allows
    (before any folder is made)."""
    from sim.harness.threads import check_local_workers

    if ray_address is not None and not ray:
        raise ValueError(f"--ray-address needs --ray (got --ray-address {ray_address} alone); "
                         f"accepted: --ray --ray-address ADDRESS, or no --ray-address to run "
                         f"on this machine")
    if not ray:
        check_local_workers(workers)
    elif ray_address is not None:
        check_ray_address(ray_address)
    return "ray" if ray else "local"


#: Ray's own words for "find the cluster" and "start one here".
RAY_ADDRESS_WORDS = ("auto", "local")
#: How long a Ray head has to answer; Ray itself retries an address nobody answers for minutes.
RAY_CONNECT_TIMEOUT_S = 5.0


def check_ray_address(address: str) -> None:
    """A ValueError of one line unless ``address`` is one of :data:`RAY_ADDRESS_WORDS` or a
    ``host:port`` (``ray://host:port``) where something accepts a connection: Ray, given an
    address nobody answers at, logs its retries and waits for minutes."""
    import socket

    accepted = (f"accepted: {' or '.join(repr(word) for word in RAY_ADDRESS_WORDS)}, or the "
                f"HOST:PORT (ray://HOST:PORT for Ray Client) of a running Ray cluster's head")
    if address in RAY_ADDRESS_WORDS:
        return
    host, separator, port = address.removeprefix("ray://").rpartition(":")
    host = host.strip("[]")  # an IPv6 host is written in brackets
    if not (separator and host and port.isascii() and port.isdigit()
            and 0 < int(port) < 65536):
        raise ValueError(f"--ray-address {address!r}: is not an address; {accepted}")
    try:
        socket.create_connection((host, int(port)), timeout=RAY_CONNECT_TIMEOUT_S).close()
    except OSError as error:
        reason = error.strerror or type(error).__name__
        raise ValueError(f"--ray-address {address}: nothing answers at {host}:{port} ({reason}); "
                         f"{accepted}") from None


def run_on_command_line(kind: str, run: Callable[..., Any], spec: Any, out_dir: Path,
                        backend: str, workers: int | None, ray_address: str | None) -> int:
    """Run a sweep or suite for ``egostab sweep|suite``: print its tables, each failed run and
    its folder. Returns the exit status: 1 if a run failed, 2 without Ray's extra, else 0."""
    from sim.atomic import folder_in_use

    try:
        with folder_in_use(out_dir):  # a second sweep or suite into it is refused
            result = run(spec, out_dir, backend=backend, workers=workers,
                         ray_address=ray_address, progress=True)
    except ImportError as error:  # --ray without the cluster extra: the message says the fix
        print(f"egostab {kind}: error: {error}", file=sys.stderr)
        return 2
    print(result.markdown)
    for outcome in result.failed:
        print(f"run failed: {outcome.run.name}: {outcome.error}", file=sys.stderr)
    print(f"{kind} folder: {out_dir}")
    return 1 if result.failed else 0
