"""A failing cell's message is stored once in full and capped everywhere else (issue 30): a 5-million-character
exception message was copied into results.csv (past the csv module's field limit), the cell JSON twice and the
page three times."""

from __future__ import annotations

import csv
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from bench.run.values import MAX_MESSAGE, cap_tail, cap_text, error_text

REPO = Path(__file__).resolve().parent.parent
TESTS = Path(__file__).resolve().parent
HUGE = 5_000_000


def test_cap_text_keeps_short_text_and_cuts_long_text_with_a_note():
    assert cap_text("short") == "short"
    capped = cap_text("y" * HUGE, where="cells/c.json")
    assert len(capped) < MAX_MESSAGE + 100 and capped.startswith("y" * MAX_MESSAGE)
    assert "5,000,000 characters; full text in cells/c.json" in capped
    assert len(error_text(RuntimeError("z" * HUGE))) < MAX_MESSAGE + 100
    tb = "Traceback (most recent call last):\n" + "  frame\n" * 1000 + "RuntimeError: " + "w" * HUGE + "\n"
    shown = cap_tail(tb, where="cells/c.json")
    assert len(shown) < 2 * MAX_MESSAGE and shown.startswith("Traceback") and "RuntimeError: www" in shown


@pytest.mark.heavy
def test_a_huge_message_is_stored_once_and_capped_in_csv_and_page(tmp_path):
    cfg = tmp_path / "g.toml"
    cfg.write_text('[grid]\nphantoms = ["sphere"]\nn = [24]\n[run]\nimports = ["runner_plugins"]\n'
                   '[[methods]]\nname = "huge_message"\n[[methods]]\nname = "marching_cubes"\n')
    out = tmp_path / "run"
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(TESTS), str(REPO)]), PYTHONWARNINGS="ignore")
    r = subprocess.run([sys.executable, "-m", "bench", "run", "--config", str(cfg), "--out", str(out), "--jobs", "1"],
                       cwd=REPO, env=env, capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr[-2000:]
    assert len(r.stdout) + len(r.stderr) < 20_000           # the terminal gets the capped line too
    with open(out / "results.csv", newline="") as fh:        # the csv module's default field limit holds
        rows = {row["method"]: row for row in csv.DictReader(fh)}
    error = rows["huge_message"]["error"]
    assert rows["huge_message"]["status"] == "failed" and len(error) < MAX_MESSAGE + 200
    assert "(5,000,014 characters; full text in the cell's traceback)" in error
    cell = out / "cells" / f"{rows['huge_message']['cell_id']}.json"
    text = cell.read_text()
    assert HUGE < len(text) < HUGE + 100_000                 # the full text once (in the traceback)
    assert "x" * HUGE in json.loads(text)["traceback"]
    page = (out / "index.html").read_text()
    assert "x" * (MAX_MESSAGE + 1) not in page and page.count("x" * 100) < 10 * MAX_MESSAGE // 100
    assert rows["marching_cubes"]["status"] == "ok"
