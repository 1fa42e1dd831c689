"""bench.run.row: ResultRow — its dict form exactly the stored one, metric keys the registry's, the column lists
derived from it in the order results.csv has always had."""

from __future__ import annotations

import dataclasses
import json
import math
import pickle

import pytest

from bench.metrics.registry import METRICS
from bench.run import CellResult, ResultRow, failed_result
from bench.run.grid import as_cell
from bench.run.row import ID_COLUMNS, JSON_ONLY, RUNNER_COLUMNS, TAIL_COLUMNS, TEXT_COLUMNS, as_row
from bench.run.results import result_columns

#: an ``ok`` row as run_cell stored it in cells/<cell_id>.json before ResultRow existed (keys in its order)
_STORED = {
    "cell_id": "sphere_sdf_n48_none_s0_marching_cubes_472f2740", "phantom": "sphere", "variant": "sdf", "N": 48,
    "noise": "none", "snr_requested": None, "snr_achieved": None, "seed": 0, "method": "marching_cubes",
    "label": "marching_cubes", "parameters": '{"method":"lewiner","step_size":1}', "degrade": "none",
    "input_kind": "sdf", "phase_s": {"volume": 0.01, "method": 0.02}, "h": 0.10638297872340426, "has_truth": True,
    "method_info": {"iterations": 0, "stop_reason": "done"}, "phi_gradient": 1.0,
    **{k: (float("nan") if k == "edge_chamfer" else 0.5) for k, m in METRICS.items() if m.kind != "runner"},
    "watertight": True, "euler": 2, "iterations": 0, "energy_final": None, "stop_reason": "done",
    "wall_s": 0.018, "peak_mem_mb": 3.0, "flags": "", "status": "ok", "error": "", "cell_s": 0.17, "cpu_s": 0.15,
}

#: the column lists of results.csv as store.py spelled them out before they derived from ResultRow
_OLD_ID = ["cell_id", "phantom", "variant", "N", "noise", "snr_requested", "snr_achieved", "seed", "method", "label",
           "parameters"]
_OLD_RUNNER = ["iterations", "energy_final", "stop_reason", "wall_s", "peak_mem_mb"]
_OLD_TAIL = ["flags", "status", "error"]
_OLD_TEXT = {"cell_id", "phantom", "variant", "noise", "method", "label", "parameters", "source", "stop_reason",
             "shape_kind",   # (added with the recommendation table: the phantom's kind of shape)
             "flags", "status", "error"}
_OLD_JSON_ONLY = {"cell_s", "cpu_s", "artifact_error", "method_info", "method_output", "phase_s"}


def _same(a: dict, b: dict) -> bool:
    """Same keys in the same order and the same values (NaN equal to NaN), as the json would hold them."""
    return list(a) == list(b) and json.dumps(a) == json.dumps(b)


def test_a_stored_row_round_trips_to_the_same_dict_keys_order_and_values():
    row = ResultRow.from_dict(_STORED, strict=True)
    assert _same(row.to_dict(), _STORED)
    assert row.status == "ok" and row.N == 48 and row.has_truth is True and row.snr_achieved is None
    assert row.metrics["hausdorff_h"] == 0.5 and math.isnan(row.metrics["edge_chamfer"])
    assert row.metrics["energy_final"] is None and row.has("energy_final") and not row.has("source")
    assert ResultRow.from_dict(row.to_dict()) == row
    assert _same(pickle.loads(pickle.dumps(row)).to_dict(), _STORED)      # how a worker sends it back (NaN: by json)


def test_an_absent_key_stays_absent_and_a_none_one_stays_none():
    failed = {k: _STORED[k] for k in _OLD_ID} | {"degrade": "none", "input_kind": "sdf", "status": "failed",
                                                 "error": "volume: boom", "cell_s": 0.1}
    row = ResultRow.from_dict(failed, strict=True)
    assert _same(row.to_dict(), failed)
    assert row.h is None and not row.has("h") and "h" not in row.to_dict()          # absent: not written as null
    assert row.value("h", "absent") == "absent" and row.value("snr_achieved", "absent") is None


