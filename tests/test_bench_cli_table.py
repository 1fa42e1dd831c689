"""bench.cli.table: ``bench table`` as LaTeX (compiled when pdflatex is here, parsed always), markdown (a GitHub
pipe table, rendered) and CSV, with the numbers of results.parquet."""

from __future__ import annotations

import re
import shutil
import subprocess

import pandas as pd
import pyarrow.parquet as pq
import pytest

from bench.cli import main
from bench.report.export import DEFAULT_METRICS, DIGITS

METRICS = ["hausdorff_h", "mean_dist_h", "fscore@h", "roughness_deg", "self_intersections", "wall_s"]


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    """Quick grid at N = 24, two seeds (the noisy cells' means are over two seeds), two methods."""
    out = tmp_path_factory.mktemp("table") / "run"
    assert main(["run", "--quick", "--n", "24", "--n-samples", "2000", "--seeds", "0,1", "--jobs", "2",
                 "--no-report", "--method", "marching_cubes", "--add-method", "mc_taubin", "--out", str(out)]) == 0
    return out


def _expected(run) -> dict[tuple, float]:
    """``{(table title part, label, metric): mean}`` computed straight from results.parquet."""
    df = pq.read_table(run / "results.parquet").to_pandas()
    ok = df[df["status"] == "ok"].copy()
    ok["snr"] = ok["snr_requested"].fillna(-1)
    means = ok.groupby(["phantom", "noise", "snr", "label"], sort=False)[METRICS].mean()
    return {(p, "clean" if n == "none" else f"{s:g} dB", lab, m): float(means.loc[(p, n, s, lab), m])
            for (p, n, s, lab) in means.index for m in METRICS}


def _table(argv, capsys) -> str:
    capsys.readouterr()
    assert main(["table", *argv]) == 0
    return capsys.readouterr().out


def _check_numbers(blocks: dict[str, list[list[str]]], expected: dict, header_of) -> int:
    """Every printed number equals the parquet mean at DIGITS significant digits; returns how many were checked."""
    checked = 0
    for title, rows in blocks.items():
        phantom = title.split(" ")[0]
        noise = "clean" if "clean" in title else re.search(r"SNR ([\d.]+ dB)", title).group(1)
        header = rows[0]
        for r in rows[1:]:
            label = r[0].replace("\\_", "_")
            for col, m in header_of(header).items():
                text = re.sub(r"\\textbf\{(.*)\}|\*\*(.*)\*\*", lambda x: x.group(1) or x.group(2), r[col])
                want = expected[(phantom, noise, label, m)]
                assert text == f"{want:.{DIGITS}g}" or (want.is_integer() and text == str(int(want))), (title, r, m)
                checked += 1
    return checked


def test_markdown_is_a_github_table_with_the_parquet_numbers(run, capsys):
    md = _table([str(run), "--format", "markdown"], capsys)
    blocks: dict[str, list[list[str]]] = {}
    for chunk in md.strip().split("\n\n### "):
        title, _, table = chunk.lstrip("# ").partition("\n\n")
        lines = table.splitlines()
        assert re.fullmatch(r"\|(:?-{3,}:?\|)+", lines[1]), lines[1]          # the header separator
        width = lines[0].count(" | ") + 1
        assert all(line.startswith("| ") and line.endswith(" |") and line.count(" | ") + 1 == width
                   for line in lines[:1] + lines[2:])
        blocks[title] = [[c.strip() for c in line.strip("| ").split(" | ")] for line in lines[:1] + lines[2:]]
    assert len(blocks) == 4 and all(len(rows) == 3 for rows in blocks.values())   # 2 phantoms x 2 noises, 2 methods
    assert blocks["sphere — clean"][0][:3] == ["method", "cells", "hausdorff_h (h)"]

    def header_of(header):
        return {i: h.split(" (")[0] for i, h in enumerate(header) if h.split(" (")[0] in METRICS}

    assert _check_numbers(blocks, _expected(run), header_of) == 4 * 2 * len(METRICS)
    markdown_it = pytest.importorskip("markdown_it", reason="markdown-it-py (dev extra) renders GitHub tables")
    page = markdown_it.MarkdownIt("commonmark").enable("table").render(md)
    assert page.count("<table>") == 4 and page.count("<tr>") == 4 * 3 and "|" not in page


