"""Shared machinery of the pytest-benchmark suites: the same-session reference and each benchmark's ratio to it.

Absolute times depend on the machine and on what else it is doing; the ratio of a benchmark's median to the
median of a *reference* measured in the same session does much less.  The reference is marching cubes
(``methods.get_method("marching_cubes")``) on the ellipsoid at N = 96, the volume the method benchmarks use.

* :func:`reference` (session scope) times the reference ``REF_ROUNDS`` times after one warm-up call.
* Before every benchmark the autouse fixture :func:`_ratio_to_reference` times ``REF_TOPUP`` more rounds into
  the same pool, so the reference samples the machine's load all through the session and not only during
  its first second; after the benchmark it writes into ``benchmark.extra_info``::

      ratio               benchmark median / reference median (wall clock; pool so far, final: see below)
      cpu_ratio           the same with CPU time: user + system seconds of the process, its threads and its
                          descendant processes over each round (bench.perf.process_tree_cpu)
      cpu_median_s        the benchmark's median CPU seconds per round
      reference_median_s, reference_cpu_median_s   the reference medians the ratios use
      ratio_of_minima     fastest round / fastest reference round (information only)
      loadavg_1min        the 1-minute load average when the benchmark finished

  CPU time is recorded by swapping pytest-benchmark's timer for :class:`bench.perf.CpuRecordingTimer`, which
  still returns wall-clock time, so pytest-benchmark's own statistics stay wall-clock.  CPU time barely moves
  when other processes compete for the cores (a time-sliced process is not charged for the time it waits),
  which is why the gate compares ``cpu_ratio`` by default.

  At the end of the session every ratio is recomputed with the whole pool (``ratio_at_test`` keeps the
  value seen at the time), so all ratios of one session share one denominator.  ``--benchmark-json`` also
  gains a top-level ``levelset_bench`` entry (reference times, load averages, mode).

Modes (environment ``LSB_PERF_MODE``, set by ``python -m bench perf``): ``full`` (default) or ``quick`` —
fewer rounds (:func:`rounds`) and the tests marked ``perf_slow`` skipped.

Every test collected under ``tests/benchmarks`` is marked ``benchmark``, so the default ``pytest`` run (which
deselects ``-m benchmark``) never runs one by accident.
"""

from __future__ import annotations

import os
import statistics
import time
from pathlib import Path

import pytest

from bench.perf import CpuRecordingTimer, perf_mode, process_tree_cpu

HERE = Path(__file__).resolve().parent

MODE = perf_mode()
QUICK = MODE == "quick"
#: reference rounds at the start of the session, and before every benchmark
REF_ROUNDS = int(os.environ.get("LSB_PERF_REF_ROUNDS", "5" if QUICK else "9"))
REF_TOPUP = int(os.environ.get("LSB_PERF_REF_TOPUP", "2" if QUICK else "3"))
#: the reference: marching cubes on the ellipsoid (sdf variant) at N = 96
REF_PHANTOM, REF_N = "ellipsoid", 96


def _loadavg() -> list[float] | None:
    try:
        return [round(x, 2) for x in os.getloadavg()]
    except (AttributeError, OSError):
        return None


