"""Tests of ``bench.cli.perf`` (``python -m bench perf``): exit codes of the gate on measured input, reruns of
a benchmark over the tolerance, repeated runs merged, bad baselines and tolerances."""

from __future__ import annotations

import json

import pytest

from _perf_common import BASE, raw, summary, write
from bench import perf
from bench.cli import main


def test_cli_gate_exit_codes_on_measured_input(tmp_path, capsys):
    base = write(tmp_path / "base.json", summary(BASE))
    slow = write(tmp_path / "slow.json", raw(dict(BASE, test_b=80.0)))
    fine = write(tmp_path / "fine.json", raw(dict(BASE, test_b=50.0)))
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
    base = write(tmp_path / "base.json", summary(BASE))
    # a load spike: test_b 2x slow in the first run, normal in the rerun -> passes
    calls = _fake_suite(monkeypatch, [summary(dict(BASE, test_b=80.0)), summary({"test_b": 42.0})])
    assert main(["perf", "--quick", "--compare", base]) == 0
    assert len(calls) == 2 and calls[0]["quick"] and calls[1]["select"] == ["tests/benchmarks/x.py::test_b"]
    out, err = capsys.readouterr()
    assert "rerun 1/1: test_b" in err and "[80.0, 42.0]" in out and "passed" in out
    # a real regression: slow every time -> fails after the rerun
    calls = _fake_suite(monkeypatch, [summary(dict(BASE, test_b=80.0)), summary({"test_b": 79.0})])
    assert main(["perf", "--compare", base]) == 1
    assert len(calls) == 2
    _, err = capsys.readouterr()
    assert "FAILED — test_b slower than the baseline by more than 50 %" in err
    # --retries 0: no rerun
    calls = _fake_suite(monkeypatch, [summary(dict(BASE, test_b=80.0))])
    assert main(["perf", "--retries", "0", "--compare", base]) == 1 and len(calls) == 1
    capsys.readouterr()


def test_cli_repeat_merges_runs_and_suite_failures_exit_1(tmp_path, monkeypatch, capsys):
    out = tmp_path / "b.json"
    _fake_suite(monkeypatch, [summary({"test_a": r}) for r in (1.0, 1.4, 1.1)])
    assert main(["perf", "--repeat", "3", "--save", str(out)]) == 0
    assert json.loads(out.read_text())["benchmarks"]["test_a"]["ratio"] == pytest.approx(1.1)
    monkeypatch.setattr(perf, "run_suite", lambda **kw: (1, summary({"test_a": 1.0})))  # a benchmark failed
    assert main(["perf"]) == 1
    monkeypatch.setattr(perf, "run_suite", lambda **kw: (2, None))                       # nothing measured
    assert main(["perf"]) == 1
    capsys.readouterr()


def test_cli_bad_baseline_or_tolerance_exit_2(tmp_path, capsys):
    run = write(tmp_path / "run.json", raw(BASE))
    assert main(["perf", "--input", run, "--compare", str(tmp_path / "nope.json")]) == 2
    (tmp_path / "bad.json").write_text("{not json")
    assert main(["perf", "--input", run, "--compare", str(tmp_path / "bad.json")]) == 2
    assert main(["perf", "--input", run, "--compare", write(tmp_path / "x.json", {"a": 1})]) == 2
    with pytest.raises(SystemExit) as exc:
        main(["perf", "--tolerance", "-1"])
    assert exc.value.code == 2
    capsys.readouterr()
