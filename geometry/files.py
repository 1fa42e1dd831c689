"""Writing files so that no reader ever sees half a file, and a failed write is one clear line.

Like :mod:`geometry.errors`, this is shared by every package (``phantoms.save_volume``, the run folder of
``bench``, the command line's outputs), so it lives at the bottom of the stack.

* :func:`atomic_path` yields a hidden temporary name in the target's own folder; the caller writes it, and on
  success it is (optionally fsynced and) renamed over the target with :func:`os.replace`, which is atomic on
  one file system.  On any error the temporary file is removed and an :class:`OSError` becomes a
  :class:`WriteError` naming the path and the cause (no space left, permission denied, read-only file system,
  a directory in the way, ...).
* :func:`check_writable` checks an output path *before* a long computation: the folder exists (or is created),
  a file can be created in it, and the path itself is not a directory.
* :data:`TMP_GLOB` matches the temporary names, so a crashed writer's leftovers can be found and removed.
"""

from __future__ import annotations

import os
from contextlib import contextmanager
from pathlib import Path
from typing import Iterator

from .errors import InputError

__all__ = ["WriteError", "atomic_path", "atomic_write", "check_writable", "write_error", "TMP_GLOB",
           "remove_temp_files"]

#: glob of the temporary files :func:`atomic_path` creates (``.<stem>.<pid>.tmp<suffix>``)
TMP_GLOB = ".*.tmp*"


class WriteError(InputError):
    """A file could not be written: the message names the path and the cause."""

    def __init__(self, path: str | Path, cause: str) -> None:
        self.path, self.cause = str(path), cause
        super().__init__(f"cannot write {self.path!r}: {cause}")


def write_error(path: str | Path, exc: BaseException) -> WriteError:
    """The :class:`WriteError` for ``exc`` (an :class:`OSError`'s ``strerror``, else its text)."""
    if isinstance(exc, WriteError):
        return exc
    cause = getattr(exc, "strerror", None) or str(exc) or type(exc).__name__
    return WriteError(path, cause)


def _fsync(path: Path) -> None:
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


@contextmanager
def atomic_path(path: str | Path, *, fsync: bool = False) -> Iterator[Path]:
    """A temporary path beside ``path`` (same suffix) that replaces ``path`` when the block succeeds and is
    removed when it fails; an :class:`OSError` of the block or the rename becomes a :class:`WriteError`."""
    path = Path(path)
    if path.is_dir():
        raise WriteError(path, "it is a directory")
    tmp = path.with_name(f".{path.stem}.{os.getpid()}.tmp{path.suffix}")
    try:
        yield tmp
        if fsync:
            _fsync(tmp)
        os.replace(tmp, path)
    except BaseException as exc:
        try:
            tmp.unlink(missing_ok=True)
        except OSError:
            pass
        if isinstance(exc, OSError):
            raise write_error(path, exc) from None
        raise


def atomic_write(path: str | Path, data: bytes | str, *, fsync: bool = False) -> Path:
    """Write ``data`` (bytes, or text as UTF-8) to ``path`` atomically."""
    with atomic_path(path, fsync=fsync) as tmp:
        tmp.write_bytes(data.encode("utf-8") if isinstance(data, str) else data)
    return Path(path)


def check_writable(path: str | Path) -> Path:
    """Make sure ``path`` can be written before any work is done: its folder is created if missing, a file
    can be created there, and ``path`` is not a directory.  Raises :class:`WriteError` naming the cause."""
    path = Path(path)
    if path.is_dir():
        raise WriteError(path, "it is a directory")
    for folder in path.parents:  # the nearest existing ancestor must be a folder
        if folder.exists():
            if not folder.is_dir():
                raise WriteError(path, f"{str(folder)!r} is a file, not a folder")
            break
    probe = path.with_name(f".{path.stem}.{os.getpid()}.tmp.probe")
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        probe.write_bytes(b"")
        if path.exists() and not os.access(path, os.W_OK):
            raise PermissionError(13, "Permission denied")
    except OSError as exc:
        raise write_error(path, exc) from None
    finally:
        try:
            probe.unlink(missing_ok=True)
        except OSError:
            pass
    return path


def remove_temp_files(folder: str | Path) -> list[Path]:
    """Remove the temporary files :func:`atomic_path` left in ``folder`` (a writer that was killed); returns
    them.  Only call it when no other process writes there (e.g. holding the run folder's lock)."""
    removed = []
    folder = Path(folder)
    if folder.is_dir():
        for p in folder.glob(TMP_GLOB):
            if p.is_file():
                try:
                    p.unlink()
                    removed.append(p)
                except OSError:
                    pass
    return removed
