"""bench.run.store: atomic writes, one cell's files, results.csv columns and order, results.parquet and
:func:`read_results`."""

from __future__ import annotations

import csv
import math
import json

import numpy as np
import pandas as pd
import pytest

from bench.metrics import METRIC_NAMES
from bench.run.store import (CELLS_DIR, ID_COLUMNS, TAIL_COLUMNS, atomic_path, check_output_dir, load_cells,
                             result_columns, save_cell, write_atomic, write_results_csv)
from phantoms import InputError


def _cell(cid: str) -> dict:
    return {"cell_id": cid, "phantom": "sphere", "variant": "sdf", "n": 16, "extent": 2.5, "noise": "none",
            "snr_requested": None, "seed": 0, "method": "marching_cubes", "label": "marching_cubes", "params": {},
            "n_samples": 1000, "imports": []}


def _result(cid: str, **row) -> dict:
    tri = {"vertices": np.eye(3, dtype=np.float32), "faces": np.array([[0, 1, 2]], np.int32)}
    return {"row": {"cell_id": cid, "status": "ok", "error": "", **row}, "artifacts": tri, "traceback": None}


def test_atomic_path_replaces_on_success_and_leaves_nothing_on_failure(tmp_path):
    target = tmp_path / "a.json"
    write_atomic(target, "old")
    with pytest.raises(RuntimeError):
        with atomic_path(target) as tmp:
            tmp.write_text("half")
            raise RuntimeError("disk full")
    assert target.read_text() == "old"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.json"]
    with atomic_path(target) as tmp:
        assert tmp.parent == tmp_path and tmp.name.startswith(".") and tmp.suffix == ".json"
        tmp.write_text("new")
    assert target.read_text() == "new"


def test_a_saved_cell_loads_back_and_its_json_marks_it_done(tmp_path):
    save_cell(tmp_path, _cell("c1"), _result("c1", hausdorff=0.5), save_meshes=True)
    assert (tmp_path / CELLS_DIR / "c1.npz").exists() and (tmp_path / "meshes" / "c1.ply").exists()
    records = load_cells(tmp_path)
    assert list(records) == ["c1"] and records["c1"]["row"].metrics["hausdorff"] == 0.5   # read back typed
    assert records["c1"]["cell"]["phantom"] == "sphere" and "finished" in records["c1"]
    (tmp_path / CELLS_DIR / "broken.json").write_text("{not json")
    assert list(load_cells(tmp_path)) == ["c1"]          # an unreadable record is not a finished cell
    with np.load(tmp_path / CELLS_DIR / "c1.npz") as z:
        assert z["faces"].tolist() == [[0, 1, 2]]


def test_results_csv_has_ids_metrics_extras_runner_columns_then_status_in_grid_order(tmp_path):
    rows = [{"cell_id": "b", "hausdorff": 1.0, "my_counter": 3, "stop_reason": "converged", "cell_s": 2.0,
             "status": "ok", "error": ""}]
    cols = result_columns(rows)
    assert cols[:len(ID_COLUMNS)] == ID_COLUMNS and cols[-3:] == TAIL_COLUMNS
    metric_cols = [c for c in cols if c in METRIC_NAMES]
    assert metric_cols == [m for m in METRIC_NAMES if m in metric_cols]
    assert cols.index("my_counter") < cols.index("stop_reason") and "cell_s" not in cols
    cells = [_cell("a"), _cell("b")]
    records = {"b": {"row": rows[0]}, "a": {"row": {"cell_id": "a", "hausdorff": float("nan"), "status": "failed",
                                                     "error": "boom"}}}
    path = write_results_csv(tmp_path, cells, records)
    with open(path, newline="") as fh:
        got = list(csv.DictReader(fh))
    assert [r["cell_id"] for r in got] == ["a", "b"]
    assert got[0]["hausdorff"] == "nan" and got[1]["hausdorff"] == "1.0" and got[1]["my_counter"] == "3"


def test_check_output_dir_refuses_an_occupied_folder_unless_resuming(tmp_path):
    check_output_dir(tmp_path / "new", resume=False)
    save_cell(tmp_path / "new", _cell("c1"), _result("c1"))
    with pytest.raises(InputError, match="already holds a run"):
        check_output_dir(tmp_path / "new", resume=False)
    check_output_dir(tmp_path / "new", resume=True)
    json.loads((tmp_path / "new" / CELLS_DIR / "c1.json").read_text())


