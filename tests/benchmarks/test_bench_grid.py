"""The ``--quick`` grid end to end (``python -m bench run --quick``): 12 cells — volumes, methods, metrics,
per-cell worker processes, results.csv, run.json and the HTML report with its pictures; and the paper's grid
(``python -m bench run`` with no arguments, 64 cells), ``perf_slow``, with its cells' CPU seconds in
``extra_info`` (the slowest ten, and the total per method label) so a regression names its cells.

Run in-process through :func:`bench.run.run_grid` and :func:`bench.report.write_report` (what the CLI calls)
with **one** worker: the time is
then the total work of the grid, which compares with the single-threaded reference on any machine, instead
of depending on how many cores are free at that moment.

A one-cell grid runs first, untimed: it starts the runner's fork server (a process that preloads the suite,
≈ 1–2 s of CPU, once per session) and imports what the report needs, so every timed round costs the same —
otherwise the first round would carry it, and the mean over 1 round (``--quick``) and over 2 (full) would differ.
"""

from __future__ import annotations

import itertools

import pytest

from bench.perf import rounds


@pytest.mark.benchmark(group="grid")
def test_quick_grid_end_to_end(benchmark, tmp_path):
    from bench.config import builtin_config
    from bench.specs import parse_method_spec
    from bench.report import write_report
    from bench.run import run_grid

    def run_and_report(cfg, out):
        summary = run_grid(cfg, out, jobs=1, progress=False, argv=["perf"])
        write_report(out)
        return summary

    warm = builtin_config("quick")
    warm.phantoms, warm.n, warm.noise = ["sphere"], [16], warm.noise[:1]
    warm.methods = [parse_method_spec("marching_cubes")]
    assert run_and_report(warm, tmp_path / "warm-up").ok == 1

    counter = itertools.count()
    summaries = []

    def run():
        cfg = builtin_config("quick")
        out = tmp_path / f"run{next(counter)}"
        summaries.append(run_and_report(cfg, out))
        return out

    out = benchmark.pedantic(run, rounds=rounds(2, 1), iterations=1, warmup_rounds=0)
    s = summaries[-1]
    benchmark.extra_info["cells"] = s.total
    benchmark.extra_info["jobs"] = 1
    assert s.total == 12 and s.ok == 12, s.line()
    assert (out / "index.html").stat().st_size > 10_000


@pytest.mark.benchmark(group="grid")
def test_paper_grid_end_to_end(benchmark, tmp_path):
    """The default run, one worker (the grid's total work), no report (the quick grid times that); one round, in
    CI's short mode too, so that a regression of the default run fails the performance gate.
    ``extra_info``: ``cells``, ``cpu_s_total`` (the cells' own CPU seconds), ``slowest_cells`` (label, phantom,
    noise, CPU s) and ``cpu_s_by_label``."""
    from bench.config import builtin_config
    from bench.run import run_grid
    from bench.run.store import load_cells

    counter = itertools.count()
    outs = []

    def run():
        out = tmp_path / f"paper{next(counter)}"
        outs.append((run_grid(builtin_config("paper"), out, jobs=1, progress=False, argv=["perf"]), out))

    benchmark.pedantic(run, rounds=1, iterations=1, warmup_rounds=0)
    summary, out = outs[-1]
    assert summary.total == 64 and summary.failed == 0 and summary.timeout == 0, summary.line()
    rows = [rec["row"] for rec in load_cells(out).values()]
    cells = sorted(((r.cpu_s or 0.0, r.label, r.phantom, r.noise) for r in rows), reverse=True)
    by_label: dict[str, float] = {}
    for cpu, label, _, _ in cells:
        by_label[label] = by_label.get(label, 0.0) + cpu
    benchmark.extra_info.update({
        "cells": summary.total, "jobs": 1, "cpu_s_total": round(sum(c[0] for c in cells), 2),
        "slowest_cells": [[label, phantom, noise, round(cpu, 2)] for cpu, label, phantom, noise in cells[:10]],
        "cpu_s_by_label": {k: round(v, 2) for k, v in sorted(by_label.items(), key=lambda kv: -kv[1])}})
