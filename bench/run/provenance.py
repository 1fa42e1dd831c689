"""Where a result came from: Python and dependency versions, the suite's git commit, the machine."""

from __future__ import annotations

import os
import platform
import re
import socket
import subprocess
import sys
from importlib import metadata
from pathlib import Path

__all__ = ["environment", "git_commit", "dependency_versions", "memory_gb"]

#: the checkout the suite runs from (the folder holding bench/, methods/, ...)
SUITE_ROOT = Path(__file__).resolve().parents[2]


def git_commit() -> dict | None:
    """``{"commit": sha, "dirty": bool}`` of the suite's checkout, or None outside a git checkout."""
    try:
        commit = subprocess.run(["git", "-C", str(SUITE_ROOT), "rev-parse", "HEAD"], capture_output=True,
                                text=True, timeout=10)
        if commit.returncode != 0:
            return None
        dirty = subprocess.run(["git", "-C", str(SUITE_ROOT), "status", "--porcelain", "--untracked-files=no"],
                               capture_output=True, text=True, timeout=10)
        return {"commit": commit.stdout.strip(), "dirty": bool(dirty.stdout.strip())}
    except (OSError, subprocess.SubprocessError):
        return None


def dependency_versions() -> dict[str, str | None]:
    """Installed versions of the suite and of every dependency it declares (None: not installed)."""
    names = ["levelset-bench"]
    try:
        for req in metadata.requires("levelset-bench") or []:
            m = re.match(r"^\s*([A-Za-z0-9_.\-]+)", req)
            if m and m.group(1) not in names:
                names.append(m.group(1))
    except metadata.PackageNotFoundError:
        names += ["numpy", "scipy", "scikit-image", "trimesh", "pandas", "matplotlib", "jinja2", "tqdm"]
    out = {}
    for n in names:
        try:
            out[n] = metadata.version(n)
        except metadata.PackageNotFoundError:
            out[n] = None
    return out


def memory_gb() -> float | None:
    """Total memory of the machine in GiB (Linux), else None."""
    try:
        with open("/proc/meminfo") as fh:
            for line in fh:
                if line.startswith("MemTotal:"):
                    return round(int(line.split()[1]) / 1024 ** 2, 2)
    except OSError:
        pass
    return None


def environment() -> dict:
    """Python, dependency versions, git commit and machine facts for run.json."""
    return {
        "python": sys.version.split()[0],
        "python_implementation": platform.python_implementation(),
        "dependencies": dependency_versions(),
        "git": git_commit(),
        "machine": {
            "hostname": socket.gethostname(), "platform": platform.platform(), "machine": platform.machine(),
            "processor": platform.processor() or None, "cpu_count": os.cpu_count(), "memory_gb": memory_gb(),
        },
    }
