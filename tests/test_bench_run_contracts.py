"""bench.run.contracts: Cell and CellResult — frozen, their dict forms exactly the stored ones, cell ids unchanged."""

from __future__ import annotations

import dataclasses
import pickle

import pytest

from bench.config import builtin_config
from bench.run import Cell, CellResult, cell_id, expand_grid, failed_result, run_cell
from bench.run.grid import as_cell

#: a cell dict as an earlier run stored it in cells/<cell_id>.json (keys in expand_grid's order)
_STORED = {"phantom": "sphere", "variant": "sdf", "n": 16, "extent": 2.5, "noise": "gaussian", "snr_requested": 30.0,
           "seed": 1, "method": "marching_cubes", "label": "marching_cubes", "params": {}, "n_samples": 500,
           "imports": []}


def _stored(**more) -> dict:
    d = {**_STORED, **more}
    d["cell_id"] = cell_id(d)
    return d


def test_the_grid_gives_cells_whose_dict_form_round_trips_and_keeps_its_id():
    cells = expand_grid(builtin_config("quick"))
    assert cells and all(isinstance(c, Cell) for c in cells)
    for c in cells:
        d = c.to_dict()
        assert Cell.from_dict(d) == c and Cell.from_dict(d).to_dict() == d
        assert cell_id(d) == c.cell_id == cell_id(c)            # the id hashes the dict form, as before
        assert isinstance(d["imports"], list) and list(d)[-1] == "cell_id"


def test_a_stored_dict_reads_back_to_the_same_dict_with_its_optional_keys():
    d = {"phantom": "sphere", "source": "mesh:/data/a.ply", "input": "0123456789ab",   # expand_grid's order
         **{k: v for k, v in _STORED.items() if k != "phantom"}, "method_code": {"hash": "1" * 16, "files": ["/p.py"]}}
    d["cell_id"] = cell_id(d)
    cell = Cell.from_dict(d)
    assert (cell.source, cell.input, cell.method_code["hash"]) == ("mesh:/data/a.ply", "0123456789ab", "1" * 16)
    assert cell.to_dict() == d and list(cell.to_dict()) == list(d)      # same keys, same order
    plain = Cell.from_dict(_stored())
    assert not {"source", "input", "method_code"} & set(plain.to_dict())  # absent when unset, as expand_grid writes


def test_unknown_keys_are_kept_and_missing_optional_ones_tolerated():
    d = _stored(written_by="an older suite")
    cell = Cell.from_dict(d)
    assert cell.to_dict() == d
    no_imports = {k: v for k, v in _stored().items() if k not in ("imports", "cell_id")}
    cell = as_cell(no_imports)
    assert cell.imports == () and cell.cell_id == cell_id({**no_imports, "imports": []})   # id computed when absent
    with pytest.raises(KeyError, match="n_samples"):
        Cell.from_dict({k: v for k, v in _STORED.items() if k != "n_samples"})


def test_cells_and_results_are_frozen_and_pickle():
    cell = as_cell(_stored())
    with pytest.raises(dataclasses.FrozenInstanceError):
        cell.method = "poisson"
    result = failed_result(cell, "failed", "boom")
    with pytest.raises(dataclasses.FrozenInstanceError):
        result.row = {}
    assert pickle.loads(pickle.dumps(cell)) == cell                 # how executors ship cells to workers
    assert pickle.loads(pickle.dumps(result)) == result
    assert as_cell(cell) is cell


def test_a_result_round_trips_through_its_dict_form():
    result = CellResult({"cell_id": "x", "status": "ok"}, {"H": [1.0]}, None)
    assert result.to_dict() == {"row": {"cell_id": "x", "status": "ok"}, "artifacts": {"H": [1.0]}, "traceback": None}
    assert CellResult.from_dict(result.to_dict()) == result
    assert CellResult.from_dict({"row": {"cell_id": "x"}}) == CellResult({"cell_id": "x"}, {}, None)


def test_run_cell_takes_a_cell_or_its_dict_and_returns_a_cell_result():
    d = _stored()
    by_dict, by_cell = run_cell(d), run_cell(Cell.from_dict(d))
    for res in (by_dict, by_cell):
        assert isinstance(res, CellResult) and res.traceback is None
        assert res.row.status == "ok" and res.row.cell_id == d["cell_id"] and "vertices" in res.artifacts
    assert by_dict.row.metrics["hausdorff_h"] == by_cell.row.metrics["hausdorff_h"]
