"""Speed of the report on a large run: ``write_report`` on a synthetic 5,010-cell dataset run folder (167 shapes ×
clean + 5 noisy seeds × 5 methods; issue target ≤ 30 s and ≤ 50 MB on a quiet 2-core machine).  perf_slow:
skipped by ``python -m bench perf --quick``."""

from __future__ import annotations

import os
import sys
from pathlib import Path

import pytest

from bench.report import write_report

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))      # tests/: the shared test helpers
from _synthetic_run import write_synthetic_run  # noqa: E402


@pytest.fixture(scope="module")
def big_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("big") / "run"
    write_synthetic_run(out, n_shapes=167)
    return out


@pytest.mark.perf_slow
@pytest.mark.benchmark(group="report")
def test_report_of_5000_cells(benchmark, big_run):
    path = benchmark.pedantic(write_report, args=(big_run,), rounds=1, iterations=1, warmup_rounds=0)
    size_mb = path.stat().st_size / 2 ** 20
    benchmark.extra_info["size_mb"] = round(size_mb, 1)
    benchmark.extra_info["loadavg_1min_at_end"] = round(os.getloadavg()[0], 2)
    assert size_mb <= 50.0
