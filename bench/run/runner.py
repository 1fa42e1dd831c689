"""Run a grid into a run folder: the cells not done yet, through an executor, each result stored at once.

:func:`run_grid` expands the config, skips the cells already in the folder (``resume``), hands the rest to an
executor (the local process pool by default), writes every finished cell's record at once through
:mod:`bench.run.store` and ``results.csv`` / ``results.parquet`` at checkpoints (:mod:`bench.run.checkpoints`:
their writing grows with the grid, not with its square; always at the end of the session, an interrupted one
too), writes ``run.json``, shows progress, and returns a :class:`RunSummary`.  It does not render the
report: the command line does that after the run.
"""

from __future__ import annotations

import contextlib
import datetime as _dt
import os
import shutil
import sys
import time
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from geometry.files import WriteError

from ..terminal import printable
from .audit import REJECTED, set_aside
from .checkpoints import ResultTables
from .contracts import Cell, CellResult, ResultRow
from .estimate import SCALING_PHASES, RemainingTime, screen_cells
from .executors.local import LocalExecutor
from .grid import expand_grid
from .identity import MixedCodeError, changed_methods, code_identity, config_fingerprint, mixed_code
from .inputs import ExecutorSpec, check_run_inputs
from .integrity import UNSEALED
from .limits import TimeLimits
from .lock import RunLock
from .options import RunOptions, memory_limit, time_limits
from .provenance import environment
from .store import CACHE_DIR, IGNORED, clean_temp_files, read_json, save_cell, scan_cells, write_json

__all__ = ["RunOptions", "RunSummary", "memory_limit", "run_grid", "time_limits"]

STATUSES = ("ok", "invalid", "failed", "timeout")
#: the method declined the cell's input (:meth:`methods.Method.skip_reason`): a row, not a failure; counted in
#: :attr:`RunSummary.statuses` (``RunSummary.skipped`` counts the cells a resumed run found done)
SKIPPED = "skipped"


def _now() -> str:
    return _dt.datetime.now().astimezone().isoformat(timespec="seconds")


@dataclass
class RunSummary:
    """What a run did: cell counts by status, how many ran now and how many were already done.

    Parameters
    ----------
    out : Path
        The run folder.
    total : int
        Cells in the grid.
    ok, invalid, failed, timeout : int
        Finished cells by status.
    skipped : int
        Cells already done before this run (``--resume``).
    ran : int
        Cells run now.
    seconds : float
        Wall time of the run.
    report, report_error : Path or str, optional
        The report written after the run, or why it could not be.
    statuses : dict
        Further counts by status: ``skipped`` (the method declined the input).
    """

    out: Path
    total: int
    ok: int = 0
    invalid: int = 0
    failed: int = 0
    timeout: int = 0
    skipped: int = 0
    ran: int = 0
    seconds: float = 0.0
    report: Path | None = None
    report_error: str | None = None
    statuses: dict = field(default_factory=dict)

    def line(self) -> str:
        parts = [f"{self.ok} ok"] + ([f"{self.invalid} invalid"] if self.invalid else []) \
            + [f"{self.failed} failed", f"{self.timeout} timeout"] + [f"{n} {k}" for k, n in self.statuses.items()]
        resumed = f", {self.skipped} already done" if self.skipped else ""
        where = f" → {self.report}" if self.report else f" → {self.out}"
        return (f"{self.total} cells: {', '.join(parts)} ({self.ran} run{resumed}) in "
                f"{self.seconds:.1f} s{where}")


