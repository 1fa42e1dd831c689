"""bench.run.checkpoints: the results tables of a running grid are written at checkpoints — the counts double,
timed ones take a bounded share of the time — and always at the end of a session, an interrupted one too; a
folder whose tables lag behind its records (a run killed between checkpoints) is refused, and ``--resume``
rewrites the tables to what an uninterrupted run writes."""

from __future__ import annotations

import csv
import hashlib
from pathlib import Path

import pytest

from bench.config import builtin_config
from bench.run import checkpoints, run_grid
from bench.run.audit import check_run_folder
from bench.run.checkpoints import ResultTables
from bench.run.contracts import CellResult
from bench.run.grid import expand_grid
from bench.run.row import ResultRow
from bench.run.results import RESULTS_CSV, RESULTS_PARQUET, read_results


def _csv_ids(out: Path) -> list[str]:
    with open(out / RESULTS_CSV, newline="") as fh:
        return [r["cell_id"] for r in csv.DictReader(fh)]


def _grid():
    """66 cells: 2 phantoms × (clean + 10 noisy seeds) × 3 methods, at N = 16 (never computed here)."""
    cfg = builtin_config("quick")
    cfg.seeds, cfg.n = list(range(10)), [16]
    return cfg


def _row(cell) -> dict:
    """A made-up row whose values follow from the cell id alone (the same in every run)."""
    h = int(hashlib.sha256(cell.cell_id.encode()).hexdigest()[:8], 16) / 2 ** 32
    return {"cell_id": cell.cell_id, "phantom": cell.phantom, "variant": cell.variant, "N": cell.n,
            "noise": cell.noise, "snr_requested": cell.snr_requested, "seed": cell.seed, "method": cell.method,
            "label": cell.label, "parameters": "{}", "hausdorff_h": 0.5 + h, "euler": 2, "watertight": h > 0.3,
            "wall_s": 0.01, "flags": "", "status": "ok", "error": ""}


class _MadeUpExecutor:
    """Hands back a made-up result per cell at once; ``stop_after``: then stops as Ctrl-C would."""

    def __init__(self, stop_after: int | None = None) -> None:
        self.stop_after = stop_after
        self.given = 0

    def run(self, cells, on_start, on_result) -> None:
        for cell in cells:
            if self.given == self.stop_after:
                raise KeyboardInterrupt
            self.given += 1
            on_start(cell)
            on_result(cell, CellResult(row=_row(cell)))


def _feed(tables: ResultTables, cells, records: dict, n: int) -> list[int]:
    """Finish the next ``n`` cells one by one; the number of finished cells at each checkpoint."""
    at = []
    for cell in cells[len(records):len(records) + n]:
        records[cell.cell_id] = {"row": ResultRow.from_dict(_row(cell))}
        if tables.finished():
            at.append(len(records))
    return at


class _Clock:
    def __init__(self) -> None:
        self.now = 1000.0

    def __call__(self) -> float:
        return self.now


# ---------------------------------------------------------------------------------------------- the policy
def test_count_checkpoints_double_and_each_holds_exactly_the_cells_finished_by_then(tmp_path):
    cells, records = expand_grid(_grid()), {}
    tables = ResultTables(tmp_path, [c.cell_id for c in cells], records, every_cells=3, every_s=1e9)
    seen = []
    for cell in cells[:50]:
        records[cell.cell_id] = {"row": ResultRow.from_dict(_row(cell))}
        if tables.finished():
            seen.append(_csv_ids(tmp_path))
    assert [len(ids) for ids in seen] == [3, 6, 12, 24, 48]
    assert seen[-1] == [c.cell_id for c in cells if c.cell_id in records][:48]      # grid order, no cell twice
    assert len(_csv_ids(tmp_path)) == 48 and tables.pending == 2                      # two cells not written yet
    tables.write()                                                                     # the end of the session
    assert _csv_ids(tmp_path) == [c.cell_id for c in cells[:50]]
    assert list(read_results(tmp_path)["cell_id"]) == _csv_ids(tmp_path)             # the parquet file too
    assert tables.writes == 6


