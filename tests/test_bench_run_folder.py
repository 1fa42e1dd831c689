"""``bench report DIR`` validates the run folder first (issue 30): a results.csv cut in half or malformed is
one line, exit 2, with the line number and a ``--resume`` hint — never a report of a half row."""

from __future__ import annotations

import shutil

import pytest

from bench.cli import main
from bench.run.store import RESULTS_PARQUET

GRID = ('[grid]\nphantoms = ["sphere"]\nn = [24]\nseeds = [0, 1]\nnoise = ["none", "gaussian"]\n'
        '[[methods]]\nname = "marching_cubes"\n')


@pytest.fixture(scope="module")
def run_folder(tmp_path_factory):
    base = tmp_path_factory.mktemp("run")
    cfg = base / "g.toml"
    cfg.write_text(GRID)
    out = base / "run"
    assert main(["run", "--config", str(cfg), "--out", str(out), "--jobs", "1", "--no-report"]) == 0
    return out


def _copy(run_folder, tmp_path):
    out = tmp_path / "run"
    shutil.copytree(run_folder, out)
    return out


def _one_error(capsys, *needles):
    err = capsys.readouterr().err
    lines = [x for x in err.splitlines() if x.strip()]
    assert len(lines) == 1 and lines[0].startswith("error: ") and "Traceback" not in err, err
    assert all(n in err for n in needles), err


@pytest.mark.parametrize("cut", ["half", "mid_last_row", "extra_field"])
def test_report_on_a_truncated_or_malformed_results_csv_exits_2_with_the_line(cut, run_folder, tmp_path, capsys):
    out = _copy(run_folder, tmp_path)
    csv_path = out / "results.csv"
    text = csv_path.read_text()
    lines = text.splitlines(keepends=True)
    assert len(lines) == 4          # header + 3 cells (the clean volume has one seed)
    if cut == "half":
        text = text[: len(text) // 2]
    elif cut == "mid_last_row":
        text = text[: len(text) - len(lines[-1]) // 2]
    else:
        text = "".join(lines[:2]) + lines[2].rstrip("\r\n") + ",surplus\n" + "".join(lines[3:])
    csv_path.write_text(text, newline="")
    assert main(["report", str(out)]) == 2
    _one_error(capsys, "results.csv", "line ", "--resume")
    assert not (out / "index.html").exists()
    (out / RESULTS_PARQUET).unlink(missing_ok=True)   # with or without the parquet copy
    assert main(["report", str(out)]) == 2


def test_report_on_an_intact_folder_still_renders(run_folder, tmp_path, capsys):
    out = _copy(run_folder, tmp_path)
    (out / RESULTS_PARQUET).unlink(missing_ok=True)   # through the CSV path
    assert main(["report", str(out)]) == 0
    assert (out / "index.html").is_file()
