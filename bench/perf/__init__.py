"""Performance tracking: run the pytest-benchmark suites, compare their ratios with a baseline, gate regressions.

``python -m bench perf [--compare BASELINE.json] [--save OUT.json] [--tolerance 0.5] [--quick]`` (see
:mod:`bench.cli.perf`) runs ``tests/benchmarks`` (:mod:`.suite`: pytest with ``--benchmark-json`` into a
temporary file), prints a table and, with ``--compare``, exits 1 when a benchmark got slower than the baseline
by more than the tolerance (:mod:`.gate`).  Summaries and the committed baseline: :mod:`.baseline`.

Why ratios, and why CPU time
----------------------------
Absolute times depend on the machine and on its load.  Every benchmark records in ``extra_info`` its median
time divided by the median time of a *reference* measured in the same pytest session (marching cubes on the
ellipsoid at N = 96; ``tests/benchmarks/conftest.py``): ``ratio`` with wall-clock times and ``cpu_ratio`` with
CPU times (user + system of the process, its threads and its worker processes: :func:`process_tree_cpu` in
:mod:`.timing`).  A faster machine changes the benchmark and the reference alike; the ratio moves when the
benchmarked code itself changes speed.  The reference rounds a benchmark is divided by are the ones timed around
it (before, between its rounds, after): the speed of a shared virtual machine drifts over tens of seconds.

Wall-clock ratios are not enough on a shared machine: other processes slow a long benchmark and a short
reference round by different amounts depending on when they run.  CPU time is charged only while the process
runs, so the CPU-time ratio moves much less under such load; the gate compares
``cpu_ratio`` (``--metric cpu``, the default) and falls back to ``ratio`` for a benchmark without CPU times on
both sides.  What CPU time cannot see — time spent waiting — is in the wall-clock column, for information
(``--metric wall`` gates on it).  The suite runs pinned to one CPU (:func:`run_suite` ``cpus``), with the native
thread pools at one thread, so a benchmark's cost does not depend on how many cores are free: the suite
measures work, not parallel speed-up.

``--compare`` and ``--input`` also accept a raw ``--benchmark-json`` file of pytest-benchmark.
"""

from __future__ import annotations

from .baseline import BASELINE, FORMAT, load_summary, machine_note, merge_runs, save_summary, summarise
from .gate import (DEFAULT_TOLERANCE, FASTER, MISSING, NEW, NO_RATIO, OK, REGRESSION, SKIPPED, GateResult,
                   format_seconds, format_table, gate)
from .suite import THREAD_ENV, benchmarks_dir, pinned_cpus, repo_root, run_suite
from .timing import ENV_MODE, ENV_ROUNDS, CpuRecordingTimer, perf_mode, process_tree_cpu, rounds

__all__ = ["perf_mode", "rounds", "DEFAULT_TOLERANCE", "FORMAT", "summarise", "load_summary", "merge_runs",
           "gate", "GateResult", "format_table", "run_suite", "benchmarks_dir",
           # also used by the command line and the benchmark suites
           "BASELINE", "ENV_MODE", "ENV_ROUNDS", "THREAD_ENV", "OK", "FASTER", "REGRESSION", "NEW", "MISSING",
           "SKIPPED", "NO_RATIO", "process_tree_cpu", "CpuRecordingTimer", "repo_root", "pinned_cpus",
           "machine_note", "save_summary", "format_seconds"]
