"""The performance gate (bench.perf.gate), perf summaries and ``python -m bench perf``."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from bench import perf
from bench.cli import main

REPO = Path(__file__).resolve().parent.parent

BASE = {"test_a": 1.0, "test_b": 40.0, "test_c": 120.0}


def _summary(ratios: dict, **extra) -> dict:
    return {"format": perf.FORMAT, "mode": "full", "created": "2026-01-01T00:00:00+00:00",
            "benchmarks": {k: {"median_s": 0.1 * v, "ratio": v, "fullname": f"tests/benchmarks/x.py::{k}"}
                           for k, v in ratios.items()}, **extra}


# ---------------------------------------------------------------------------------------------- the gate
def test_a_run_twice_as_slow_on_one_benchmark_fails_the_gate():
    run = dict(BASE, test_b=80.0)
    res = perf.gate(_summary(BASE), _summary(run), tolerance=0.5)
    assert not res.passed
    assert res.failures == ["test_b"]
    row = {r["name"]: r for r in res.rows}["test_b"]
    assert row["status"] == perf.REGRESSION and row["change"] == pytest.approx(1.0)
    assert {r["name"]: r["status"] for r in res.rows if r["name"] != "test_b"} == {"test_a": "ok", "test_c": "ok"}


def test_a_run_within_the_tolerance_passes():
    run = {"test_a": 1.0, "test_b": 40.0 * 1.45, "test_c": 120.0 * 0.8}   # +45 %, −20 %
    res = perf.gate(_summary(BASE), _summary(run), tolerance=0.5)
    assert res.passed and res.failures == []
    assert all(r["status"] == perf.OK for r in res.rows)
    # the same run against a tighter tolerance fails on the +45 % one only
    assert perf.gate(_summary(BASE), _summary(run), tolerance=0.3).failures == ["test_b"]


def test_the_tolerance_is_configurable_and_plain_ratio_maps_work():
    assert perf.gate(BASE, dict(BASE, test_a=2.0), tolerance=1.5).passed
    assert not perf.gate(BASE, dict(BASE, test_a=2.6), tolerance=1.5).passed
    with pytest.raises(ValueError):
        perf.gate(BASE, BASE, tolerance=-0.1)


def test_new_missing_skipped_faster_and_no_ratio_benchmarks_do_not_fail():
    base = _summary(BASE)
    run = _summary({"test_a": 1.0, "test_b": 10.0, "test_new": 3.0}, skipped=["test_c"])
    run["benchmarks"]["test_a"]["ratio"] = None            # e.g. measured with --benchmark-disable
    res = perf.gate(base, run)
    status = {r["name"]: r["status"] for r in res.rows}
    assert status == {"test_a": perf.NO_RATIO, "test_b": perf.FASTER, "test_c": perf.SKIPPED,
                      "test_new": perf.NEW}
    assert res.passed

    run_missing = _summary({"test_a": 1.0, "test_b": 40.0})  # test_c gone, not skipped: missing
    res = perf.gate(base, run_missing)
    assert {r["name"]: r["status"] for r in res.rows}["test_c"] == perf.MISSING and res.passed
    assert perf.gate(base, run_missing, fail_on_missing=True).failures == ["test_c"]
    # a skipped benchmark never fails, even with fail_on_missing
    assert perf.gate(base, _summary({"test_a": 1.0, "test_b": 40.0}, skipped=["test_c"]),
                     fail_on_missing=True).passed


def test_the_gate_compares_cpu_ratios_when_both_sides_have_them():
    base = _summary(BASE)
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


def test_process_tree_cpu_counts_worker_processes():
    import multiprocessing as mp

    c0 = perf.process_tree_cpu()
    p = mp.get_context("fork").Process(target=_burn, args=(0.3,))
    p.start()
    p.join()
    assert perf.process_tree_cpu(self_last=False) - c0 >= 0.25


def _burn(seconds: float) -> None:
    import time

    t = time.process_time()
    while time.process_time() - t < seconds:
        pass


def test_cpu_recording_timer_returns_wall_time_and_records_cpu():
    import time

    timer = perf.CpuRecordingTimer()
    t0 = timer()
    time.sleep(0.05)
    _burn(0.1)
    t1 = timer()
    assert t1 - t0 >= 0.15 and len(timer.cpu) == 1 and 0.08 <= timer.cpu[0] < t1 - t0


def test_without_a_baseline_every_row_passes():
    res = perf.gate(None, _summary(BASE))
    assert res.passed and not res.compared
    table = perf.format_table(res)
    assert "test_b" in table and "40.000" in table and "baseline" not in table


def test_table_shows_median_ratio_and_change():
    res = perf.gate(_summary(BASE), _summary(dict(BASE, test_b=80.0)))
    table = perf.format_table(res)
    line = next(ln for ln in table.splitlines() if ln.startswith("test_b"))
    assert "8.00 s" in line and "80.000" in line and "40.000" in line and "+100 %" in line and "REGRESSION" in line


# ---------------------------------------------------------------------------------------------- summaries
def _raw(ratios: dict, dup: bool = False) -> dict:
    benches = []
    for k, v in ratios.items():
        benches.append({"group": "g", "name": k, "fullname": f"tests/benchmarks/test_x.py::{k}",
                        "stats": {"median": 0.1 * v, "min": 0.09 * v, "max": 0.12 * v, "iqr": 0.01, "rounds": 3},
                        "extra_info": {"ratio": v, "loadavg_1min": 1.0}})
    if dup:
        benches.append(dict(benches[0], fullname="tests/benchmarks/test_y.py::" + benches[0]["name"]))
    return {"machine_info": {"node": "n", "cpu": {"brand_raw": "CPU X"}}, "commit_info": {"id": "abc"},
            "benchmarks": benches, "datetime": "2026-01-01T00:00:00",
            "levelset_bench": {"mode": "quick", "reference": {"median_s": 0.1}, "loadavg_start": [1, 1, 1],
                               "loadavg_end": [2, 2, 2], "cpu_count": 2, "skipped": ["test_slow"]}}


def test_summarise_reads_pytest_benchmark_json():
    s = perf.summarise(_raw({"test_a": 1.0, "test_b": 40.0}))
    assert s["format"] == perf.FORMAT and s["mode"] == "quick" and s["skipped"] == ["test_slow"]
    assert s["benchmarks"]["test_b"]["ratio"] == 40.0
    assert s["benchmarks"]["test_b"]["median_s"] == pytest.approx(4.0)
    assert s["machine"]["cpu"] == "CPU X" and s["loadavg"]["end"] == [2, 2, 2]
    assert perf.summarise(s) is s
    # duplicate test names in two files: keyed by the full node id
    d = perf.summarise(_raw({"test_a": 1.0}, dup=True))
    assert sorted(d["benchmarks"]) == ["tests/benchmarks/test_x.py::test_a", "tests/benchmarks/test_y.py::test_a"]
    from phantoms import InputError
    with pytest.raises(InputError):
        perf.summarise({"something": 1})


def test_merge_runs_takes_the_median_ratio():
    runs = [_summary({"test_a": r, "test_b": 40.0}) for r in (1.0, 3.0, 1.2)]
    m = perf.merge_runs(runs)
    assert m["benchmarks"]["test_a"]["ratio"] == pytest.approx(1.2)
    assert m["benchmarks"]["test_a"]["runs"]["ratio"] == [1.0, 3.0, 1.2]
    assert m["repeats"] == 3
    # a merge of merges counts every run: median over the 3 + 2 runs
    m2 = perf.merge_runs([m, perf.merge_runs([_summary({"test_a": 5.0, "test_b": 40.0}),
                                              _summary({"test_a": 6.0, "test_b": 40.0})])])
    assert m2["repeats"] == 5 and m2["benchmarks"]["test_a"]["runs"]["ratio"] == [1.0, 3.0, 1.2, 5.0, 6.0]
    assert m2["benchmarks"]["test_a"]["ratio"] == pytest.approx(3.0)


# ---------------------------------------------------------------------------------------------- the CLI
def _write(path: Path, data: dict) -> str:
    path.write_text(json.dumps(data))
    return str(path)


def test_cli_gate_exit_codes_on_measured_input(tmp_path, capsys):
    base = _write(tmp_path / "base.json", _summary(BASE))
    slow = _write(tmp_path / "slow.json", _raw(dict(BASE, test_b=80.0)))
    fine = _write(tmp_path / "fine.json", _raw(dict(BASE, test_b=50.0)))
    assert main(["perf", "--input", slow, "--compare", base]) == 1
    out, err = capsys.readouterr()
    assert "REGRESSION" in out and "test_b" in err and "FAILED" in err
    assert main(["perf", "--input", fine, "--compare", base]) == 0
    out, _ = capsys.readouterr()
    assert "+25 %" in out and "passed" in out
    assert main(["perf", "--input", slow, "--compare", base, "--tolerance", "1.5"]) == 0
    capsys.readouterr()
    # --save writes a summary that can serve as the next baseline
    saved = tmp_path / "saved.json"
    assert main(["perf", "--input", fine, "--save", str(saved)]) == 0
    data = json.loads(saved.read_text())
    assert data["format"] == perf.FORMAT and data["benchmarks"]["test_b"]["ratio"] == 50.0
    assert "loadavg_now" in data["note"]
    assert main(["perf", "--input", fine, "--compare", str(saved)]) == 0


def _fake_suite(monkeypatch, runs: list[dict]):
    """Replace the pytest run by summaries served in order; returns the list of calls (select=...)."""
    calls = []

    def fake(**kw):
        calls.append(kw)
        return 0, json.loads(json.dumps(runs[min(len(calls), len(runs)) - 1]))

    monkeypatch.setattr(perf, "run_suite", fake)
    return calls


def test_cli_reruns_a_benchmark_over_the_tolerance_and_keeps_its_best_ratio(tmp_path, monkeypatch, capsys):
    base = _write(tmp_path / "base.json", _summary(BASE))
    # a load spike: test_b 2x slow in the first run, normal in the rerun -> passes
    calls = _fake_suite(monkeypatch, [_summary(dict(BASE, test_b=80.0)), _summary({"test_b": 42.0})])
    assert main(["perf", "--quick", "--compare", base]) == 0
    assert len(calls) == 2 and calls[0]["quick"] and calls[1]["select"] == ["tests/benchmarks/x.py::test_b"]
    out, err = capsys.readouterr()
    assert "rerun 1/1: test_b" in err and "[80.0, 42.0]" in out and "passed" in out
    # a real regression: slow every time -> fails after the rerun
    calls = _fake_suite(monkeypatch, [_summary(dict(BASE, test_b=80.0)), _summary({"test_b": 79.0})])
    assert main(["perf", "--compare", base]) == 1
    assert len(calls) == 2
    _, err = capsys.readouterr()
    assert "FAILED — test_b slower than the baseline by more than 50 %" in err
    # --retries 0: no rerun
    calls = _fake_suite(monkeypatch, [_summary(dict(BASE, test_b=80.0))])
    assert main(["perf", "--retries", "0", "--compare", base]) == 1 and len(calls) == 1
    capsys.readouterr()


def test_cli_repeat_merges_runs_and_suite_failures_exit_1(tmp_path, monkeypatch, capsys):
    out = tmp_path / "b.json"
    _fake_suite(monkeypatch, [_summary({"test_a": r}) for r in (1.0, 1.4, 1.1)])
    assert main(["perf", "--repeat", "3", "--save", str(out)]) == 0
    assert json.loads(out.read_text())["benchmarks"]["test_a"]["ratio"] == pytest.approx(1.1)
    monkeypatch.setattr(perf, "run_suite", lambda **kw: (1, _summary({"test_a": 1.0})))  # a benchmark failed
    assert main(["perf"]) == 1
    monkeypatch.setattr(perf, "run_suite", lambda **kw: (2, None))                       # nothing measured
    assert main(["perf"]) == 1
    capsys.readouterr()


def test_cli_bad_baseline_or_tolerance_exit_2(tmp_path, capsys):
    run = _write(tmp_path / "run.json", _raw(BASE))
    assert main(["perf", "--input", run, "--compare", str(tmp_path / "nope.json")]) == 2
    (tmp_path / "bad.json").write_text("{not json")
    assert main(["perf", "--input", run, "--compare", str(tmp_path / "bad.json")]) == 2
    assert main(["perf", "--input", run, "--compare", _write(tmp_path / "x.json", {"a": 1})]) == 2
    with pytest.raises(SystemExit) as exc:
        main(["perf", "--tolerance", "-1"])
    assert exc.value.code == 2
    capsys.readouterr()


def test_committed_baseline_is_a_summary_of_every_benchmark():
    assert perf.BASELINE == REPO / "bench" / "perf" / "baseline.json"
    base = perf.load_summary(REPO / "bench" / "perf" / "baseline.json")
    assert base["format"] == perf.FORMAT
    names = set(base["benchmarks"])
    assert {"test_marching_cubes_ellipsoid_n96", "test_poisson_ellipsoid_n96", "test_distmesh_ellipsoid_n96",
            "test_evaluate_100k_faces_ellipsoid", "test_quick_grid_end_to_end"} <= names
    for b in base["benchmarks"].values():
        assert b["ratio"] is not None and b["ratio"] > 0
    assert base["benchmarks"]["test_marching_cubes_ellipsoid_n96"]["ratio"] == pytest.approx(1.0, abs=0.3)
    assert base["loadavg"] and base["note"]["loadavg_now"]


def test_benchmarks_are_deselected_by_the_default_pytest_run():
    """Every test under tests/benchmarks carries the benchmark marker (conftest adds it when missing)."""
    proc = subprocess.run([sys.executable, "-m", "pytest", "tests/benchmarks", "--collect-only", "-q",
                           "-p", "no:cacheprovider"], cwd=REPO, capture_output=True, text=True, timeout=300)
    assert "no tests collected" in proc.stdout or " deselected" in proc.stdout, proc.stdout[-2000:]
    assert "::" not in proc.stdout, proc.stdout[-2000:]


def test_perf_runs_a_benchmark_and_records_its_ratio(tmp_path):
    """The real pipeline on the cheapest benchmark: pytest-benchmark JSON → ratio to the reference → summary."""
    out = tmp_path / "mc.json"
    env = dict(os.environ, LSB_PERF_REF_ROUNDS="3", LSB_PERF_REF_TOPUP="1")
    proc = subprocess.run([sys.executable, "-m", "bench", "perf", "-k", "marching_cubes_ellipsoid_n96", "--rounds", "3",
                           "--save", str(out)], cwd=REPO, env=env, capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    data = json.loads(out.read_text())
    b = data["benchmarks"]["test_marching_cubes_ellipsoid_n96"]
    assert b["rounds"] == 3 and b["ratio"] > 0
    assert 0.3 < b["ratio"] < 3.0          # the reference measured against itself
    assert 0.3 < b["cpu_ratio"] < 3.0 and b["cpu_mean_s"] > 0
    # reference rounds: 3 at the start, 1 before the benchmark, 1 before each of its 1 + 3 (warm-up) rounds, 1 after
    assert data["reference"]["rounds"] == 9 and data["threads"]["OMP_NUM_THREADS"]
    assert "test_marching_cubes_ellipsoid_n96" in proc.stdout
