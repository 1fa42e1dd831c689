"""Run the benchmark grid on Dask's distributed scheduler (``python -m bench run --executor dask``).

:class:`DaskExecutor` replaces the runner's local process pool (:class:`bench.run.executors.local.LocalExecutor`) behind
the same tiny interface, ``run(cells, on_start, on_result)``, so everything else of :func:`bench.run.run_grid`
— the per-cell store ``DIR/cells/<cell_id>.json|.npz``, ``results.csv``, ``--resume``, ``run.json`` and the
HTML report — is shared, not reimplemented.

* **One task per cell.**  The client submits every cell (a small dict of parameters) as one task keyed
  ``bench-cell-<cell_id>-<run token>``; the worker builds the volume itself (nothing large is shipped).
  Results are collected with ``as_completed`` and handed to ``on_result`` *by the client*, which writes the
  cell to the store as soon as it arrives.  A cell id is recorded at most once (a guard on top of Dask's
  one-result-per-key), so a row is never duplicated.
* **Timeouts and crashes: the same as the local executor.**  On the worker the task runs the cell in its own
  child process through a one-job :class:`~bench.run.executors.local.LocalExecutor` (fork server preloaded once per
  worker): after ``timeout`` seconds *of the cell's own run on the worker* (queueing time does not count) the
  child is killed and the cell becomes a ``timeout`` row (the per-phase method / score limits of
  :mod:`bench.run.limits` likewise); a method that kills its process (segfault, OOM
  kill) becomes a ``failed`` ``crash: ...`` row, and the worker lives on.
* **Worker death.**  If a whole worker process (or machine) dies mid-cell, its cell processes exit with it
  (lifeline pipe) and the scheduler reschedules the task on another worker — Dask's own retry of tasks
  whose worker died (scheduler setting ``distributed.scheduler.allowed-failures``, default 3).  A task that
  keeps killing workers ends as ``KilledWorker`` and is recorded as a ``failed`` ``crash: ...`` row;
  exceptions raised by the task wrapper itself are retried ``retries`` times (``Client.submit(retries=)``).
  A cell whose future is lost without a result (e.g. the scheduler went away) is *not* written: the run
  stops with :class:`DaskRunIncomplete` and ``--resume`` completes it.
* **Plug-in modules** (``--import MODULE``): a :class:`WorkerPlugin` imports them in every worker (also in
  workers that join later), each cell imports them again in its own process (``run_cell``), and before any
  work starts the client checks that every worker can import the suite and the modules.
* **Same code everywhere.**  The same check compares every worker's :func:`suite_fingerprint` with the
  client's: a worker on another git commit of the suite stops the run (exit 2) before any work; other
  Python or dependency versions are printed as warnings and recorded in run.json
  (``executor.version_differences``).
* **Cluster.**  ``scheduler=None``: a :class:`distributed.LocalCluster` of ``workers`` processes with one
  thread each (the cells share the volume cache ``DIR/cache`` like the local executor).  Otherwise the client
  connects to the scheduler at that address (``dask scheduler`` / ``dask worker ADDRESS`` on any machines with
  the suite installed); each worker then caches volumes in its own local directory.

Dask is optional (``pip install -e ".[dask]"``); importing this module does not need it.
"""

from __future__ import annotations

import importlib
import logging
import multiprocessing
import os
import re
import socket
import sys
import time
import uuid
from typing import Callable

from phantoms import InputError

__all__ = ["DaskExecutor", "DaskRunIncomplete", "require_dask", "parse_scheduler_address"]

INSTALL_HINT = 'pip install -e ".[dask]"'
DEFAULT_PORT = 8786
_SCHEMES = ("tcp", "tls", "ws", "wss", "ucx")
_ADDRESS = re.compile(r"^(?:(?P<scheme>[A-Za-z0-9]+)://)?(?P<host>\[[0-9A-Fa-f:.]+\]|[A-Za-z0-9_.\-]+)"
                      r"(?::(?P<port>\d{1,5}))?/?$")
