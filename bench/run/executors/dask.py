"""The grid on Dask's distributed scheduler (``--executor dask``): one task per cell (``Client.submit``), each result
stored by the client as it arrives (``as_completed``), behind the local executor's ``run(cells, on_start, on_result)``.
A task runs its cell in a child process through a one-job :class:`~bench.run.executors.local.LocalExecutor` (timeouts
and crashes are rows as locally); Dask reruns the cell of a worker that died (``allowed-failures``)."""

from __future__ import annotations

import contextlib
import importlib
import logging
import multiprocessing
import os
import sys
import time
import warnings

from distributed import Client, KilledWorker, as_completed, get_worker
from distributed.diagnostics.plugin import WorkerPlugin

from phantoms import InputError

from .. import provenance
from ..cell import Cell, CellResult, failed_result   # the stage contracts, as run_cell takes and gives them
from ..limits import TimeLimits
from ..values import error_text
from .local import LocalExecutor

__all__ = ["DaskExecutor", "DaskRunIncomplete", "WorkerRefused"]


class DaskRunIncomplete(RuntimeError):
    """Cells the cluster lost without a result (e.g. the scheduler went away): the run stops, nothing written."""


class WorkerRefused(Exception):
    """A worker whose cells could differ from this machine's: it cannot import a module, or runs other code."""


class SuiteOnWorker(WorkerPlugin):
    """On every worker, also those joining later: import the suite and the plug-ins, refuse another git commit of the
    suite, and let the (daemonic) worker start cell processes; they exit with it through their lifeline pipe."""

    name = "levelset-bench"

    def __init__(self, imports: list[str], commit: str | None) -> None:
        self.imports, self.commit = imports, commit

    def setup(self, worker) -> None:
        multiprocessing.current_process().daemon = False
        for mod in ["bench.run.cell", "bench.metrics", "methods", *self.imports]:
            try:
                importlib.import_module(mod)
            except BaseException as exc:  # noqa: BLE001 - sent to the client as one line
                raise WorkerRefused(f"Dask worker {worker.address} cannot import {mod!r} ({type(exc).__name__}: "
                                    f"{exc}); it must be importable on every worker (installed or on PYTHONPATH)")
        theirs = (provenance.git_commit() or {}).get("commit")   # after the plug-ins: a test one fakes a checkout
        if self.commit and theirs and theirs != self.commit:
            raise WorkerRefused(f"Dask worker {worker.address} runs the suite at git commit {theirs[:12]}, this "
                                f"machine at {self.commit[:12]}: install the same checkout on every worker machine")


def _run_cell_task(cell: Cell, cache_dir: str | None, limits: TimeLimits, imports: list[str]) -> CellResult:
    """The Dask task: one cell in a child process of this worker; its :class:`CellResult`."""
    results: list[CellResult] = []
    cache_dir = cache_dir or os.path.join(get_worker().local_directory, "levelset-bench-cache")
    LocalExecutor(1, limits, cache_dir, preload=imports).run([cell], lambda c: None, lambda c, r: results.append(r))
    return results[0]


