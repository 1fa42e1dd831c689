"""Bounded, honest under hostile plug-ins: the per-cell memory limit (bench.run.limits; ``--memory-limit``,
``run.memory_limit``) and process isolation (a plug-in that kills its parent, the local executor's fork server,
or its whole process group).

Two grid runs (sphere, N = 16, two jobs, a 2 GB limit) put the hostile methods beside marching cubes (and a
well-behaved slow cell): each hostile cell is a failed row saying why, every other cell is ok, the run exits 0.
The limit of 2 GB leaves room for a normal cell: its address space peaks at about 1 GB (VmPeak of a marching
cubes cell at N = 48 measured at 0.99 GB with two jobs, 1.05 GB with one; see bench/run/limits.py).  The
runs take 15-25 s on the 2-core machine (the isolation run restarts the fork server: its warm-up twice), so
both are ``heavy``; the default tests still run a cell over the limit, in tests/test_bench_run_limits.py's grid.
"""

from __future__ import annotations

import csv
import json
import math
import os
import subprocess
import sys
from pathlib import Path

import pytest

from bench.config import builtin_config, config_from_dict
from bench.run.limits import (DEFAULT_MEMORY_FLOOR_GB, MAX_MEMORY_FACTOR, check_gb, current_memory_limit_gb,
                              default_memory_gb, memory_error, memory_phase, physical_memory_gb)
from bench.run.runner import memory_limit
from phantoms import InputError

REPO = Path(__file__).resolve().parent.parent
TESTS = Path(__file__).resolve().parent


# ---------------------------------------------------------------------------------------------- units
def test_memory_values_are_range_checked():
    assert check_gb(None, "x") is None and check_gb(0, "x") == 0.0 and check_gb(1.5, "x") == 1.5
    phys = physical_memory_gb()
    assert phys and phys > 0
    for bad in (-1, float("inf"), float("nan"), "1.5", True, MAX_MEMORY_FACTOR * phys * 1.01):
        with pytest.raises(InputError, match=r"^--memory-limit: "):
            check_gb(bad, "--memory-limit")


def test_the_default_is_three_quarters_of_the_memory_per_job():
    phys = physical_memory_gb()
    floor = min(DEFAULT_MEMORY_FLOOR_GB, phys)                   # a normal cell maps about 1 GB (see limits.py)
    assert math.isclose(default_memory_gb(2), max(0.75 * phys / 2, floor))
    assert math.isclose(default_memory_gb(1), max(0.75 * phys, floor)) and default_memory_gb(10 ** 6) == floor
    cfg = builtin_config("quick")
    assert cfg.memory_limit is None and math.isclose(memory_limit(cfg, None, 4), max(0.75 * phys / 4, floor))
    assert memory_limit(cfg, 3.0, 4) == 3.0 and memory_limit(cfg, 0, 4) is None      # 0 = no limit
    cfg.memory_limit = 0.0
    assert memory_limit(cfg, None, 4) is None and memory_limit(cfg, 2.5, 4) == 2.5    # the argument wins


def test_run_memory_limit_in_the_config():
    data = builtin_config("quick").to_dict()
    assert "memory_limit" not in data["run"]                      # unset: the fingerprint of old runs is kept
    data["run"]["memory_limit"] = 4
    cfg = config_from_dict(data)
    assert cfg.memory_limit == 4.0 and config_from_dict(cfg.to_dict()).memory_limit == 4.0
    data["run"]["memory_limit"] = -2
    with pytest.raises(InputError, match=r"^run.memory_limit: must be 0 \(no limit\) or a memory size"):
        config_from_dict(data)
    data["run"]["memory_limit"] = "big"
    with pytest.raises(InputError, match=r"run.memory_limit"):
        config_from_dict(data)


def test_the_message_names_the_limit_and_the_phase():
    assert memory_phase("reconstruction") == memory_phase("method setup") == "in the method"
    for stage in ("validity", "metrics", "pictures", "scoring"):
        assert memory_phase(stage) == "in scoring (validity check and metrics)"
    assert memory_phase("volume") == memory_phase("setup") == "building the volume"
    assert memory_error(MemoryError("Unable to allocate 30 GiB"), "reconstruction", 1.5) == (
        "memory limit (1.5 GB) exceeded in the method (MemoryError: Unable to allocate 30 GiB)")
    try:                                                           # a method that wraps the MemoryError
        try:
            raise MemoryError()
        except MemoryError as exc:
            raise RuntimeError("solver failed") from exc
    except RuntimeError as wrapped:
        assert memory_error(wrapped, "metrics", 2).startswith("memory limit (2 GB) exceeded in scoring "
                                                              "(validity check and metrics) (RuntimeError")
    assert memory_error(ValueError("bad"), "reconstruction", 2) is None          # not a memory error
    if current_memory_limit_gb() is None:                          # no limit given, none in force: no claim
        assert memory_error(MemoryError(), "reconstruction") is None