def test_a_row_of_another_suite_version_keeps_its_unknown_keys_but_a_stage_may_not_add_them():
    older = {**_STORED, "removed_metric": 1.5, "written_by": "an older suite"}
    row = ResultRow.from_dict(older)
    assert row.extra == {"removed_metric": 1.5, "written_by": "an older suite"} and _same(row.to_dict(), older)
    with pytest.raises(ValueError, match="removed_metric"):
        ResultRow.from_dict(older, strict=True)
    with pytest.raises(KeyError, match="cell_id"):
        ResultRow.from_dict({"status": "ok"})


def test_a_metric_not_in_the_registry_is_refused():
    with pytest.raises(ValueError, match="not a registered metric: 'hausdorf_h'"):
        ResultRow(cell_id="x", metrics={"hausdorf_h": 0.5})                  # a typo of hausdorff_h
    with pytest.raises(ValueError, match="hausdorf_h"):
        ResultRow.from_dict({"cell_id": "x"}).updated({"hausdorf_h": 0.5})
    with pytest.raises(ValueError, match="bogus"):
        CellResult({"cell_id": "x", "bogus": 1})                             # a stage's row is strict
    with pytest.raises(TypeError):
        ResultRow.from_dict({"cell_id": 7})


def test_updated_sets_keys_as_dict_update_and_replace_cannot_lose_a_value():
    row = failed_result(as_cell({"phantom": "sphere", "variant": "sdf", "n": 16, "extent": 2.5, "noise": "none",
                                 "snr_requested": None, "seed": 0, "method": "marching_cubes",
                                 "label": "marching_cubes", "params": {}, "n_samples": 500}), "timeout", "late").row
    facts = {"iterations": 3, "stop_reason": "done", "wall_s": 1.0}
    new = row.updated(facts, cell_s=2.0)
    assert _same(new.to_dict(), {**row.to_dict(), **facts, "cell_s": 2.0})       # new keys last, as dict.update
    assert row.cell_s is None and not row.has("cell_s")                           # frozen: a copy
    with pytest.raises(dataclasses.FrozenInstanceError):
        row.status = "ok"
    moved = dataclasses.replace(row, h=0.5)
    assert moved.to_dict()["h"] == 0.5 and list(moved.to_dict())[-1] == "h"


def test_a_row_built_from_its_fields_has_the_keys_run_cell_writes():
    row = ResultRow(cell_id="x", phantom="sphere", status="ok", error="", metrics={"euler": 2})
    d = row.to_dict()
    assert list(d)[:len(_OLD_ID)] == _OLD_ID and d["snr_achieved"] is None and "source" not in d
    assert list(d)[len(_OLD_ID):] == ["euler", "status", "error"]
    assert as_row(d) == row and as_row(row) is row


def test_the_column_lists_are_the_ones_results_csv_always_had():
    assert (ID_COLUMNS, RUNNER_COLUMNS, TAIL_COLUMNS) == (_OLD_ID, _OLD_RUNNER, _OLD_TAIL)
    assert set(TEXT_COLUMNS) == _OLD_TEXT and set(JSON_ONLY) == _OLD_JSON_ONLY
    cols = result_columns([ResultRow.from_dict(_STORED)])
    # as the old lists put them: ID, every metric in registry order (the runner's metrics among them), the input's
    # columns in the order the row carries them, stop_reason (the runner's column no metric has), the tail
    assert cols == _OLD_ID + list(METRICS) + ["degrade", "input_kind", "h", "has_truth", "phi_gradient",
                                              "stop_reason"] + _OLD_TAIL
    with pytest.raises(TypeError, match="ResultRow"):
        result_columns([_STORED])                                      # the store writes typed rows only
