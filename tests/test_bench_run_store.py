"""bench.run.store: atomic writes, one cell's files, results.csv columns and order."""

from __future__ import annotations

import csv
import json

import numpy as np
import pytest

from bench.metrics import METRIC_NAMES
from bench.run.store import (CELLS_DIR, ID_COLUMNS, TAIL_COLUMNS, atomic_path, check_output_dir, load_cells,
                             result_columns, save_cell, write_atomic, write_results_csv)
from phantoms import InputError


def _cell(cid: str) -> dict:
    return {"cell_id": cid, "phantom": "sphere", "variant": "sdf", "n": 16, "noise": "none",
            "snr_requested": None, "seed": 0, "method": "marching_cubes", "label": "marching_cubes", "params": {}}


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
    assert list(records) == ["c1"] and records["c1"]["row"]["hausdorff"] == 0.5
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
