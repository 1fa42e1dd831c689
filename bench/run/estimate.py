"""Refuse, before it runs, a cell whose method would not finish within the cell's time limit.

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
from typing import Callable

from phantoms import InputError

from .cell import failed_result
from .contracts import Cell, CellResult
from .grid import as_cell
from .limits import TimeLimits

__all__ = ["method_estimate", "method_budget", "refusal", "screen_cells", "format_duration", "check_force"]


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
