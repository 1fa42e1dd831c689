"""The sealed cell records are the truth of a run folder; ``results.csv`` and ``results.parquet`` are copies.

:func:`check_run_folder` lists every way a folder departs from its sealed records (``cells/<cell_id>.json``
with its ``checksum``, :mod:`bench.run.integrity`): a record that is unreadable, unsealed, altered, or whose
``.npz`` is missing or altered; and, in each results table, a cell with no row, a row with no record, a cell with
several rows, a value that is not its record's.  ``report``, ``table`` and ``compare`` refuse such a folder
(:func:`refuse_damaged`: one line naming the cells, exit 2) — the tables are rewritten from the records by
``python -m bench run --resume --out DIR``.  A stray copy (a record file not named after the cell it claims) is
no cell's record: ignored, with a warning, never a reason to refuse.

:func:`set_aside` is the runner's end of a session: a record file it did not write (a plug-in's) is renamed
``<name>.rejected``, never accepted.  :func:`seal_unsealed` is the migration path of a folder written before
seals existed (``python -m bench report DIR --accept-unsealed``).
"""

from __future__ import annotations

import datetime as _dt
import json
import sys
from pathlib import Path

from phantoms import InputError

from .integrity import UNSEALED, record_problem, seal
from .row import as_row
from ..terminal import printable
from .store import CELLS_DIR, IGNORED, _artifact_problem, read_json, scan_cells, write_json
from .results import RESULTS_CSV, RESULTS_PARQUET, _read_csv_table, frame_of, result_columns, results_table

__all__ = ["check_run_folder", "table_problems", "refuse_damaged", "set_aside", "seal_unsealed", "REJECTED"]

REJECTED = ".rejected"   # the suffix of a record file set aside by the runner
_SHOWN = 8               # problems named in one line


