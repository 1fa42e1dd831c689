"""Tests of ``bench.perf.history``: a JSON line per run, read back the same, drawn into a self-contained page.
(The injected-slowdown hook: test_bench_perf_timing.py.)"""

from __future__ import annotations

import json
import re

import pytest

from bench.cli import main
from bench.perf import history as h

TIMING = {"mode": "quick", "commit": {"id": "a" * 40, "dirty": False},
          "benchmarks": {"test_mc": {"ratio": 1.1, "cpu_ratio": 1.0}, "test_sg": {"ratio": 40.0, "cpu_ratio": None}}}
QUALITY = {"commit": {"commit": "b" * 40, "dirty": True},
           "cells": {"quick/sphere_mc": {"status": "ok", "flags": [], "metrics": {"hausdorff_h": 0.4,
                                                                                   "watertight": True}}}}


def test_an_entry_holds_ratios_quality_verdicts_and_provenance():
    e = h.history_entry(TIMING, QUALITY, timing_passed=True, quality_passed=False, failures=["x hausdorff_h"])
    assert e["ratios"] == {"test_mc": 1.0, "test_sg": 40.0}        # the gated ratio: CPU where there is one
    assert e["wall_ratios"] == {"test_mc": 1.1, "test_sg": 40.0}
    assert e["quality"]["quick/sphere_mc"] == {"hausdorff_h": 0.4, "watertight": True, "status": "ok"}
    assert e["commit"] == "b" * 40 and e["dirty"] is True
    assert e["gate"] == {"timing": True, "quality": False, "failures": ["x hausdorff_h"]}
    assert e["date"] and e["machine"]["cpu_count"]


def test_the_history_file_round_trips_and_survives_an_interrupted_last_line(tmp_path):
    path = tmp_path / "sub" / "history.jsonl"
    entries = [h.history_entry(TIMING, None, timing_passed=True), h.history_entry(None, QUALITY,
                                                                                  quality_passed=True)]
    for e in entries:
        h.append_history(path, e)
    assert h.read_history(path) == entries
    with open(path, "a") as fh:
        fh.write('{"format": "levelset-bench-hist')           # a crash in the middle of an append
    assert h.read_history(path) == entries
    path.write_text(path.read_text().replace('{"format": "levelset-bench-hist', "") + '["no"]\n')
    with pytest.raises(Exception, match="line 3: not a history entry"):
        h.read_history(path)


def test_the_plot_is_self_contained_draws_every_series_and_marks_failed_runs(tmp_path, capsys):
    path = tmp_path / "history.jsonl"
    for i, ok in enumerate([True, True, False]):
        t = json.loads(json.dumps(TIMING))
        t["benchmarks"]["test_mc"]["cpu_ratio"] = 1.0 + i
        h.append_history(path, h.history_entry(t, QUALITY, timing_passed=ok, quality_passed=True))
    out = tmp_path / "history.html"
    assert main(["perf", "--plot", str(path), "-o", str(out)]) == 0
    html = out.read_text()
    # plotly.js embedded (once), no script fetched at viewing time
    assert html.count("<script") >= 3 and not re.search(r"<script[^>]*\bsrc=", html)
    assert html.count("Plotly=") + html.count("window.Plotly") >= 1 and len(html) > 1_000_000
    assert html.count("Plotly.newPlot") == 3          # ratios, hausdorff_h, watertight
    for name in ("test_mc", "test_sg", "sphere_mc", "gate failed"):
        assert name in html
    assert "1 with a failed gate" in html


def test_plotting_a_missing_or_empty_history_is_one_line_exit_2(tmp_path, capsys):
    assert main(["perf", "--plot", str(tmp_path / "nope.jsonl")]) == 2
    (tmp_path / "empty.jsonl").write_text("")
    assert main(["perf", "--plot", str(tmp_path / "empty.jsonl")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 2 and "cannot read the history file" in err[0] and "no history entries" in err[1]


