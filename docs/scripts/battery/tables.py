"""A finished run folder edited by hand or by a plug-in: its results tables (cause 1) and its sealed cell records
(cause 2).  The records are the truth: ``report``, ``table`` and ``compare`` refuse a table that departs from
them, naming the cell; ``run --resume`` recomputes an altered record and never copies a forged value."""

from __future__ import annotations

import csv
import io
import json
import shutil
from pathlib import Path

import pandas as pd

from .core import Case, Ctx, exits_ok, first, one_line, rows

GRID = ("--phantoms", "sphere", "--n", "16", "--noise", "none", "--method", "marching_cubes",
        "--add-method", "flying_edges", "--add-method", "mc_taubin", "--jobs", "2")


def base(ctx: Ctx) -> Path:
    """A finished three-cell run (sphere N = 16: marching cubes, flying edges, mc_taubin), made once."""
    def make() -> Path:
        out = ctx.root / "tables" / "base"
        res = ctx.bench("run", *GRID, "--out", str(out), timeout=180)
        if res.rc != 0 or len(rows(out)) != 3:
            raise RuntimeError(f"the base run failed: {res.show()}")
        return out
    return ctx.once("tables.base", make)


def copy(ctx: Ctx, tag: str) -> Path:
    """A fresh copy of the base run folder (each case edits its own)."""
    dst = ctx.root / "tables" / tag
    shutil.rmtree(dst, ignore_errors=True)
    shutil.copytree(base(ctx), dst)
    return dst


def csv_rows(folder: Path) -> tuple[list[str], list[list[str]]]:
    with (folder / "results.csv").open(newline="") as fh:
        table = list(csv.reader(fh))
    return table[0], table[1:]


def write_csv(folder: Path, header: list[str], body: list[list[str]]) -> None:
    buf = io.StringIO()
    csv.writer(buf, lineterminator="\n").writerows([header, *body])
    (folder / "results.csv").write_text(buf.getvalue())


def _scaled(header, row, column="hausdorff_h", factor=0.5):
    row = list(row)
    i = header.index(column)
    row[i] = repr(float(row[i]) * factor)
    return row


# every edit returns the cell id the refusal must name ("" when any cell will do)
def _drop(i):
    def edit(folder):
        header, body = csv_rows(folder)
        gone = body.pop(i)
        write_csv(folder, header, body)
        return gone[0]
    return edit


def _header_only(folder):
    header, _ = csv_rows(folder)
    write_csv(folder, header, [])
    return ""


def _edit_value(folder):
    header, body = csv_rows(folder)
    body[1] = _scaled(header, body[1])
    write_csv(folder, header, body)
    return body[1][0]


def _edit_column(column, value):
    def edit(folder):
        header, body = csv_rows(folder)
        body[0][header.index(column)] = value
        write_csv(folder, header, body)
        return body[0][0]
    return edit


def _duplicate(folder):
    header, body = csv_rows(folder)
    write_csv(folder, header, body + [body[0]])
    return body[0][0]


def _extra(folder):
    header, body = csv_rows(folder)
    made = list(body[0])
    made[0] = made[0] + "x"
    write_csv(folder, header, body + [made])
    return made[0]


def _parquet(how):
    def edit(folder):
        df = pd.read_parquet(folder / "results.parquet")
        cid = str(df["cell_id"].iloc[1])
        if how == "drop":
            df = df.drop(index=df.index[1])
        elif how == "value":
            df.loc[df.index[1], "hausdorff_h"] *= 0.5
        else:
            df = pd.concat([df, df.iloc[[1]]])
        df.to_parquet(folder / "results.parquet")
        return cid
    return edit


