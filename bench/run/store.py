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

Readers of the results table (``compare``, ``table``, the report) go through :func:`read_results`: the parquet
file when it matches results.csv (it records the CSV's SHA-1), else results.csv (a folder of an older suite
version, or a CSV rewritten since), typed the same way.  The cell records are the truth: ``report``, ``table``
and ``compare`` first check both tables against them (:mod:`bench.run.audit`).
"""

from __future__ import annotations

import csv
import datetime as _dt
import hashlib
import io
import json
import math
import os
from pathlib import Path
from typing import Any

import numpy as np

from geometry.files import TMP_GLOB, WriteError, atomic_path, atomic_write, remove_temp_files
from phantoms import InputError

from .contracts import Cell, CellResult
from .grid import as_cell
from .integrity import record_problem, seal
from .row import ID_COLUMNS, JSON_ONLY, RUNNER_COLUMNS, TAIL_COLUMNS, TEXT_COLUMNS, ResultRow
from .row import COLUMN_KINDS as _ID_KINDS
from .values import plain

__all__ = [
    "CELLS_DIR", "MESHES_DIR", "CACHE_DIR", "ID_COLUMNS", "RUNNER_COLUMNS", "TAIL_COLUMNS",
    "RESULTS_CSV", "RESULTS_PARQUET", "TEXT_COLUMNS", "atomic_path", "write_atomic", "save_cell", "load_cells",
    "result_columns", "write_results_csv", "results_table", "read_results", "column_kind",
    "check_output_dir", "write_json", "read_json", "scan_cells", "clean_temp_files", "TMP_GLOB",
    "frame_of",
]

CELLS_DIR = "cells"
MESHES_DIR = "meshes"
CACHE_DIR = "cache"
RESULTS_CSV = "results.csv"
RESULTS_PARQUET = "results.parquet"

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
    """Create ``out`` and make sure it is writable; refuse to mix a new run into an old one."""
    try:
        out.mkdir(parents=True, exist_ok=True)
        probe = out / f".write-test-{os.getpid()}"
        probe.write_bytes(b"")
        probe.unlink()
    except OSError as exc:
        raise InputError(f"output folder {str(out)!r} is not writable: {exc.strerror or exc}") from None
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


def save_cell(out: Path, cell: Cell | dict, result: CellResult | dict, save_meshes: bool = False,
              code: dict | None = None) -> dict:
    """Write one finished cell: artifacts (``.npz``) first, then the row (``.json``, which marks it done and
    lists the arrays the ``.npz`` must hold, and the suite ``code`` that computed it).  The record holds plain
    dicts (:meth:`Cell.to_dict`): the storage boundary of the stage contracts.  Returns the record's seal (its
    ``checksum``), which the runner keeps to tell its own records from any other file."""
    cell = as_cell(cell)
    result = result if isinstance(result, CellResult) else CellResult.from_dict(result)
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


# ---------------------------------------------------------------------------------------------- results.csv
def _dicts(rows: "list[ResultRow | dict]") -> list[dict]:
    """The rows' dict forms (:meth:`ResultRow.to_dict`; a dict row as it is)."""
    return [r.to_dict() if isinstance(r, ResultRow) else r for r in rows]


def result_columns(rows: "list[ResultRow | dict]") -> list[str]:
    """ID columns, every registered metric (in registry order, then any further keys the rows carry, e.g. a
    plug-in's info), the runner's columns, then status and error."""
    from bench.metrics import METRIC_NAMES

    rows = _dicts(rows)

    tail = set(TAIL_COLUMNS) | set(ID_COLUMNS)
    cols = list(ID_COLUMNS)
    for name in METRIC_NAMES:
        if name not in tail and name not in cols:
            cols.append(name)
    extra = []
    for r in rows:
        for k in r:
            if k not in cols and k not in tail and k not in extra and k not in JSON_ONLY:
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


def _csv_text(cols: list[str], rows: list[dict]) -> str:
    buf = io.StringIO(newline="")
    w = csv.writer(buf)
    w.writerow(cols)
    for r in rows:
        w.writerow([_csv_value(r.get(c)) for c in cols])
    return buf.getvalue()


