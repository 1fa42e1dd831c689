"""Timing the benchmarks: the suite's mode and rounds (environment), and the CPU time of the whole process
tree (this process, its threads and every worker process it started), recorded around each timed round by
:class:`CpuRecordingTimer` — CPU time is charged only while a process runs, so other load on a shared machine
moves it much less than wall-clock time."""

from __future__ import annotations

import os
import time

__all__ = [
    "ENV_MODE", "ENV_ROUNDS", "ENV_SLOWDOWN", "slowdown_for", "perf_mode", "rounds", "process_tree_cpu",
    "CpuRecordingTimer",
]

ENV_MODE = "LSB_PERF_MODE"
ENV_ROUNDS = "LSB_PERF_ROUNDS"


def perf_mode() -> str:
    """``"quick"`` or ``"full"`` (environment ``LSB_PERF_MODE``; default full)."""
    mode = os.environ.get(ENV_MODE, "full").strip().lower()
    return "quick" if mode == "quick" else "full"


def rounds(full: int, quick: int) -> int:
    """Rounds a benchmark runs in the current mode (``LSB_PERF_ROUNDS`` overrides both)."""
    forced = os.environ.get(ENV_ROUNDS, "").strip()
    if forced:
        return max(1, int(forced))
    return quick if perf_mode() == "quick" else full


_CLK = os.sysconf("SC_CLK_TCK") if hasattr(os, "sysconf") else 100


def _children_of(pid: int) -> list[int]:
    try:
        tasks = os.listdir(f"/proc/{pid}/task")
    except OSError:
        return []
    out: list[int] = []
    for t in tasks:
        try:
            with open(f"/proc/{pid}/task/{t}/children") as fh:
                out += [int(x) for x in fh.read().split()]
        except (OSError, ValueError):
            continue
    return out


def _descendants_cpu() -> float:
    """CPU seconds (user + system, own + reaped children) of the live descendants of this process (Linux
    ``/proc``; 0 elsewhere).  A descendant that is reaped later moves its time into its parent's children
    time, which is counted too: nothing is lost or counted twice between two readings."""
    total = 0.0
    todo, seen = _children_of(os.getpid()), set()
    while todo:
        pid = todo.pop()
        if pid in seen:
            continue
        seen.add(pid)
        try:
            with open(f"/proc/{pid}/stat") as fh:
                fields = fh.read().rsplit(")", 1)[1].split()
            total += sum(int(x) for x in fields[11:15]) / _CLK   # utime stime cutime cstime
        except (OSError, ValueError, IndexError):
            continue
        todo += _children_of(pid)
    return total


def _own_cpu() -> float:
    import resource

    s, c = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    return s.ru_utime + s.ru_stime + c.ru_utime + c.ru_stime


def process_tree_cpu(*, self_last: bool = True) -> float:
    """CPU seconds used so far by this process, its threads and every descendant process (the worker processes
    of the grid runner, forked from a fork server, included).  ``self_last``: read this process's own time
    after scanning ``/proc`` (use at the start of a measured interval, and ``self_last=False`` at its end, so
    the scan's own CPU falls outside the interval)."""
    if self_last:
        d = _descendants_cpu()
        return d + _own_cpu()
    own = _own_cpu()
    return own + _descendants_cpu()


#: test hook of the gate's detection measurement: ``NAME=FACTOR`` makes every benchmark whose name contains
#: NAME run FACTOR times as long (a busy loop inside each timed round: CPU and wall time alike)
ENV_SLOWDOWN = "LSB_PERF_SLOWDOWN"


def slowdown_for(name: str) -> float:
    """The injected slowdown factor of benchmark ``name`` (:data:`ENV_SLOWDOWN`; 1.0 = none)."""
    spec = os.environ.get(ENV_SLOWDOWN, "").strip()
    if not spec or "=" not in spec:
        return 1.0
    key, _, factor = spec.rpartition("=")
    try:
        f = float(factor)
    except ValueError:
        return 1.0
    return f if key and key in name and f > 1.0 else 1.0


def _spin(until_cpu: float) -> None:
    x = 0
    while time.process_time() < until_cpu:
        for i in range(2000):
            x += i


class CpuRecordingTimer:
    """A pytest-benchmark timer: returns ``time.perf_counter()`` (the statistics stay wall-clock) and records
    the CPU time of the process tree over each timed interval in :attr:`cpu` (one entry per timed call,
    warm-up rounds included; the calls alternate start, end).  ``before``: called at each start, before the
    clocks are read (outside the timed interval) — the benchmarks time a reference round there."""

    __name__ = "perf_counter+cpu"

    def __init__(self, before=None, slowdown: float = 1.0) -> None:
        import time

        self._clock = time.perf_counter
        self._before = before
        self._start: float | None = None
        self._t0 = 0.0
        self.slowdown = float(slowdown)
        self.cpu: list[float] = []

    def __call__(self) -> float:
        if self._start is None:
            if self._before is not None:
                self._before()
            self._start = process_tree_cpu(self_last=True)
            self._t0 = self._clock()
            return self._t0
        if self.slowdown > 1.0:            # test hook: a real (factor − 1) × longer busy loop inside the interval
            _spin(time.process_time() + (self.slowdown - 1.0) * (self._clock() - self._t0))
        t = self._clock()
        self.cpu.append(process_tree_cpu(self_last=False) - self._start)
        self._start = None
        return t
