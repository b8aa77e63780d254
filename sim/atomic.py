"""Atomic file writes: write under a temporary name in the same folder, then ``os.replace``.

A reader (or a run interrupted by Ctrl-C) never sees a half-written file: the target path holds
either the previous complete file or the new complete one (docs/design.md, "Results are written
atomically"). The temporary file lives in the target's folder because ``os.replace`` is atomic
only within one file system.
"""

from __future__ import annotations

import os
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

#: Permissions of a finished file (``mkstemp`` creates files readable by their owner only).
FILE_MODE = 0o644


@contextmanager
def atomic_path(path: str | os.PathLike) -> Iterator[Path]:
    """Yield a temporary path beside ``path``; on success rename it to ``path``.

    The caller writes the whole file to the yielded path (any library that takes a file name
    works: matplotlib, rerun, open()). If the block raises, the temporary file is removed and
    ``path`` is left as it was. Missing parent folders are created.
    """
    target = Path(path)
    target.parent.mkdir(parents=True, exist_ok=True)
    handle, temporary = tempfile.mkstemp(dir=target.parent, prefix=f".{target.name}.",
                                         suffix=".tmp")
    os.close(handle)
    temporary = Path(temporary)
    try:
        yield temporary
        os.chmod(temporary, FILE_MODE)
        os.replace(temporary, target)
    finally:
        temporary.unlink(missing_ok=True)


def remove_stale_temporaries(folder: str | os.PathLike) -> None:
    """Remove the temporary files :func:`atomic_path` left in ``folder`` (not below it) when a
    process writing there was killed outright (SIGKILL, a power cut), which no ``finally``
    survives. Call it only while no other process writes into ``folder``."""
    for path in Path(folder).glob(".*.tmp"):
        if path.is_file():
            path.unlink(missing_ok=True)


def write_text_atomic(path: str | os.PathLike, text: str) -> Path:
    """Write ``text`` (UTF-8) to ``path`` atomically; returns the path."""
    with atomic_path(path) as temporary:
        temporary.write_text(text, encoding="utf-8")
    return Path(path)



def check_output_path(path: str | os.PathLike, option: str = "--out") -> Path:
    """``path`` as a Path, or ValueError (one line) when it exists and is not a folder; makes
    nothing, so that a command with two output folders can check both before making either."""
    folder = Path(path)
    try:
        exists = folder.exists()
    except OSError as error:  # a name longer than the system allows, say
        raise ValueError(f"{option} {folder}: cannot be looked up ({error.strerror or error}); "
                         "accepted: a folder this user can create and write") from None
    if exists and not folder.is_dir():
        raise ValueError(f"{option} {folder}: exists and is not a folder; accepted: a folder "
                         "(created if missing)")
    return folder


def prepare_output_dir(path: str | os.PathLike, option: str = "--out") -> Path:
    """Create the output folder ``path`` and prove it writable, before any work starts.

    A run that finds an unwritable folder only at its first write loses all the simulation
    before it; this check moves that failure to the start. Raises ValueError with one line
    naming the folder, the problem and what is accepted.
    """
    folder = check_output_path(path, option)
    try:
        folder.mkdir(parents=True, exist_ok=True)
        handle, probe = tempfile.mkstemp(dir=folder, prefix=".write-test.", suffix=".tmp")
        os.close(handle)
        os.unlink(probe)
    except OSError as error:
        raise ValueError(f"{option} {folder}: cannot write there ({error.strerror or error}); "
                         "accepted: a folder this user can create and write") from None
    return folder


#: The lock file of a folder in use (:func:`folder_in_use`).
LOCK_FILE = ".egostab.lock"


@contextmanager
def folder_in_use(path: str | os.PathLike, option: str = "--out") -> Iterator[None]:
    """Hold ``path`` for this process while the block runs: a second command asking for it
    (another sweep or suite writing the same runs) is refused with a ValueError of one line,
    instead of recording over the first one's files. An exclusive ``flock`` on a lock file in
    the folder, released (and the file removed) at the end, also on an interrupt; the system
    releases it when the process dies."""
    import fcntl

    lock_path = Path(path) / LOCK_FILE
    handle = open(lock_path, "a+", encoding="utf-8")
    try:
        fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        handle.close()
        raise ValueError(f"{option} {path}: in use by another egostab command; accepted: "
                         f"another folder, or this one once that command has ended") from None
    try:
        yield
    finally:
        lock_path.unlink(missing_ok=True)
        fcntl.flock(handle, fcntl.LOCK_UN)
        handle.close()
