"""The run folder's contract: what is written where, written atomically, read back the same way.

A run folder ``DIR`` holds::

    config.json            the run's config (what ``--resume`` reruns)
    run.json               provenance and sessions (bench.run.runner)
    cells/<cell_id>.json   one finished cell: its results.csv row, the cell, the traceback of a failure
    cells/<cell_id>.npz    its arrays: mesh, per-vertex H, energy history, snapshots (written first)
    results.csv            one row per finished cell, in grid order (written at checkpoints: bench.run.checkpoints)
    results.parquet        the same table with typed columns (bool / int / float / string), written with it
    meshes/<cell_id>.ply   with --save-meshes
    cache/                 clean phantom volumes shared by the cells (removed when the run is complete)
    index.html             the report (bench.report), rendered from the files above

A cell's ``.json`` is written last, so its presence marks the cell done.  Every file is written to a hidden
temporary name in the same folder and renamed into place, so a reader never sees half a file.

The two results tables are written and read by :mod:`bench.run.results`.  The cell records are the truth:
``report``, ``table`` and ``compare`` first check both tables against them (:mod:`bench.run.audit`).
"""

from __future__ import annotations

import datetime as _dt
import json
import os
from pathlib import Path
from typing import Any

import numpy as np

from geometry.files import TMP_GLOB, WriteError, atomic_path, atomic_write, remove_temp_files
from phantoms import InputError

from .contracts import Cell, CellResult
from .integrity import record_problem, seal
from .row import ResultRow
from .values import plain

__all__ = [
    "CELLS_DIR", "MESHES_DIR", "CACHE_DIR", "atomic_path", "write_atomic", "save_cell", "load_cells",
    "check_output_dir", "write_json", "read_json", "scan_cells", "clean_temp_files", "TMP_GLOB",
]

CELLS_DIR = "cells"
MESHES_DIR = "meshes"
CACHE_DIR = "cache"

# The columns (ID_COLUMNS, RUNNER_COLUMNS, TAIL_COLUMNS, TEXT_COLUMNS) are the ResultRow's: bench/run/row.py.
#: how :func:`scan_cells` ends the problem of a record file that is no cell's record
IGNORED = "ignored"


# ---------------------------------------------------------------------------------------------- atomic writes
def write_atomic(path: str | Path, data: bytes | str) -> Path:
    """Write ``data`` (bytes, or text as UTF-8) to ``path`` atomically (fsynced: run-folder files are small)."""
    return atomic_write(path, data, fsync=True)


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
    with atomic_path(path, fsync=compressed) as tmp:
        (np.savez_compressed if compressed else np.savez)(tmp, **arrays)
    return Path(path)


# ---------------------------------------------------------------------------------------------- the folder
def check_output_dir(out: Path, resume: bool) -> None:
    """Create ``out`` and make sure it is writable and that its ``cells`` / ``meshes`` / ``cache`` entries, where
    present, are folders; refuse to mix a new run into an old one."""
    try:
        out.mkdir(parents=True, exist_ok=True)
        probe = out / f".write-test-{os.getpid()}"
        probe.write_bytes(b"")
        probe.unlink()
    except OSError as exc:
        raise InputError(f"output folder {str(out)!r} is not writable: {exc.strerror or exc}") from None
    for sub in (CELLS_DIR, MESHES_DIR, CACHE_DIR):      # the run's own folders: a file in the way of one is named
        if (out / sub).exists() and not (out / sub).is_dir():
            raise InputError(f"{str(out / sub)!r} is not a folder (the run keeps its {sub} there): move it away "
                             "or choose another --out")
    from .lock import RunLock

    RunLock(out).check()  # another live run owns the folder: say whose, before anything else
    if not resume and any((out / CELLS_DIR).glob("[!.]*.json")):  # (not the hidden temp files)
        raise InputError(f"output folder {str(out)!r} already holds a run; use --resume to complete it or "
                         "choose another --out")


def _mkdir(folder: Path) -> Path:
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise WriteError(folder, exc.strerror or str(exc)) from None
    return folder


