"""Helpers shared by the perf tests (not collected: the name starts with an underscore): summaries and raw
pytest-benchmark JSON with given ratios, and a CPU burner."""

from __future__ import annotations

import json
from pathlib import Path

from bench import perf

REPO = Path(__file__).resolve().parent.parent

BASE = {"test_a": 1.0, "test_b": 40.0, "test_c": 120.0}


def summary(ratios: dict, **extra) -> dict:
    return {"format": perf.FORMAT, "mode": "full", "created": "2026-01-01T00:00:00+00:00",
            "benchmarks": {k: {"median_s": 0.1 * v, "ratio": v, "fullname": f"tests/benchmarks/x.py::{k}"}
                           for k, v in ratios.items()}, **extra}


def raw(ratios: dict, dup: bool = False) -> dict:
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


def write(path: Path, data: dict) -> str:
    path.write_text(json.dumps(data))
    return str(path)


def burn(seconds: float) -> None:
    import time

    t = time.process_time()
    while time.process_time() - t < seconds:
        pass
