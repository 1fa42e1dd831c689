"""Test helpers for file-system faults: a small tmpfs (a real full disk, a real read-only file system) when the
tests run as root and mounting works, else None (the tests then simulate the error with monkeypatch)."""

from __future__ import annotations

import os
import subprocess
from contextlib import contextmanager
from pathlib import Path


def _mount(*args: str) -> bool:
    try:
        return subprocess.run(["mount", *args], capture_output=True, timeout=20).returncode == 0
    except (OSError, subprocess.SubprocessError):
        return False


@contextmanager
def small_tmpfs(path: Path, size: str = "1m", read_only: bool = False):
    """Mount a tmpfs of ``size`` at ``path`` for the block (yields the path), or yield None when that is not
    possible (not root, no mount permission)."""
    path.mkdir(parents=True, exist_ok=True)
    opts = f"size={size}" + (",ro" if read_only else "")
    if os.geteuid() != 0 or not _mount("-t", "tmpfs", "-o", opts, "tmpfs", str(path)):
        yield None
        return
    try:
        yield path
    finally:
        subprocess.run(["umount", "-l", str(path)], capture_output=True, timeout=20)


def remount(path: Path, options: str) -> bool:
    """Change a mounted tmpfs's options (e.g. ``size=64m`` after a disk-full test)."""
    return _mount("-o", f"remount,{options}", str(path))


def temp_files(folder: Path) -> list[Path]:
    """Every temporary file an atomic write leaves when it is killed (``.<stem>.<pid>.tmp<suffix>``)."""
    return sorted(p for p in Path(folder).rglob(".*.tmp*"))
