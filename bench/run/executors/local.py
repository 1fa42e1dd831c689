"""The local executor: every cell in its own worker process, at most ``jobs`` at a time.

Processes come from a fork server that preloaded the suite, so starting one costs milliseconds, and a cell
that crashes, hangs (``timeout``) or leaks cannot take the others down: a crash or a timeout becomes a
``failed`` / ``timeout`` row and the run goes on.  Each cell process has an address-space limit
(``memory_gb``, :func:`bench.run.limits.apply_memory_limit`) and its own session and process group, so a
plug-in that kills its process group (``os.killpg(0, SIGKILL)``) kills only its own cell; one that kills its
parent — the fork server — orphans the cells running beside it, which the runner keeps watching through their
pipes (their rows arrive as usual) while the next cell starts a new fork server.  An executor is any object with
``run(cells, on_start, on_result)``; :class:`bench.run.executors.dask.DaskExecutor` is the other one.
"""

from __future__ import annotations

import os
import tempfile
import threading
import time
from collections import deque
from dataclasses import dataclass
from typing import Any, Callable

from ..cell import failed_result, run_cell
from ..contracts import Cell, CellResult
from ..limits import TimeLimits, apply_memory_limit, memory_phase
from ..values import error_text
from ...terminal import captured_head, redirect_output

__all__ = ["LocalExecutor"]


#: bytes of a cell's own stdout / stderr kept in its record
OUTPUT_KEPT = 4096


def _cell_process(cell: Cell, cache_dir: str | None, result_conn, lifeline_conn,
                  memory_gb: float | None = None) -> None:
    """Body of a worker process: run one cell, send the result, exit.  Exits at once if the runner dies.
    What the cell writes on stdout / stderr (a plug-in's prints, a library's warnings) goes to a temporary file;
    its first :data:`OUTPUT_KEPT` bytes, escaped, and its size are the row's ``method_output`` (the cell's json).

    The process leaves the runner's process group first (a new session: a plug-in's ``os.killpg(0, ...)``
    reaches only this cell; Ctrl-C reaches the runner, which kills its cells), then limits its own address
    space to ``memory_gb`` (after its watch thread has its stack)."""
    try:
        os.setsid()
    except OSError:  # already a group leader: nothing to leave
        pass

    def watch() -> None:
        try:
            lifeline_conn.recv()
        except (EOFError, OSError):
            pass
        os._exit(3)

    threading.Thread(target=watch, daemon=True).start()
    apply_memory_limit(memory_gb)

    def on_phase(phase: str, facts: dict) -> None:  # the parent's per-phase deadlines (bench.run.limits)
        result_conn.send(("phase", phase, facts))

    with tempfile.TemporaryFile() as out:          # what the method prints: kept in the record, not shown raw
        redirect_output(out.fileno())
        try:
            result = run_cell(cell, cache_dir, on_phase)
        except KeyboardInterrupt:  # a SIGINT sent to the cell itself (Ctrl-C reaches the runner, which kills it)
            os._exit(130)
        except BaseException as exc:  # run_cell catches Exception; this is SystemExit etc.
            result = failed_result(cell, "failed", f"worker: {error_text(exc)}")
        size, head = captured_head(out.fileno(), OUTPUT_KEPT)
    if size:
        result = result.with_row(method_output={"bytes": size, "head": head})
    try:
        result_conn.send(result)
    except Exception as exc:  # e.g. an unpicklable artifact: send the row alone
        row = result.row.updated(artifact_error=f"could not send artifacts: {error_text(exc)}")
        result_conn.send(CellResult(row, {}, result.traceback))
    result_conn.close()


@dataclass
class _Running:
    proc: Any
    conn: Any
    lifeline: Any
    cell: Cell
    started: float
    deadline: float | None
    phase: str = "setup"
    phase_started: float = 0.0
    facts: dict | None = None          # the method's wall time and info columns, once it returned
    orphan: bool = False               # its fork server died: only the pipe and the pid tell if it still runs


_THREAD_VARS = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMEXPR_NUM_THREADS")


