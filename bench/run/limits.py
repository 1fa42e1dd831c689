"""Time limits of a cell: the whole cell, the method alone, the scoring alone.

A cell runs in phases — ``setup`` (plug-ins, the volume, the noise), ``method`` (``method.reconstruct``) and
``scoring`` (validity check and metrics).  :func:`bench.run.cell.run_cell` reports each phase change to the
executor, which kills the cell's process when the phase's deadline passes:

* ``cell``   (``--timeout`` / ``run.timeout``): from the start of the cell, every phase;
* ``method`` (``--method-timeout`` / ``run.method_timeout``): from the start of ``method.reconstruct``;
* ``score``  (``--score-timeout`` / ``run.score_timeout``): from the moment the method returned.

The ``timeout`` row's ``error`` names the limit and the phase that ran out, so a method that finished in 0.05 s
whose mesh took 30 s to score is not mistaken for a slow method.

Memory (``--memory-limit`` / ``run.memory_limit``, GB = 2**30 bytes; 0 = none; default
:func:`default_memory_gb`: 75 % of the machine's physical memory divided by the number of jobs) is limited in
the cell's own process, by the kernel: :func:`apply_memory_limit` sets ``RLIMIT_AS`` (the process's virtual
address space) before the cell starts, so an allocation over it fails there (``MemoryError``) instead of the
machine swapping or the kernel's OOM killer picking a victim among the other cells.  :func:`memory_error`
turns such a failure into the row's ``error``: ``memory limit (N GB) exceeded in the method`` / ``in scoring
(validity check and metrics)`` / ``building the volume``.

What a normal cell needs: the address space counts every mapping, not just the memory in use — the libraries
the fork server preloaded (numba's LLVM, scipy, pymeshlab, VTK ...), thread stacks (8 MiB each) and malloc's
per-thread arenas (64 MiB of reserve each).  Measured on the 2-core, 23 GiB machine (Python 3.11), a marching
cubes cell at N = 48, sphere and torus, with and without noise: VmPeak 0.99 GB with ``--jobs 2`` (one
BLAS/OpenMP thread per worker), 1.05 GB with ``--jobs 1``; the resident peak (VmHWM) 0.18 GB.  At N = 96
(sphere, two jobs): marching cubes 1.01 GB, DistMesh 1.03 GB, Poisson 1.13 GB, shape_gradient 1.82 GB (resident
0.20 / 0.22 / 0.34 / 0.49 GB).  So no limit under about 1.5 GB is usable, the test limit is 2 GB, and the
default (8.8 GB per cell there with two jobs) is never below :data:`DEFAULT_MEMORY_FLOOR_GB`.
"""

from __future__ import annotations

import math
import os
import threading
from dataclasses import dataclass

from phantoms import InputError

__all__ = ["TimeLimits", "PHASES", "MAX_SECONDS", "check_seconds", "GB", "MAX_MEMORY_FACTOR", "physical_memory_gb",
           "default_memory_gb", "check_gb", "apply_memory_limit", "current_memory_limit_gb", "memory_phase",
           "memory_error", "is_memory_error"]

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
        """A :class:`TimeLimits` from one itself, or from a number / None (the whole-cell limit alone)."""
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


# ---------------------------------------------------------------------------------------------- memory
#: bytes in the GB of ``--memory-limit`` (GiB)
GB = 2 ** 30
#: the largest memory limit accepted, in multiples of the machine's physical memory (address space may exceed
#: it — mapped files, swap — but a limit far above it protects nothing and is surely a typo)
MAX_MEMORY_FACTOR = 4.0
#: the share of the physical memory the cells of a run may use together by default
DEFAULT_MEMORY_SHARE = 0.75
#: the smallest default limit, GB (never above the physical memory): the address space a normal cell maps is
#: about 1 GB before it allocates anything, and shape_gradient at N = 96 peaks at 1.8 GB, so on a machine with
#: many cores and little memory per core the share alone would fail normal cells
DEFAULT_MEMORY_FLOOR_GB = 4.0