class DaskExecutor:
    """Cells as Dask tasks on a ``LocalCluster`` of ``workers`` one-thread processes sharing ``cache_dir``, or on the
    cluster at ``scheduler`` (connecting within Dask's ``distributed.comm.timeouts.connect``).  A context manager."""

    def __init__(self, scheduler: str | None = None, workers: int | None = None, timeout=None,
                 cache_dir: str | None = None, imports: list[str] | None = None, retries: int = 2,
                 wait_for_workers_s: float = 60.0) -> None:
        self.scheduler, self.workers, self.limits = scheduler, workers or os.cpu_count() or 1, TimeLimits.of(timeout)
        self.cache_dir, self.imports, self.retries = None if scheduler else cache_dir, list(imports or []), retries
        self.wait_for_workers_s, self.client, self.version_warnings = wait_for_workers_s, None, []

    def describe(self) -> dict:
        """What run.json records about the executor."""
        return {"executor": "dask", "scheduler": self.scheduler or "LocalCluster", **self.limits.to_dict(),
                "retries": self.retries, **({} if self.scheduler else {"workers": self.workers}),
                **({"workers_connected": len(self.client.scheduler_info()["workers"])} if self.client else {}),
                **({"version_differences": self.version_warnings} if self.version_warnings else {})}

    def connect(self) -> DaskExecutor:
        """Start the LocalCluster or connect to the scheduler, then check the workers (:class:`InputError`)."""
        if self.client is not None:
            return self
        local = {} if self.scheduler else dict(   # no address: the client starts a LocalCluster, and closes it
            n_workers=self.workers, threads_per_worker=1, processes=True, memory_limit=0, dashboard_address=":0",
            silence_logs=logging.CRITICAL)          # a refusing worker's log: the client says it in one line
        try:
            self.client = Client(self.scheduler, **local)
            self.client.wait_for_workers(1, timeout=self.wait_for_workers_s)
            self.client.register_plugin(SuiteOnWorker(self.imports, (provenance.git_commit() or {}).get("commit")))
        except Exception as exc:  # noqa: BLE001 - each becomes one line and exit 2
            why = (f"cannot reach the Dask scheduler at {self.scheduler} ({exc}); start one with `dask scheduler`"
                   if self.client is None else str(exc) if isinstance(exc, WorkerRefused) else
                   f"no Dask worker connected to {self.scheduler} within {self.wait_for_workers_s:g} s (start some "
                   f"with `dask worker {self.scheduler}`)" if isinstance(exc, TimeoutError) else
                   f"the Dask workers cannot load this checkout of the suite ({type(exc).__name__}: {exc}); install "
                   "the same checkout on every worker machine")
            self.close()
            raise InputError(why) from None
        with warnings.catch_warnings(record=True) as caught:   # Dask's table of the packages whose versions differ
            warnings.simplefilter("always")
            self.client.get_versions(check=True, packages=list(provenance.dependency_versions()))
        self.version_warnings = [str(w.message) for w in caught]
        for text in self.version_warnings:
            print(f"warning: versions differ on the Dask cluster (kept in run.json): {text}", file=sys.stderr)
        return self

    def close(self) -> None:
        with contextlib.suppress(Exception):  # best effort at shutdown (e.g. the scheduler is gone)
            self.client and self.client.close()
        self.client = None

    def __enter__(self) -> DaskExecutor:
        return self.connect()

    def __exit__(self, *exc) -> None:
        self.close()

    def run(self, cells: list[Cell], on_start, on_result) -> None:
        """Submit every cell (the runner's order first), hand each result to ``on_result`` as it arrives.  The client
        does not see a task start (no ``on_start``); closing the client cancels what is left on the cluster."""
        owned, start, lost = self.client is None, time.monotonic(), []
        futures = {self.connect().client.submit(_run_cell_task, cell, self.cache_dir, self.limits, self.imports,
                                                pure=False, retries=self.retries, priority=len(cells) - i): cell
                   for i, cell in enumerate(cells)}
        try:
            for fut in as_completed(futures):
                cell, exc = futures.pop(fut), fut.exception()   # waits while Dask recomputes a result its worker lost
                if fut.cancelled():  # cancelled, or lost with the scheduler: no row
                    lost.append(cell.cell_id)
                    continue
                why = ("crash: the Dask workers running this cell died repeatedly (KilledWorker)"
                       if isinstance(exc, KilledWorker) else f"dask: {error_text(exc)}")
                result = fut.result() if exc is None else failed_result(cell, "failed", why)
                if not result.row.has("cell_s"):
                    result = result.with_row(cell_s=time.monotonic() - start)
                on_result(cell, result)
        finally:
            if owned:
                self.close()
        if lost:
            raise DaskRunIncomplete(f"{len(lost)} cell(s) lost by the Dask cluster without a result, e.g. {lost[0]}")
