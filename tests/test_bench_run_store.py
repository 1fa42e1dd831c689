"""bench.run.store: atomic writes, one cell's files, the folder's checks, verification on resume."""

from __future__ import annotations

import json

import numpy as np
import pytest

from bench.run.store import CELLS_DIR, atomic_path, check_output_dir, load_cells, save_cell, write_atomic
from bench.run.contracts import Cell, CellResult
from bench.run.row import ResultRow
from phantoms import InputError


def _cell(cid: str) -> Cell:
    return Cell.from_dict({"cell_id": cid, "phantom": "sphere", "variant": "sdf", "n": 16, "extent": 2.5,
                           "noise": "none", "snr_requested": None, "seed": 0, "method": "marching_cubes",
                           "label": "marching_cubes", "params": {}, "n_samples": 1000, "imports": []})


def _result(cid: str, **row) -> CellResult:
    tri = {"vertices": np.eye(3, dtype=np.float32), "faces": np.array([[0, 1, 2]], np.int32)}
    return CellResult(ResultRow.from_dict({"cell_id": cid, "status": "ok", "error": "", **row}), tri, None)


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
