"""geometry.files: atomic writes, output checks before work, temp-file cleanup, one-line write errors."""

from __future__ import annotations

import errno
import os

import pytest

from _fs import small_tmpfs
from geometry.files import (TMP_GLOB, WriteError, atomic_path, atomic_write, check_writable, remove_temp_files)


def test_atomic_write_replaces_whole_and_a_failure_keeps_the_old_file(tmp_path):
    target = atomic_write(tmp_path / "a.csv", "old")
    with pytest.raises(KeyError):
        with atomic_path(target) as tmp:
            assert tmp.parent == tmp_path and tmp.match(TMP_GLOB) and tmp.suffix == ".csv"
            tmp.write_text("half")
            raise KeyError("boom")                      # not an OSError: raised as it is
    assert target.read_text() == "old" and os.listdir(tmp_path) == ["a.csv"]
    atomic_write(target, b"new", fsync=True)
    assert target.read_bytes() == b"new"


@pytest.mark.parametrize("code, cause", [(errno.ENOSPC, "No space left on device"),
                                         (errno.EACCES, "Permission denied"),
                                         (errno.EROFS, "Read-only file system")])
def test_an_os_error_becomes_one_line_naming_path_and_cause(tmp_path, code, cause):
    with pytest.raises(WriteError) as err:
        with atomic_path(tmp_path / "x.npz") as tmp:
            tmp.write_bytes(b"partial")
            raise OSError(code, os.strerror(code))
    assert str(err.value) == f"cannot write '{tmp_path / 'x.npz'}': {cause}"
    assert os.listdir(tmp_path) == []                   # the temporary file is gone


def test_check_writable_before_the_work(tmp_path):
    assert check_writable(tmp_path / "new" / "deep" / "m.ply") == tmp_path / "new" / "deep" / "m.ply"
    assert (tmp_path / "new" / "deep").is_dir() and os.listdir(tmp_path / "new" / "deep") == []
    (tmp_path / "d.ply").mkdir()
    with pytest.raises(WriteError, match="it is a directory"):
        check_writable(tmp_path / "d.ply")
    (tmp_path / "file").write_text("")
    with pytest.raises(WriteError, match="file. is a file, not a folder"):
        check_writable(tmp_path / "file" / "m.ply")     # a file where a folder should be
    with small_tmpfs(tmp_path / "ro", read_only=True) as ro:
        if ro is not None:
            with pytest.raises(WriteError, match="Read-only file system"):
                check_writable(ro / "m.ply")


def test_remove_temp_files_takes_only_the_temporaries(tmp_path):
    keep = [tmp_path / "a.json", tmp_path / ".hidden", tmp_path / "b.tmp"]
    junk = [tmp_path / ".a.123.tmp.json", tmp_path / ".results.9.tmp.csv", tmp_path / ".v.1.tmp.npz"]
    for p in keep + junk:
        p.write_text("x")
    assert sorted(remove_temp_files(tmp_path)) == sorted(junk)
    assert sorted(tmp_path.iterdir()) == sorted(keep)
    assert remove_temp_files(tmp_path / "missing") == []
