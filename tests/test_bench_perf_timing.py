"""Tests of ``bench.perf.timing``: the process-tree CPU clock (worker processes counted), the CPU-recording
timer pytest-benchmark uses, and the injected-slowdown hook the gate's detection is measured with."""

from __future__ import annotations

from _perf_common import burn
from bench import perf
from bench.perf import timing


def test_process_tree_cpu_counts_worker_processes():
    import multiprocessing as mp

    c0 = perf.process_tree_cpu()
    p = mp.get_context("fork").Process(target=burn, args=(0.3,))
    p.start()
    p.join()
    assert perf.process_tree_cpu(self_last=False) - c0 >= 0.25


def test_cpu_recording_timer_returns_wall_time_and_records_cpu():
    import time

    timer = perf.CpuRecordingTimer()
    t0 = timer()
    time.sleep(0.05)
    burn(0.1)
    t1 = timer()
    assert t1 - t0 >= 0.15 and len(timer.cpu) == 1 and 0.08 <= timer.cpu[0] < t1 - t0


def test_the_slowdown_hook_parses_its_spec(monkeypatch):
    monkeypatch.setenv(timing.ENV_SLOWDOWN, "iteration=2")
    assert timing.slowdown_for("test_flow_iteration_100k") == 2.0
    assert timing.slowdown_for("test_marching_cubes") == 1.0
    monkeypatch.setenv(timing.ENV_SLOWDOWN, "iteration=abc")
    assert timing.slowdown_for("test_iteration") == 1.0


def test_an_injected_slowdown_is_real_cpu_inside_the_timed_interval():
    def cpu_of_round(factor: float) -> float:
        t = timing.CpuRecordingTimer(slowdown=factor)
        t()
        sum(range(3_000_000))
        t()
        return t.cpu[-1]

    plain = min(cpu_of_round(1.0) for _ in range(3))
    slowed = min(cpu_of_round(3.0) for _ in range(3))
    # a busy loop of (3 − 1) × the round's wall time: CPU time about three times the plain round's (less when
    # another process takes turns on the core during the busy loop); outside the interval it would add nothing
    assert slowed > 1.6 * plain