def write_results_csv(out: Path, cells: "list[Cell | dict]", records: dict[str, dict]) -> Path:
    """Write ``results.csv``, then ``results.parquet`` recording the CSV's SHA-1: a row per finished cell.

    Parameters
    ----------
    out : Path
        The run folder.
    cells : list of Cell
        The grid's cells (or their dict forms); rows follow their order.
    records : dict
        ``{cell_id: record}`` of the finished cells (:func:`load_cells`).

    Returns
    -------
    Path
        The CSV file.
    """
    ids = [c.cell_id if isinstance(c, Cell) else c["cell_id"] for c in cells]
    rows = _dicts([records[cid]["row"] for cid in ids if cid in records])
    cols = result_columns(rows)
    path = Path(out) / RESULTS_CSV
    data = _csv_text(cols, rows).encode("utf-8")
    write_atomic(path, data)
    _write_parquet(Path(out) / RESULTS_PARQUET, results_table(rows, cols), hashlib.sha1(data).hexdigest())
    return path


# ---------------------------------------------------------------------------------------------- typed table
#: the parquet file's metadata key holding the SHA-1 of the results.csv written with it
_CSV_SHA1 = b"levelset-bench.results_csv_sha1"
_INFERRED = {"boolean": "bool", "integer": "int", "floating": "float", "mixed-integer-float": "float",
             "decimal": "float", "empty": "float"}


def column_kind(name: str, values: list) -> str:
    """``"bool"``, ``"int"``, ``"float"`` or ``"string"``: the registry's dtype for a metric, fixed kinds for
    the identifying columns, what the values are for any other column (a plug-in's info)."""
    from bench.metrics.registry import METRICS

    if name in TEXT_COLUMNS:
        return "string"
    if name in _ID_KINDS:
        return _ID_KINDS[name]
    if name in METRICS:
        return METRICS[name].dtype
    import pandas as pd

    return _INFERRED.get(pd.api.types.infer_dtype(values, skipna=True), "string")


def _missing(v: Any) -> bool:
    return v is None or (isinstance(v, float) and math.isnan(v))


def _number(v: Any) -> float | None:
    if v is None or isinstance(v, str) and not v.strip():
        return None
    try:
        return float(v)
    except (TypeError, ValueError):
        return None


def _boolean(v: Any) -> bool | None:
    if _missing(v):
        return None
    if isinstance(v, str):
        return {"true": True, "1": True, "1.0": True, "yes": True,
                "false": False, "0": False, "0.0": False, "no": False}.get(v.strip().lower())
    return bool(v)


def _arrow_column(values: list, kind: str):
    import pyarrow as pa

    if kind == "bool":
        return pa.array([_boolean(v) for v in values], pa.bool_())
    if kind == "int":
        nums = [_number(v) for v in values]
        nums = [None if x is None or math.isnan(x) else x for x in nums]
        if all(x is None or (math.isfinite(x) and x.is_integer()) for x in nums):
            return pa.array([None if x is None else int(x) for x in nums], pa.int64())
        kind = "float"  # a non-integral value in an integer column is kept, not truncated
    if kind == "float":
        return pa.array([_number(v) for v in values], pa.float64())
    return pa.array([None if _missing(v) else str(v) for v in values], pa.string())


def results_table(rows: "list[ResultRow | dict]", cols: list[str] | None = None):
    """The rows as a :class:`pyarrow.Table` with one typed column each (``cols``: default
    :func:`result_columns`); NaN stays NaN, a missing value is null, an empty text stays empty."""
    import pyarrow as pa

    rows = _dicts(rows)
    cols = result_columns(rows) if cols is None else cols
    arrays = {}
    for c in cols:
        values = [r.get(c) for r in rows]
        arrays[c] = _arrow_column(values, column_kind(c, values))
    return pa.table(arrays)


def _write_parquet(path: Path, table, csv_sha1: str) -> None:
    import pyarrow.parquet as pq

    table = table.replace_schema_metadata({**(table.schema.metadata or {}), _CSV_SHA1: csv_sha1.encode()})
    with atomic_path(path, fsync=True) as tmp:
        pq.write_table(table, tmp)


