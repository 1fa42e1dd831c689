"""A grid run with a method that declines some inputs (:meth:`methods.Method.skip_reason`): each such cell is a
row with status ``skipped`` and the method's reason, counted apart from the failures in the summary line and in
run.json, beside the method's ok cells."""

from __future__ import annotations

import csv
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parent.parent
TESTS = Path(__file__).resolve().parent


@pytest.mark.heavy   # end to end, ~10 s: run by .ci/run's second pytest
def test_a_declined_cell_is_a_skipped_row_with_its_reason_not_a_failure(tmp_path):
    cfg = tmp_path / "g.toml"
    cfg.write_text('[grid]\nphantoms = ["sphere"]\nn = [24, 32]\n[run]\nimports = ["hook_plugins"]\n'
                   '[[methods]]\nname = "picky_mc"\n[metrics]\nn_samples = 2000\n')
    out = tmp_path / "run"
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(TESTS), str(REPO)]), PYTHONWARNINGS="ignore")
    r = subprocess.run([sys.executable, "-m", "bench", "run", "--config", str(cfg), "--out", str(out), "--jobs", "1",
                        "--no-report"], cwd=REPO, env=env, capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr
    with open(out / "results.csv", newline="") as fh:
        rows = {row["N"]: row for row in csv.DictReader(fh)}
    assert rows["24"]["status"] == "skipped" and rows["32"]["status"] == "ok"
    assert rows["24"]["error"] == "the grid has 24 points per axis, fewer than the 30 it needs"
    assert rows["24"]["hausdorff_h"] == "" and rows["32"]["hausdorff_h"] != ""
    summary = [line for line in (r.stdout + r.stderr).splitlines() if line.startswith("2 cells:")]
    assert summary and "1 ok" in summary[0] and "0 failed" in summary[0] and "1 skipped" in summary[0], r.stdout
    status = json.loads((out / "run.json").read_text())["cells"]["status"]
    assert status["skipped"] == 1 and status["ok"] == 1 and status["failed"] == 0
