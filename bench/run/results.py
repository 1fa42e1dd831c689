"""The run folder's results tables: ``results.csv`` and ``results.parquet``, written from the cell records' typed
rows (:class:`~bench.run.row.ResultRow`) and read back as one typed frame.

Both are copies of the cell records (:mod:`bench.run.store`), written at checkpoints
(:mod:`bench.run.checkpoints`).  Readers of the results table (``compare``, ``table``, the report) go through
:func:`read_results`: the parquet file when it matches results.csv (it records the CSV's SHA-1), else results.csv
(a folder of an older suite version, or a CSV rewritten since), typed the same way.
"""

from __future__ import annotations

import csv
import hashlib
import io
import math
from pathlib import Path
from typing import Any

import numpy as np

from geometry.files import atomic_path
from phantoms import InputError

from .row import ID_COLUMNS, JSON_ONLY, RUNNER_COLUMNS, TAIL_COLUMNS, TEXT_COLUMNS, ResultRow
from .row import COLUMN_KINDS as _ID_KINDS
from .store import write_atomic

__all__ = ["RESULTS_CSV", "RESULTS_PARQUET", "result_columns", "write_results_csv", "results_table", "read_results",
           "column_kind", "frame_of"]

RESULTS_CSV = "results.csv"
RESULTS_PARQUET = "results.parquet"


# ---------------------------------------------------------------------------------------------- results.csv
def _dicts(rows: list[ResultRow]) -> list[dict]:
    """The rows' dict forms (:meth:`ResultRow.to_dict`): the one place the store turns rows into text."""
    try:
        return [r.to_dict() for r in rows]
    except AttributeError:
        raise TypeError("the store writes ResultRow rows (ResultRow.from_dict reads a dict)") from None


def result_columns(rows: list[ResultRow]) -> list[str]:
    """ID columns, every registered metric (in registry order, then any further keys the rows carry, e.g. a
    plug-in's info), the runner's columns, then status and error."""
    return _columns(_dicts(rows))


def _columns(rows: list[dict]) -> list[str]:
    """:func:`result_columns` of the rows' dict forms."""
    from bench.metrics import METRIC_NAMES

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


def write_results_csv(out: Path, order: list[str], records: dict[str, dict]) -> Path:
    """Write ``results.csv``, then ``results.parquet`` recording the CSV's SHA-1: a row per finished cell.

    Parameters
    ----------
    out : Path
        The run folder.
    order : list of str
        The grid's cell ids (:attr:`~bench.run.contracts.Cell.cell_id`) in grid order; rows follow it.
    records : dict
        ``{cell_id: record}`` of the finished cells, each row a :class:`~bench.run.row.ResultRow`
        (:func:`scan_cells`, the runner's records).

    Returns
    -------
    Path
        The CSV file.
    """
    rows = _dicts([records[cid]["row"] for cid in order if cid in records])
    cols = _columns(rows)
    path = Path(out) / RESULTS_CSV
    data = _csv_text(cols, rows).encode("utf-8")
    write_atomic(path, data)
    _write_parquet(Path(out) / RESULTS_PARQUET, _table(rows, cols), hashlib.sha1(data).hexdigest())
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


def results_table(rows: list[ResultRow], cols: list[str] | None = None):
    """The rows as a :class:`pyarrow.Table` with one typed column each (``cols``: default
    :func:`result_columns`); NaN stays NaN, a missing value is null, an empty text stays empty."""
    return _table(_dicts(rows), cols)


def _table(rows: list[dict], cols: list[str] | None = None):
    """:func:`results_table` of the rows' dict forms."""
    import pyarrow as pa

    cols = _columns(rows) if cols is None else cols
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
