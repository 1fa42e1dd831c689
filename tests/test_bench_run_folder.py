"""``bench report DIR`` validates the run folder first (issue 30): a results.csv cut in half or malformed is
one line, exit 2, with the line number and a ``--resume`` hint — never a report of a half row."""

from __future__ import annotations

import shutil

import pytest

from bench.cli import main
from bench.run.results import RESULTS_PARQUET

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


# ---------------------------------------------------------------------------------------------- cell checksums
import csv  # noqa: E402
import json  # noqa: E402

import numpy as np  # noqa: E402


def _first_cell(out):
    with open(out / "results.csv", newline="") as fh:
        return next(csv.DictReader(fh))["cell_id"]


def _edit_hausdorff(out, cid):
    path = out / "cells" / f"{cid}.json"
    rec = json.loads(path.read_text())
    rec["row"]["hausdorff"] = 123
    path.write_text(json.dumps(rec, indent=1))


def test_every_cell_record_is_written_with_its_checksums(run_folder):
    from bench.run.integrity import record_problem

    for path in sorted((run_folder / "cells").glob("*.json")):
        rec = json.loads(path.read_text())
        assert set(rec["checksum"]) == {"record", "npz"} and len(rec["checksum"]["record"]) == 64
        assert record_problem(rec, path.with_suffix(".npz")) is None


@pytest.mark.parametrize("damage, named", [
    ("edit_json", ".json was altered after it was written"),
    ("delete_json", ".json is missing"),
    ("delete_npz", ".npz is missing"),
    ("alter_npz", "does not match its checksum"),
])
def test_report_lists_missing_or_altered_cell_files_and_renders_them_only_with_force(
        damage, named, run_folder, tmp_path, capsys):
    out = _copy(run_folder, tmp_path)
    cid = _first_cell(out)
    npz = out / "cells" / f"{cid}.npz"
    if damage == "edit_json":
        _edit_hausdorff(out, cid)
    elif damage == "delete_json":
        (out / "cells" / f"{cid}.json").unlink()
    elif damage == "delete_npz":
        npz.unlink()
    else:
        with np.load(npz) as z:
            arrays = {k: z[k] for k in z.files}
        arrays["vertices"] = arrays["vertices"] * 1.01
        np.savez(npz, **arrays)
    assert main(["report", str(out)]) == 2
    _one_error(capsys, f"cells/{cid}", named, "--force", "--resume")
    assert not (out / "index.html").exists()
    assert main(["report", str(out), "--force"]) == 0
    page = (out / "index.html").read_text()
    assert "Damaged run folder" in page and f"cells/{cid}" in page


def test_resume_recomputes_an_edited_cell_and_says_so(run_folder, tmp_path, capsys):
    out = _copy(run_folder, tmp_path)
    cid = _first_cell(out)
    _edit_hausdorff(out, cid)
    assert main(["run", "--resume", "--out", str(out), "--jobs", "1", "--no-report"]) == 0
    err = capsys.readouterr().err
    assert f"{cid}.json was altered after it was written (checksum mismatch); the cell will be rerun" in err
    with open(out / "results.csv", newline="") as fh:
        row = {r["cell_id"]: r for r in csv.DictReader(fh)}[cid]
    assert float(row["hausdorff"]) != 123
    assert main(["report", str(out)]) == 0


def _strip_seal(path, hausdorff=None):
    rec = json.loads(path.read_text())
    del rec["checksum"]
    if hausdorff is not None:
        rec["row"]["hausdorff"] = hausdorff
    path.write_text(json.dumps(rec, indent=1))


def test_a_record_whose_checksum_was_deleted_is_altered_and_accept_unsealed_seals_an_old_folder(
        run_folder, tmp_path, capsys):
    out = _copy(run_folder, tmp_path)
    for path in (out / "cells").glob("*.json"):          # a folder written before seals existed
        _strip_seal(path)
    assert main(["report", str(out)]) == 2
    _one_error(capsys, "has no seal", "--accept-unsealed", "--resume")
    assert main(["report", str(out), "--accept-unsealed"]) == 0
    assert "sealed 3 cell record(s) written before seals" in capsys.readouterr().err
    assert main(["report", str(out)]) == 0                 # sealed for good
    assert all("sealed_later" in json.loads(p.read_text())["checksum"] for p in (out / "cells").glob("*.json"))