def _read_parquet(path: Path, csv_path: Path):
    """The parquet table, or None when it is missing, unreadable or not the one written with results.csv."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    if not path.is_file():
        return None
    try:
        table = pq.read_table(path)
        if csv_path.is_file():
            recorded = (table.schema.metadata or {}).get(_CSV_SHA1, b"").decode()
            if recorded != hashlib.sha1(csv_path.read_bytes()).hexdigest():
                return None  # results.csv was rewritten since (an older suite version, an edit): it wins
    except (OSError, pa.ArrowException, UnicodeDecodeError):
        return None
    return table


def _first_line(exc: BaseException) -> str:
    text = str(exc).strip()
    return text.splitlines()[0] if text else "empty"


def _check_csv_rows(path: Path) -> None:
    """Every record of ``path`` has the header's number of fields and the file ends with a newline (as
    :func:`write_results_csv` writes it), else an :class:`InputError` with the line number — a file cut in half
    mid-row must not be rendered as a half row (pandas pads a short row with NaN)."""
    import csv
    import io

    hint = (f"; rerun the grid with `python -m bench run --resume --out {str(path.parent)}` to rewrite it "
            "from the cell records")
    try:
        with open(path, newline="", encoding="utf-8") as fh:
            text = fh.read()
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"{str(path)!r} is not a readable results table ({type(exc).__name__}: "
                         f"{_first_line(exc)}){hint}") from None
    if not text.strip():
        return                                                    # an empty file: pandas' own message
    limit = csv.field_size_limit()
    csv.field_size_limit(max(limit, len(text)))
    try:
        reader = csv.reader(io.StringIO(text, newline=""), strict=True)
        header = next(reader)
        if not {"cell_id", "status", "label"} <= set(header):
            return                                                # not a results table: read_results says so
        for record in reader:
            if len(record) != len(header):
                raise InputError(f"{str(path)!r} line {reader.line_num}: {len(record)} fields where the header "
                                 f"has {len(header)} (a truncated or malformed results table){hint}")
    except csv.Error as exc:
        raise InputError(f"{str(path)!r} line {reader.line_num}: {exc} (a truncated or malformed results "
                         f"table){hint}") from None
    finally:
        csv.field_size_limit(limit)
    if not text.endswith("\n"):
        raise InputError(f"{str(path)!r} line {reader.line_num}: the last row does not end with a newline (a "
                         f"truncated results table){hint}")


def _read_csv_table(path: Path):
    import pandas as pd

    _check_csv_rows(path)
    try:
        df = pd.read_csv(path, keep_default_na=True)
    except (OSError, ValueError, pd.errors.ParserError, pd.errors.EmptyDataError, UnicodeDecodeError) as exc:
        raise InputError(f"{str(path)!r} is not a readable results table ({type(exc).__name__}: "
                         f"{_first_line(exc)}); rerun the grid with --resume to rewrite it") from None
    return _table_of_frame(df)


def _table_of_frame(df):
    import pyarrow as pa

    arrays = {}
    for c in df.columns:
        values = df[c].tolist()
        arrays[str(c)] = _arrow_column(values, column_kind(str(c), values))
    return pa.table(arrays)


def read_results(out: str | Path):
    """The results table of the run folder ``out`` as a :class:`pandas.DataFrame`, one row per finished cell.

    Read from ``results.parquet`` when it is the one written with ``results.csv``, else from ``results.csv``
    (typed the same way: the registry's bool / int / float columns, text columns as text).  A missing value is
    NaN in every column (as pandas reads a CSV; an integer column with one becomes float); an empty text stays
    ``""`` from the parquet file.

    Raises
    ------
    InputError
        ``out`` holds no results table, or one that does not read or lacks ``cell_id`` / ``status`` / ``label``
        (one line, naming the file).
    """
    out = Path(out)
    csv_path, pq_path = out / RESULTS_CSV, out / RESULTS_PARQUET
    if not csv_path.is_file() and not pq_path.is_file():
        raise InputError(f"{str(out)!r} is not a run folder (no {RESULTS_PARQUET} or {RESULTS_CSV} in it)")
    table = _read_parquet(pq_path, csv_path)
    path = pq_path if table is not None else csv_path
    if table is None:
        if not csv_path.is_file():
            raise InputError(f"{str(pq_path)!r} is not a readable results table; rerun the grid with --resume "
                             "to rewrite it")
        table = _read_csv_table(csv_path)
    return frame_of(table, path)


def frame_of(table, path: Path):
    """The typed ``table`` read from ``path`` as :func:`read_results` returns it (a missing value NaN in every
    column); :class:`InputError` when it lacks ``cell_id`` / ``status`` / ``label``."""
    missing = [c for c in ("cell_id", "status", "label") if c not in table.column_names]
    if missing:
        raise InputError(f"{str(path)!r} is not a results table of levelset-bench (no column "
                         f"{', '.join(missing)}); rerun the grid with --resume to rewrite it")
    df = table.to_pandas()
    for c in df.columns:
        if df[c].dtype == object:
            df[c] = df[c].where(df[c].notna(), np.nan)
    return df
