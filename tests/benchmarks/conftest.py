"""Shared machinery of the pytest-benchmark suites: the same-session reference and each benchmark's ratio to it.

Absolute times depend on the machine and on what else it is doing; the ratio of a benchmark's median to the
median of a *reference* measured in the same session does much less.  The reference is marching cubes
(``methods.get_method("marching_cubes")``) on the ellipsoid at N = 96, the volume the method benchmarks use.

* :func:`reference` (session scope) warms the reference up and times it ``REF_ROUNDS`` times.
* Around every benchmark the autouse fixture :func:`_ratio_to_reference` times more reference rounds:
  ``REF_TOPUP`` before the benchmark, one just before each of its rounds (outside the timed interval) and
  ``REF_TOPUP`` after it, and divides the benchmark by those rounds — the ones measured *around it*.  It writes
  into ``benchmark.extra_info``::

      ratio               benchmark median / median of the reference rounds around it (wall clock)
      cpu_ratio           benchmark mean / mean of the reference rounds around it, in CPU time (user + system
                          seconds of the process, its threads and its descendant processes, over each round:
                          bench.perf.process_tree_cpu); means trimmed of the lowest and highest tenth
      cpu_mean_s, cpu_median_s   the benchmark's CPU seconds per round
      reference_median_s, reference_cpu_mean_s, reference_rounds   the reference values the ratios use
      ratio_session, cpu_ratio_session   the same against every reference round of the session
      ratio_of_minima     fastest round / fastest reference round of the session (information only)
      loadavg_1min        the 1-minute load average when the benchmark finished

  Why CPU time: a time-sliced process is not charged for the time it waits, so other processes competing for
  the cores barely move it; the gate compares ``cpu_ratio`` by default.  Why means, around the benchmark, for
  CPU time: on the shared virtual machine the CPU itself changes speed in phases of a few seconds — the
  reference's *user* time alternates between ≈ 50 and ≈ 80 ms with no page faults and no other load — so a
  benchmark round of several seconds averages over phases, and the reference rounds spread around it estimate
  the same average (a median would snap to one phase or the other).  Wall-clock times still use medians
  (preemption makes their outliers one-sided).

  CPU time is recorded by swapping pytest-benchmark's timer for :class:`bench.perf.CpuRecordingTimer`, which
  still returns wall-clock time, so pytest-benchmark's own statistics stay wall-clock.  ``--benchmark-json``
  also gains a top-level ``levelset_bench`` entry (every reference round, load averages, mode).

Modes (environment ``LSB_PERF_MODE``, set by ``python -m bench perf``): ``full`` (default) or ``quick`` —
fewer rounds (:func:`bench.perf.rounds`) and the tests marked ``perf_slow`` skipped.

Every test collected under ``tests/benchmarks`` is marked ``benchmark``, so the default ``pytest`` run (which
deselects ``-m benchmark``) never runs one by accident.
"""

from __future__ import annotations

import os
import statistics
import time
from pathlib import Path

import pytest

from bench.perf.timing import CpuRecordingTimer, perf_mode, process_tree_cpu, slowdown_for

HERE = Path(__file__).resolve().parent

MODE = perf_mode()
QUICK = MODE == "quick"
#: reference rounds at the start of the session, and before every benchmark
REF_ROUNDS = int(os.environ.get("LSB_PERF_REF_ROUNDS", "5" if QUICK else "9"))
REF_TOPUP = int(os.environ.get("LSB_PERF_REF_TOPUP", "2" if QUICK else "3"))
#: the reference: marching cubes on the ellipsoid (sdf variant) at N = 96
REF_PHANTOM, REF_N = "ellipsoid", 96


def trimmed_mean(values: list[float]) -> float:
    """Mean without the lowest and highest tenth (none below 10 values)."""
    v = sorted(values)
    k = len(v) // 10
    v = v[k:len(v) - k] if k else v
    return sum(v) / len(v)


def _loadavg() -> list[float] | None:
    try:
        return [round(x, 2) for x in os.getloadavg()]
    except (AttributeError, OSError):
        return None