def test_accept_unsealed_still_refuses_a_record_that_disagrees_with_the_table(run_folder, tmp_path, capsys):
    out = _copy(run_folder, tmp_path)
    cid = _first_cell(out)
    for path in (out / "cells").glob("*.json"):          # an old folder, one record edited by hand
        _strip_seal(path, hausdorff=123 if path.stem == cid else None)
    assert main(["report", str(out), "--accept-unsealed"]) == 2       # not sealed: its value is not the truth
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 2 and "sealed 2 cell record(s)" in err[0] and "left 1 unsealed that disagree" in err[0]
    assert err[1].startswith("error: ") and f"{cid}.json has no seal" in err[1] and "--resume" in err[1]
    assert "sealed once with" not in err[1] and "--accept-unsealed left unsealed the records that disagree" in err[1]
    assert "checksum" not in json.loads((out / "cells" / f"{cid}.json").read_text())


def test_resume_recomputes_a_forged_record_without_its_checksum(run_folder, tmp_path, capsys):
    out = _copy(run_folder, tmp_path)
    cid = _first_cell(out)
    _strip_seal(out / "cells" / f"{cid}.json", hausdorff=123)
    assert main(["run", "--resume", "--out", str(out), "--jobs", "1", "--no-report"]) == 0
    assert f"{cid}.json has no seal" in capsys.readouterr().err
    with open(out / "results.csv", newline="") as fh:
        assert float({r["cell_id"]: r for r in csv.DictReader(fh)}[cid]["hausdorff"]) != 123
    assert main(["report", str(out)]) == 0


def test_a_stray_record_claiming_an_existing_cell_does_not_win_on_resume(run_folder, tmp_path, capsys):
    out = _copy(run_folder, tmp_path)
    cid = _first_cell(out)
    with open(out / "results.csv", newline="") as fh:
        true = float(next(csv.DictReader(fh))["hausdorff"])
    stray = out / "cells" / "zzz_copy.json"               # sorted after the real one: it read last
    rec = json.loads((out / "cells" / f"{cid}.json").read_text())
    stray.write_text(json.dumps(rec))                      # a valid seal, but not this file's cell
    assert main(["table", str(out)]) == 0                 # no cell's record: ignored, as the warning says
    err = [x for x in capsys.readouterr().err.splitlines() if x.strip()]
    assert len(err) == 1 and err[0].startswith("warning: ") and f"zzz_copy.json claims cell {cid}" in err[0]
    assert "ignored" in err[0]
    _strip_seal(stray, hausdorff=123)
    assert main(["run", "--resume", "--out", str(out), "--jobs", "1", "--no-report"]) == 0
    err = capsys.readouterr().err
    assert "set aside" in err and "zzz_copy" in err and "the cell will be rerun" not in err
    with open(out / "results.csv", newline="") as fh:
        assert float({r["cell_id"]: r for r in csv.DictReader(fh)}[cid]["hausdorff"]) == true
    assert not stray.exists() and stray.with_name("zzz_copy.json.rejected").exists()
    assert main(["report", str(out)]) == 0


# ---------------------------------------------------------------------------------------------- tables vs records
def _csv_rows(out):
    with open(out / "results.csv", newline="") as fh:
        return list(csv.reader(fh))


def _write_csv(out, rows):
    with open(out / "results.csv", "w", newline="") as fh:
        csv.writer(fh).writerows(rows)


def test_report_refuses_a_results_csv_that_disagrees_with_the_records_and_force_lists_it(
        run_folder, tmp_path, capsys):
    out = _copy(run_folder, tmp_path)
    rows = _csv_rows(out)
    col = rows[0].index("hausdorff_h")
    rows[2][col] = str(float(rows[2][col]) / 2)
    _write_csv(out, rows)
    assert main(["report", str(out)]) == 2
    _one_error(capsys, f"{rows[2][0]}: hausdorff_h is", "in results.csv", "in its record", "--force")
    assert not (out / "index.html").exists()
    assert main(["report", str(out), "--force"]) == 0
    assert f"{rows[2][0]}: hausdorff_h is" in (out / "index.html").read_text()


@pytest.mark.parametrize("entry", ["cells", "cache"])
def test_resume_with_a_file_where_a_run_folder_belongs_names_it_before_any_progress(entry, run_folder, tmp_path,
                                                                                    capsys):
    out = _copy(run_folder, tmp_path)
    if (out / entry).is_dir():
        shutil.rmtree(out / entry)
    (out / entry).write_text("not a folder")
    assert main(["run", "--resume", "--out", str(out), "--jobs", "1", "--no-report"]) == 2
    captured = capsys.readouterr()
    err = [x for x in captured.err.splitlines() if x.strip()]
    assert "progress" not in captured.out + captured.err and "Traceback" not in captured.err
    assert len(err) == 1 and err[0].startswith("error: ") and f"{out / entry}' is not a folder" in err[0], captured
    assert "free space" not in err[0] and "permissions" not in err[0]
