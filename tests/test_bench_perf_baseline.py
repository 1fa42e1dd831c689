"""Tests of ``bench.perf.baseline``: summaries of pytest-benchmark JSON, the median merge of repeated runs, and
the committed baseline."""

from __future__ import annotations

import json

import pytest

from _perf_common import REPO, raw, summary
from bench import perf


def test_summarise_reads_pytest_benchmark_json():
    s = perf.summarise(raw({"test_a": 1.0, "test_b": 40.0}))
    assert s["format"] == perf.FORMAT and s["mode"] == "quick" and s["skipped"] == ["test_slow"]
    assert s["benchmarks"]["test_b"]["ratio"] == 40.0
    assert s["benchmarks"]["test_b"]["median_s"] == pytest.approx(4.0)
    assert s["machine"]["cpu"] == "CPU X" and s["loadavg"]["end"] == [2, 2, 2]
    assert perf.summarise(s) is s
    # duplicate test names in two files: keyed by the full node id
    d = perf.summarise(raw({"test_a": 1.0}, dup=True))
    assert sorted(d["benchmarks"]) == ["tests/benchmarks/test_x.py::test_a", "tests/benchmarks/test_y.py::test_a"]
    from phantoms import InputError
    with pytest.raises(InputError):
        perf.summarise({"something": 1})


def test_merge_runs_takes_the_median_ratio():
    runs = [summary({"test_a": r, "test_b": 40.0}) for r in (1.0, 3.0, 1.2)]
    m = perf.merge_runs(runs)
    assert m["benchmarks"]["test_a"]["ratio"] == pytest.approx(1.2)
    assert m["benchmarks"]["test_a"]["runs"]["ratio"] == [1.0, 3.0, 1.2]
    assert m["repeats"] == 3
    # a merge of merges counts every run: median over the 3 + 2 runs
    m2 = perf.merge_runs([m, perf.merge_runs([summary({"test_a": 5.0, "test_b": 40.0}),
                                              summary({"test_a": 6.0, "test_b": 40.0})])])
    assert m2["repeats"] == 5 and m2["benchmarks"]["test_a"]["runs"]["ratio"] == [1.0, 3.0, 1.2, 5.0, 6.0]
    assert m2["benchmarks"]["test_a"]["ratio"] == pytest.approx(3.0)


def test_committed_baseline_is_a_summary_of_every_benchmark():
    assert perf.BASELINE == REPO / "bench" / "perf" / "baseline.json"
    base = perf.load_summary(REPO / "bench" / "perf" / "baseline.json")
    assert base["format"] == perf.FORMAT
    names = set(base["benchmarks"])
    assert {"test_marching_cubes_ellipsoid_n96", "test_poisson_ellipsoid_n96", "test_distmesh_ellipsoid_n96",
            "test_evaluate_100k_faces_ellipsoid", "test_quick_grid_end_to_end"} <= names
    for b in base["benchmarks"].values():
        assert b["ratio"] is not None and b["ratio"] > 0
    assert base["benchmarks"]["test_marching_cubes_ellipsoid_n96"]["ratio"] == pytest.approx(1.0, abs=0.3)
    assert base["loadavg"] and base["note"]["loadavg_now"]


def test_save_and_load_a_summary_round_trip_with_its_note(tmp_path):
    from bench.perf.baseline import machine_note, save_summary

    s = summary({"test_a": 1.5})
    note = machine_note()
    assert note["cpu_count"] >= 1 and "platform" in note
    path = save_summary(s, tmp_path / "deep" / "b.json", note)
    assert path.exists() and not list(path.parent.glob("*.tmp"))
    back = perf.load_summary(path)
    assert back["benchmarks"] == s["benchmarks"] and back["note"] == note
    raw_file = tmp_path / "raw.json"
    raw_file.write_text(json.dumps(raw({"test_a": 2.0})))
    assert perf.load_summary(raw_file)["benchmarks"]["test_a"]["ratio"] == 2.0   # raw pytest-benchmark JSON
    (tmp_path / "list.json").write_text("[1, 2]")
    from phantoms import InputError
    with pytest.raises(InputError, match="not a perf summary"):
        perf.load_summary(tmp_path / "list.json")
    with pytest.raises(InputError, match="is not JSON"):
        (tmp_path / "bad.json").write_text("{")
        perf.load_summary(tmp_path / "bad.json")
