"""sim.atomic: a file is replaced whole or not at all."""

import os
import stat

import pytest

from sim.atomic import (LOCK_FILE, atomic_path, check_output_path, folder_in_use,
                        prepare_output_dir, remove_stale_temporaries, write_text_atomic)


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


def test_missing_folders_are_made_at_any_depth(tmp_path):
    target = write_text_atomic(tmp_path / "a" / "b" / "c" / "file.txt", "deep")
    assert target.read_text() == "deep"


def test_an_output_path_is_checked_without_making_anything(tmp_path):
    missing = tmp_path / "runs" / "new"
    assert check_output_path(missing) == missing and not missing.parent.exists()
    assert check_output_path(tmp_path) == tmp_path
    a_file = tmp_path / "file.txt"
    a_file.write_text("")
    with pytest.raises(ValueError, match="--runs .*file.txt: exists and is not a folder"):
        check_output_path(a_file, "--runs")


def test_an_output_folder_is_made_at_any_depth_and_left_empty(tmp_path):
    folder = prepare_output_dir(tmp_path / "a" / "b")
    assert folder.is_dir() and os.listdir(folder) == []
    assert prepare_output_dir(folder) == folder  # an existing folder is fine


def test_a_folder_in_use_is_refused_to_a_second_holder_and_freed_after(tmp_path):
    with folder_in_use(tmp_path):
        assert (tmp_path / LOCK_FILE).exists()
        with pytest.raises(ValueError, match="in use by another egostab command"):
            with folder_in_use(tmp_path):
                pass
    assert not (tmp_path / LOCK_FILE).exists()
    with folder_in_use(tmp_path):  # free again
        pass
