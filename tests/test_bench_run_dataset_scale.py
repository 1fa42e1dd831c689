"""docs/scripts/dataset500.py: a dataset (a glob of volume files) gives the same rows on Dask as on the local pool."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import pytest

SCRIPT = Path(__file__).resolve().parent.parent / "docs" / "scripts" / "dataset500.py"


@pytest.fixture(scope="module")
def ds():
    spec = importlib.util.spec_from_file_location("dataset500", SCRIPT)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def _row(**kw) -> dict:
    row = {"cell_id": "a", "method": "marching_cubes", "n_faces": "100", "sdf_rms_h": "0.1", "wall_s": "0.02",
           "peak_mem_mb": "50", "status": "ok"}
    row.update(kw)
    return row


def test_the_comparison_ignores_the_cost_columns_only(ds):
    assert ds.compare_results([_row()], [_row(wall_s="9.9", peak_mem_mb="900")]) == []
    diffs = ds.compare_results([_row()], [_row(sdf_rms_h="0.1000001")])
    assert diffs == ["a: sdf_rms_h '0.1' != '0.1000001'"]


def test_the_comparison_reports_missing_duplicated_and_reordered_cells(ds):
    a, b = _row(cell_id="a"), _row(cell_id="b")
    assert ds.compare_results([a, b], [a]) == ["b: in the first run only"]
    assert "the cells are in another order" in ds.compare_results([a, b], [b, a])
    assert "the second run has a cell more than once" in ds.compare_results([a, b], [a, b, b])
    assert ds.compare_results([a], [dict(a, extra="1")])[0].startswith("columns differ")


def test_the_dataset_is_seeded_and_bad_sizes_are_one_line_errors(ds, tmp_path):
    one = [p.read_bytes() for p in ds.make_dataset(tmp_path / "a", 2, seed=3)]
    two = [p.read_bytes() for p in ds.make_dataset(tmp_path / "b", 2, seed=3)]
    assert one == two and len(one) == 2
    assert ds.main(["--files", "0"]) == 2
    assert ds.main(["--workers", "0", "--files", "1"]) == 2


@pytest.mark.heavy
def test_a_64_cell_dataset_gives_identical_results_on_dask_and_on_the_local_executor(ds, tmp_path):
    pytest.importorskip("distributed")
    pytest.importorskip("vtk")   # flying_edges
    res = ds.compare_executors(tmp_path, files=8, workers=2)
    assert res["cells"] == 64 and res["statuses"] == {"ok": 64}
    assert res["diffs"] == [], res["diffs"][:20]
    assert set(res["overhead_per_cell_s"]) == {"local", "dask"}
