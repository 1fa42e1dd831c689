"""The ``--quick`` grid end to end (``python -m bench run --quick``): 12 cells — volumes, methods, metrics,
per-cell worker processes, results.csv, run.json and the HTML report with its pictures.

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
