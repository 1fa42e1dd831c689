"""Cost of one call: wall-clock time and peak memory (docs/METRICS.md ``wall_s``, ``peak_mem_mb``).

>>> from bench.run.cost import measure
>>> result, cost = measure(method.reconstruct, volume)          # doctest: +SKIP
>>> cost                                                         # doctest: +SKIP
{'wall_s': 1.93, 'peak_mem_mb': 212.4}

What is measured
----------------
* ``wall_s``: ``time.perf_counter()`` around the call alone (no metrics, no I/O done by the caller).
* ``peak_mem_mb``: the peak **resident set size** of the process during the call minus its resident size
  just before the call, in MiB (2²⁰ bytes).  RSS sees every allocation that touches memory — numpy, and
  also C/C++ libraries (pymeshlab, scipy's C code) that ``tracemalloc`` cannot see.  How the peak is read,
  best first (see :func:`memory_backend`):

  1. ``"hwm"`` (Linux): reset the kernel's high-water mark by writing ``5`` to ``/proc/self/clear_refs``,
     run the call, read ``VmHWM`` from ``/proc/self/status``.  Exact: no sampling, no short spike missed.
  2. ``"sampled"`` (Linux without a writable ``clear_refs``): a daemon thread reads the RSS from
     ``/proc/self/statm`` every ``interval`` seconds (default 2 ms) while the call runs; spikes shorter
     than the interval can be missed.
  3. ``"none"`` (no ``/proc``): ``peak_mem_mb`` is NaN.

Caveats: the process's own bookkeeping counts too (other threads allocating at the same time); memory the
allocator already holds from earlier frees is reused without raising the RSS, so a call that only reuses
such memory reads low — run each measured call in a fresh process (the runner does) for clean numbers.
The result is never negative (a call that frees memory reads 0).

``measure`` is not reentrant for the ``"hwm"`` backend (the high-water mark is process-wide): a nested
``measure`` resets the outer one's peak; the outer reading then covers only the time after the inner call
started (still ≥ the inner peak).  Exceptions from the call propagate unchanged.
"""

from __future__ import annotations

import math
import os
import threading
import time

__all__ = ["measure", "memory_backend", "current_rss_mb"]

_MB = 1024.0 * 1024.0
_PAGE = os.sysconf("SC_PAGE_SIZE") if hasattr(os, "sysconf") else 4096


def current_rss_mb() -> float:
    """Resident set size of this process now, MiB (NaN without ``/proc``)."""
    try:
        with open("/proc/self/statm") as fh:
            return int(fh.read().split()[1]) * _PAGE / _MB
    except (OSError, ValueError, IndexError):
        return float("nan")


def _status_kb(field: str) -> float:
    try:
        with open("/proc/self/status") as fh:
            for line in fh:
                if line.startswith(field + ":"):
                    return float(line.split()[1])
    except (OSError, ValueError, IndexError):
        pass
    return float("nan")


def _reset_hwm() -> bool:
    try:
        with open("/proc/self/clear_refs", "w") as fh:
            fh.write("5")
        return True
    except OSError:
        return False


_BACKEND: str | None = None


def memory_backend() -> str:
    """How peak memory is measured here: ``"hwm"``, ``"sampled"`` or ``"none"`` (see module doc)."""
    global _BACKEND
    if _BACKEND is None:
        if math.isnan(current_rss_mb()):
            _BACKEND = "none"
        elif _reset_hwm() and not math.isnan(_status_kb("VmHWM")):
            _BACKEND = "hwm"
        else:
            _BACKEND = "sampled"
    return _BACKEND


class _Sampler(threading.Thread):
    def __init__(self, interval: float):
        super().__init__(daemon=True, name="bench-cost-rss-sampler")
        self.interval = interval
        self.peak = current_rss_mb()
        self._stop_event = threading.Event()

    def run(self):
        while not self._stop_event.is_set():
            self.peak = max(self.peak, current_rss_mb())
            self._stop_event.wait(self.interval)

    def stop(self) -> float:
        self._stop_event.set()
        self.join()
        return max(self.peak, current_rss_mb())


def measure(fn, *args, interval: float = 0.002, **kw):
    """Call ``fn(*args, **kw)`` once; return ``(result, {"wall_s": float, "peak_mem_mb": float})``.

    ``interval`` is the RSS sampling period for the ``"sampled"`` backend (keyword reserved: it is not
    passed on to ``fn``).
    """
    backend = memory_backend()
    sampler = None
    if backend == "hwm":
        _reset_hwm()
    before = current_rss_mb()
    if backend == "sampled":
        sampler = _Sampler(interval)
        sampler.start()
    t0 = time.perf_counter()
    try:
        result = fn(*args, **kw)
    finally:
        wall = time.perf_counter() - t0
        if sampler is not None:
            peak = sampler.stop()
        elif backend == "hwm":
            peak = _status_kb("VmHWM") / 1024.0
        else:
            peak = float("nan")
    return result, {"wall_s": float(wall), "peak_mem_mb": float(max(0.0, peak - before))
                    if not math.isnan(peak) else float("nan")}