def _tables(out: Path) -> list[tuple[str, object]]:
    """``[(file name, frame)]`` of results.csv and results.parquet (those present), each read on its own: a
    reader of either file must see the records' values.  :class:`InputError` for a malformed CSV (its line)."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    csv_path, pq_path = out / RESULTS_CSV, out / RESULTS_PARQUET
    if not csv_path.is_file() and not pq_path.is_file():
        raise InputError(f"{str(out)!r} is not a run folder (no {RESULTS_PARQUET} or {RESULTS_CSV} in it)")
    found = []
    if csv_path.is_file():
        found.append((RESULTS_CSV, frame_of(_read_csv_table(csv_path), csv_path)))
    if pq_path.is_file():
        try:
            table = pq.read_table(pq_path)
        except (OSError, pa.ArrowException) as exc:
            found.append((RESULTS_PARQUET, f"{RESULTS_PARQUET} does not read ({type(exc).__name__})"))
        else:
            found.append((RESULTS_PARQUET, frame_of(table, pq_path)))
    return found


def _blank(s):
    return s.isna() | (s.astype(str) == "")


def _equal(a, b):
    """Element-wise: ``a`` and ``b`` (object series of one column) hold the same value — both missing, the
    same number (to 1e-9 relative: what a CSV round trip keeps exactly) or the same text."""
    import numpy as np
    import pandas as pd

    am, bm = _blank(a).to_numpy(), _blank(b).to_numpy()
    an = pd.to_numeric(a.mask(am), errors="coerce").to_numpy(float)
    bn = pd.to_numeric(b.mask(bm), errors="coerce").to_numpy(float)
    num = ~np.isnan(an) & ~np.isnan(bn)
    close = np.zeros(len(a), bool)
    close[num] = np.isclose(an[num], bn[num], rtol=1e-9, atol=0.0)
    text = a.mask(am, "").astype(str).to_numpy() == b.mask(bm, "").astype(str).to_numpy()
    return (am & bm) | close | (text & ~num)


def _value_problems(name: str, df, records: dict[str, dict], columns: bool) -> list[str]:
    """``"<cell>: <column> is X in <name>, Y in its record"`` for each cell whose row differs from its record
    (the cells given once in ``df`` and in ``records``), and (``columns``) the columns one side lacks."""
    import pandas as pd

    ids = [c for c in df["cell_id"].astype(str) if c in records]
    rows = [as_row(records[c]["row"]) for c in ids]       # a record read here, not by scan_cells: its row a dict
    want_cols = result_columns([as_row(r["row"]) for r in records.values()])
    # a column no record carries (a metric added to the registry after this run) is not a damage of the table
    carried = {k for r in records.values() for k in as_row(r["row"]).present}
    problems = ([f"{name} lacks column {c!r}" for c in want_cols if c not in df.columns and c in carried]
                if columns else [])
    problems += [f"{name} has column {c!r}, which no record has" for c in df.columns
                 if c not in want_cols and columns]
    if not ids:
        return problems
    got = df.assign(cell_id=df["cell_id"].astype(str)).set_index("cell_id").loc[ids]
    want = frame_of(results_table(rows, want_cols), Path(name)).set_index("cell_id").loc[ids]
    diffs: dict[str, list[str]] = {}
    for c in want_cols:
        if c == "cell_id" or c not in got.columns:
            continue
        a, b = got[c].astype(object).reset_index(drop=True), want[c].astype(object).reset_index(drop=True)
        for i in (~_equal(a, b)).nonzero()[0]:
            shown = "empty" if _blank(pd.Series([a[i]], dtype=object))[0] else repr(a[i])
            diffs.setdefault(ids[i], []).append(f"{c} is {shown} in {name}, {b[i]!r} in its record")
    return problems + [f"{cid}: {'; '.join(d[:3])}" + (f" (+{len(d) - 3} more)" if len(d) > 3 else "")
                       for cid, d in diffs.items()]


def table_problems(name: str, df, records: dict[str, dict], damaged: set[str]) -> list[str]:
    """How the results table ``df`` (read from ``name``) departs from the sealed ``records``: a cell with no row,
    a row with no record (its record is missing: ``damaged`` cells, whose records are named elsewhere, aside),
    a cell with several rows, a value that is not the record's."""
    ids = df["cell_id"].astype(str).tolist()
    counts: dict[str, int] = {}
    for cid in ids:
        counts[cid] = counts.get(cid, 0) + 1
    problems = [f"{cid}: {n} rows in {name}" for cid, n in counts.items() if n > 1]
    problems += [f"{cid}: a row in {name} but no record ({CELLS_DIR}/{cid}.json is missing)"
                 for cid in counts if cid not in records and cid not in damaged]
    rowless = [cid for cid in records if cid not in counts]
    if len(rowless) > 3:                                  # a table cut short, or emptied: one entry
        problems.append(f"{len(rowless)} cells have no row in {name}: {', '.join(rowless[:3])} and "
                        f"{len(rowless) - 3} more")
    else:
        problems += [f"{cid}: no row in {name}" for cid in rowless]
    once = {cid for cid, n in counts.items() if n == 1}
    columns = bool(records) and not damaged       # (a damaged record's columns are not known)
    return problems + _value_problems(name, df[df["cell_id"].astype(str).isin(once)], records, columns)


def _warn(message: str) -> None:
    print(printable(message), file=sys.stderr)


def check_run_folder(out: str | Path, arrays: bool = True, warn=_warn) -> list[str]:
    """Every problem of the run folder ``out`` against its sealed records, each naming its cell or file:
    damaged records (``"cells/<file> <why>"``, :func:`bench.run.store.scan_cells`; ``arrays``: the ``.npz``
    files too), then each results table's departures from the valid records (:func:`table_problems`).  Empty:
    the tables are the records.  A stray copy of a record is no problem: ``warn`` (a function of one line, by
    default printed on stderr) says it is ignored.

    Raises
    ------
    InputError
        ``out`` holds no results table, or a malformed one (one line, naming the file and line).
    """
    out = Path(out)
    tables = _tables(out)
    records, problems = scan_cells(out, verify_artifacts=arrays)
    if not arrays:                                           # the seal of the record itself, still
        for cid, rec in list(records.items()):
            err = record_problem(rec, None)
            if err:
                problems.append(f"{out / CELLS_DIR / cid}.json {err}")
                del records[cid]
    problems = [p.replace(str(out / CELLS_DIR), CELLS_DIR, 1) for p in problems]
    for p in problems:
        if p.endswith(f"{IGNORED})"):
            warn(f"warning: {p}")
    problems = [p for p in problems if not p.endswith(f"{IGNORED})")]
    damaged = {Path(p.split(" ", 1)[0]).stem for p in problems}
    for name, df in tables:
        problems += [df] if isinstance(df, str) else table_problems(name, df, records, damaged)
    return problems


