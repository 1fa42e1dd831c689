"""Running the benchmark grid: config → cells → executor → run folder.

* :mod:`~bench.run.contracts` — the stage contracts :class:`Cell` and :class:`CellResult` (frozen; plain dicts only
  in the run folder), the result's row a :class:`ResultRow` (:mod:`~bench.run.row`: the results row's schema);
* :mod:`~bench.run.grid` — a config's cells and their ids;
* :mod:`~bench.run.cell` — one cell from its parameters alone (volume, method, cost, metrics);
* :mod:`~bench.run.executors` — where cells run (local processes, Dask);
* :mod:`~bench.run.store` — the run folder's files, written atomically;
* :mod:`~bench.run.results` — results.csv and results.parquet, written from the typed rows and read back;
* :mod:`~bench.run.checkpoints` — when a running grid writes its results tables;
* :mod:`~bench.run.provenance` — versions, git commit, machine;
* :mod:`~bench.run.runner` — :func:`run_grid`, which ties them together, run as its
  :class:`~bench.run.options.RunOptions` say.

>>> from bench.config import builtin_config
>>> from bench.run import expand_grid, run_cell, run_grid
>>> cells = expand_grid(builtin_config("quick"))          # doctest: +SKIP
>>> result = run_cell(cells[0])                            # doctest: +SKIP
"""

from .cell import failed_result, run_cell
from .contracts import Cell, CellResult, ResultRow
from .executors import LocalExecutor
from .grid import cell_id, expand_grid
from .options import RunOptions
from .runner import RunSummary, run_grid
from .store import load_cells
from .results import write_results_csv

__all__ = ["Cell", "CellResult", "LocalExecutor", "ResultRow", "RunOptions", "RunSummary", "cell_id", "expand_grid",
           "failed_result", "load_cells", "run_cell", "run_grid", "write_results_csv"]