class Reference:
    """The same-session reference: a growing pool of marching-cubes timings and their median."""

    def __init__(self, volume) -> None:
        from methods import get_method

        self.volume = volume
        self.method = get_method("marching_cubes")
        self.times: list[float] = []
        self.cpu_times: list[float] = []
        self.loadavg_start = _loadavg()
        self._records: list[tuple[dict, float, float]] = []  # (extra_info, median, min) to finalise

    def sample(self, n: int) -> None:
        for _ in range(n):
            c0 = process_tree_cpu(self_last=True)
            t0 = time.perf_counter()
            self.method.reconstruct(self.volume)
            t1 = time.perf_counter()
            self.cpu_times.append(process_tree_cpu(self_last=False) - c0)
            self.times.append(t1 - t0)

    @property
    def median(self) -> float:
        return statistics.median(self.times)

    @property
    def cpu_median(self) -> float:
        return statistics.median(self.cpu_times)

    def record(self, extra_info: dict, median_s: float, min_s: float, cpu_median_s: float | None) -> None:
        extra_info["ratio_at_test"] = median_s / self.median
        extra_info["loadavg_1min"] = (_loadavg() or [None])[0]
        extra_info["mode"] = MODE
        extra_info["cpu_median_s"] = cpu_median_s
        self._records.append((extra_info, median_s, min_s, cpu_median_s))
        self._fill(extra_info, median_s, min_s, cpu_median_s)

    def _fill(self, extra: dict, med: float, lo: float, cpu: float | None) -> None:
        extra["ratio"] = med / self.median
        extra["ratio_of_minima"] = lo / min(self.times)   # for information: the gate uses medians
        extra["reference_median_s"] = self.median
        cm = self.cpu_median
        extra["cpu_ratio"] = cpu / cm if cpu is not None and cm > 0 else None
        extra["reference_cpu_median_s"] = cm

    def finalise(self) -> None:
        for rec in self._records:
            self._fill(*rec)

    def summary(self) -> dict:
        t = sorted(self.times)
        return {
            "what": f"methods.get_method('marching_cubes').reconstruct({REF_PHANTOM} sdf volume, N = {REF_N})",
            "median_s": self.median if t else None,
            "cpu_median_s": self.cpu_median if t else None,
            "min_s": t[0] if t else None,
            "max_s": t[-1] if t else None,
            "rounds": len(t),
            "times_s": [round(x, 5) for x in self.times],
            "cpu_times_s": [round(x, 5) for x in self.cpu_times],
        }


_SESSION: dict = {}


@pytest.fixture(scope="session")
def ellipsoid_volume_96():
    """The ellipsoid (sdf variant) on the default 96³ grid over [−2.5, 2.5]³: input of the method benchmarks
    and of the reference."""
    from phantoms import get_phantom

    return get_phantom(REF_PHANTOM).volume(n=REF_N)


@pytest.fixture(scope="session")
def reference(ellipsoid_volume_96):
    ref = Reference(ellipsoid_volume_96)
    ref.sample(1)          # warm-up (imports, first-touch allocations): not kept
    ref.times.clear()
    ref.cpu_times.clear()
    ref.sample(REF_ROUNDS)
    _SESSION["reference"] = ref
    yield ref
    ref.finalise()
    ref.loadavg_end = _loadavg()


@pytest.fixture(autouse=True)
def _ratio_to_reference(request):
    """For tests using ``benchmark``: top up the reference pool, then record the ratio in ``extra_info``."""
    if "benchmark" not in request.fixturenames:
        yield
        return
    ref: Reference = request.getfixturevalue("reference")
    bm = request.getfixturevalue("benchmark")
    ref.sample(REF_TOPUP)
    timer = None
    if hasattr(bm, "_timer"):  # pytest-benchmark internals: a wall-clock timer that also records CPU time
        timer = bm._timer = CpuRecordingTimer()
    yield
    stats = getattr(bm, "stats", None)
    if stats is None or getattr(bm, "disabled", False):   # --benchmark-disable, or the test never timed
        return
    n = int(stats.stats.rounds)
    cpu = None
    if timer is not None and len(timer.cpu) >= n > 0:
        cpu = statistics.median(timer.cpu[-n:]) / max(1, int(getattr(stats, "iterations", 1) or 1))
    ref.record(bm.extra_info, float(stats.stats.median), float(stats.stats.min), cpu)


def pytest_configure(config):
    config.addinivalue_line("markers", "perf_slow: benchmark skipped by `python -m bench perf --quick`")


@pytest.hookimpl(tryfirst=True)
def pytest_collection_modifyitems(config, items):
    for item in items:
        if HERE in Path(str(item.fspath)).resolve().parents:
            if item.get_closest_marker("benchmark") is None:
                item.add_marker(pytest.mark.benchmark)
            if QUICK and item.get_closest_marker("perf_slow") is not None:
                item.add_marker(pytest.mark.skip(reason="perf_slow: skipped in quick mode"))
                _SESSION.setdefault("skipped", []).append(item.name)


def pytest_benchmark_update_json(config, benchmarks, output_json):
    ref = _SESSION.get("reference")
    output_json["levelset_bench"] = {
        "mode": MODE,
        "reference": ref.summary() if ref is not None else None,
        "loadavg_start": getattr(ref, "loadavg_start", None),
        "loadavg_end": getattr(ref, "loadavg_end", None) or _loadavg(),
        "cpu_count": os.cpu_count(),
        "skipped": sorted(_SESSION.get("skipped", [])),
    }
