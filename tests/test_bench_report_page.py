"""bench.report.page: ``report`` on a damaged run folder renders what it can, or says in one line why not."""

from __future__ import annotations

import json

import pytest

from bench.cli import main

GRID = ["--quick", "--phantoms", "sphere", "--noise", "none", "--n", "16", "--n-samples", "2000",
        "--method", "marching_cubes", "--add-method", "mc_taubin", "--jobs", "2", "--no-report"]


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory):
    out = tmp_path_factory.mktemp("page") / "run"
    assert main(["run", *GRID, "--out", str(out)]) == 0
    return out


@pytest.fixture
def damaged(run_dir, tmp_path):
    import shutil

    copy = tmp_path / "run"
    shutil.copytree(run_dir, copy)
    return copy


def test_report_lists_unreadable_cells_and_with_force_renders_the_rest(damaged, capsys):
    cells = sorted((damaged / "cells").glob("*.npz"))
    cells[0].write_bytes(cells[0].read_bytes()[:200])                       # truncated archive
    bad_json = cells[1].with_suffix(".json")
    bad_json.write_text("{")                                                # half a record
    assert main(["report", str(damaged)]) == 2                              # listed, not rendered ...
    err = capsys.readouterr().err
    assert f"cells/{cells[0].name} does not load (BadZipFile" in err and f"cells/{bad_json.name} is unreadable" in err
    assert main(["report", str(damaged), "--force"]) == 0                   # ... unless forced
    err = capsys.readouterr().err
    assert f"warning: {cells[0]} does not load (BadZipFile)" in err
    assert f"warning: {bad_json} is unreadable" in err and "Traceback" not in err
    page = (damaged / "index.html").read_text()
    assert "marching_cubes" in page and "mc_taubin" in page                # both rows still rendered


@pytest.mark.parametrize("content, message", [
    (b"", "is not a readable results table (EmptyDataError"),
    (b"\x00\x01garbage\n1,2,3\n4\n", "is not a results table of levelset-bench"),
    (b'a,b\n"unclosed,1\n', "is not a"),
])
def test_report_on_an_empty_or_malformed_results_csv_is_one_line_exit_2(damaged, capsys, content, message):
    (damaged / "results.csv").write_bytes(content)
    assert main(["report", str(damaged)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: ") and message in err[0] and "results.csv" in err[0]


def test_report_with_a_run_json_that_is_a_list_warns_and_renders(damaged, capsys):
    (damaged / "run.json").write_text(json.dumps([1, 2, 3]))
    assert main(["report", str(damaged)]) == 0
    assert "run.json holds a list, not the run's metadata" in capsys.readouterr().err
    assert (damaged / "index.html").stat().st_size > 0


def test_after_preload_writing_the_report_imports_none_of_the_heavy_libraries(run_dir):
    """bench run preloads the report in a thread while the cells run; whatever write_report still imports after
    preload() is paid after the run."""
    import subprocess
    import sys

    code = ("import sys\nfrom bench.report import preload, write_report\npreload()\nbefore = set(sys.modules)\n"
            f"write_report({str(run_dir)!r})\n"
            "heavy = ('pandas', 'pyarrow', 'plotly', 'matplotlib', 'PIL', 'jinja2', 'scipy', 'numba')\n"
            "print(sorted(m for m in set(sys.modules) - before if m.split('.')[0] in heavy))\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip().splitlines()[-1] == "[]"


def test_the_page_opens_with_the_recommendation_table(run_dir):
    """The first section after the title: which method per shape kind × input, before the counts and the nav."""
    from bench.report import write_report

    page = write_report(run_dir).read_text()
    body = page[page.index("<body>"):]
    assert body.index('<section id="recommend">') < body.index('<p class="counts">') < body.index("<nav>")
    first = body[body.index("</h1>"):body.index('<section id="recommend">')]
    assert "<table" not in first and "<h2" not in first                   # nothing before it but warnings
    table = body[body.index('<table class="recommend">'):body.index("</table>")]
    assert "clean φ" in table and "no method is clearly better on hausdorff_h" in table
    assert "rests on 1 input (sphere), 2 results" in table


def test_a_run_from_before_the_shape_kind_column_still_renders(damaged):
    """An older suite's run folder: no ``shape_kind`` in results.csv nor in the cells' records, no parquet."""
    import csv

    from bench.report import write_report

    path = damaged / "results.csv"
    rows = list(csv.DictReader(path.open()))
    assert "shape_kind" in rows[0]
    cols = [c for c in rows[0] if c != "shape_kind"]
    with path.open("w", newline="") as f:
        w = csv.DictWriter(f, cols, extrasaction="ignore")
        w.writeheader()
        w.writerows(rows)
    (damaged / "results.parquet").unlink()
    for cell in (damaged / "cells").glob("*.json"):
        rec = json.loads(cell.read_text())
        rec["row"].pop("shape_kind", None)
        cell.write_text(json.dumps(rec))
    page = write_report(damaged).read_text()
    table = page[page.index('<table class="recommend">'):]
    assert "<th>unclassified</th>" in table[:table.index("</table>")]
    assert "marching_cubes" in page and "mc_taubin" in page

def test_a_phantom_name_with_control_bytes_reaches_the_page_escaped(tmp_path, capsys):
    import re

    from _synthetic_run import write_synthetic_run
    from bench.report.interactive import plotly_js

    out = tmp_path / "run"
    hostile = "volume:/scans/\x1b]0;pwned\x07<img src=x onerror=alert(1)>\x1b[2J.nii.gz?label=1"
    write_synthetic_run(out, n_shapes=1, seeds=1, noise=("none",), sealed=True, phantom=hostile)
    assert main(["report", str(out)]) == 0
    page = (out / "index.html").read_text("utf-8")
    js = plotly_js()                                  # embedded as it is (its string literals hold \x01, \x1a)
    assert page.count(js) == 1
    rest = page.replace(js, "")
    assert not re.search(r"[\x00-\x08\x0b-\x1f\x7f-\x9f]", rest.replace("\n", "")), "a raw control byte"
    assert "\\x1b]0;pwned\\x07&lt;img src=x onerror=alert(1)&gt;" in rest
    assert "\\u001b" not in rest and "\\u0007" not in rest         # the charts and viewer data say the same