# ---------------------------------------------------------------------------------------------- verified on resume
def test_scan_cells_with_verification_leaves_out_a_truncated_or_incomplete_npz(tmp_path):
    """A truncated cell .npz is not a finished cell (resume reruns it); a record that does not load is named."""
    from bench.run.store import scan_cells

    for cid in ("good", "cut", "lacking", "gone"):
        save_cell(tmp_path, _cell(cid), _result(cid))
    cells = tmp_path / CELLS_DIR
    data = (cells / "cut.npz").read_bytes()
    (cells / "cut.npz").write_bytes(data[: len(data) // 2])
    np.savez_compressed(cells / "lacking.npz", vertices=np.eye(3))    # 'faces' missing
    (cells / "gone.npz").unlink()
    (cells / "broken.json").write_text("[1, 2")
    records, problems = scan_cells(tmp_path, verify_artifacts=True)
    assert list(records) == ["good"]
    text = "\n".join(problems)
    assert "cut.npz does not load (BadZipFile" in text and "lacking.npz lacks arrays ['faces']" in text
    assert "gone.npz is missing" in text and "broken.json is unreadable" in text
    assert sorted(scan_cells(tmp_path)[0]) == ["cut", "gone", "good", "lacking"]   # without verification


def test_resume_reruns_a_cell_whose_npz_was_truncated_and_cleans_temp_files(tmp_path, capsys):
    from bench.cli import main

    out = tmp_path / "run"
    grid = ["--quick", "--phantoms", "sphere", "--noise", "none", "--n", "16", "--n-samples", "2000",
            "--method", "marching_cubes", "--jobs", "1", "--out", str(out)]
    assert main(["run", *grid]) == 0
    npz = next((out / CELLS_DIR).glob("*.npz"))
    whole = npz.read_bytes()
    npz.write_bytes(whole[:100])
    stale = [out / CELLS_DIR / ".x.999.tmp.npz", out / ".results.999.tmp.csv", out / "cache" / ".v.9.tmp.npz"]
    for p in stale:
        p.parent.mkdir(exist_ok=True)
        p.write_bytes(b"half")
    capsys.readouterr()
    assert main(["run", *grid, "--resume"]) == 0
    cap = capsys.readouterr()
    assert f"warning: {npz} does not load" in cap.err and "the cell will be rerun" in cap.err
    assert "1 run" in cap.out
    with np.load(npz) as z:                                  # rewritten whole
        assert {"vertices", "faces", "H"} <= set(z.files)
    assert not any(p.exists() for p in stale)
    assert main(["report", str(out)]) == 0                   # and the report renders again


def test_write_errors_name_the_path_and_leave_no_temp_file(tmp_path, monkeypatch):
    import errno

    from geometry.files import WriteError

    target = tmp_path / "results.csv"
    (tmp_path / "cells.json").mkdir()
    with pytest.raises(WriteError, match="cells.json': it is a directory"):
        write_atomic(tmp_path / "cells.json", "x")

    def full(self, data):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr("pathlib.Path.write_bytes", full)
    with pytest.raises(WriteError, match=r"results.csv': No space left on device"):
        write_atomic(target, "x")
    monkeypatch.undo()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["cells.json"]


def test_resume_over_a_run_json_that_is_a_list_rewrites_it(tmp_path, capsys):
    from bench.cli import main

    out = tmp_path / "run"
    grid = ["--quick", "--phantoms", "sphere", "--noise", "none", "--n", "16", "--n-samples", "2000",
            "--method", "marching_cubes", "--jobs", "1", "--no-report", "--out", str(out)]
    assert main(["run", *grid]) == 0
    (out / "run.json").write_text("[1, 2]")
    assert main(["run", *grid, "--resume"]) == 0
    assert json.loads((out / "run.json").read_text())["cells"]["finished"] == 1


# ---------------------------------------------------------------------------------------------- results.parquet
def _typed_records() -> tuple[list[dict], dict[str, dict]]:
    cells = [_cell("a"), _cell("b")]
    records = {
        "a": {"row": {"cell_id": "a", "label": "mc", "N": 16, "seed": 0, "snr_requested": None,
                      "hausdorff_h": float("nan"), "mean_dist_h": float("inf"), "watertight": True, "euler": 2,
                      "my_counter": 3, "my_note": "x,y", "flags": "", "status": "ok", "error": ""}},
        "b": {"row": {"cell_id": "b", "label": "mc", "N": 16, "seed": 1, "snr_requested": 40.0,
                      "hausdorff_h": 0.25, "watertight": None, "my_counter": None,
                      "flags": "self_intersecting;not_converged", "status": "failed", "error": "boom, twice"}},
    }
    return cells, records


def test_results_parquet_is_written_with_the_csv_and_keeps_types_nan_inf_and_empty_flags(tmp_path):
    import pyarrow.parquet as pq

    from bench.run.store import RESULTS_PARQUET, read_results

    cells, records = _typed_records()
    write_results_csv(tmp_path, cells, records)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["results.csv", RESULTS_PARQUET]   # no temp file left
    table = pq.read_table(tmp_path / RESULTS_PARQUET)
    types = {f.name: str(f.type) for f in table.schema}
    assert types["watertight"] == "bool" and types["euler"] == "int64" and types["N"] == "int64"
    assert types["hausdorff_h"] == "double" and types["my_counter"] == "int64" and types["my_note"] == "string"
    assert types["flags"] == types["status"] == types["label"] == "string"
    col = table.column("hausdorff_h").to_pylist()
    assert math.isnan(col[0]) and col[1] == 0.25                   # NaN stays NaN (not null, not text)
    assert table.column("mean_dist_h").to_pylist() == [float("inf"), None]   # missing is null
    assert table.column("flags").to_pylist() == ["", "self_intersecting;not_converged"]
    df = read_results(tmp_path)
    assert df["watertight"].tolist()[0] is True and pd.isna(df["watertight"].iloc[1])
    assert df["euler"].iloc[0] == 2 and pd.isna(df["euler"].iloc[1])
    assert df["flags"].tolist() == ["", "self_intersecting;not_converged"] and df["error"].iloc[1] == "boom, twice"
    assert df["mean_dist_h"].iloc[0] == float("inf") and df["my_note"].iloc[0] == "x,y"


def test_read_results_of_an_old_folder_reads_the_csv_typed_as_the_parquet(tmp_path):
    from bench.run.store import RESULTS_PARQUET, read_results

    cells, records = _typed_records()
    write_results_csv(tmp_path, cells, records)
    new = read_results(tmp_path)
    (tmp_path / RESULTS_PARQUET).unlink()                          # a folder written before results.parquet
    old = read_results(tmp_path)
    assert list(old.columns) == list(new.columns)
    typed = [c for c in new.columns if c not in ("flags", "error", "my_note")]
    assert {c: str(old[c].dtype) for c in typed} == {c: str(new[c].dtype) for c in typed}
    pd.testing.assert_frame_equal(old[typed], new[typed])


def test_a_results_csv_rewritten_after_the_parquet_is_what_is_read(tmp_path):
    from bench.run.store import read_results

    cells, records = _typed_records()
    write_results_csv(tmp_path, cells, records)
    path = tmp_path / "results.csv"
    path.write_text(path.read_text().replace("0.25", "0.5"))     # e.g. an older suite version resumed the run
    assert read_results(tmp_path)["hausdorff_h"].iloc[1] == 0.5


@pytest.mark.parametrize("damage, message", [
    ("nothing", "is not a run folder (no results.parquet or results.csv"),
    ("parquet only, broken", "results.parquet' is not a readable results table"),
    ("no ids", "is not a results table of levelset-bench (no column cell_id, status, label)"),
])
def test_read_results_refuses_a_folder_without_a_readable_table_in_one_line(tmp_path, damage, message):
    from bench.run.store import read_results

    if damage == "parquet only, broken":
        (tmp_path / "results.parquet").write_bytes(b"PAR1 not really")
    elif damage == "no ids":
        (tmp_path / "results.csv").write_text("a,b\n1,2\n")
    with pytest.raises(InputError) as info:
        read_results(tmp_path)
    assert message in str(info.value) and "\n" not in str(info.value)