EDITS = {
    "the last row of results.csv removed": _drop(-1),
    "the middle row of results.csv removed": _drop(1),
    "the first row of results.csv removed": _drop(0),
    "results.csv header only": _header_only,
    "hausdorff_h halved in results.csv": _edit_value,
    "status ok -> failed in results.csv": _edit_column("status", "failed"),
    "label renamed in results.csv": _edit_column("label", "my_method"),
    "flags cleared to 'self_intersecting' in results.csv": _edit_column("flags", "self_intersecting"),
    "a second row for one cell in results.csv": _duplicate,
    "a row for a cell with no record in results.csv": _extra,
    "a row removed from results.parquet only": _parquet("drop"),
    "hausdorff_h halved in results.parquet only": _parquet("value"),
    "a row doubled in results.parquet only": _parquet("double"),
}


def _command(ctx: Ctx, command: str, folder: Path):
    if command == "table":
        return ctx.bench("table", str(folder))
    if command == "report":
        return ctx.bench("report", str(folder))
    return ctx.bench("compare", str(base(ctx)), str(folder))


def table_cases() -> list[Case]:
    """Each edit of results.csv / results.parquet refused by table, report and compare, naming the cell."""
    out: list[Case] = []
    for i, (name, edit) in enumerate(EDITS.items()):
        for command in ("table", "report", "compare"):
            def check(ctx, edit=edit, command=command, tag=f"e{i}_{command}"):
                folder = copy(ctx, tag)
                cid = edit(folder)
                return one_line(_command(ctx, command, folder), cid)
            out.append(Case("1", f"{command}: {name}", check))
    for command in ("table", "report", "compare"):
        out.append(Case("1", f"control: {command} of the untouched folder", lambda ctx, command=command: exits_ok(
            _command(ctx, command, copy(ctx, f"ok_{command}")))))

    def reordered(ctx):
        folder = copy(ctx, "reordered")
        header, body = csv_rows(folder)
        write_csv(folder, header, body[::-1])
        return exits_ok(ctx.bench("table", str(folder)))
    out.append(Case("1", "control: rows of results.csv reordered are the same table", reordered))
    return out


# ------------------------------------------------------------------------------------------------ cause 2
def _record(folder: Path, i: int = 1) -> Path:
    return sorted((folder / "cells").glob("*.json"))[i]


def _forge(folder: Path, drop_checksum: bool, tables_too: bool = False, checksum=None) -> str:
    path = _record(folder)
    rec = json.loads(path.read_text())
    rec["row"]["hausdorff_h"] = rec["row"]["hausdorff_h"] * 0.5
    if drop_checksum:
        rec.pop("checksum", None)
    if checksum is not None:
        rec["checksum"] = checksum
    path.write_text(json.dumps(rec))
    cid = rec["row"]["cell_id"]
    if tables_too:
        header, body = csv_rows(folder)
        write_csv(folder, header, [_scaled(header, r) if r[0] == cid else r for r in body])
        df = pd.read_parquet(folder / "results.parquet")
        df.loc[df["cell_id"] == cid, "hausdorff_h"] *= 0.5
        df.to_parquet(folder / "results.parquet")
    return cid


def _unseal(folder):
    path = _record(folder)
    rec = json.loads(path.read_text())
    rec.pop("checksum")
    path.write_text(json.dumps(rec))
    return rec["row"]["cell_id"]