class RunLog:
    """``run.json``: the config, provenance, cell counts, timings and one entry per session (a resumed run
    appends its session to the earlier ones)."""

    def __init__(self, out: Path, cfg, n_cells: int, session: dict, resume: bool) -> None:
        self.path = Path(out) / "run.json"
        self.cfg = cfg
        self.n_cells = n_cells
        self.session = session
        previous = read_json(self.path, {}) if resume and self.path.exists() else {}
        self.previous = previous if isinstance(previous, dict) else {}  # a damaged run.json: start it again
        self.started = time.time()
        self.mixed_code: dict = {}

    def write(self, records: dict[str, dict], end: bool, cells_run: int = 0) -> None:
        sessions = list(self.previous.get("sessions", []))
        s = dict(self.session)
        if end:
            s["end"] = _now()
            s["total_s"] = round(time.time() - self.started, 3)
            s["cells_run"] = cells_run
        sessions.append(s)
        rows = [r["row"] for r in records.values()]
        by_method: dict[str, list[float]] = {}
        for r in rows:
            if r.value("wall_s") is not None:
                by_method.setdefault(r.value("label", "?"), []).append(float(r.value("wall_s")))
        meta = {
            "suite": "levelset-bench",
            "config": self.cfg.to_dict(),
            "config_source": self.cfg.source,
            "cells": {"total": self.n_cells, "finished": len(records),
                      "status": {k: sum(1 for r in rows if r.status == k) for k in STATUSES + (SKIPPED,)}},
            "start": self.previous.get("start", self.session["start"]),
            "end": s.get("end"),
            "total_s": round(sum(x.get("total_s", 0.0) for x in sessions), 3),
            "timings": {"cells_s_sum": round(sum(float(r.cell_s or 0.0) for r in rows), 3),
                        "method_wall_s_mean": {k: round(float(np.mean(v)), 4) for k, v in by_method.items()}},
            "sessions": sessions,
            "config_fingerprint": config_fingerprint(self.cfg.to_dict()),
            **({"mixed_code": self.mixed_code} if self.mixed_code else {}),
            **environment(),
        }
        write_json(self.path, meta)