def physical_memory_gb() -> float | None:
    """This machine's physical memory in GB (None where the platform does not tell)."""
    try:
        return os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES") / GB
    except (AttributeError, ValueError, OSError):
        return None


def default_memory_gb(jobs: int) -> float | None:
    """The default per-cell limit: 75 % of the physical memory divided by ``jobs``, but at least
    :data:`DEFAULT_MEMORY_FLOOR_GB` (or the physical memory, if less); None: unknown memory."""
    phys = physical_memory_gb()
    if not phys:
        return None
    return max(DEFAULT_MEMORY_SHARE * phys / max(1, int(jobs)), min(DEFAULT_MEMORY_FLOOR_GB, phys))


def check_gb(value, what: str) -> float | None:
    """``value`` (GB; None = unset, 0 = no limit) range-checked: an :class:`InputError` naming ``what`` unless it
    is 0 or a finite positive number (not a string, not a bool) of at most :data:`MAX_MEMORY_FACTOR` × the
    physical memory."""
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise InputError(f"{what}: expected a number of GB, got {value!r}")
    v = float(value)
    phys = physical_memory_gb()
    top = MAX_MEMORY_FACTOR * phys if phys else math.inf
    if not (v == 0 or 0 < v <= top) or math.isinf(v):
        bound = f" and {top:.4g} GB ({MAX_MEMORY_FACTOR:g} x this machine's {phys:.3g} GB)" if phys else ""
        raise InputError(f"{what}: must be 0 (no limit) or a memory size in GB between 0{bound}; got {value!r}")
    return v


def apply_memory_limit(gb: float | None) -> None:
    """Limit this process's address space (``RLIMIT_AS``) to ``gb`` GB (None / 0: leave it); never above the
    hard limit the process already has."""
    if not gb:
        return
    import resource

    soft, hard = resource.getrlimit(resource.RLIMIT_AS)
    want = int(gb * GB)
    if hard != resource.RLIM_INFINITY:
        want = min(want, hard)
    resource.setrlimit(resource.RLIMIT_AS, (want, hard))


def current_memory_limit_gb() -> float | None:
    """This process's address-space limit in GB (None: unlimited or not available)."""
    try:
        import resource

        soft = resource.getrlimit(resource.RLIMIT_AS)[0]
    except (ImportError, AttributeError, OSError, ValueError):
        return None
    return None if soft == resource.RLIM_INFINITY or soft < 0 else soft / GB


def memory_phase(stage: str) -> str:
    """Where a cell was when it ran out of memory, from :func:`bench.run.cell.run_cell`'s stage (or a phase of
    :data:`PHASES`): in the method, in scoring, or building the volume."""
    if stage in ("method setup", "reconstruction", "method"):
        return "in the method"
    if stage in ("validity", "metrics", "pictures", "scoring"):
        return "in scoring (validity check and metrics)"
    return "building the volume"


def is_memory_error(exc: BaseException) -> bool:
    """A failed allocation: a ``MemoryError`` anywhere in the exception's chain (a method may wrap it), or a
    thread that could not get its stack."""
    seen = set()
    while exc is not None and id(exc) not in seen:
        seen.add(id(exc))
        if isinstance(exc, MemoryError) or (isinstance(exc, RuntimeError)
                                            and "can't start new thread" in str(exc)):
            return True
        exc = exc.__cause__ or exc.__context__
    return False


def memory_error(exc: BaseException, stage: str, gb: float | None = None) -> str | None:
    """The row's ``error`` of a cell that ran out of memory under a limit (``gb``; default: this process's
    own); None when ``exc`` is no memory error or no limit is in force."""
    gb = gb if gb is not None else current_memory_limit_gb()
    if not gb or not is_memory_error(exc):
        return None
    from .values import error_text

    return f"memory limit ({gb:.3g} GB) exceeded {memory_phase(stage)} ({error_text(exc, 300)})"
