"""When a running grid writes its results tables: at checkpoints, not after every cell.

``results.csv`` and ``results.parquet`` hold a row per finished cell, so one write of them costs time in
proportion to the cells done; written after every cell, a grid's writing would grow with the square of its size.
The sealed cell records (``cells/<cell_id>.json``, :func:`bench.run.store.save_cell`) are written as each cell
finishes and are the truth; the two tables are copies of them, written by :class:`ResultTables`:

* when the cells finished since the last write reach the number of rows that write held (and at least
  :data:`EVERY_CELLS`): each write is about twice the size of the one before, so all of them together cost about
  twice the last one — the writing cost per cell does not grow with the grid;
* when :data:`EVERY_S` seconds have passed since the last write, and at least ``1 / WRITE_SHARE`` times as long
  as that write took: the tables of a slow grid stay current, and the timed writes take at most
  :data:`WRITE_SHARE` of the run's wall time;
* at the end of every session, an interrupted one too (the runner writes them in its ``finally``).

A run killed between two checkpoints (SIGKILL, a power cut) leaves tables that lack its last cells: ``report``,
``table`` and ``compare`` then refuse the folder (:mod:`bench.run.audit`), and ``python -m bench run --resume``
writes both tables again from the records, as it does after any interruption.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path

from .results import write_results_csv

__all__ = ["EVERY_CELLS", "EVERY_S", "WRITE_SHARE", "ResultTables"]

#: finished cells before the first checkpoint (after it: as many cells as the last write's rows)
EVERY_CELLS = 100
#: seconds after which finished cells are written even when fewer than the count above
EVERY_S = 30.0
#: the largest share of the wall time that timed checkpoints may take
WRITE_SHARE = 0.05


class ResultTables:
    """The results tables of one session of a run, written at checkpoints.

    Parameters
    ----------
    out : Path
        The run folder.
    order : list of str
        The grid's cell ids (:attr:`~bench.run.contracts.Cell.cell_id`) in grid order; rows follow it.
    records : dict
        ``{cell_id: record}`` of the finished cells: the runner's own dict, which it fills as cells finish (the
        tables are written from it).
    every_cells : int, optional
        Finished cells before the first checkpoint (default :data:`EVERY_CELLS`).
    every_s : float, optional
        Seconds after which finished cells are written whatever their number (default :data:`EVERY_S`).
    clock : callable
        Seconds, monotonic (for tests).
    """

    def __init__(self, out: Path, order: list[str], records: dict[str, dict], every_cells: int | None = None,
                 every_s: float | None = None, clock: Callable[[], float] = time.monotonic) -> None:
        self.out, self.order, self.records = Path(out), list(order), records
        self.every_cells = EVERY_CELLS if every_cells is None else every_cells
        self.every_s = EVERY_S if every_s is None else every_s
        self.clock = clock
        self.pending = 0            # cells finished since the last write
        self.rows_written = 0       # rows the last write held
        self.writes = 0
        self.last_end = clock()
        self.last_cost = 0.0        # seconds the last write took

    def due(self) -> bool:
        """Whether the cells finished since the last write are to be written now."""
        if not self.pending:
            return False
        if self.pending >= max(self.every_cells, self.rows_written):
            return True
        return self.clock() - self.last_end >= max(self.every_s, self.last_cost / WRITE_SHARE)

    def finished(self, n: int = 1) -> bool:
        """Count ``n`` more finished cells (already in ``records``) and write the tables when a checkpoint is
        due; True when they were written."""
        self.pending += n
        if not self.due():
            return False
        self.write()
        return True

    def write(self) -> Path:
        """Write both tables now, from every record (the end of a session, an interruption); returns the CSV's
        path."""
        start = self.clock()
        path = write_results_csv(self.out, self.order, self.records)
        self.last_end = self.clock()
        self.last_cost = self.last_end - start
        self.rows_written = len(self.records)
        self.pending = 0
        self.writes += 1
        return path
