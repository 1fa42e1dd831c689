"""Tests of ``bench.run.executors.local``: :class:`LocalExecutor` runs each cell in its own worker process,
reports every cell's start and result, turns a cell over its time limit into a ``timeout`` row and a cell whose
process dies into a ``failed`` row, and the run goes on."""

from __future__ import annotations

import time

from bench.config import config_from_dict
from bench.run import Cell, CellResult, expand_grid
from bench.run.executors.local import LocalExecutor
from bench.run.limits import TimeLimits


def _cells() -> list[Cell]:
    cfg = config_from_dict({"grid": {"phantoms": ["sphere"], "n": 24},
                            "methods": [{"name": "marching_cubes"}, {"name": "mc_taubin"}],
                            "metrics": {"n_samples": 1000}})
    cfg.validate()
    return expand_grid(cfg)


def _plugin_cell(base: Cell, method: str, params: dict | None = None) -> Cell:
    return Cell.from_dict({**base.to_dict(), "method": method, "label": method, "params": params or {},
                           "imports": ["runner_plugins"], "cell_id": f"{method}_cell"})


def _run(executor: LocalExecutor, cells: list[Cell]) -> tuple[list[str], dict[str, CellResult]]:
    started, results = [], {}
    executor.run(cells, on_start=lambda c: started.append(c.cell_id),
                 on_result=lambda c, r: results.__setitem__(c.cell_id, r))
    return started, results


def test_local_executor_runs_two_cells_and_reports_each_start_and_result():
    cells = _cells()
    started, results = _run(LocalExecutor(jobs=2, timeout=None), cells)
    assert started == [c.cell_id for c in cells]
    assert set(results) == {c.cell_id for c in cells}
    for cell in cells:
        row = results[cell.cell_id].row.to_dict()
        assert row["status"] == "ok", row["error"]
        assert row["method"] == cell.method and row["watertight"] and row["euler"] == 2


def test_local_executor_turns_a_cell_over_its_time_limit_into_a_timeout_row():
    sleepy = _plugin_cell(_cells()[0], "sleepy", {"seconds": 60.0})
    t0 = time.monotonic()
    _, results = _run(LocalExecutor(jobs=1, timeout=3.0, preload=["runner_plugins"]), [sleepy])
    assert time.monotonic() - t0 < 30                       # killed at its deadline, not after 60 s
    row = results["sleepy_cell"].row.to_dict()
    assert row["status"] == "timeout"
    assert "no result after 3 s" in row["error"] and "in the method" in row["error"]
    assert row["cell_s"] >= 3.0


def test_local_executor_reports_a_crashed_cell_as_failed_and_runs_the_others():
    ok, _ = _cells()
    crash = _plugin_cell(ok, "crashing")
    _, results = _run(LocalExecutor(jobs=1, timeout=None, preload=["runner_plugins"]), [crash, ok])
    crashed = results["crashing_cell"].row.to_dict()
    assert crashed["status"] == "failed" and crashed["error"].startswith("crash: worker process killed by SIGKILL")
    assert results[ok.cell_id].row.status == "ok"


def test_local_executor_settings():
    ex = LocalExecutor(jobs=0, timeout=TimeLimits(cell=10.0, method=2.0), memory_gb=0)
    assert ex.jobs == 1 and ex.memory_gb is None
    assert ex.timeout == 10.0 and ex.limits.method == 2.0
    assert LocalExecutor(jobs=3, timeout=5).limits.cell == 5
    assert not LocalExecutor(jobs=1, timeout=None).limits


def test_local_executor_with_no_cells_returns_at_once():
    started, results = _run(LocalExecutor(jobs=1, timeout=1.0), [])
    assert started == [] and results == {}


LOUD = r'''
import os
import sys

from methods import Method, get_method, register_method


@register_method
class Loud(Method):
    name = "loud"
    description = "prints control codes and 20 KB before meshing"

    def reconstruct(self, volume):
        print("\x1b]0;stdout title\x07" + "o" * 20000)
        sys.stderr.write("\x1b[2J stderr line\n")
        os.write(2, b"\x07 fd 2 from C\n")
        return get_method("marching_cubes").reconstruct(volume)
'''


def test_a_plugins_output_in_a_run_is_kept_in_its_record_not_shown_raw(tmp_path):
    import json
    import os
    import subprocess
    import sys
    from pathlib import Path

    (tmp_path / "loud_plugin.py").write_text(LOUD)
    repo = Path(__file__).resolve().parents[1]
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(tmp_path), str(repo)])}
    out = tmp_path / "run"
    proc = subprocess.run([sys.executable, "-m", "bench", "run", "--quick", "--phantoms", "sphere", "--n", "16",
                           "--noise", "none", "--method", "loud", "--import", "loud_plugin", "--no-report",
                           "--out", str(out)], capture_output=True, text=True, timeout=300, env=env, cwd=repo)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert "\x1b" not in proc.stdout + proc.stderr and "\x07" not in proc.stdout + proc.stderr
    (record,) = [json.loads(p.read_text()) for p in (out / "cells").glob("*.json")]
    row = record.get("row", record)
    kept = row["method_output"]
    assert kept["bytes"] > 20000 and len(kept["head"]) >= 4096
    assert kept["head"].startswith("\\x1b]0;stdout title\\x07ooo")
