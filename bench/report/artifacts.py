"""Reading the arrays a run's cells stored for the report (``cells/<cell_id>.npz``)."""

from __future__ import annotations

import zipfile
from pathlib import Path

import numpy as np

from ..run.store import CELLS_DIR

__all__ = ["Artifacts"]


class Artifacts:
    """Lazy, cached access to the ``cells/<cell_id>.npz`` arrays of a run folder."""

    def __init__(self, out: Path, warn=None) -> None:
        self.dir = Path(out) / CELLS_DIR
        self._cache: dict[str, dict | None] = {}
        self.warn = warn

    def get(self, cid: str) -> dict | None:
        """Every array of the cell (None when it stored none or the file is unreadable)."""
        if cid not in self._cache:
            p = self.dir / f"{cid}.npz"
            try:
                with np.load(p, allow_pickle=False) as z:
                    self._cache[cid] = {k: z[k] for k in z.files}
            except FileNotFoundError:
                self._cache[cid] = None
            except Exception as exc:  # a truncated or corrupt archive: BadZipFile, zlib.error, EOFError, ...
                self._cache[cid] = None
                if self.warn is not None:
                    self.warn(f"{p} does not load ({type(exc).__name__}); the report draws no picture of the cell")
        return self._cache[cid]

    def has_snapshots(self, cid: str) -> bool:
        """Whether the cell kept meshes of intermediate iterations (read from the archive's index only)."""
        if cid in self._cache:
            a = self._cache[cid]
            return a is not None and "snapshot_iterations" in a
        try:
            with zipfile.ZipFile(self.dir / f"{cid}.npz") as z:
                return "snapshot_iterations.npy" in z.namelist()
        except Exception:  # missing, truncated or corrupt: no snapshots
            return False

    def snapshot_iterations(self, cid: str) -> list[int]:
        a = self.get(cid)
        if a is None or "snapshot_iterations" not in a:
            return []
        return [int(i) for i in a["snapshot_iterations"]]

    def mesh(self, cid: str, iteration: int | None = None):
        """(vertices, faces, H, None) of the final mesh (``iteration`` None) or of a kept snapshot; None if
        not stored."""
        a = self.get(cid)
        if a is None or "vertices" not in a:
            return None
        if iteration is None:
            return a["vertices"], a["faces"], a.get("H"), None
        if iteration in self.snapshot_iterations(cid):
            v = a[f"snap{iteration}_vertices"]
            f = a.get(f"snap{iteration}_faces", a["faces"])
            H = a.get(f"snap{iteration}_H")
            if H is None and "spacing" in a:   # fitted here, for the snapshots a table draws
                from ..run.cell import vertex_mean_curvature

                H = a[f"snap{iteration}_H"] = vertex_mean_curvature(v, f, float(a["spacing"]))
            return v, f, H, None
        return None

    def energy(self, cid: str):
        a = self.get(cid)
        return None if a is None else a.get("energy_history")
