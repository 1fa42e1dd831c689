"""bench.run.limits: separate time limits for the whole cell, the method and the scoring — the deadlines
themselves, and a grid run where each limit runs out in its own phase and the row says which.  The same run
checks that a method returning the wrong type is a named failure and that the method's own info keys reach
the cell's record and the report."""

from __future__ import annotations

import csv
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from bench.config import builtin_config
from bench.run.limits import TimeLimits
from bench.run.runner import time_limits

REPO = Path(__file__).resolve().parent.parent
TESTS = Path(__file__).resolve().parent


def test_deadlines_per_phase():
    lim = TimeLimits(cell=10, method=3, score=2)
    assert lim.deadline(100.0, "setup", 100.0) == 110.0                 # only the cell limit while building
    assert lim.deadline(100.0, "method", 101.0) == 104.0                # 1 s of setup, then 3 s of method
    assert lim.deadline(100.0, "scoring", 105.0) == 107.0               # 2 s from the method's return
    assert lim.deadline(100.0, "scoring", 109.0) == 110.0               # but never past the cell's limit
    assert lim.which(100.0, "scoring", 105.0) == "score" and lim.which(100.0, "scoring", 109.0) == "cell"
    assert lim.which(100.0, "method", 101.0) == "method" and lim.which(100.0, "setup", 100.0) == "cell"
    only_method = TimeLimits(method=5)
    assert only_method.deadline(0.0, "setup", 0.0) is None and only_method.deadline(0.0, "method", 2.0) == 7.0
    assert only_method.deadline(0.0, "scoring", 8.0) is None
    assert not TimeLimits() and not TimeLimits(0, 0, 0) and TimeLimits(score=1)
    assert TimeLimits.of(5) == TimeLimits(cell=5) and TimeLimits.of(None) == TimeLimits()    # --timeout as before
    assert TimeLimits.of(lim) is lim


def test_messages_name_the_limit_and_the_phase():
    lim = TimeLimits(cell=10, method=3, score=2)
    assert lim.message("method", "method") == ("timeout in the method: no result after the method limit of 3 s "
                                               "(cell killed)")
    assert lim.message("score", "scoring", 0.05) == ("timeout in scoring (validity check and metrics): over the "
                                                     "score limit of 2 s (cell killed); the method itself "
                                                     "finished in 0.05 s")
    assert lim.message("cell", "setup").endswith("10 s (cell killed) — building the volume")


def test_time_limits_from_config_and_arguments():
    cfg = builtin_config("quick")
    cfg.timeout, cfg.method_timeout, cfg.score_timeout = 100.0, 50.0, None
    assert time_limits(cfg) == TimeLimits(100, 50, None)
    assert time_limits(cfg, timeout=0, score_timeout=7) == TimeLimits(None, 50, 7)    # 0 = none, None = config's
    data = cfg.to_dict()
    assert data["run"]["method_timeout"] == 50.0 and "score_timeout" not in data["run"]
    from bench.config import config_from_dict
    from phantoms import InputError

    assert config_from_dict(data).method_timeout == 50.0
    data["run"]["score_timeout"] = -1
    with pytest.raises(InputError, match=r"run.score_timeout: must be >= 0"):
        config_from_dict(data)


# ---------------------------------------------------------------------------------------------- a grid run
def _run(out: Path, *args) -> subprocess.CompletedProcess:
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(TESTS), str(REPO)] + [p for p in [env.get("PYTHONPATH")] if p])
    env["PYTHONWARNINGS"] = "ignore"
    return subprocess.run([sys.executable, "-m", "bench", "run", "--quick", "--phantoms", "sphere", "--noise",
                           "none", "--n", "16", "--n-samples", "2000", "--import", "broken_methods", "--import",
                           "runner_plugins", "--import", "hostile_plugins", "--jobs", "2", "--out", str(out), *args],
                          cwd=REPO, env=env, capture_output=True, text=True, timeout=300)


