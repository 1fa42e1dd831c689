"""Tests of ``bench.perf.gate``: the performance gate (ratios against a baseline, the tolerance, new / missing /
skipped / faster rows, CPU ratios) and its table.  (Summaries: test_bench_perf_baseline.py; the timers:
test_bench_perf_timing.py; ``python -m bench perf``: test_bench_cli_perf.py.)"""

from __future__ import annotations

import json

import pytest

from _perf_common import BASE, summary
from bench import perf


# ---------------------------------------------------------------------------------------------- the gate
def test_a_run_twice_as_slow_on_one_benchmark_fails_the_gate():
    run = dict(BASE, test_b=80.0)
    res = perf.gate(summary(BASE), summary(run), tolerance=0.5)
    assert not res.passed
    assert res.failures == ["test_b"]
    row = {r["name"]: r for r in res.rows}["test_b"]
    assert row["status"] == perf.REGRESSION and row["change"] == pytest.approx(1.0)
    assert {r["name"]: r["status"] for r in res.rows if r["name"] != "test_b"} == {"test_a": "ok", "test_c": "ok"}


def test_a_run_within_the_tolerance_passes():
    run = {"test_a": 1.0, "test_b": 40.0 * 1.45, "test_c": 120.0 * 0.8}   # +45 %, −20 %
    res = perf.gate(summary(BASE), summary(run), tolerance=0.5)
    assert res.passed and res.failures == []
    assert all(r["status"] == perf.OK for r in res.rows)
    # the same run against a tighter tolerance fails on the +45 % one only
    assert perf.gate(summary(BASE), summary(run), tolerance=0.3).failures == ["test_b"]


def test_the_tolerance_is_configurable_and_plain_ratio_maps_work():
    assert perf.gate(BASE, dict(BASE, test_a=2.0), tolerance=1.5).passed
    assert not perf.gate(BASE, dict(BASE, test_a=2.6), tolerance=1.5).passed
    with pytest.raises(ValueError):
        perf.gate(BASE, BASE, tolerance=-0.1)


def test_new_missing_skipped_faster_and_no_ratio_benchmarks_do_not_fail():
    base = summary(BASE)
    run = summary({"test_a": 1.0, "test_b": 10.0, "test_new": 3.0}, skipped=["test_c"])
    run["benchmarks"]["test_a"]["ratio"] = None            # e.g. measured with --benchmark-disable
    res = perf.gate(base, run)
    status = {r["name"]: r["status"] for r in res.rows}
    assert status == {"test_a": perf.NO_RATIO, "test_b": perf.FASTER, "test_c": perf.SKIPPED,
                      "test_new": perf.NEW}
    assert res.passed

    run_missing = summary({"test_a": 1.0, "test_b": 40.0})  # test_c gone, not skipped: missing
    res = perf.gate(base, run_missing)
    assert {r["name"]: r["status"] for r in res.rows}["test_c"] == perf.MISSING and res.passed
    assert perf.gate(base, run_missing, fail_on_missing=True).failures == ["test_c"]
    # a skipped benchmark never fails, even with fail_on_missing
    assert perf.gate(base, summary({"test_a": 1.0, "test_b": 40.0}, skipped=["test_c"]),
                     fail_on_missing=True).passed


def test_the_gate_compares_cpu_ratios_when_both_sides_have_them():
    base = summary(BASE)
    for b in base["benchmarks"].values():
        b["cpu_ratio"] = b["ratio"]
    run = json.loads(json.dumps(base))
    run["benchmarks"]["test_b"]["ratio"] = 80.0            # wall clock 2x slower (a busy machine) ...
    assert perf.gate(base, run).passed                    # ... the CPU-time ratio did not move: passes
    assert perf.gate(base, run, metric="wall").failures == ["test_b"]
    run["benchmarks"]["test_c"]["cpu_ratio"] = 240.0      # CPU time 2x: fails
    res = perf.gate(base, run)
    assert res.failures == ["test_c"] and {r["name"]: r["metric"] for r in res.rows}["test_c"] == "cpu"
    # a side without CPU ratios: the wall-clock ratios are compared
    base["benchmarks"]["test_b"]["cpu_ratio"] = None
    row = {r["name"]: r for r in perf.gate(base, run).rows}["test_b"]
    assert row["metric"] == "wall" and row["status"] == perf.REGRESSION
    assert "80.000*" not in perf.format_table(perf.gate(base, run)) and "40.000*" in perf.format_table(
        perf.gate(base, run))
    with pytest.raises(ValueError):
        perf.gate(base, run, metric="user")


def test_without_a_baseline_every_row_passes():
    res = perf.gate(None, summary(BASE))
    assert res.passed and not res.compared
    table = perf.format_table(res)
    assert "test_b" in table and "40.000" in table and "baseline" not in table


def test_table_shows_median_ratio_and_change():
    res = perf.gate(summary(BASE), summary(dict(BASE, test_b=80.0)))
    table = perf.format_table(res)
    line = next(ln for ln in table.splitlines() if ln.startswith("test_b"))
    assert "8.00 s" in line and "80.000" in line and "40.000" in line and "+100 %" in line and "REGRESSION" in line
