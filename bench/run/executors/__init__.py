"""Executors run cells and hand each result back: ``run(cells, on_start, on_result)``.

* :class:`~bench.run.executors.local.LocalExecutor` — worker processes on this machine (the default);
* :mod:`bench.run.executors.dask` — one Dask task per cell on a cluster (optional dependency).
"""

from .local import LocalExecutor

__all__ = ["LocalExecutor"]