def refuse_damaged(out: str | Path, problems: list[str], escape: str = "", sealing_tried: bool = False) -> None:
    """:class:`InputError`, one line: the run folder's ``problems`` (the first few, and how many more), how to
    rewrite its tables from the records, and ``escape`` (e.g. ``", or render anyway with --force"``).  An unsealed
    record adds how to seal a folder written before seals — unless ``sealing_tried`` (``--accept-unsealed`` ran
    and left it unsealed: it disagrees with the tables, and only ``--resume`` helps)."""
    if not problems:
        return
    shown = "; ".join(problems[:_SHOWN]) + (f"; ... {len(problems) - _SHOWN} more" if len(problems) > _SHOWN else "")
    unsealed = any(UNSEALED in p for p in problems)
    if unsealed and sealing_tried:
        migrate = "; --accept-unsealed left unsealed the records that disagree with the results tables"
    elif unsealed:
        migrate = (f"; a folder written before seals is sealed once with `python -m bench report {out} "
                   "--accept-unsealed`")
    else:
        migrate = ""
    raise InputError(f"{str(out)!r}: {len(problems)} problem(s) against the sealed cell records: {shown}; "
                     f"rewrite the tables from the records (and recompute any damaged cell) with "
                     f"`python -m bench run --resume --out {out}`{migrate}{escape}")


def set_aside(out: Path, known: dict[str, dict | None]) -> list[str]:
    """Rename to ``<name>.rejected`` every record file in ``out/cells`` that is not one the runner wrote or
    found sealed (``known``: ``{cell_id: its checksum}``): a record a plug-in wrote, a stray copy, one changed
    during the run.  Returns the cell ids set aside (the caller drops them from its records: they rerun)."""
    cells_dir = Path(out) / CELLS_DIR
    gone = []
    for p in sorted(cells_dir.glob("*.json")) if cells_dir.is_dir() else ():
        if p.name.startswith("."):
            continue
        rec = read_json(p)
        mine = known.get(p.stem)
        if mine is not None and isinstance(rec, dict) and rec.get("checksum") == mine \
                and record_problem(rec, None) is None:
            continue
        try:
            p.replace(p.with_name(p.name + REJECTED))
        except OSError:
            continue
        gone.append(p.stem)
    return gone


def seal_unsealed(out: str | Path) -> tuple[list[str], list[str]]:
    """Seal, in place, every record of ``out/cells`` that has no checksum but otherwise holds — it reads, is
    named after its cell, its ``.npz`` loads with the arrays it lists, and it agrees with every results table
    (one row each, the same values): the one-time migration of a folder written before seals existed.  The seal
    records ``sealed_later``.  Returns ``(sealed, refused)`` cell ids; a refused record stays unsealed (so
    ``--resume`` recomputes it): sealing it would make its values the truth."""
    from .lock import RunLock

    out = Path(out)
    RunLock(out).check()                  # not under a live run
    cells_dir = out / CELLS_DIR
    found = {}
    for p in sorted(cells_dir.glob("*.json")) if cells_dir.is_dir() else ():
        try:
            rec = json.loads(p.read_text())
            cid = rec["row"]["cell_id"]
        except (OSError, ValueError, KeyError, TypeError):
            continue
        if not p.name.startswith(".") and "checksum" not in rec and p.stem == cid:
            found[cid] = rec
    refused = {cid for cid, rec in found.items() if _artifact_problem(cells_dir / f"{cid}.npz", rec.get("artifacts"))}
    for name, df in _tables(out):
        if isinstance(df, str):
            return [], sorted(found)
        mine = df[df["cell_id"].astype(str).isin(found)]
        refused |= {p.split(":", 1)[0] for p in table_problems(name, mine, found, set())}
    stamp = _dt.datetime.now().astimezone().isoformat(timespec="seconds")
    for cid, rec in found.items():
        if cid not in refused:
            npz = cells_dir / f"{cid}.npz"
            sealed = seal(rec, npz if npz.exists() else None)
            sealed["checksum"]["sealed_later"] = stamp
            write_json(cells_dir / f"{cid}.json", sealed)
    return sorted(set(found) - refused), sorted(refused & set(found))
