"""Output files of the single-file commands (``reconstruct``, ``volume``): checked before the work, written
atomically, and a method result that cannot be written faithfully (non-finite vertices) refused.

A write problem — no space left, permission denied, read-only file system, a directory in the way — is a
:class:`geometry.files.WriteError`: one line naming the path and the cause, exit code 2, no temporary file
left behind.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from geometry.files import atomic_path, check_writable
from methods import ReconstructionFailed

__all__ = ["check_outputs", "write_mesh", "refuse_non_finite", "FLOAT32_MAX"]

#: PLY and STL store vertex coordinates as float32: anything larger in magnitude is written as inf
FLOAT32_MAX = float(np.finfo(np.float32).max)


def check_outputs(*paths: str | Path | None) -> None:
    """Every given output path is writable (checked before a long computation)."""
    for p in paths:
        if p is not None:
            check_writable(p)


def refuse_non_finite(mesh, method: str) -> None:
    """A mesh with NaN / infinite vertex coordinates (or ones beyond the float32 range of PLY and STL, which
    become inf once written) is a failed reconstruction, as it is in the grid: nothing is written."""
    v = np.asarray(mesh.vertices, dtype=float)
    bad = ~np.isfinite(v).all(axis=1)
    with np.errstate(invalid="ignore"):
        bad |= (np.abs(v) > FLOAT32_MAX).any(axis=1)
    if bad.any():
        raise ReconstructionFailed(f"method {method!r} returned non-finite vertex coordinates ({int(bad.sum())} "
                                   f"of {len(v)} vertices NaN, infinite or beyond the float32 range); the "
                                   "method diverged — nothing written")


def write_mesh(mesh, path: str | Path, file_type: str) -> Path:
    """Write ``mesh`` to ``path`` atomically (a failed write leaves neither a partial file nor a temp file)."""
    with atomic_path(path) as tmp:
        mesh.export(tmp, file_type=file_type)
    return Path(path)