def save_cell(out: Path, cell: Cell, result: CellResult, save_meshes: bool = False,
              code: dict | None = None) -> dict:
    """Write one finished cell: artifacts (``.npz``) first, then the row (``.json``, which marks it done and
    lists the arrays the ``.npz`` must hold, and the suite ``code`` that computed it).  The record holds plain
    dicts (:meth:`Cell.to_dict`): the storage boundary of the stage contracts.  Returns the record's seal (its
    ``checksum``), which the runner keeps to tell its own records from any other file."""
    if not isinstance(cell, Cell) or not isinstance(result, CellResult):
        raise TypeError(f"save_cell takes a Cell and a CellResult, not {type(cell).__name__} and "
                        f"{type(result).__name__}")
    cells_dir = _mkdir(Path(out) / CELLS_DIR)
    cid = cell.cell_id
    art = result.artifacts
    if art:
        save_npz(cells_dir / f"{cid}.npz", art)
        if save_meshes and "vertices" in art:
            import trimesh

            _mkdir(Path(out) / MESHES_DIR)
            mesh = trimesh.Trimesh(np.asarray(art["vertices"], float), np.asarray(art["faces"]), process=False)
            write_atomic(Path(out) / MESHES_DIR / f"{cid}.ply", mesh.export(file_type="ply"))
    record = {"row": result.row.to_dict(), "cell": cell.to_dict(), "traceback": result.traceback,
              "artifacts": sorted(art), "code": code,
              "finished": _dt.datetime.now().astimezone().isoformat(timespec="seconds")}
    sealed = seal(record, cells_dir / f"{cid}.npz" if art else None)
    write_json(cells_dir / f"{cid}.json", sealed)
    return sealed["checksum"]


def scan_cells(out: Path, verify_artifacts: bool = False) -> tuple[dict[str, dict], list[str]]:
    """``({cell_id: record}, problems)`` of the finished cells in ``out/cells``.

    A record that does not load, is not named after the cell it claims (a stray copy: ignored), or
    (``verify_artifacts``) whose seal is missing or broken or whose ``.npz`` is missing or does not load with
    every array the record lists, is left out and described in ``problems`` — such a cell is not done.
    """
    records: dict[str, dict] = {}
    problems: list[str] = []
    cells_dir = Path(out) / CELLS_DIR
    if not cells_dir.is_dir():
        return records, problems
    for p in sorted(cells_dir.glob("*.json")):
        if p.name.startswith("."):
            continue
        try:
            rec = json.loads(p.read_text())
            cid = rec["row"]["cell_id"]
            if not isinstance(rec["row"], dict) or not isinstance(cid, str):
                raise TypeError("not a cell record")
        except (OSError, ValueError, KeyError, TypeError, IndexError) as exc:
            problems.append(f"{p} is unreadable ({type(exc).__name__}: {exc})")
            continue
        if p.stem != cid:
            problems.append(f"{p} claims cell {cid}, whose record is {cid}.json (a stray record: {IGNORED})")
            continue
        if verify_artifacts:
            err = _artifact_problem(cells_dir / f"{cid}.npz", rec.get("artifacts"))
            if err:
                problems.append(f"{cells_dir / (cid + '.npz')} {err}")
                continue
            err = record_problem(rec, cells_dir / f"{cid}.npz")
            if err is not None:
                problems.append(f"{p} {err}")
                continue
        rec["row"] = ResultRow.from_dict(rec["row"])    # converted once, here (keys of other versions kept)
        records[cid] = rec
    return records, problems


def _artifact_problem(path: Path, expected: list | None) -> str | None:
    """Why the cell's ``.npz`` is not what its record says (None: fine).  ``expected`` None: an older record
    that does not list its arrays — then an existing file must still load."""
    if not path.exists():
        return "is missing" if expected else None
    try:
        with np.load(path, allow_pickle=False) as z:
            for k in z.files:  # reading every array checks each member's CRC
                z[k]
            missing = sorted(set(expected or ()) - set(z.files))
    except Exception as exc:  # BadZipFile, zlib.error, EOFError, OSError, ValueError ...
        return f"does not load ({type(exc).__name__}: {exc})"
    return f"lacks arrays {missing}" if missing else None


def load_cells(out: Path) -> dict[str, dict]:
    """``{cell_id: record}`` of every finished cell in ``out/cells`` (unreadable files are skipped).

    Parameters
    ----------
    out : Path
        The run folder.
    """
    return scan_cells(out)[0]


def clean_temp_files(out: Path) -> list[Path]:
    """Remove temporary files left by killed writers in the run folder and its ``cells``, ``cache`` and
    ``meshes`` (call it holding the folder's lock)."""
    out = Path(out)
    return [p for d in (out, out / CELLS_DIR, out / CACHE_DIR, out / MESHES_DIR) for p in remove_temp_files(d)]