#: modules every cell process needs; preloaded by the fork server on each worker
_PRELOAD = ["bench.run.cell", "bench.metrics", "methods", "geometry"]


class DaskRunIncomplete(RuntimeError):
    """Some cells came back from the cluster without a result (lost futures); nothing was written for them."""

    def __init__(self, lost: list[str]):
        self.lost = lost
        super().__init__(f"{len(lost)} cell(s) were lost by the Dask cluster without a result (e.g. the "
                         f"scheduler connection broke): {', '.join(lost[:3])}{' ...' if len(lost) > 3 else ''}")


def require_dask() -> None:
    """Raise :class:`InputError` naming the extra to install when ``dask.distributed`` is missing."""
    try:
        import distributed  # noqa: F401
    except ImportError as exc:
        raise InputError(f"--executor dask needs Dask's distributed scheduler, which is not installed "
                         f"({exc}); install it with: {INSTALL_HINT}") from None


def parse_scheduler_address(text: str) -> str:
    """``tcp://host:8786`` from ``host``, ``host:port`` or ``scheme://host[:port]``; :class:`InputError` if malformed."""
    m = _ADDRESS.match((text or "").strip())
    if not m:
        raise InputError(f"--scheduler: not a scheduler address: {text!r} (expected e.g. tcp://host:{DEFAULT_PORT})")
    scheme = (m.group("scheme") or "tcp").lower()
    if scheme not in _SCHEMES:
        raise InputError(f"--scheduler: unknown protocol {scheme!r} in {text!r} "
                         f"(one of {', '.join(s + '://' for s in _SCHEMES)})")
    port = int(m.group("port") or DEFAULT_PORT)
    if not 0 < port < 65536:
        raise InputError(f"--scheduler: port out of range in {text!r}")
    return f"{scheme}://{m.group('host')}:{port}"


# ---------------------------------------------------------------------------------------------- worker side
def _import_all(modules) -> dict[str, str]:
    """Import ``modules``; ``{module: error}`` for those that fail."""
    errors = {}
    for mod in modules:
        try:
            importlib.import_module(mod)
        except BaseException as exc:  # noqa: BLE001 - reported to the client, never raised on the worker
            errors[mod] = f"{type(exc).__name__}: {exc}"
    return errors


def suite_fingerprint() -> dict:
    """What must match between the client and every worker for their results to be comparable: the git
    commit of the suite's checkout (None when it is not a git checkout), the Python version and the
    versions of the suite's dependencies."""
    from bench.run.provenance import dependency_versions, git_commit

    git = git_commit()
    return {"commit": git["commit"] if git else None, "python": sys.version.split()[0],
            "dependencies": dependency_versions()}


def _worker_check(imports: list[str]) -> dict:
    """Run on every worker before the grid: can it import the suite and the plug-in modules, and which
    code does it run (:func:`suite_fingerprint`)?"""
    errors = _import_all(["bench.run.cell", "bench.metrics", "methods", *imports])
    fingerprint = None
    if not errors:
        try:
            fingerprint = suite_fingerprint()
        except Exception as exc:  # noqa: BLE001 - reported to the client
            errors["fingerprint"] = f"{type(exc).__name__}: {exc}"
    return {"errors": errors, "fingerprint": fingerprint}


def compare_fingerprints(local: dict, workers: dict[str, dict]) -> tuple[str | None, list[str]]:
    """(error, warnings) from the client's :func:`suite_fingerprint` and the workers' ones.

    A worker on another git commit of the suite is an error (its cells would come from other code);
    another Python or dependency version is a warning (recorded in run.json, printed).  A missing commit
    (not a git checkout) on either side is not compared.
    """
    error = None
    warnings: list[str] = []
    for worker, fp in sorted(workers.items()):
        if not fp:
            continue
        if local.get("commit") and fp.get("commit") and fp["commit"] != local["commit"]:
            error = error or (f"Dask worker {worker} runs the suite at git commit {fp['commit'][:12]}, this machine "
                              f"at {local['commit'][:12]}: install the same checkout on every worker machine "
                              f"(README: Running the grid on a cluster)")
        if fp.get("python") != local.get("python"):
            warnings.append(f"{worker}: Python {fp.get('python')} (here {local.get('python')})")
        ldeps, wdeps = local.get("dependencies") or {}, fp.get("dependencies") or {}
        for name in sorted(set(ldeps) | set(wdeps)):
            if ldeps.get(name) != wdeps.get(name):
                warnings.append(f"{worker}: {name} {wdeps.get(name)} (here {ldeps.get(name)})")
    return error, warnings


