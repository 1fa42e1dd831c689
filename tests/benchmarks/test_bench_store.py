"""Writing a run's results tables as the runner does (:class:`bench.run.checkpoints.ResultTables`): synthetic
cells finish one after another, the tables are written at the checkpoints and at the end.  One write costs in
proportion to the rows written so far; the writing cost *per cell* must not grow with the grid — the time per
cell at 5,000 cells within 1.5x of the time per cell at 500.

The two sizes are timed in alternation (a 500-cell round before each 5,000-cell round, outside its timed interval)
and compared by their medians, so a busy machine slows both alike.  What is timed is the tables' writing alone:
the cell records (one ``.json`` and one ``.npz`` per cell) cost the same for every cell at any grid size.
"""

from __future__ import annotations

import itertools
import statistics
import time

import pytest

from bench.metrics.registry import METRICS
from bench.perf import rounds
from bench.run.checkpoints import ResultTables
from bench.run.row import ResultRow
from bench.run.results import RESULTS_CSV

SMALL, LARGE = 500, 5000
#: the largest ratio of the time per cell at LARGE to the time per cell at SMALL
MAX_GROWTH = 1.5
_VALUE = {"bool": True, "int": 2}


def _record(i: int) -> dict:
    """A finished cell's record: the identifying columns and a value in every registered metric."""
    row = {"cell_id": f"shape_{i // 10:04d}_sdf_n32_gaussian_s{i % 10}_marching_cubes", "phantom": f"shape_{i // 10}",
           "variant": "sdf", "N": 32, "noise": "gaussian", "snr_requested": 30.0, "snr_achieved": 29.97,
           "seed": i % 10, "method": "marching_cubes", "label": "marching_cubes", "parameters": "{}"}
    for k, (name, spec) in enumerate(METRICS.items()):
        row[name] = _VALUE.get(spec.dtype, 0.1 + (i * 7 + k) % 1000 / 997)
    row.update({"iterations": None, "energy_final": None, "stop_reason": None, "wall_s": 0.0123,
                "peak_mem_mb": 51.5, "flags": "", "status": "ok", "error": ""})
    return {"row": ResultRow.from_dict(row)}


def _write_run(out, records: list[dict]) -> float:
    """Seconds to finish ``records`` one by one into fresh tables, as the runner does, and close the session."""
    order = [r["row"].cell_id for r in records]
    done: dict[str, dict] = {}
    out.mkdir()
    t0 = time.perf_counter()
    tables = ResultTables(out, order, done)
    for r in records:
        done[r["row"].cell_id] = r
        tables.finished()
    tables.write()
    return time.perf_counter() - t0


@pytest.mark.benchmark(group="store")
def test_writing_the_results_costs_the_same_per_cell_at_500_and_5000_cells(benchmark, tmp_path):
    small, large = [_record(i) for i in range(SMALL)], [_record(i) for i in range(LARGE)]
    folders = (tmp_path / f"run{i}" for i in itertools.count())
    per_cell: dict[int, list[float]] = {SMALL: [], LARGE: []}
    _write_run(next(folders), small)                     # warm-up: imports, the first parquet write

    def small_round():                                  # untimed by the benchmark, just before each timed round
        per_cell[SMALL].append(_write_run(next(folders), small) / SMALL)

    def large_round():
        out = next(folders)
        per_cell[LARGE].append(_write_run(out, large) / LARGE)
        return out

    out = benchmark.pedantic(large_round, setup=small_round, rounds=rounds(5, 3), iterations=1, warmup_rounds=0)
    with open(out / RESULTS_CSV) as fh:
        assert sum(1 for _ in fh) == LARGE + 1
    small_s, large_s = statistics.median(per_cell[SMALL]), statistics.median(per_cell[LARGE])
    benchmark.extra_info.update(cells=LARGE, per_cell_us_500=round(small_s * 1e6, 1),
                                per_cell_us_5000=round(large_s * 1e6, 1), growth=round(large_s / small_s, 3))
    assert large_s <= MAX_GROWTH * small_s, (per_cell, MAX_GROWTH)