def test_a_bad_limit_on_the_command_line_is_one_line_and_exit_2(capsys):
    from bench.cli import main

    assert main(["run", "--quick", "--dry-run", "--memory-limit", "1e9"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: --memory-limit: must be 0 (no limit) or a memory size")
    with pytest.raises(SystemExit) as exc:                         # not a number / negative: argparse, exit 2
        main(["run", "--quick", "--dry-run", "--memory-limit", "-1"])
    assert exc.value.code == 2
    assert main(["run", "--quick", "--dry-run", "--memory-limit", "2"]) == 0


# ---------------------------------------------------------------------------------------------- grid runs
def _run(out: Path, methods: list[str], *args) -> tuple[subprocess.CompletedProcess, dict[str, dict]]:
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(TESTS), str(REPO)] + [p for p in [env.get("PYTHONPATH")] if p])
    env["PYTHONWARNINGS"] = "ignore"
    specs = [a for m in methods for a in ("--add-method", m)]
    specs[0] = "--method"
    res = subprocess.run([sys.executable, "-m", "bench", "run", "--quick", "--phantoms", "sphere", "--noise",
                          "none", "--n", "16", "--n-samples", "2000", "--import", "hostile_plugins", *specs,
                          "--jobs", "2", "--no-report", "--out", str(out), *args],
                         cwd=REPO, env=env, capture_output=True, text=True, timeout=300)
    assert res.returncode == 0, res.stderr[-3000:]
    with open(out / "results.csv", newline="") as fh:
        return res, {r["method"]: r for r in csv.DictReader(fh)}


@pytest.mark.heavy
def test_a_cell_over_the_memory_limit_is_a_failed_row_saying_where(tmp_path):
    """30 GB asked for in the method, and by the mesh in scoring, under a 2 GB limit; marching cubes is fine."""
    out = tmp_path / "run"
    res, rows = _run(out, ["memory_hog", "hungry_to_score", "marching_cubes"], "--memory-limit", "2")
    assert "1 ok, 2 failed, 0 timeout" in res.stdout
    assert rows["marching_cubes"]["status"] == "ok"
    assert rows["memory_hog"]["status"] == rows["hungry_to_score"]["status"] == "failed"
    assert rows["memory_hog"]["error"].startswith("memory limit (2 GB) exceeded in the method (MemoryError: ")
    assert rows["hungry_to_score"]["error"].startswith("memory limit (2 GB) exceeded in scoring (validity check "
                                                       "and metrics) (MemoryError: ")
    session = json.loads((out / "run.json").read_text())["sessions"][-1]
    assert session["memory_limit_gb"] == 2.0


@pytest.mark.heavy
def test_killing_the_fork_server_or_the_process_group_fails_only_that_cell(tmp_path):
    """A cell that SIGKILLs its parent (the fork server) while a slow, well-behaved cell runs beside it, and one
    that SIGKILLs its process group: only their own rows fail, the run finishes, the rest is ok."""
    out = tmp_path / "run"
    res, rows = _run(out, ["slow_ok:seconds=60", "kills_parent", "kills_group", "marching_cubes"],
                     "--memory-limit", "2")
    assert "2 ok, 2 failed, 0 timeout" in res.stdout
    assert rows["marching_cubes"]["status"] == "ok" and rows["slow_ok"]["status"] == "ok"
    assert rows["kills_parent"]["error"] == "reconstruction: RuntimeError: killed my parent"
    assert rows["kills_group"]["status"] == "failed"
    assert rows["kills_group"]["error"].startswith("crash: worker process ")
    assert " in the method; memory limit (2 GB) in force" in rows["kills_group"]["error"]
    # the slow cell ran while its fork server was killed (it was reparented) and still gave its row
    record = json.loads((out / "cells" / f"{rows['slow_ok']['cell_id']}.json").read_text())
    assert record["row"]["method_info"]["reparented"] is True
