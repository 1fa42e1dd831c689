"""Refuse, before it runs, a cell whose method would not finish within the cell's time limit; say how long a run
has left (:class:`RemainingTime`, learnt from its own cells per method and input size, with a range).

A method may declare a cost model (:meth:`methods.Method.estimate_seconds`, from the grid's size).  Before the
executor starts, :func:`screen_cells` asks each cell's method for its estimate at the cell's N and compares it
with the tightest time limit that applies to the method — ``--timeout`` (the whole cell) or
``--method-timeout``.  A cell over it is not run: it is recorded at once as a ``failed`` row whose ``error``
gives the estimate and the limit, ``estimated 47 min > timeout 10 min (use --force to run it anyway)``, and
whose ``estimate_s`` column holds the estimate (the report's failed-cells list shows the error).  ``--force``
(or ``run.force = true``) skips the check; a method without a model, a run without a time limit and a user
volume on its native grid (N unknown before the file is read) are never refused.  The check runs in the
runner, before any volume is built, so it works the same for every executor.

The built-in models estimate a quiet machine's seconds (fitted to CPU time): on a loaded machine a cell takes
longer than its estimate, so the check refuses only cells that would not finish even there — it never replaces
the time limit, which still kills a cell that runs out of it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable

import numpy as np

from phantoms import InputError

from .cell import failed_result
from .contracts import Cell, CellResult
from .grid import as_cell
from .limits import TimeLimits

__all__ = ["method_estimate", "method_budget", "refusal", "screen_cells", "format_duration", "check_force",
           "RemainingTime", "SCALING_PHASES"]


def format_duration(seconds: float) -> str:
    """``"45 s"``, ``"47 min"``, ``"3.2 h"``: a duration as people read it."""
    if seconds < 120:
        return f"{seconds:.3g} s"
    if seconds < 7200:
        return f"{seconds / 60:.3g} min"
    return f"{seconds / 3600:.3g} h"


def method_estimate(cell: Cell) -> float | None:
    """The cell's method's estimate in seconds at the cell's N (None: no model, no N, a model that raises or
    returns no finite number ≥ 0, or a method that cannot even be built — that cell fails on its own when it
    runs)."""
    if not cell.n:
        return None
    from methods import get_method

    try:
        estimate = get_method(cell.method, **cell.params).estimate_seconds((cell.n,) * 3)
    except Exception:  # noqa: BLE001 - a broken method or model must not stop the run: it is not refused
        return None
    try:
        estimate = None if estimate is None else float(estimate)
    except (TypeError, ValueError):  # not a number: no usable model
        return None
    return estimate if estimate is not None and math.isfinite(estimate) and estimate >= 0 else None


def method_budget(limits: TimeLimits) -> tuple[float, str] | None:
    """``(seconds, name)`` of the tightest limit on the method's run: the cell's (``timeout``) or the
    method's own (``method timeout``); None when neither is set."""
    options = [(s, name) for s, name in ((limits.cell, "timeout"), (limits.method, "method timeout")) if s]
    return min(options) if options else None


def refusal(cell: Cell, limits: TimeLimits, force: bool = False) -> CellResult | None:
    """The ``failed`` result of a cell whose estimate exceeds its budget (see the module docstring); None when
    it may run."""
    budget = method_budget(limits)
    if force or budget is None:
        return None
    estimate = method_estimate(cell)
    if estimate is None or estimate <= budget[0]:
        return None
    error = (f"estimated {format_duration(estimate)} > {budget[1]} {format_duration(budget[0])} "
             "(use --force to run it anyway)")
    return failed_result(cell, "failed", error).with_row(estimate_s=round(estimate, 3), cell_s=0.0)


def screen_cells(cells: list[Cell], limits: TimeLimits, force: bool, on_start: Callable[[Cell], None],
                 on_result: Callable[[Cell, CellResult], None]) -> list[Cell]:
    """The cells to run; each refused one is reported at once (``on_start``, then ``on_result`` with its
    failed row), as if an executor had run it."""
    todo = []
    for cell in map(as_cell, cells):
        result = refusal(cell, limits, force)
        if result is None:
            todo.append(cell)
            continue
        on_start(cell)
        on_result(cell, result)
    return todo


def check_force(value, what: str = "run.force") -> bool:
    """``value`` as the ``force`` setting: True or False, else an :class:`InputError` naming ``what``."""
    if not isinstance(value, bool):
        raise InputError(f"{what}: expected true or false, got {value!r}")
    return value


