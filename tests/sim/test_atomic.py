"""sim.atomic: a file is replaced whole or not at all."""

import os
import stat

import pytest

from sim.atomic import atomic_path, remove_stale_temporaries, write_text_atomic


def test_atomic_write_leaves_the_old_file_when_the_writer_fails(tmp_path):
    target = tmp_path / "sub" / "file.txt"
    write_text_atomic(target, "old")
    with pytest.raises(RuntimeError):
        with atomic_path(target) as temporary:
            temporary.write_text("half")
            raise RuntimeError("crash while writing")
    assert target.read_text() == "old"
    assert os.listdir(target.parent) == ["file.txt"]


def test_a_finished_file_is_readable_by_all(tmp_path):
    target = write_text_atomic(tmp_path / "file.txt", "new")
    assert target.read_text() == "new"
    assert stat.S_IMODE(target.stat().st_mode) == 0o644


def test_stale_temporaries_are_removed_and_nothing_else(tmp_path):
    with pytest.raises(KeyboardInterrupt):
        with atomic_path(tmp_path / "file.txt") as temporary:
            temporary.write_text("half")
            kept = temporary.with_name(temporary.name + ".copy.tmp")
            kept.write_text("left by a killed writer")  # no finally removes this one
            raise KeyboardInterrupt
    (tmp_path / "results.md").write_text("kept")
    (tmp_path / "notes.tmp").write_text("a user's, not one atomic_path names")
    remove_stale_temporaries(tmp_path)
    assert sorted(os.listdir(tmp_path)) == ["notes.tmp", "results.md"]
