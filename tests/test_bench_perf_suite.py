"""Tests of ``bench.perf.suite``: the benchmark suite is left out of the default pytest run, and a real run of
the cheapest benchmark records its ratio to the reference (the pytest-benchmark pipeline end to end)."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest

from _perf_common import REPO


def test_benchmarks_are_deselected_by_the_default_pytest_run():
    """Every test under tests/benchmarks carries the benchmark marker (conftest adds it when missing)."""
    proc = subprocess.run([sys.executable, "-m", "pytest", "tests/benchmarks", "--collect-only", "-q",
                           "-p", "no:cacheprovider"], cwd=REPO, capture_output=True, text=True, timeout=300)
    assert "no tests collected" in proc.stdout or " deselected" in proc.stdout, proc.stdout[-2000:]
    assert "::" not in proc.stdout, proc.stdout[-2000:]


@pytest.mark.heavy
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