# ---------------------------------------------------------------------------------------------- time left
#: a cell's phases (``phase_s``) whose seconds grow with its surface: the method, the validity check, the metrics
#: and the pictures (not the volume's building nor the method's imports and warm-up)
SCALING_PHASES = ("method", "validity", "metrics", "artifacts")

def _size_key(cell: Cell):
    """What a cell's cost scales with besides its method: N, or for a user volume on its native grid the file
    (every label of a label map shares its grid)."""
    if cell.n:
        return int(cell.n)
    return (cell.source or cell.phantom).split("?")[0]


def _surface(cell: Cell) -> int | None:
    """The surface size of a label of a label map (:func:`phantoms.labels.label_surfaces`), None for any other
    input: the labels of one map share its grid, but not their cost."""
    source = cell.source or cell.phantom
    if cell.n or not source.startswith("volume:") or "label=" not in source:
        return None
    from phantoms.labels import label_surfaces
    from phantoms.user import parse_spec

    try:
        label = parse_spec(source)[1].get("label")
    except Exception:  # noqa: BLE001 — a spec the cell will refuse itself
        return None
    return label_surfaces(source).get(label) or None


@dataclass
class _Guess:
    """One cell's expected seconds ``mean``, its own spread ``spread`` (cell to cell) and ``shared``, the error
    of the mean it comes from (the same for every cell of its group: those errors add up, the spreads do not)."""

    mean: float
    spread: float
    shared: float
    group: tuple


