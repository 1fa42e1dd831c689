"""The run folder's contract: what is written where, written atomically, read back the same way.

A run folder ``DIR`` holds::

    config.json            the run's config (what ``--resume`` reruns)
    run.json               provenance and sessions (bench.run.runner)
    cells/<cell_id>.json   one finished cell: its results.csv row, the cell, the traceback of a failure
    cells/<cell_id>.npz    its arrays: mesh, per-vertex H, energy history, snapshots (written first)
    results.csv            one row per finished cell, in grid order (rewritten after every cell)
    meshes/<cell_id>.ply   with --save-meshes
    cache/                 clean phantom volumes shared by the cells (removed when the run is complete)
    index.html             the report (bench.report), rendered from the files above

A cell's ``.json`` is written last, so its presence marks the cell done.  Every file is written to a hidden
temporary name in the same folder and renamed into place, so a reader never sees half a file.
"""

from __future__ import annotations

import csv
import datetime as _dt
import json
import math
import os
from contextlib import contextmanager
from pathlib import Path
from typing import Any, Iterator

import numpy as np

from phantoms import InputError

from .values import plain

__all__ = [
    "CELLS_DIR", "MESHES_DIR", "CACHE_DIR", "ID_COLUMNS", "RUNNER_COLUMNS", "TAIL_COLUMNS",
    "atomic_path", "write_atomic", "save_cell", "load_cells", "result_columns", "write_results_csv",
    "check_output_dir", "write_json", "read_json",
]

CELLS_DIR = "cells"
MESHES_DIR = "meshes"
CACHE_DIR = "cache"

#: the leading columns of results.csv (then every metric, then the runner's columns, then the tail)
ID_COLUMNS = ["cell_id", "phantom", "variant", "N", "noise", "snr_requested", "snr_achieved", "seed",
              "method", "label", "parameters"]
#: columns the runner fills from the method's info and the cost measurement
RUNNER_COLUMNS = ["iterations", "energy_final", "stop_reason", "wall_s", "peak_mem_mb"]
TAIL_COLUMNS = ["flags", "status", "error"]
#: row keys kept in the cell's json but not in results.csv
_NOT_IN_CSV = ("cell_s", "artifact_error", "method_info")


# ---------------------------------------------------------------------------------------------- atomic writes
@contextmanager
def atomic_path(path: str | Path) -> Iterator[Path]:
    """A temporary path beside ``path`` (same suffix) that replaces ``path`` when the block succeeds and is
    removed when it fails."""
    path = Path(path)
    tmp = path.with_name(f".{path.stem}.{os.getpid()}.tmp{path.suffix}")
    try:
        yield tmp
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


def write_atomic(path: str | Path, data: bytes | str) -> Path:
    """Write ``data`` (bytes, or text as UTF-8) to ``path`` atomically."""
    with atomic_path(path) as tmp:
        tmp.write_bytes(data.encode("utf-8") if isinstance(data, str) else data)
    return Path(path)


def write_json(path: str | Path, obj: Any) -> Path:
    """``obj`` as indented JSON (numpy values made plain, NaN kept), written atomically."""
    return write_atomic(path, json.dumps(obj, indent=1, default=plain, allow_nan=True))


def read_json(path: str | Path, default: Any = None) -> Any:
    """The JSON in ``path``, or ``default`` when it is missing or unreadable."""
    try:
        return json.loads(Path(path).read_text())
    except (OSError, ValueError):
        return default


def save_npz(path: str | Path, arrays: dict, compressed: bool = True) -> Path:
    """Arrays as an ``.npz`` file, written atomically."""
    with atomic_path(path) as tmp:
        (np.savez_compressed if compressed else np.savez)(tmp, **arrays)
    return Path(path)


# ---------------------------------------------------------------------------------------------- the folder
def check_output_dir(out: Path, resume: bool) -> None:
    """Create ``out`` and make sure it is writable; refuse to mix a new run into an old one."""
    try:
        out.mkdir(parents=True, exist_ok=True)
        probe = out / f".write-test-{os.getpid()}"
        probe.write_bytes(b"")
        probe.unlink()
    except OSError as exc:
        raise InputError(f"output folder {str(out)!r} is not writable: {exc.strerror or exc}") from None
    if not resume and any((out / CELLS_DIR).glob("*.json")):
        raise InputError(f"output folder {str(out)!r} already holds a run; use --resume to complete it or "
                         "choose another --out")


def save_cell(out: Path, cell: dict, result: dict, save_meshes: bool = False) -> None:
    """Write one finished cell: artifacts (``.npz``) first, then the row (``.json``, which marks it done)."""
    cells_dir = Path(out) / CELLS_DIR
    cells_dir.mkdir(parents=True, exist_ok=True)
    cid = cell["cell_id"]
    art = result.get("artifacts") or {}
    if art:
        save_npz(cells_dir / f"{cid}.npz", art)
        if save_meshes and "vertices" in art:
            import trimesh

            (Path(out) / MESHES_DIR).mkdir(exist_ok=True)
            mesh = trimesh.Trimesh(np.asarray(art["vertices"], float), np.asarray(art["faces"]), process=False)
            write_atomic(Path(out) / MESHES_DIR / f"{cid}.ply", mesh.export(file_type="ply"))
    record = {"row": result["row"], "cell": cell, "traceback": result.get("traceback"),
              "finished": _dt.datetime.now().astimezone().isoformat(timespec="seconds")}
    write_json(cells_dir / f"{cid}.json", record)


def load_cells(out: Path) -> dict[str, dict]:
    """``{cell_id: record}`` of every finished cell in ``out/cells`` (unreadable files are skipped)."""
    records = {}
    cells_dir = Path(out) / CELLS_DIR
    if not cells_dir.is_dir():
        return records
    for p in sorted(cells_dir.glob("*.json")):
        if p.name.startswith("."):
            continue
        try:
            rec = json.loads(p.read_text())
            records[rec["row"]["cell_id"]] = rec
        except (OSError, ValueError, KeyError, TypeError):
            continue
    return records


# ---------------------------------------------------------------------------------------------- results.csv
def result_columns(rows: list[dict]) -> list[str]:
    """ID columns, every registered metric (in registry order, then any further keys the rows carry, e.g. a
    plug-in's info), the runner's columns, then status and error."""
    from bench.metrics import METRIC_NAMES

    tail = set(TAIL_COLUMNS) | set(ID_COLUMNS)
    cols = list(ID_COLUMNS)
    for name in METRIC_NAMES:
        if name not in tail and name not in cols:
            cols.append(name)
    extra = []
    for r in rows:
        for k in r:
            if k not in cols and k not in tail and k not in extra and k not in _NOT_IN_CSV:
                extra.append(k)
    cols += [k for k in extra if k not in RUNNER_COLUMNS]
    cols += [k for k in RUNNER_COLUMNS if k not in cols]
    return cols + TAIL_COLUMNS


def _csv_value(v: Any) -> Any:
    if v is None:
        return ""
    if isinstance(v, float):
        return repr(v) if math.isfinite(v) else str(v)
    return v


def write_results_csv(out: Path, cells: list[dict], records: dict[str, dict]) -> Path:
    """``results.csv``: one row per finished cell of the grid, in grid order."""
    rows = [records[c["cell_id"]]["row"] for c in cells if c["cell_id"] in records]
    cols = result_columns(rows)
    path = Path(out) / "results.csv"
    with atomic_path(path) as tmp:
        with open(tmp, "w", newline="") as fh:
            w = csv.writer(fh)
            w.writerow(cols)
            for r in rows:
                w.writerow([_csv_value(r.get(c)) for c in cols])
    return path