def _rows(out: Path) -> dict[str, dict]:
    with open(out / "results.csv", newline="") as fh:
        return {r["method"]: r for r in csv.DictReader(fh)}


@pytest.fixture(scope="module")
def phase_run(tmp_path_factory):
    """Method limit 2 s, score limit 2 s, no cell limit, 2 GB of memory per cell: a method that sleeps 60 s, one
    that returns at once but whose mesh takes 60 s to score, one returning a bare trimesh, one asking for 30 GB
    (tests/test_bench_run_memory.py has the rest), marching cubes."""
    out = tmp_path_factory.mktemp("limits") / "run"
    res = _run(out, "--method", "sleepy:seconds=60", "--add-method", "slow_to_score:seconds=60",
               "--add-method", "broken_type", "--add-method", "memory_hog", "--add-method", "marching_cubes",
               "--timeout", "0", "--method-timeout", "2", "--score-timeout", "2", "--memory-limit", "2")
    assert res.returncode == 0, res.stderr[-3000:]
    return out, res


def test_each_limit_runs_out_in_its_own_phase(phase_run):
    out, res = phase_run
    rows = _rows(out)
    assert rows["sleepy"]["status"] == "timeout"
    assert rows["sleepy"]["error"].startswith("timeout in the method: no result after the method limit of 2 s")
    slow = rows["slow_to_score"]
    assert slow["status"] == "timeout" and slow["error"].startswith("timeout in scoring (validity check and "
                                                                    "metrics): over the score limit of 2 s")
    assert float(slow["wall_s"]) < 2.0 and f"finished in {float(slow['wall_s']):.3g} s" in slow["error"]
    assert rows["marching_cubes"]["status"] == "ok"
    session = json.loads((out / "run.json").read_text())["sessions"][-1]
    assert (session["timeout_s"], session["method_timeout_s"], session["score_timeout_s"]) == (None, 2.0, 2.0)


def test_a_cell_over_the_memory_limit_is_a_failed_row(phase_run):
    row = _rows(phase_run[0])["memory_hog"]
    assert row["status"] == "failed"
    assert row["error"].startswith("memory limit (2 GB) exceeded in the method (MemoryError: Unable to allocate")
    session = json.loads((phase_run[0] / "run.json").read_text())["sessions"][-1]
    assert session["memory_limit_gb"] == 2.0
    assert "<td>2 GB</td>" in (phase_run[0] / "index.html").read_text(encoding="utf-8")   # the sessions table


def test_a_wrong_return_type_is_a_named_failure(phase_run):
    row = _rows(phase_run[0])["broken_type"]
    assert row["status"] == "failed"
    assert row["error"] == ("reconstruction: WrongReturnType: method 'broken_type' returned Trimesh, expected "
                            "methods.Reconstruction (return Reconstruction(mesh, info))")


def test_the_methods_own_info_is_in_the_cell_record_and_the_report(phase_run):
    out, _ = phase_run
    row = _rows(out)["marching_cubes"]
    record = json.loads((out / "cells" / f"{row['cell_id']}.json").read_text())
    info = record["row"]["method_info"]
    assert info["stop_reason"] == "done" and info["mesh_faces"] == int(row["n_faces"])  # the author's own keys
    assert isinstance(info["wall_mc_s"], float)
    assert "method_info" not in row and "wall_mc_s" not in row                  # not a results.csv column
    html = (out / "index.html").read_text(encoding="utf-8")
    assert "Method facts per cell" in html and f"mesh_faces={row['n_faces']}" in html


@pytest.mark.heavy
def test_the_whole_cell_limit_still_works_and_says_where_it_ran_out(tmp_path):
    out = tmp_path / "run"
    res = _run(out, "--method", "slow_to_score:seconds=60", "--timeout", "3", "--no-report")
    assert res.returncode == 0, res.stderr[-3000:]
    row = _rows(out)["slow_to_score"]
    assert row["status"] == "timeout"
    assert row["error"].startswith("timeout: no result after 3 s (cell killed) — in scoring (validity check")