def _allow_child_processes() -> None:
    """Dask worker processes are daemonic, and multiprocessing refuses to start children from a daemon.  The
    cell processes need no daemon clean-up (they exit by themselves when the worker dies: lifeline pipe), so
    lift the flag in this worker process."""
    proc = multiprocessing.current_process()
    if proc._config.get("daemon"):  # noqa: SLF001 - the documented workaround for Dask/multiprocessing
        proc._config["daemon"] = False  # noqa: SLF001


def _worker_cache_dir() -> str | None:
    try:
        from distributed import get_worker

        return os.path.join(get_worker().local_directory, "levelset-bench-cache")
    except (ImportError, ValueError, AttributeError):
        return None


def run_cell_task(cell: dict, cache_dir: str | None, timeout, preload: list[str]) -> dict:
    """The Dask task: one cell in its own child process on this worker (timeout and crash isolation exactly as
    with the local executor).  Returns the runner's result dict ``{"row", "artifacts", "traceback"}``."""
    from bench.run.cell import failed_result
    from bench.run.executors.local import LocalExecutor

    _allow_child_processes()
    if cache_dir is None:
        cache_dir = _worker_cache_dir()
    results: list[dict] = []
    LocalExecutor(1, timeout, cache_dir=cache_dir, preload=_PRELOAD + list(preload)).run(
        [cell], lambda c: None, lambda c, r: results.append(r))
    if not results:  # pragma: no cover - LocalExecutor always produces a result
        return failed_result(cell, "failed", "dask: the worker produced no result")
    return results[0]


def _plugin_class():
    from distributed.diagnostics.plugin import WorkerPlugin

    class ImportModules(WorkerPlugin):
        """Import the ``--import`` modules in every worker, including workers that join later."""

        name = "levelset-bench-imports"

        def __init__(self, modules: list[str]):
            self.modules = list(modules)
            self.errors: dict[str, str] = {}

        def setup(self, worker):
            self.errors = _import_all(self.modules)

    return ImportModules