class RemainingTime:
    """The time a run has left, learnt from its own cells: each finished cell's seconds (as the cell measured
    them, times the median over the cells of the runner's start-to-result time over them) per method label and
    input size (N, or the file of a native-grid volume; a label of a label map scales its surface-bound phases by
    its surface, :func:`phantoms.labels.label_surfaces`).  A cell to run is expected to take the mean of its
    (label, size) group; a label seen at another N scales by the power of N its
    own cells show (N³ with one size); a label not seen yet on a label map by the other labels' fixed and
    per-surface seconds there, elsewhere by the method's cost model calibrated on the cells seen
    (:meth:`methods.Method.estimate_seconds`), else by the median cell.  The sum over the cells left is
    divided by the parallelism the run shows (the most cells seen running at once).

    :meth:`text` gives it with its uncertainty: ``about T left (LOW–HIGH)`` (durations as :func:`format_duration`
    writes them), the range ±1.64 σ of the sum — the cell-to-cell spread of each group and the error of its mean
    (large while a group has few cells)."""

    def __init__(self, cells: list[Cell], now: float) -> None:
        self.t0 = now
        self.most = 0                 # the most cells seen running at once: the run's parallelism
        self.overheads: list[float] = []   # a cell's start-to-result seconds over its own (the process, its result)
        self.pending: dict[str, Cell] = {c.cell_id: c for c in map(as_cell, cells)}
        self.started: dict[str, float] = {}
        self.seconds: dict[tuple, list[float]] = {}     # (label, size) → seconds of its finished cells
        self.examples: dict[tuple, Cell] = {}           # (label, size) → one of its cells (for the cost model)
        # (label, label map) → (seconds that do not grow with the label's surface, seconds per surface voxel)
        self.parts: dict[tuple, list[tuple[float, float]]] = {}
        self.work = 0.0                                 # cell-seconds of the finished cells
        self._models: dict[tuple, float | None] = {}

    def start(self, cell: Cell, now: float) -> None:
        self.started[cell.cell_id] = now
        self.most = max(self.most, sum(cid in self.pending for cid in self.started))

    def finish(self, cell: Cell, seconds_in_cell: float | None, now: float, scaling_s: float | None = None) -> None:
        """Learn from a finished cell: its seconds from its start (when seen) or its own ``cell_s``, of which
        ``scaling_s`` (its method, validity, metrics and pictures: what grows with the surface) when known; a cell
        that did not run (refused before it started, ``cell_s`` 0) teaches nothing."""
        self.pending.pop(cell.cell_id, None)
        t_start = self.started.pop(cell.cell_id, None)
        if seconds_in_cell is not None and seconds_in_cell <= 0:
            return
        seen = now - t_start if t_start is not None else None
        seconds = seconds_in_cell if seconds_in_cell is not None else seen
        if seconds is None or not math.isfinite(seconds) or seconds < 0:
            return
        if seen is not None and seconds_in_cell is not None:
            self.overheads.append(max(seen / seconds_in_cell, 1.0))
        group = (cell.label, _size_key(cell))
        self.seconds.setdefault(group, []).append(float(seconds))
        surface = _surface(cell)
        if surface and scaling_s is not None and 0 <= scaling_s <= seconds:
            self.parts.setdefault(group, []).append((float(seconds) - scaling_s, float(scaling_s) / surface))
        self.examples.setdefault(group, cell)
        self.work += float(seconds)

    # ------------------------------------------------------------------ the guesses
    def _model(self, cell: Cell) -> float | None:
        key = (cell.label, cell.n)
        if key not in self._models:
            self._models[key] = method_estimate(cell) or None
        return self._models[key]

    def _guess(self, cell: Cell) -> _Guess:
        label, size = cell.label, _size_key(cell)
        own = self.seconds.get((label, size))
        parts, surface = self.parts.get((label, size)), _surface(cell)
        if parts and surface:     # a label of a label map: its fixed seconds, and the rest by its surface
            guesses = [fixed + per * surface for fixed, per in parts]
            m = float(np.mean(guesses))
            sd = float(np.std(guesses, ddof=1)) if len(guesses) > 1 else 0.0
            sd = max(sd, 0.25 * m)           # the surface explains only part of what a label costs
            return _Guess(m, sd, sd / math.sqrt(len(guesses)), (label, size))
        if own:
            m = float(np.mean(own))
            sd = float(np.std(own, ddof=1)) if len(own) > 1 else 0.5 * m
            return _Guess(m, sd, sd / math.sqrt(len(own)) if len(own) > 1 else 0.5 * m, (label, size))
        sizes = {s: float(np.mean(v)) for (lab, s), v in self.seconds.items() if lab == label and isinstance(s, int)}
        if sizes and isinstance(size, int):
            near = min(sizes, key=lambda s: abs(math.log(s / size)))
            power = 3.0
            if len(sizes) > 1:
                ns = np.log(np.array(list(sizes), float))
                power = float(np.clip(np.polyfit(ns, np.log(list(sizes.values())), 1)[0], 0.5, 4.0))
            m = sizes[near] * (size / near) ** power
            return _Guess(m, 0.5 * m, 0.5 * m, (label, size))
        if surface:               # a method not seen on this label map yet: the other methods' fixed and per-surface
            others = [float(np.mean([f + p * surface for f, p in v]))
                      for (_, sz), v in self.parts.items() if sz == size]
            if others:
                m = float(np.median(others))
                return _Guess(m, 0.5 * m, 0.5 * m, (label, size))
        model = self._model(cell)
        ratios = []
        if model:                 # the cost model's ratio between methods, scaled to this machine by the cells seen
            for group, v in self.seconds.items():
                est = self._model(self.examples[group])
                if est:
                    ratios.append(float(np.mean(v)) / est)
        if ratios:
            m = float(np.median(ratios)) * model
        else:
            m = float(np.median([np.mean(v) for v in self.seconds.values()]))
        return _Guess(m, m, m, (label, size))

    def expected(self, now: float) -> tuple[float, float, float] | None:
        """``(seconds left, low, high)`` of wall time, or None before any cell finished."""
        if not self.seconds or not self.pending:
            return None if self.pending else (0.0, 0.0, 0.0)
        running = {cid: now - t for cid, t in self.started.items() if cid in self.pending}
        # the workers seen running side by side; without starts (Dask) the cell-seconds per second of the run
        parallel = float(self.most) if self.most else max(1.0, self.work / max(now - self.t0, 1e-9))
        overhead = float(np.median(self.overheads)) if self.overheads else 1.0
        total, var_spread, shared = 0.0, 0.0, {}
        for cid, cell in self.pending.items():
            g = self._guess(cell)
            g = _Guess(g.mean * overhead, g.spread * overhead, g.shared * overhead, g.group)
            left = max(g.mean - running.get(cid, 0.0), 0.0)
            total += left
            var_spread += g.spread ** 2
            shared[g.group] = shared.get(g.group, 0.0) + g.shared * (left / g.mean if g.mean > 0 else 0.0)
        sigma = math.sqrt(var_spread + sum(v ** 2 for v in shared.values()))
        return total / parallel, max(total - 1.64 * sigma, 0.0) / parallel, (total + 1.64 * sigma) / parallel

    def text(self, now: float) -> str:
        """``about T left (LOW–HIGH)``; empty before any cell finished or when nothing is left."""
        got = self.expected(now)
        if got is None or not self.pending:
            return ""
        mid, lo, hi = got
        return f"about {format_duration(mid)} left ({format_duration(lo)}–{format_duration(hi)})"
