"""Time limits of a cell: the whole cell, the method alone, the scoring alone.

A cell runs in phases — ``setup`` (plug-ins, the volume, the noise), ``method`` (``method.reconstruct``) and
``scoring`` (validity check and metrics).  :func:`bench.run.cell.run_cell` reports each phase change to the
executor, which kills the cell's process when the phase's deadline passes:

* ``cell``   (``--timeout`` / ``run.timeout``): from the start of the cell, every phase;
* ``method`` (``--method-timeout`` / ``run.method_timeout``): from the start of ``method.reconstruct``;
* ``score``  (``--score-timeout`` / ``run.score_timeout``): from the moment the method returned.

The ``timeout`` row's ``error`` names the limit and the phase that ran out, so a method that finished in 0.05 s
whose mesh took 30 s to score is not mistaken for a slow method.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass

from phantoms import InputError

__all__ = ["TimeLimits", "PHASES", "MAX_SECONDS", "check_seconds"]

PHASES = ("setup", "method", "scoring")

# The longest limit the platform can wait for: the executors wait with poll()/select(), whose timeout is a C int
# of milliseconds (2**31 - 1 ms, about 24.8 days); threading's own ceiling is far larger on 64-bit machines.
MAX_SECONDS = float(min(threading.TIMEOUT_MAX, (2 ** 31 - 1) // 1000))


def check_seconds(value, what: str) -> float | None:
    """``value`` (seconds, None or 0 = no limit) range-checked: an :class:`InputError` naming ``what`` when it
    is not a finite number in [0, :data:`MAX_SECONDS`], instead of an ``OverflowError`` once the run started."""
    if value is None:
        return None
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise InputError(f"{what}: not a number: {value!r}") from None
    if not 0 <= v <= MAX_SECONDS:
        raise InputError(f"{what}: must be between 0 (no limit) and {MAX_SECONDS:.0f} s (about "
                         f"{MAX_SECONDS / 86400:.1f} days, the longest wait this platform can represent); "
                         f"got {value!r}")
    return v


def _positive(value, what: str) -> float | None:
    value = check_seconds(value, what)
    return value if value else None


@dataclass(frozen=True)
class TimeLimits:
    """Seconds allowed per cell, per method run and per scoring; None = no limit."""

    cell: float | None = None
    method: float | None = None
    score: float | None = None

    def __post_init__(self) -> None:
        for name, what in (("cell", "timeout"), ("method", "method timeout"), ("score", "score timeout")):
            object.__setattr__(self, name, _positive(getattr(self, name), what))

    @classmethod
    def of(cls, value) -> "TimeLimits":
        """A :class:`TimeLimits` from one itself, or from a number / None (the whole-cell limit, as before)."""
        return value if isinstance(value, TimeLimits) else cls(cell=value)

    def __bool__(self) -> bool:
        return any(v is not None for v in (self.cell, self.method, self.score))

    def deadline(self, started: float, phase: str, phase_started: float) -> float | None:
        """The time (same clock as the arguments) at which a cell in ``phase`` is killed; None = never."""
        ends = [started + self.cell] if self.cell else []
        if phase == "method" and self.method:
            ends.append(phase_started + self.method)
        if phase == "scoring" and self.score:
            ends.append(phase_started + self.score)
        return min(ends) if ends else None

    def which(self, started: float, phase: str, phase_started: float) -> str:
        """Which limit a cell killed at its deadline ran out of: ``cell``, ``method`` or ``score``."""
        own = {"method": self.method, "scoring": self.score}.get(phase)
        if own and (not self.cell or phase_started + own <= started + self.cell):
            return "method" if phase == "method" else "score"
        return "cell"

    def message(self, limit: str, phase: str, method_s: float | None = None) -> str:
        """The ``error`` of a timed-out cell: which limit, in which phase."""
        ran = f"; the method itself finished in {method_s:.3g} s" if method_s is not None else ""
        if limit == "method":
            return f"timeout in the method: no result after the method limit of {self.method:g} s (cell killed)"
        if limit == "score":
            return (f"timeout in scoring (validity check and metrics): over the score limit of {self.score:g} s "
                    f"(cell killed){ran}")
        where = {"setup": "building the volume", "method": "in the method",
                 "scoring": "in scoring (validity check and metrics)"}.get(phase, phase)
        return f"timeout: no result after {self.cell:g} s (cell killed) — {where}{ran}"

    def to_dict(self) -> dict:
        return {"timeout_s": self.cell, "method_timeout_s": self.method, "score_timeout_s": self.score}