def test_timed_checkpoints_write_the_few_cells_of_a_slow_grid(tmp_path):
    cells, records, clock = expand_grid(_grid()), {}, _Clock()
    tables = ResultTables(tmp_path, [c.cell_id for c in cells], records, every_cells=1000, every_s=10.0, clock=clock)
    at = []
    for _ in range(9):
        clock.now += 4.0                                  # a cell every 4 s: a write every third cell (12 s)
        at += _feed(tables, cells, records, 1)
    assert at == [3, 6, 9]
    assert not tables.finished(0) and tables.pending == 0  # nothing new: nothing to write, however long it waited


def test_a_slow_write_spaces_the_timed_checkpoints_to_keep_its_share_of_the_time(tmp_path, monkeypatch):
    cells, records, clock = expand_grid(_grid()), {}, _Clock()
    writes = []

    def slow_write(out, order_, records_):                # a table that takes 2 s to write
        writes.append(len(records_))
        clock.now += 2.0
        return Path(out) / RESULTS_CSV

    monkeypatch.setattr(checkpoints, "write_results_csv", slow_write)
    tables = ResultTables(tmp_path, [c.cell_id for c in cells], records, every_cells=1000, every_s=10.0, clock=clock)
    for _ in range(40):
        clock.now += 4.0                                  # a cell every 4 s
        _feed(tables, cells, records, 1)
    # 2 s of writing needs 2 / WRITE_SHARE = 40 s after it: every 10th cell, not every 3rd
    assert writes == [3, 13, 23, 33]


# ---------------------------------------------------------------------------------------------- in the runner
def _tables_of(out: Path) -> tuple[bytes, bytes]:
    return (out / RESULTS_CSV).read_bytes(), read_results(out).to_csv(index=False).encode()


def test_an_interrupted_run_writes_its_tables_and_resumes_to_the_uninterrupted_tables(tmp_path, monkeypatch):
    monkeypatch.setattr(checkpoints, "EVERY_CELLS", 4)
    cfg = _grid()
    whole = run_grid(cfg, tmp_path / "whole", executor=_MadeUpExecutor(), progress=False)
    assert whole.ok == 66

    out = tmp_path / "stopped"
    with pytest.raises(KeyboardInterrupt):
        run_grid(cfg, out, executor=_MadeUpExecutor(stop_after=23), progress=False)
    assert len(_csv_ids(out)) == 23                      # checkpoints at 4, 8, 16 cells; the last 7 at the stop
    assert check_run_folder(out) == []                   # the tables are the records
    summary = run_grid(cfg, out, executor=_MadeUpExecutor(), progress=False, resume=True)
    assert (summary.skipped, summary.ran) == (23, 43)
    assert _tables_of(out) == _tables_of(tmp_path / "whole")


def test_tables_left_behind_by_a_killed_run_are_refused_and_resume_rewrites_them(tmp_path, monkeypatch):
    """A SIGKILL between checkpoints leaves the tables of the last checkpoint beside every record written."""
    monkeypatch.setattr(checkpoints, "EVERY_CELLS", 4)
    cfg, out = _grid(), tmp_path / "run"
    copies = {}
    real_write = ResultTables.write

    def keep_first_checkpoint(self):                     # the tables as a kill after the first checkpoint leaves them
        path = real_write(self)
        if not copies:
            copies.update({p: (out / p).read_bytes() for p in (RESULTS_CSV, RESULTS_PARQUET)})
        return path

    monkeypatch.setattr(ResultTables, "write", keep_first_checkpoint)
    run_grid(cfg, out, executor=_MadeUpExecutor(), progress=False)
    finished = _tables_of(out)
    for name, data in copies.items():
        (out / name).write_bytes(data)
    assert len(_csv_ids(out)) == 4
    problems = check_run_folder(out)
    assert any("62 cells have no row in results.csv" in p for p in problems), problems
    summary = run_grid(cfg, out, executor=_MadeUpExecutor(), progress=False, resume=True)
    assert summary.ran == 0 and check_run_folder(out) == []
    assert _tables_of(out) == finished
