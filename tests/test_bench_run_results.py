"""bench.run.results: results.csv columns and order, results.parquet's types, :func:`read_results` (the parquet
file, or the CSV of an older folder, typed alike; a damaged table refused in one line)."""

from __future__ import annotations

import csv
import math

import pandas as pd
import pytest

from bench.metrics import METRIC_NAMES
from bench.run.results import result_columns, write_results_csv
from bench.run.row import ID_COLUMNS, TAIL_COLUMNS, ResultRow
from phantoms import InputError


def _typed(records: dict[str, dict]) -> dict[str, dict]:
    """Records whose rows are ResultRows, as the runner and scan_cells hold them."""
    return {cid: {**rec, "row": ResultRow.from_dict(rec["row"])} for cid, rec in records.items()}


def test_results_csv_has_ids_metrics_extras_runner_columns_then_status_in_grid_order(tmp_path):
    rows = [{"cell_id": "b", "hausdorff": 1.0, "my_counter": 3, "stop_reason": "converged", "cell_s": 2.0,
             "status": "ok", "error": ""}]
    cols = result_columns([ResultRow.from_dict(r) for r in rows])
    assert cols[:len(ID_COLUMNS)] == ID_COLUMNS and cols[-3:] == TAIL_COLUMNS
    metric_cols = [c for c in cols if c in METRIC_NAMES]
    assert metric_cols == [m for m in METRIC_NAMES if m in metric_cols]
    assert cols.index("my_counter") < cols.index("stop_reason") and "cell_s" not in cols
    cells = ["a", "b"]
    records = {"b": {"row": rows[0]}, "a": {"row": {"cell_id": "a", "hausdorff": float("nan"), "status": "failed",
                                                     "error": "boom"}}}
    path = write_results_csv(tmp_path, cells, _typed(records))
    with open(path, newline="") as fh:
        got = list(csv.DictReader(fh))
    assert [r["cell_id"] for r in got] == ["a", "b"]
    assert got[0]["hausdorff"] == "nan" and got[1]["hausdorff"] == "1.0" and got[1]["my_counter"] == "3"


# ---------------------------------------------------------------------------------------------- results.parquet
def _typed_records() -> tuple[list[str], dict[str, dict]]:
    cells = ["a", "b"]
    records = {
        "a": {"row": {"cell_id": "a", "label": "mc", "N": 16, "seed": 0, "snr_requested": None,
                      "hausdorff_h": float("nan"), "mean_dist_h": float("inf"), "watertight": True, "euler": 2,
                      "my_counter": 3, "my_note": "x,y", "flags": "", "status": "ok", "error": ""}},
        "b": {"row": {"cell_id": "b", "label": "mc", "N": 16, "seed": 1, "snr_requested": 40.0,
                      "hausdorff_h": 0.25, "watertight": None, "my_counter": None,
                      "flags": "self_intersecting;not_converged", "status": "failed", "error": "boom, twice"}},
    }
    return cells, _typed(records)


def test_results_parquet_is_written_with_the_csv_and_keeps_types_nan_inf_and_empty_flags(tmp_path):
    import pyarrow.parquet as pq

    from bench.run.results import RESULTS_PARQUET, read_results

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
    from bench.run.results import RESULTS_PARQUET, read_results

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
    from bench.run.results import read_results

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
    from bench.run.results import read_results

    if damage == "parquet only, broken":
        (tmp_path / "results.parquet").write_bytes(b"PAR1 not really")
    elif damage == "no ids":
        (tmp_path / "results.csv").write_text("a,b\n1,2\n")
    with pytest.raises(InputError) as info:
        read_results(tmp_path)
    assert message in str(info.value) and "\n" not in str(info.value)