def _npz(how):
    def edit(folder):
        path = _record(folder)
        npz = path.with_suffix(".npz")
        if how == "delete":
            npz.unlink()
        else:
            data = bytearray(npz.read_bytes())
            data[len(data) // 2] ^= 0xFF
            npz.write_bytes(bytes(data))
        return path.stem
    return edit


def _record_file(how):
    def edit(folder):
        path = _record(folder)
        if how == "delete":
            path.unlink()
        else:
            path.write_text('{"row": {"cell_id": ')
        return path.stem
    return edit


SEALS = {
    "the checksum key deleted": _unseal,
    "hausdorff_h halved, checksum kept": lambda f: _forge(f, drop_checksum=False),
    "hausdorff_h halved and the checksum deleted": lambda f: _forge(f, drop_checksum=True),
    "hausdorff_h halved in the record and both tables, checksum deleted": lambda f: _forge(f, True, True),
    "hausdorff_h halved, checksum made up": lambda f: _forge(f, False, checksum={"record": "0" * 64, "npz": None}),
    "hausdorff_h halved, checksum a string": lambda f: _forge(f, False, checksum="ok"),
    "the cell's .npz altered": _npz("alter"),
    "the cell's .npz deleted": _npz("delete"),
    "the cell's record deleted": _record_file("delete"),
    "the cell's record cut short": _record_file("cut"),
}


def _true_value(ctx: Ctx, cid: str) -> float:
    return float(next(r for r in rows(base(ctx)) if r["cell_id"] == cid)["hausdorff_h"])


def _resumed_truly(ctx: Ctx, folder: Path, cid: str) -> str | None:
    res = ctx.bench("run", "--resume", "--out", str(folder), "--jobs", "1", "--no-report", timeout=180)
    got = {r["cell_id"]: r for r in rows(folder)}
    if res.rc != 0:
        return f"--resume: {res.show()}"
    if cid not in got or len(got) != 3:
        return f"after --resume results.csv has {sorted(got)}, expected the three cells"
    want, value = _true_value(ctx, cid), float(got[cid]["hausdorff_h"] or "nan")
    if abs(value - want) > 1e-9 * max(1.0, abs(want)):
        return f"after --resume hausdorff_h of {cid} is {value}, the uninterrupted run's {want}"
    return exits_ok(ctx.bench("table", str(folder)))


def seal_cases() -> list[Case]:
    """Each record edit refused by table (naming the cell) and undone by --resume."""
    out: list[Case] = []
    for i, (name, edit) in enumerate(SEALS.items()):
        # table reads no arrays, so an altered .npz is the report's to refuse (its viewers read the meshes)
        command = "report" if ".npz" in name else "table"

        def refused(ctx, edit=edit, tag=f"s{i}_table", command=command):
            folder = copy(ctx, tag)
            cid = edit(folder)
            return one_line(ctx.bench(command, str(folder)), cid)

        def resumed(ctx, edit=edit, tag=f"s{i}_resume"):
            folder = copy(ctx, tag)
            return _resumed_truly(ctx, folder, edit(folder))
        out += [Case("2", f"{command}: {name}", refused), Case("2", f"run --resume: {name}", resumed)]

    def stray(ctx, command):
        folder = copy(ctx, f"stray_{command}")
        path = _record(folder)
        rec = json.loads(path.read_text())
        rec["row"]["hausdorff_h"] *= 0.5
        (path.parent / f"aaa_{path.name}").write_text(json.dumps(rec))
        if command == "table":
            res = ctx.bench("table", str(folder), "--format", "csv")
            forged = f"{rec['row']['hausdorff_h']}"
            return first(exits_ok(res) if res.rc == 0 else one_line(res),
                         f"the stray copy's value {forged} is shown" if forged in res.out else None)
        return _resumed_truly(ctx, folder, rec["row"]["cell_id"])
    out += [Case("2", "table: a stray record copy claiming a cell, value halved", lambda c: stray(c, "table")),
            Case("2", "run --resume: a stray record copy claiming a cell", lambda c: stray(c, "resume"))]

    def migrated(ctx):
        folder = copy(ctx, "migrated")
        for path in (folder / "cells").glob("*.json"):
            rec = json.loads(path.read_text())
            rec.pop("checksum")
            path.write_text(json.dumps(rec))
        res = ctx.bench("report", str(folder), "--accept-unsealed")
        return first(exits_ok(res), exits_ok(ctx.bench("table", str(folder))))
    out.append(Case("2", "report --accept-unsealed seals a pre-seal folder that agrees with its tables", migrated))
    return out


def cases() -> list[Case]:
    return table_cases() + seal_cases()