class Reference:
    """The same-session reference: a growing pool of marching-cubes timings (wall and CPU seconds)."""

    def __init__(self, volume) -> None:
        from methods import get_method

        self.volume = volume
        self.method = get_method("marching_cubes")
        self.times: list[float] = []
        self.cpu_times: list[float] = []
        self.loadavg_start = _loadavg()
        self._records: list[tuple[dict, float, float, float | None]] = []  # to finalise: extra, median, min, cpu

    def sample(self, n: int) -> list[tuple[float, float]]:
        """Time ``n`` rounds; add them to the pool and return them as (wall, cpu) pairs."""
        out = []
        for _ in range(n):
            c0 = process_tree_cpu(self_last=True)
            t0 = time.perf_counter()
            self.method.reconstruct(self.volume)
            t1 = time.perf_counter()
            out.append((t1 - t0, process_tree_cpu(self_last=False) - c0))
        self.times += [w for w, _ in out]
        self.cpu_times += [c for _, c in out]
        return out

    @property
    def median(self) -> float:
        return statistics.median(self.times)

    @property
    def cpu_median(self) -> float:
        return statistics.median(self.cpu_times)

    def record(self, extra: dict, median_s: float, min_s: float, cpu_rounds: list[float] | None,
               local: list[tuple[float, float]]) -> None:
        """Write the ratios of a benchmark (its round times and the reference rounds ``local`` around it)."""
        ref_wall = statistics.median(w for w, _ in local)
        ref_cpu = trimmed_mean([c for _, c in local])
        cpu = trimmed_mean(cpu_rounds) if cpu_rounds else None
        extra["ratio"] = median_s / ref_wall
        extra["cpu_ratio"] = cpu / ref_cpu if cpu is not None and ref_cpu > 0 else None
        extra["cpu_mean_s"] = cpu
        extra["cpu_median_s"] = statistics.median(cpu_rounds) if cpu_rounds else None
        extra["reference_median_s"] = ref_wall
        extra["reference_cpu_mean_s"] = ref_cpu
        extra["reference_rounds"] = len(local)
        extra["loadavg_1min"] = (_loadavg() or [None])[0]
        extra["mode"] = MODE
        self._records.append((extra, median_s, min_s, cpu))
        self._session_ratios(extra, median_s, min_s, cpu)

    def _session_ratios(self, extra: dict, med: float, lo: float, cpu: float | None) -> None:
        extra["ratio_session"] = med / self.median
        cm = trimmed_mean(self.cpu_times)
        extra["cpu_ratio_session"] = cpu / cm if cpu is not None and cm > 0 else None
        extra["ratio_of_minima"] = lo / min(self.times)

    def finalise(self) -> None:
        """At the end of the session: the session ratios against the whole pool."""
        for rec in self._records:
            self._session_ratios(*rec)

    def summary(self) -> dict:
        t = sorted(self.times)
        return {
            "what": f"methods.get_method('marching_cubes').reconstruct({REF_PHANTOM} sdf volume, N = {REF_N})",
            "median_s": self.median if t else None,
            "cpu_median_s": self.cpu_median if t else None,
            "cpu_mean_s": trimmed_mean(self.cpu_times) if t else None,
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
    """For tests using ``benchmark``: time reference rounds around it, then record the ratios in ``extra_info``."""
    if "benchmark" not in request.fixturenames:
        yield
        return
    ref: Reference = request.getfixturevalue("reference")
    bm = request.getfixturevalue("benchmark")
    local = ref.sample(REF_TOPUP)
    timer = None
    if hasattr(bm, "_timer"):  # pytest-benchmark internals: a wall-clock timer that also records CPU time
        timer = bm._timer = CpuRecordingTimer(before=lambda: local.extend(ref.sample(1)),
                                              slowdown=slowdown_for(request.node.name))
    yield
    stats = getattr(bm, "stats", None)
    if stats is None or getattr(bm, "disabled", False):   # --benchmark-disable, or the test never timed
        return
    local += ref.sample(REF_TOPUP)
    n = int(stats.stats.rounds)
    cpu = None
    if timer is not None and len(timer.cpu) >= n > 0:
        per = max(1, int(getattr(stats, "iterations", 1) or 1))
        cpu = [c / per for c in timer.cpu[-n:]]      # the timed rounds (warm-up rounds come first)
    ref.record(bm.extra_info, float(stats.stats.median), float(stats.stats.min), cpu, local)
    if timer is not None and timer.slowdown > 1.0:
        bm.extra_info["injected_slowdown"] = timer.slowdown


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