class LocalExecutor:
    """Run cells in at most ``jobs`` worker processes at a time, each cell in its own process.

    Processes come from a fork server that preloaded the suite, so starting one costs milliseconds, and
    killing one (timeout) cannot take the others down.  The interface is kept tiny so another executor can
    replace it: ``run(cells, on_start, on_result)``.

    Parameters
    ----------
    jobs : int
        Cells run at once (at least 1).
    timeout : float or TimeLimits or None
        The time limits (:class:`bench.run.limits.TimeLimits`); a number is the whole-cell limit in seconds,
        None no limit.
    cache_dir : str, optional
        The shared volume cache of :func:`bench.run.cell.run_cell`.
    preload : list of str, optional
        Further modules the fork server imports once (e.g. plug-ins), so no cell pays for them.
    memory_gb : float, optional
        GB of address space per cell process; None: no limit.
    """

    def __init__(self, jobs: int, timeout: "float | TimeLimits | None", cache_dir: str | None = None,
                 preload: list[str] | None = None, memory_gb: float | None = None) -> None:
        self.jobs = max(1, int(jobs))
        self.memory_gb = memory_gb or None     # GB of address space per cell process (None: no limit)
        self.limits = TimeLimits.of(timeout)   # a number: the whole-cell limit
        self.timeout = self.limits.cell
        self.cache_dir = cache_dir
        self.preload = preload or []

    def _context(self):
        import multiprocessing as mp

        ctx = mp.get_context("forkserver")
        mods = ["bench.run.cell", "bench.metrics", "methods", "geometry", "trimesh",
                "scipy.spatial", "skimage.measure"] + [f"methods.{m}" for m in
                                                       ("marching_cubes", "mc_taubin", "distmesh", "poisson",
                                                        "shape_gradient")] + list(self.preload) \
            + ["bench.run.warmup"]       # last: the first calls of a cell's steps, paid once here, not per cell
        ctx.set_forkserver_preload(mods)
        # one BLAS/OpenMP thread per worker when several run at once (the fork server inherits this env)
        if self.jobs > 1:
            for var in _THREAD_VARS:
                os.environ.setdefault(var, "1")
        return ctx

    def _start(self, ctx, cell: Cell) -> _Running:
        recv_end, send_end = ctx.Pipe(duplex=False)
        life_recv, life_send = ctx.Pipe(duplex=False)
        proc = ctx.Process(target=_cell_process, args=(cell, self.cache_dir, send_end, life_recv, self.memory_gb),
                           name=f"cell-{cell.cell_id}", daemon=True)
        proc.start()
        send_end.close()
        life_recv.close()
        now = time.monotonic()
        return _Running(proc, recv_end, life_send, cell, now, self.limits.deadline(now, "setup", now), "setup", now)

    def _receive(self, r: _Running):
        """The cell's result if it sent one; phase messages move the cell's deadline (None: still running)."""
        while r.conn.poll():
            msg = r.conn.recv()
            if not (isinstance(msg, tuple) and len(msg) == 3 and msg[0] == "phase"):
                return msg
            now = time.monotonic()
            r.phase, r.phase_started = msg[1], now
            r.facts = msg[2] if msg[1] == "scoring" else r.facts
            r.deadline = self.limits.deadline(r.started, r.phase, now)
        return None

    @staticmethod
    def _kill(r: _Running) -> None:
        """Kill the cell's process and its process group (whatever it started); an orphan by its pid (its
        ``Process`` object believes it dead)."""
        import signal

        if r.orphan or r.proc.is_alive():
            for kill in (os.killpg, os.kill):
                try:
                    kill(r.proc.pid, signal.SIGKILL)
                except (ProcessLookupError, PermissionError, OSError):
                    pass
        r.proc.kill()

    def _gone(self, r: _Running) -> bool:
        """Whether the cell's process ended.  When its fork server dies (a plug-in killed its parent) the
        ``Process`` object reports exit code 255 at once although the cell still runs: such a cell becomes an
        orphan, watched through its pipe (EOF when it dies) and its pid."""
        if not r.orphan:
            if r.proc.is_alive():
                return False
            if r.proc.exitcode != 255 or not _pid_running(r.proc.pid):
                return True
            r.orphan = True
        return not _pid_running(r.proc.pid)

    def _timed_out(self, r: _Running) -> CellResult:
        """The row of a cell killed at its deadline: which limit ran out, in which phase."""
        self._kill(r)
        limit = self.limits.which(r.started, r.phase, r.phase_started)
        facts = r.facts or {}
        result = failed_result(r.cell, "timeout", self.limits.message(limit, r.phase, facts.get("wall_s")))
        return result.with_row({k: v for k, v in facts.items() if v is not None})

    @staticmethod
    def _finish(r: _Running) -> None:
        for c in (r.conn, r.lifeline):
            try:
                c.close()
            except OSError:
                pass
        r.proc.join(timeout=5)
        if r.proc.is_alive():  # pragma: no cover
            r.proc.kill()
            r.proc.join(timeout=5)
        if r.orphan and _pid_running(r.proc.pid):   # its lifeline is closed: it exits by itself; make sure
            LocalExecutor._kill(r)

    def run(self, cells: list[Cell], on_start: Callable[[Cell], None],
            on_result: Callable[[Cell, CellResult], None]) -> None:
        """Run ``cells`` and report each as it starts and ends; returns when all have ended.

        Parameters
        ----------
        cells : list of Cell
            The cells, started in this order.
        on_start : callable
            ``on_start(cell)``, as a cell's process starts.
        on_result : callable
            ``on_result(cell, result)`` with :func:`bench.run.cell.run_cell`'s :class:`CellResult`, or a ``timeout`` /
            ``failed`` result for a cell killed at its deadline or whose process ended without one.
        """
        from multiprocessing.connection import wait

        ctx = self._context()
        pending = deque(cells)
        running: list[_Running] = []
        try:
            while pending or running:
                while pending and len(running) < self.jobs:
                    cell = pending.popleft()
                    on_start(cell)
                    running.append(self._start(ctx, cell))
                deadlines = [r.deadline for r in running if r.deadline is not None]
                wait_s = max(0.0, min(deadlines) - time.monotonic()) if deadlines else None
                if any(r.orphan for r in running):   # an orphan's end shows on its pipe; its pid: poll it
                    wait_s = 1.0 if wait_s is None else min(wait_s, 1.0)
                wait([r.conn for r in running] + [r.proc.sentinel for r in running if not r.orphan],
                     timeout=wait_s)
                still = []
                for r in running:
                    try:
                        result = self._receive(r)
                        if result is None and self._gone(r):
                            result = self._receive(r) or self._crash(r)
                    except (EOFError, OSError):
                        result = self._crash(r)
                    if result is None and r.deadline is not None and time.monotonic() >= r.deadline:
                        result = self._timed_out(r)
                    if result is None:
                        still.append(r)
                        continue
                    self._finish(r)
                    if not result.row.has("cell_s"):
                        result = result.with_row(cell_s=time.monotonic() - r.started)
                    on_result(r.cell, result)
                running = still
        finally:
            for r in running:  # interrupted: stop what is still running
                self._kill(r)
                self._finish(r)

    def _crash(self, r: _Running) -> CellResult:
        """The row of a cell whose process ended without a result: how it ended, in which phase, and the memory
        limit when there was one (a library that cannot allocate may abort or crash instead of raising)."""
        if not r.orphan:
            r.proc.join(timeout=5)
        code = r.proc.exitcode
        where = memory_phase(r.phase)
        limit = (f"; memory limit ({self.memory_gb:.3g} GB) in force: an allocation over it ends some "
                 "libraries this way" if self.memory_gb else "")
        if r.orphan:
            why = "worker process ended without a result (its fork server died, so how it ended is unknown)"
        elif code is not None and code < 0:
            import signal

            try:
                name = signal.Signals(-code).name
            except ValueError:
                name = str(-code)
            why = f"worker process killed by {name}" + (" (out of memory?)" if name == "SIGKILL" else "")
        else:
            why = f"worker process exited with code {code} without a result"
        return failed_result(r.cell, "failed", f"crash: {why} {where}{limit}")


def _pid_running(pid: int | None) -> bool:
    """Whether a process ``pid`` exists (an orphaned cell is reaped by init, so a dead one soon does not)."""
    if not pid:
        return False
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # pragma: no cover - another user's process took the pid
        return False
    return True