class _Progress:
    """Progress over the cells: on a terminal a tqdm bar naming the cell running, the failures so far and the time
    left; otherwise (a log file, a pipe) a plain line ``progress: 12/72 cells, 1 not ok, about 4 min left`` at
    each tenth of the cells, at least every :data:`LOG_EVERY_S` seconds and at the end — a long run or
    ``--resume`` never runs in silence."""

    #: seconds between two plain progress lines when stderr is not a terminal
    LOG_EVERY_S = 30.0

    def __init__(self, total: int, done: int, show: bool, log: bool = True, todo: list[Cell] | None = None) -> None:
        from tqdm import tqdm

        self.show, self.log = show, log and not show
        self.total, self.done, self.start_done, self.failed = total, done, done, 0
        self.t0 = self.last_log = time.monotonic()
        self.left = RemainingTime(todo or [], self.t0)      # learns each method's seconds from its cells
        self.bar = tqdm(total=total, initial=done, unit="cell", disable=not show, dynamic_ncols=True,
                        desc="cells", file=sys.stderr)
        if self.log and total > done:
            print(f"progress: {done}/{total} cells done, {total - done} to run", file=sys.stderr, flush=True)

    def start(self, cell: Cell) -> None:
        self.left.start(cell, time.monotonic())
        self.bar.set_postfix_str(printable(f"{cell.phantom}/{cell.noise}/{cell.label}")
                                 + (f", {self.failed} failed" if self.failed else ""), refresh=True)

    def finish(self, cell: Cell, row: ResultRow) -> None:
        self.done += 1
        cell_s = row.value("cell_s", None)
        phases = row.value("phase_s", None) or {}
        scaling = sum(float(v) for k, v in phases.items() if k in SCALING_PHASES and isinstance(v, (int, float)))
        self.left.finish(cell, float(cell_s) if isinstance(cell_s, (int, float)) else None, time.monotonic(),
                         scaling if phases else None)
        if self.show:
            eta = self.left.text(time.monotonic())
            self.bar.set_description_str(f"cells ({eta})" if eta else "cells", refresh=False)
        if row.status != "ok":
            self.failed += row.status != SKIPPED      # a skipped cell is shown, but is no failure
            if self.show:
                self.bar.write(printable(f"{row.status}: {cell.cell_id}: {row.value('error', '')}"))
        self.bar.update(1)
        now = time.monotonic()
        tenth = max(1, (self.total - self.start_done) // 10)
        if self.log and (now - self.last_log >= self.LOG_EVERY_S or self.done == self.total
                         or (self.done - self.start_done) % tenth == 0):
            self.last_log = now
            print(self.line(now), file=sys.stderr, flush=True)

    def line(self, now: float) -> str:
        """``progress: done/total cells, failed, time left`` (:class:`~bench.run.estimate.RemainingTime`: from
        the seconds of this session's cells per method and input size, with its range)."""
        eta = "" if self.done >= self.total else self.left.text(now)
        return f"progress: {self.done}/{self.total} cells, {self.failed} not ok" + (f", {eta}" if eta else "")

    def close(self) -> None:
        self.bar.close()


def _changed_note(method: str, entry: dict) -> str:
    n = len(entry["cells"])
    where = f" (plug-in {', '.join(entry['files'])})" if entry["files"] else ""
    why = ("its cells were computed before the suite recorded a plug-in's code" if entry["unknown"]
           else "changed since its cells were computed")
    return f"note: method {method!r} {why}{where}; rerunning its {n} cell{'s' if n != 1 else ''}"


def _load_done(out: Path, cells: list[Cell], resume: bool, retry_failed: bool,
               allow_mixed_code: bool) -> tuple[dict, dict, dict, dict]:
    """The finished cells to keep (verified: a cell whose json or npz does not load is rerun, with a warning;
    a cell whose plug-in method's code changed since is rerun, with a note per method), ``{code: cells}`` when
    several versions of the code are (or would be) mixed, and ``{method: cells rerun}`` of the changed plug-ins.
    That the folder's config gives the same grid was checked before the run (:func:`check_run_inputs`).
    Last, ``{cell_id: checksum}`` of every sealed record found (:func:`~bench.run.audit.set_aside` keeps those)."""
    if not resume:
        return {}, {}, {}, {}
    ids = {c.cell_id for c in cells}
    found, problems = scan_cells(out, verify_artifacts=True)
    for msg in problems:   # an unsealed or altered record is recomputed, never copied into results.csv
        tail = "" if msg.endswith(f"{IGNORED})") else "; the cell will be rerun"
        print(printable(f"warning: {msg}{tail}"), file=sys.stderr)
    if any(UNSEALED in msg for msg in problems):
        print(printable(f"note: records written before seals are sealed once with `python -m bench report {out} "
                        "--accept-unsealed` (instead of being recomputed)"), file=sys.stderr)
    known = {cid: rec.get("checksum") for cid, rec in found.items()}
    records = {k: v for k, v in found.items() if k in ids}
    if retry_failed:
        records = {k: v for k, v in records.items() if v["row"].status == "ok"}
    changed = changed_methods(records, cells)       # rerun and overwritten: one row per cell, the new code's
    for entry in changed.values():
        for cid in entry["cells"]:
            del records[cid]
    # the current code counts when it will compute cells (a complete run's report can be re-rendered)
    mixed = mixed_code(records, code_identity() if len(records) < len(cells) else None) if records else {}
    if mixed and not allow_mixed_code:
        raise MixedCodeError(f"--resume: the cells in {str(out)!r} were computed by other code than this "
                             f"({'; '.join(f'{k}: {n} cells' for k, n in mixed.items())}); rerun into a new "
                             "--out, or pass --allow-mixed-code to mix them (run.json and the report say so)")
    for method, entry in changed.items():
        print(printable(_changed_note(method, entry)), file=sys.stderr)
    return records, mixed, {m: len(e["cells"]) for m, e in changed.items()}, known


def _set_aside(out: Path, known: dict, records: dict) -> None:
    """End of a session: a record file the runner did not write or find sealed (a plug-in's, a stray copy) is
    set aside as ``.rejected``, with a warning; a cell whose record was replaced is dropped (it reruns)."""
    gone = set_aside(out, known)
    for cid in gone:
        records.pop(cid, None)
    if gone:
        shown = ", ".join(gone[:5]) + (f" and {len(gone) - 5} more" if len(gone) > 5 else "")
        print(printable(f"warning: {len(gone)} cell record(s) not written by the runner (a plug-in's?) set aside "
                        f"as cells/*.json{REJECTED}: {shown}"), file=sys.stderr)


def run_grid(cfg, out: str | Path, options: RunOptions | None = None, **overrides) -> RunSummary:
    """Run every cell of the validated config ``cfg`` into the folder ``out``.

    Every input is checked first (:func:`~bench.run.inputs.check_run_inputs`: an :class:`~phantoms.InputError`
    before anything runs); the folder is locked for the run (:mod:`bench.run.lock`).

    Parameters
    ----------
    cfg : bench.config.RunConfig
        The validated grid configuration.
    out : str or Path
        The run folder (created; with ``resume``, an earlier run's folder).
    options : RunOptions, optional
        How to run it: jobs, resume, limits, executor ... (default: :class:`~bench.run.options.RunOptions`'s).
    **overrides
        Fields of :class:`~bench.run.options.RunOptions` replacing those of ``options``:
        ``run_grid(cfg, out, jobs=2, resume=True)`` is ``run_grid(cfg, out, RunOptions(jobs=2, resume=True))``.

    Returns
    -------
    RunSummary
        Cell counts by status, how many ran now, the seconds taken.

    Raises
    ------
    InputError
        A bad input (folder, config, limits, executor) — before anything runs.
    geometry.files.WriteError
        A write error (disk full, ...), after the finished cells are saved.
    TypeError
        An override that is no field of :class:`~bench.run.options.RunOptions`.
    """
    opts = replace(options or RunOptions(), **overrides)
    out = Path(out)
    executor = check_run_inputs(cfg, out, **opts.input_checks())
    limits = time_limits(cfg, opts.timeout, opts.method_timeout, opts.score_timeout)
    with RunLock(out), _started(executor, cfg, out, limits) as ex:
        clean_temp_files(out)
        return _run_locked(cfg, out, opts, ex)


@contextlib.contextmanager
def _started(executor, cfg, out: Path, limits: TimeLimits):
    """The executor object for the run: None (the local pool, built by the run) for a ``local`` spec, a connected
    :class:`~bench.run.executors.dask.DaskExecutor` for a ``dask`` one (closed after the run), else ``executor``."""
    if not isinstance(executor, ExecutorSpec):
        yield executor
    elif executor.kind == "local":
        yield None
    else:
        from .executors.dask import DaskExecutor

        with DaskExecutor(scheduler=executor.scheduler, workers=executor.workers, timeout=limits,
                          cache_dir=str(out / CACHE_DIR), imports=list(cfg.imports)) as dask:
            print(f"dask: {dask.describe()}", file=sys.stderr)
            yield dask


def _expected_cost(cell: Cell) -> float:
    """A rough relative cost of a cell (the method's ``relative_cost`` × N³, noisy cells more): the runner starts
    the dearest cells first, so that the workers finish together instead of one running the longest cell alone
    at the end.  Results are written in grid order whatever the order of running."""
    from methods import get_method

    try:
        rel = float(getattr(get_method(cell.method, **cell.params), "relative_cost", 1.0))
    except Exception:  # noqa: BLE001 — a cell that cannot even build its method fails fast anyway
        rel = 1.0
    return rel * (cell.n / 96.0) ** 3 * (1.5 if cell.noise != "none" else 1.0)


@dataclass
class _Plan:
    """A session decided before any cell runs: the grid, what is done and kept, what to run, the limits and
    the session's entry of run.json."""

    cells: list[Cell]
    todo: list[Cell]                  # the dearest first
    records: dict[str, dict]          # {cell_id: record} of the finished cells: filled as cells finish
    known: dict[str, dict | None]     # {cell_id: checksum} of the sealed records found or written
    mixed: dict                       # {code: cells} when versions of the code are mixed
    limits: TimeLimits
    jobs: int
    memory: float | None              # GB per local cell process
    force: bool
    code: dict
    session: dict


def _plan(cfg, out: Path, opts: RunOptions, executor) -> _Plan:
    """The session's plan from the config, the options and the folder's finished cells; records the config
    (``config.json``) before anything runs."""
    cells = expand_grid(cfg)
    limits = time_limits(cfg, opts.timeout, opts.method_timeout, opts.score_timeout)
    force = bool(opts.force or cfg.force)
    jobs = opts.jobs or os.cpu_count() or 1
    memory = memory_limit(cfg, opts.memory_gb, jobs) if executor is None else None   # local cells only
    records, mixed, changed, known = _load_done(out, cells, opts.resume, opts.retry_failed, opts.allow_mixed_code)
    write_json(out / "config.json", cfg.to_dict())
    code = code_identity()
    todo = sorted((c for c in cells if c.cell_id not in records), key=_expected_cost, reverse=True)
    session = {"start": _now(), "argv": opts.argv if opts.argv is not None else sys.argv[1:], "jobs": jobs,
               **limits.to_dict(), "memory_limit_gb": memory, "cells_to_run": len(todo),
               "resumed_from": len(cells) - len(todo),
               "code": code, "allow_mixed_code": bool(opts.allow_mixed_code), "force": force,
               **({"methods_changed": changed} if changed else {}),
               "executor": (executor.describe() if hasattr(executor, "describe") else {"executor": "local"})}
    return _Plan(cells, todo, records, known, mixed, limits, jobs, memory, force, code, session)


def _count(summary: RunSummary, records: dict[str, dict]) -> None:
    """Add the finished cells to the summary's counts by status."""
    for r in records.values():
        st = r["row"].status
        if st in STATUSES:
            setattr(summary, st, getattr(summary, st) + 1)
        elif st == SKIPPED:
            summary.statuses[st] = summary.statuses.get(st, 0) + 1


def _run_locked(cfg, out: Path, opts: RunOptions, executor) -> RunSummary:
    plan = _plan(cfg, out, opts, executor)
    cells, records, known = plan.cells, plan.records, plan.known
    summary = RunSummary(out=out, total=len(cells), skipped=len(cells) - len(plan.todo))
    log = RunLog(out, cfg, len(cells), plan.session, opts.resume)
    log.mixed_code = plan.mixed
    log.write(records, end=False)
    bar = _Progress(len(cells), summary.skipped, sys.stderr.isatty() if opts.progress is None else opts.progress,
                    log=opts.progress is None, todo=plan.todo)
    if bar.show:
        bar.bar.write(printable(f"{cfg.name}: {len(cells)} cells → {out}"), file=sys.stderr)
    tables = ResultTables(out, [c.cell_id for c in cells], records)

    def on_result(cell: Cell, result: CellResult) -> None:
        known[cell.cell_id] = save_cell(out, cell, result, opts.save_meshes, code=plan.code)
        # a record as read back by --resume (bench.run.store.scan_cells): plain dicts, the row a ResultRow
        records[cell.cell_id] = {"row": result.row, "cell": cell.to_dict(), "code": plan.code}
        tables.finished()
        summary.ran += 1
        bar.finish(cell, result.row)

    if executor is None:
        executor = LocalExecutor(plan.jobs, plan.limits, cache_dir=str(out / CACHE_DIR), preload=list(cfg.imports),
                                 memory_gb=plan.memory)
    error = None
    try:
        todo = screen_cells(plan.todo, plan.limits, plan.force, bar.start, on_result)   # over their estimate: failed
        executor.run(todo, bar.start, on_result)
    except BaseException as exc:
        error = exc
        raise
    finally:
        bar.close()
        _set_aside(out, known, records)
        _count(summary, records)
        summary.seconds = time.time() - log.started
        try:  # after a write error these may fail too: the first error is the one to report
            tables.write()
            write_json(out / "config.json", cfg.to_dict())     # again: a plug-in may have removed it
            log.write(records, end=True, cells_run=summary.ran)
        except WriteError:
            if error is None:
                raise
    if len(records) == len(cells):  # complete: the volume cache is only needed to resume
        shutil.rmtree(out / CACHE_DIR, ignore_errors=True)
    return summary