# ---------------------------------------------------------------------------------------------- client side
class DaskExecutor:
    """Run cells as Dask tasks on a ``LocalCluster`` of ``workers`` processes (``scheduler=None``) or on the
    cluster at ``scheduler``.  Use as a context manager (or :meth:`connect` / :meth:`close`) to start the
    cluster before :func:`bench.run.run_grid`; :meth:`run` connects by itself otherwise."""

    def __init__(self, scheduler: str | None = None, workers: int | None = None, timeout: float | None = None,
                 cache_dir: str | None = None, imports: list[str] | None = None, retries: int = 2,
                 connect_timeout: float = 10.0, wait_for_workers_s: float = 60.0) -> None:
        require_dask()
        self.scheduler = parse_scheduler_address(scheduler) if scheduler else None
        if self.scheduler and workers:
            raise InputError("--workers sets the size of the local Dask cluster; with --scheduler the "
                             "cluster's own workers run the cells (start more with `dask worker ADDRESS`)")
        self.workers = int(workers or os.cpu_count() or 1)
        if self.workers < 1:
            raise InputError("--workers must be >= 1")
        from ..limits import TimeLimits

        self.limits = TimeLimits.of(timeout)   # a number: the whole-cell limit; or per phase (bench.run.limits)
        self.timeout = self.limits.cell
        # the volume cache folder is shared only when the workers run on this machine
        self.cache_dir = None if self.scheduler else cache_dir
        self.imports = list(imports or [])
        self.retries = int(retries)
        self.connect_timeout = connect_timeout
        self.wait_for_workers_s = wait_for_workers_s
        self.client = None
        self.cluster = None
        self.version_warnings: list[str] = []

    # ------------------------------------------------------------------ cluster
    def describe(self) -> dict:
        """What run.json records about the executor."""
        d = {"executor": "dask", "scheduler": self.scheduler or "LocalCluster",
             **self.limits.to_dict(), "retries": self.retries}
        if self.scheduler is None:
            d["workers"] = self.workers
        if self.client is not None:
            try:
                info = self.client.scheduler_info()
                d["workers_connected"] = len(info.get("workers", {}))
                d["threads"] = sum(w.get("nthreads", 0) for w in info.get("workers", {}).values())
            except Exception:  # noqa: BLE001 - metadata only
                pass
        if self.version_warnings:
            d["version_differences"] = list(self.version_warnings)
        return d

    def _check_reachable(self) -> None:
        m = _ADDRESS.match(self.scheduler)
        if m.group("scheme") != "tcp":
            return
        host = m.group("host").strip("[]")
        try:
            socket.create_connection((host, int(m.group("port"))), timeout=self.connect_timeout).close()
        except OSError as exc:
            raise InputError(f"cannot reach the Dask scheduler at {self.scheduler}: {exc.strerror or exc} "
                             f"(start one with `dask scheduler`)") from None

    def connect(self) -> "DaskExecutor":
        """Start the LocalCluster or connect to the scheduler, then check the workers (InputError if unusable)."""
        if self.client is not None:
            return self
        from distributed import Client, LocalCluster

        if self.scheduler is None:
            try:
                import bokeh  # noqa: F401
                dashboard = ":0"
            except ImportError:
                dashboard = None
            self.cluster = LocalCluster(n_workers=self.workers, threads_per_worker=1, processes=True,
                                        memory_limit=0, dashboard_address=dashboard,
                                        silence_logs=logging.ERROR)
            self.client = Client(self.cluster)
        else:
            self._check_reachable()
            try:
                self.client = Client(self.scheduler, timeout=self.connect_timeout)
            except Exception as exc:  # noqa: BLE001 - OSError, TimeoutError, comm errors
                raise InputError(f"cannot connect to the Dask scheduler at {self.scheduler}: "
                                 f"{type(exc).__name__}: {exc}") from None
        try:
            self._check_workers()
        except BaseException:
            self.close()
            raise
        return self

    def _check_workers(self) -> None:
        try:
            self.client.wait_for_workers(1, timeout=self.wait_for_workers_s)
        except Exception:  # noqa: BLE001 - TimeoutError
            raise InputError(f"no Dask worker connected to {self.scheduler} within {self.wait_for_workers_s:g} s "
                             f"(start workers with `dask worker {self.scheduler}`)") from None
        if self.imports:
            self.client.register_plugin(_plugin_class()(self.imports))
        try:
            checks = self.client.run(_worker_check, self.imports)
        except Exception as exc:  # noqa: BLE001 - e.g. the workers cannot even unpickle bench.run.executors.dask
            raise InputError(f"the Dask workers cannot run the suite ({type(exc).__name__}: {exc}); install it "
                             f"on every worker machine: {INSTALL_HINT}") from None
        bad = {w: c["errors"] for w, c in checks.items() if c["errors"]}
        if bad:
            worker, errs = next(iter(bad.items()))
            mod, err = next(iter(errs.items()))
            hint = (f"install the suite on every worker machine: {INSTALL_HINT}" if mod in ("bench.run.cell",
                    "bench.metrics", "methods") else "the module must be importable on every worker "
                    "(installed, or on the workers' PYTHONPATH)")
            if mod == "fingerprint":
                raise InputError(f"Dask worker {worker} cannot report which version of the suite it runs: {err}")
            raise InputError(f"{len(bad)} Dask worker(s) cannot import {mod!r} (e.g. {worker}: {err}); {hint}")
        error, self.version_warnings = compare_fingerprints(
            suite_fingerprint(), {w: c["fingerprint"] for w, c in checks.items()})
        if error:
            raise InputError(error)
        for line in self.version_warnings[:10]:
            print(f"warning: version differs on a Dask worker: {line}", file=sys.stderr)
        if len(self.version_warnings) > 10:
            print(f"warning: ... {len(self.version_warnings) - 10} more (all in run.json)", file=sys.stderr)

    def close(self) -> None:
        for obj in (self.client, self.cluster):
            if obj is not None:
                try:
                    obj.close()
                except Exception:  # noqa: BLE001 - best effort at shutdown
                    pass
        self.client = self.cluster = None

    def __enter__(self) -> "DaskExecutor":
        return self.connect()

    def __exit__(self, *exc) -> None:
        self.close()

    # ------------------------------------------------------------------ the run
    def run(self, cells: list[dict], on_start: Callable[[dict], None],
            on_result: Callable[[dict, dict], None]) -> None:
        owned = self.client is None
        if owned:
            self.connect()
        try:
            self._run(cells, on_start, on_result)
        finally:
            if owned:
                self.close()

    def _slots(self) -> int:
        try:
            return max(1, sum(w.get("nthreads", 1) for w in self.client.scheduler_info()["workers"].values()))
        except Exception:  # noqa: BLE001
            return self.workers

    def _run(self, cells, on_start, on_result) -> None:
        from concurrent.futures import CancelledError

        from distributed import as_completed
        from distributed.scheduler import KilledWorker

        from bench.run.cell import failed_result
        from bench.run.values import error_text

        if not cells:
            return
        token = uuid.uuid4().hex[:8]
        by_key: dict[str, dict] = {}
        futures = []
        submitted = {}
        for i, cell in enumerate(cells):
            key = f"bench-cell-{cell['cell_id']}-{token}"
            by_key[key] = cell
            fut = self.client.submit(run_cell_task, cell, self.cache_dir, self.limits, self.imports, key=key,
                                     retries=self.retries, priority=len(cells) - i)  # grid order first
            futures.append(fut)
            submitted[key] = time.monotonic()
        # progress: the client does not see a task start on a worker; announce cells in grid order, as many as
        # the cluster runs at once, and the next one whenever a result arrives
        announce = iter(cells)
        for _ in range(min(self._slots(), len(cells))):
            on_start(next(announce))
        seen: set[str] = set()
        lost: list[str] = []
        done = 0
        ac = as_completed(futures)
        try:
            for fut in ac:
                cell = by_key[fut.key]
                cid = cell["cell_id"]
                result = None
                if fut.status == "finished":
                    try:
                        result = fut.result()
                    except CancelledError:  # lost between "finished" and the fetch: no row, --resume
                        result = None
                    except Exception as exc:  # noqa: BLE001 - e.g. a result that cannot be deserialised
                        result = failed_result(cell, "failed", f"dask: cannot fetch the result: {error_text(exc)}")
                elif fut.status == "error":
                    exc = fut.exception()
                    if isinstance(exc, KilledWorker):
                        result = failed_result(cell, "failed", "crash: the Dask workers running this cell died "
                                                               "repeatedly (KilledWorker)")
                    else:
                        result = failed_result(cell, "failed", f"dask: {error_text(exc)}")
                        try:
                            import traceback

                            result["traceback"] = "".join(traceback.format_exception(exc))
                        except Exception:  # noqa: BLE001
                            pass
                fut.release()
                if result is None:  # cancelled / lost: no row, --resume completes it
                    lost.append(cid)
                    continue
                if cid in seen:  # pragma: no cover - Dask delivers one result per key
                    continue
                seen.add(cid)
                result["row"].setdefault("cell_s", time.monotonic() - submitted[fut.key])
                done += 1
                nxt = next(announce, None)
                if nxt is not None:
                    on_start(nxt)
                on_result(cell, result)
        finally:
            pending = [f for f in futures if f.status == "pending"]
            if pending:  # interrupted: stop the rest of the grid on the cluster
                try:
                    self.client.cancel(pending)
                except Exception:  # noqa: BLE001
                    pass
        if lost:
            raise DaskRunIncomplete(lost)