def _latex_blocks(tex: str) -> dict[str, list[list[str]]]:
    """Structural parse: balanced environments, one set of booktabs rules per tabular, the same number of
    columns (from the column spec) in every row."""
    envs = re.findall(r"\\(begin|end)\{(\w+)\}", tex)
    stack = []
    for kind, name in envs:
        if kind == "begin":
            stack.append(name)
        else:
            assert stack and stack.pop() == name
    assert not stack
    blocks = {}
    for caption, spec, body in re.findall(r"\\caption\{(.*?)\}.*?\\begin\{tabular\}\{(\w+)\}(.*?)\\end\{tabular\}",
                                          tex, re.S):
        assert body.count(r"\toprule") == body.count(r"\midrule") == body.count(r"\bottomrule") == 1
        inner = body.split(r"\toprule")[1].split(r"\bottomrule")[0].replace(r"\midrule", "")
        rows = [r.strip() for r in inner.split(r"\\") if r.strip()]
        assert all(len(re.split(r"(?<!\\)&", r)) == len(spec) for r in rows), rows
        blocks[caption.replace("---", "—")] = [[c.strip() for c in re.split(r"(?<!\\)&", r)] for r in rows]
    return blocks


def test_latex_has_booktabs_units_and_the_parquet_numbers_and_compiles(run, capsys, tmp_path):
    tex = _table([str(run), "--format", "latex"], capsys)
    blocks = _latex_blocks(tex)
    assert len(blocks) == 4
    header = blocks["sphere — clean"][0]
    assert header[:3] == ["method", "cells", r"hausdorff\_h (h)"] and r"roughness\_deg ($^\circ$)" in header

    def header_of(h):
        names = {c.split(" (")[0].replace("\\_", "_"): i for i, c in enumerate(h)}
        return {i: m for m, i in names.items() if m in METRICS}

    assert _check_numbers(blocks, _expected(run), header_of) == 4 * 2 * len(METRICS)
    if not (shutil.which("pdflatex") and shutil.which("kpsewhich")
            and subprocess.run(["kpsewhich", "booktabs.sty"], capture_output=True).stdout.strip()):
        pytest.skip("pdflatex with booktabs is not installed (apt-get install texlive-latex-recommended); "
                    "parsed only")
    doc = tmp_path / "t.tex"
    doc.write_text("\\documentclass{article}\n\\usepackage{booktabs}\n\\begin{document}\n" + tex + "\\end{document}\n")
    res = subprocess.run(["pdflatex", "-interaction=nonstopmode", "-halt-on-error", doc.name], cwd=tmp_path,
                         capture_output=True, text=True, timeout=120)
    assert res.returncode == 0, res.stdout[-2000:]
    assert (tmp_path / "t.pdf").stat().st_size > 0
    assert "Missing character" not in (tmp_path / "t.log").read_text()   # every glyph exists (units, dashes)


def test_csv_holds_the_parquet_means_at_full_precision_and_goes_to_a_file(run, capsys, tmp_path):
    out = tmp_path / "t.csv"
    assert "wrote" in _table([str(run), "--format", "csv", "-o", str(out)], capsys)
    got = pd.read_csv(out)
    expected = _expected(run)
    assert len(got) == 8
    for _, r in got.iterrows():
        noise = "clean" if r["noise"] == "none" else f"{r['snr_requested']:g} dB"
        for m in METRICS:
            assert r[m] == expected[(r["phantom"], noise, r["method"], m)]        # exact: no rounding


def test_metric_and_by_options_choose_columns_and_groups(run, capsys):
    md = _table([str(run), "--metric", "euler", "--metric", "iou,sdf_rms_h", "--by", "noise"], capsys)
    assert md.count("### ") == 3                        # clean; the two phantoms' SNRs differ
    assert "| method | cells | euler | iou | sdf_rms_h (h) |" in md
    default = _table([str(run)], capsys)
    assert all(m in default for m in DEFAULT_METRICS)


