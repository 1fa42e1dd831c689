"""bench.cli.compare: ``bench compare`` on two runs of the quick grid, one with a method parameter changed."""

from __future__ import annotations

import re

import pytest

from bench.cli import main

GRID = ["run", "--quick", "--n", "24", "--n-samples", "2000", "--jobs", "2", "--no-report",
        "--method", "marching_cubes"]


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """Run A: marching cubes + Taubin with 30 passes; run B: the same with 5 (the default labels differ too)."""
    root = tmp_path_factory.mktemp("compare")
    a, b = root / "a", root / "b"
    assert main([*GRID, "--add-method", "mc_taubin:iterations=30", "--out", str(a)]) == 0
    assert main([*GRID, "--add-method", "mc_taubin:iterations=5", "--out", str(b)]) == 0
    return a, b


def _sections(out: str) -> dict[str, list[str]]:
    """The indented lines under each ``worse (...)`` / ``better (...)`` / ... heading of the output."""
    found: dict[str, list[str]] = {}
    current = None
    for line in out.splitlines():
        if line.startswith("  ") and current:
            found[current].append(line.strip())
        else:
            current = line.split(" (")[0].rstrip(":")
            found.setdefault(current, [])
    return found


def test_a_changed_parameter_names_the_changed_method_cells_and_metrics(runs, capsys):
    a, b = runs
    capsys.readouterr()
    assert main(["compare", str(a), str(b)]) == 0
    out = capsys.readouterr().out
    assert "changed: mc_taubin[iterations=30] → mc_taubin[iterations=5] (mc_taubin, 4 cells): iterations: 30 → 5" in out
    sections = _sections(out)
    changed = sections.get("worse", []) + sections.get("better", [])
    assert changed, out
    # only the Taubin cells changed; marching cubes computed the same thing in both runs
    assert all("/mc_taubin" in line for line in changed)
    assert not any("marching_cubes" in line for line in changed)
    named = {line.split()[0] for line in changed}
    assert len(named) == 4                                          # the four Taubin cells of the grid
    # fewer smoothing passes move the distances to the truth: named with both values
    assert any(re.search(r"mean_dist_h: [\d.]+ → [\d.]+", line) for line in sections["worse"])
    summary = out.strip().splitlines()[-1]
    assert summary.startswith("compare: 8 cells matched — ") and "0 only in A, 0 only in B" in summary
    assert "no change" not in out


def test_fail_on_worse_exits_1_when_something_got_worse(runs, capsys):
    a, b = runs
    assert main(["compare", str(a), str(b), "--fail-on-worse"]) == 1
    assert main(["compare", str(a), str(a), "--fail-on-worse"]) == 0


def test_a_run_and_itself_is_no_change_and_exits_0(runs, capsys):
    a, _ = runs
    capsys.readouterr()
    assert main(["compare", str(a), str(a)]) == 0
    out = capsys.readouterr().out
    assert out.strip().splitlines()[-1].startswith("no change: 8 cells matched")
    assert "worse" not in _sections(out) and "better" not in _sections(out) and "changed:" not in out


def test_html_page_has_the_same_content_and_loads_nothing(runs, tmp_path, capsys):
    a, b = runs
    page = tmp_path / "cmp.html"
    capsys.readouterr()
    assert main(["compare", str(a), str(b), "--html", str(page)]) == 0
    out = capsys.readouterr().out
    html = page.read_text()
    summary = [line for line in out.splitlines() if line.startswith("compare: ")][0]
    assert summary in html.replace("&#x27;", "'")
    for cell in {line.split()[0] for line in _sections(out)["worse"]}:
        assert cell in html
    assert "iterations: 30 → 5" in html
    assert "http" not in html and "src=" not in html                # self-contained


@pytest.mark.parametrize("argv, message", [
    (["{tmp}", "{a}"], "is not a run folder (no results.parquet or results.csv"),
    (["{a}", "{a}", "--html", "{tmp}"], "it is a directory"),
])
def test_bad_input_is_one_line_exit_2(runs, tmp_path, capsys, argv, message):
    a, _ = runs
    argv = [x.format(tmp=tmp_path, a=a) for x in argv]
    capsys.readouterr()
    assert main(["compare", *argv]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: ") and message in err[0]


def test_a_run_whose_results_table_disagrees_with_its_sealed_records_is_refused(runs, tmp_path, capsys):
    import csv
    import shutil

    a, b = runs
    edited = tmp_path / "edited"
    shutil.copytree(b, edited)
    with open(edited / "results.csv", newline="") as fh:
        rows = list(csv.reader(fh))
    col = rows[0].index("hausdorff_h")
    rows[1][col] = "0.0001"                                   # a better number, typed in by hand
    with open(edited / "results.csv", "w", newline="") as fh:
        csv.writer(fh).writerows(rows)
    capsys.readouterr()
    assert main(["compare", str(a), str(edited), "--fail-on-worse"]) == 2
    captured = capsys.readouterr()
    err = captured.err.strip().splitlines()
    assert captured.out == "" and len(err) == 1 and err[0].startswith("error: ")
    assert f"{rows[1][0]}: hausdorff_h is 0.0001 in results.csv" in err[0], err[0]


def test_a_phantom_name_with_control_bytes_is_shown_escaped_on_the_terminal_and_the_page(tmp_path, capsys):
    from _synthetic_run import write_synthetic_run

    hostile = "volume:/scans/\x1b]0;pwned\x07<img src=x onerror=alert(1)>\x1b[2J.nii.gz?label=1"
    a, b = tmp_path / "a", tmp_path / "b"
    write_synthetic_run(a, n_shapes=1, seeds=1, noise=("none",), sealed=True, phantom=hostile + "{}")
    write_synthetic_run(b, n_shapes=2, seeds=1, noise=("none",), sealed=True, phantom=hostile + "{}")
    capsys.readouterr()
    assert main(["compare", str(a), str(b), "--html", str(tmp_path / "c.html")]) == 0
    out = capsys.readouterr().out
    page = (tmp_path / "c.html").read_text("utf-8")
    for text in (out, page):
        assert not re.search(r"[\x00-\x08\x0b-\x1f\x7f-\x9f]", text.replace("\n", "")), repr(text[:400])
    assert "\\x1b]0;pwned\\x07" in out and "<img src=x" not in page

def test_runs_that_share_no_cell_exit_2_with_the_reason(tmp_path, capsys):
    """Labels that cannot be paired: not "0 cells matched" and exit 0, but one line saying why, exit 2."""
    small = ["run", "--phantoms", "sphere", "--noise", "none", "--n", "16", "--n-samples", "1000", "--jobs", "1",
             "--no-report"]
    assert main([*small, "--method", "t5=mc_taubin:iterations=5", "--method", "t9=mc_taubin:iterations=9",
                 "--out", str(tmp_path / "a")]) == 0
    assert main([*small, "--method", "u6=mc_taubin:iterations=6", "--method", "u8=mc_taubin:iterations=8",
                 "--out", str(tmp_path / "b")]) == 0
    capsys.readouterr()
    assert main(["compare", str(tmp_path / "a"), str(tmp_path / "b")]) == 2
    captured = capsys.readouterr()
    assert captured.out == "" and captured.err.count("\n") == 1
    assert "0 cells matched: the runs share 1 input(s) but no method label (A: t5, t9; B: u6, u8)" in captured.err