@pytest.mark.parametrize("argv, message", [
    (["{tmp}"], "is not a run folder"),
    (["{run}", "--metric", "nope"], "--metric nope: not a column of this run"),
    (["{run}", "--by", "colour"], "--by colour: unknown"),
    (["{run}", "-o", "{tmp}"], "it is a directory"),
])
def test_bad_input_is_one_line_exit_2(run, tmp_path, capsys, argv, message):
    capsys.readouterr()
    assert main(["table", *[a.format(run=run, tmp=tmp_path) for a in argv]]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: ") and message in err[0]


def test_the_leaderboard_exports_with_its_ranks_and_compiles(run, capsys, tmp_path):
    """``--leaderboard``: one row per method with its mean ranks (the run's own board), markdown and LaTeX."""
    from bench.report.verdicts import leaderboards
    from bench.run.results import read_results

    board = leaderboards(read_results(run).to_dict("records"))[0]
    md = _table([str(run), "--leaderboard"], capsys)
    first, primary, raw = md.split("### ")[1:4]          # the recommendation, the board, then its raw twin
    assert first.startswith("Which method, for which shape and input")
    assert board["recommendation"] in primary and "not the verdict" in raw and "usable or not" in raw
    rows = [ln for ln in primary.splitlines() if ln.startswith("| ") and not ln.startswith("| method")]
    assert len(rows) == len(board["rows"]) == 2
    for r, line in zip(board["rows"], rows):
        cells = [c.strip().strip("*") for c in line.strip("|").split("|")]
        assert cells[0] == r["label"] and float(cells[2]) == pytest.approx(r["hausdorff_h"], abs=5e-4)
    tex = _table([str(run), "--leaderboard", "--format", "latex"], capsys)
    assert r"\toprule" in tex and "rank hausdorff\\_h" in tex and "\\%" in tex
    if not shutil.which("pdflatex"):
        pytest.skip("pdflatex is not installed; parsed only")
    doc = tmp_path / "l.tex"
    doc.write_text("\\documentclass{article}\n\\usepackage{booktabs}\n\\begin{document}\n" + tex + "\\end{document}\n")
    res = subprocess.run(["pdflatex", "-interaction=nonstopmode", "-halt-on-error", doc.name], cwd=tmp_path,
                         capture_output=True, text=True, timeout=120)
    assert res.returncode == 0, res.stdout[-2000:]
    assert "Missing character" not in (tmp_path / "l.log").read_text()


# ---------------------------------------------------------------------------------------------- sealed records
def _damage(out, how: str) -> str:
    """Damage the results tables of the run folder ``out`` as ``how`` says; returns the cell id to be named."""
    import csv

    import pyarrow as pa

    with open(out / "results.csv", newline="") as fh:
        rows = list(csv.reader(fh))
    col = rows[0].index("hausdorff_h")
    named = {"end": rows[-1][0], "middle": rows[5][0], "duplicate": rows[3][0],
             "edit_csv": rows[2][0]}.get(how)
    if how in ("end", "middle", "header_only", "duplicate", "edit_csv"):
        if how == "end":
            rows = rows[:-1]
        elif how == "middle":
            rows = rows[:5] + rows[6:]
        elif how == "header_only":
            rows = rows[:1]
        elif how == "duplicate":
            rows = rows + [rows[3]]
        else:
            rows[2][col] = repr(float(rows[2][col]) * 0.5)
        with open(out / "results.csv", "w", newline="") as fh:
            csv.writer(fh).writerows(rows)
        return named
    table = pq.read_table(out / "results.parquet")       # the parquet only, its CSV hash kept: it is read first
    if how == "parquet_row":
        edited = table.slice(0, table.num_rows - 1)
        named = table.column("cell_id")[table.num_rows - 1].as_py()
    else:
        df = table.to_pandas()
        df.loc[3, "hausdorff_h"] = 0.001
        edited, named = pa.Table.from_pandas(df, preserve_index=False), df.loc[3, "cell_id"]
    pq.write_table(edited.replace_schema_metadata(table.schema.metadata), out / "results.parquet")
    return named


CASES = {"end": "{}: no row in results.csv", "middle": "{}: no row in results.csv",
         "header_only": "15 cells have no row in results.csv",
         "duplicate": "{}: 2 rows in results.csv", "edit_csv": "{}: hausdorff_h is",
         "parquet_row": "{}: no row in results.parquet", "edit_parquet": "{}: hausdorff_h is 0.001 in results.parquet"}


@pytest.mark.parametrize("how", list(CASES))
def test_a_results_table_that_disagrees_with_the_sealed_records_is_one_line_exit_2(how, tmp_path, capsys):
    from _synthetic_run import write_synthetic_run

    out = tmp_path / "run"
    write_synthetic_run(out, n_shapes=1, seeds=2, sealed=True)
    capsys.readouterr()
    assert main(["table", str(out)]) == 0                             # intact: the tables are the records
    capsys.readouterr()
    cid = _damage(out, how)
    assert main(["table", str(out)]) == 2
    captured = capsys.readouterr()
    err = captured.err.strip().splitlines()
    assert captured.out == "" and len(err) == 1 and err[0].startswith("error: "), captured
    assert CASES[how].format(cid) in err[0] and "against the sealed cell records" in err[0] and "--resume" in err[0]


def test_a_record_whose_checksum_was_deleted_is_refused_by_table(tmp_path, capsys):
    import json

    from _synthetic_run import write_synthetic_run

    out = tmp_path / "run"
    write_synthetic_run(out, n_shapes=1, seeds=1, noise=("none",), sealed=True)
    path = sorted((out / "cells").glob("*.json"))[0]
    rec = json.loads(path.read_text())
    del rec["checksum"]
    path.write_text(json.dumps(rec))
    capsys.readouterr()
    assert main(["table", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and f"{path.name} has no seal" in err[0] and "--accept-unsealed" in err[0]


def test_the_recommendation_table_prints_alone_in_each_format_and_compiles(run, capsys, tmp_path):
    """``--recommend``: the report's first section (shape kind × input, each cell a verdict and what it rests on)."""
    md = _table([str(run), "--recommend"], capsys)
    lines = md.splitlines()
    assert lines[0] == "### Which method, for which shape and input"
    head = next(ln for ln in lines if ln.startswith("| shape kind"))
    assert head == "| shape kind \\ input | noisy φ | clean φ | every input |"
    # the quick grid's phantoms declare a kind (or, before they did, are unclassified); 4 inputs per cell: no test
    row = next(ln for ln in lines if ln.startswith("| ") and ln != head)
    assert row.count("no method is clearly better on hausdorff_h (no pair shares enough inputs for a test: 6 are "
                     "needed)") >= 2
    assert "rests on 4 inputs (sphere, ellipsoid), 8 results" in row
    assert "rests on 6 inputs (sphere, ellipsoid), 12 results" in row          # the pooled column: every input
    csv = _table([str(run), "--recommend", "--format", "csv"], capsys)
    frame = pd.read_csv(__import__("io").StringIO(csv))
    # clean cells run once (no seed to vary), noisy ones per seed
    assert dict(zip(frame["input"], frame["n_results"])) == {"noisy φ": 8, "clean φ": 4, "every input": 12}
    tex = _table([str(run), "--recommend", "--format", "latex"], capsys)
    assert r"\toprule" in tex and r"$\varphi$" in tex
    if not shutil.which("pdflatex"):
        pytest.skip("pdflatex is not installed; parsed only")
    doc = tmp_path / "r.tex"
    doc.write_text("\\documentclass{article}\n\\usepackage{booktabs}\n\\begin{document}\n" + tex + "\\end{document}\n")
    res = subprocess.run(["pdflatex", "-interaction=nonstopmode", "-halt-on-error", doc.name], cwd=tmp_path,
                         capture_output=True, text=True, timeout=120)
    assert res.returncode == 0, res.stdout[-2000:]

#: a label map's file name holding a window-title OSC, BEL, a screen-clearing CSI and an HTML tag
HOSTILE = "volume:/scans/\x1b]0;pwned\x07<img src=x onerror=alert(1)>\x1b[2J.nii.gz?label=1"
_RAW_CONTROL = re.compile(r"[\x00-\x08\x0b-\x1f\x7f-\x9f]")


@pytest.mark.parametrize("fmt, shown", [("markdown", "\\\\x1b]0;pwned\\\\x07&lt;img src=x onerror=alert(1)&gt;"),
                                        ("latex", r"\textbackslash{}x1b]0;pwned\textbackslash{}x07"
                                                  r"\textless{}img src=x onerror=alert(1)\textgreater{}"),
                                        ("csv", "\\x1b]0;pwned\\x07<img src=x onerror=alert(1)>\\x1b[2J")])
def test_a_phantom_name_with_control_bytes_or_html_is_shown_escaped(fmt, shown, tmp_path, capsys):
    from _synthetic_run import write_synthetic_run

    out = tmp_path / "run"
    write_synthetic_run(out, n_shapes=1, seeds=1, noise=("none",), sealed=True, phantom=HOSTILE)
    capsys.readouterr()
    assert main(["table", str(out), "--format", fmt]) == 0
    text = capsys.readouterr().out
    assert not _RAW_CONTROL.search(text.replace("\n", "")), repr(text[:300])
    assert shown in text, text[:600]
    if fmt == "markdown":                          # a viewer that renders inline HTML shows the tag as text
        assert "<img" not in text and text.startswith("### \\\\x1b]0;pwned")
    assert main(["table", str(out), "--format", fmt, "-o", str(tmp_path / "t.txt")]) == 0
    assert not _RAW_CONTROL.search((tmp_path / "t.txt").read_text().replace("\n", ""))


def test_table_and_compare_refuse_a_run_whose_mesh_arrays_were_altered(tmp_path, capsys):
    import numpy as np

    from _synthetic_run import write_synthetic_run

    out = tmp_path / "run"
    write_synthetic_run(out, n_shapes=1, seeds=1, noise=("none",), sealed=True)
    npz = sorted((out / "cells").glob("*.npz"))[0]
    with np.load(npz) as z:
        arrays = {k: z[k] for k in z.files}
    np.savez(npz, **{**arrays, "faces": arrays["faces"][::-1]})
    capsys.readouterr()
    for argv in (["table", str(out)], ["compare", str(out), str(out)]):
        assert main(argv) == 2, argv
        captured = capsys.readouterr()
        err = captured.err.strip().splitlines()
        assert captured.out == "" and len(err) == 1 and npz.stem in err[0] and "--resume" in err[0], captured
