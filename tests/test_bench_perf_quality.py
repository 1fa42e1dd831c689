"""The quality gate (bench.perf.quality): known comparisons of hand-made summaries, and one real tiny grid."""

from __future__ import annotations

import copy
import json

import pytest

from bench.cli import main
from bench.perf import quality as q


def _summary(**metrics) -> dict:
    base = {"hausdorff_h": 0.5, "hausdorff_95_h": 0.2, "mean_dist_h": 0.05, "normal_consistency": 0.99,
            "self_intersections": 0.0, "euler": 2.0, "components": 1.0, "watertight": True}
    base.update(metrics)
    return {"format": q.QUALITY_FORMAT, "cells": {"quick/sphere_mc": {"status": "ok", "flags": [],
                                                                     "metrics": base}}}


def _failed(baseline: dict, run: dict) -> list[tuple[str, str]]:
    return [(r["cell"], r["metric"]) for r in q.quality_gate(baseline, run).failures]


def test_a_baseline_more_accurate_than_the_run_beyond_tolerance_fails_and_names_cell_and_metric():
    # tolerance of hausdorff_h: 5 % + 0.01 h → limit 0.535 for a baseline of 0.5
    assert _failed(_summary(), _summary(hausdorff_h=0.6)) == [("quick/sphere_mc", "hausdorff_h")]
    assert _failed(_summary(), _summary(hausdorff_h=0.536)) == [("quick/sphere_mc", "hausdorff_h")]
    res = q.quality_gate(_summary(), _summary(hausdorff_h=0.6))
    assert "FAIL" in q.format_quality(res) and "hausdorff_h" in q.format_quality(res)


def test_within_tolerance_and_better_pass():
    assert q.quality_gate(_summary(), _summary(hausdorff_h=0.53, normal_consistency=0.989)).passed
    res = q.quality_gate(_summary(), _summary(hausdorff_h=0.3))
    assert res.passed
    assert {r["metric"]: r["status"] for r in res.rows}["hausdorff_h"] == "better"


def test_scores_are_gated_downwards():
    assert _failed(_summary(), _summary(normal_consistency=0.98)) == [("quick/sphere_mc", "normal_consistency")]


def test_counts_topology_and_watertightness_have_no_slack():
    assert _failed(_summary(), _summary(self_intersections=1.0)) == [("quick/sphere_mc", "self_intersections")]
    assert _failed(_summary(), _summary(euler=0.0)) == [("quick/sphere_mc", "euler")]
    assert _failed(_summary(), _summary(components=2.0)) == [("quick/sphere_mc", "components")]
    assert _failed(_summary(), _summary(watertight=False)) == [("quick/sphere_mc", "watertight")]
    # a baseline with a topology flag: moving towards the sphere's χ = 2 is better, away is worse
    bad = _summary(euler=-2.0)
    bad["cells"]["quick/sphere_mc"]["flags"] = ["topology_mismatch"]
    better = copy.deepcopy(bad)
    better["cells"]["quick/sphere_mc"]["metrics"]["euler"] = 2.0
    assert q.quality_gate(bad, better).passed


def test_a_worse_status_a_new_flag_or_a_missing_cell_fails():
    run = _summary()
    run["cells"]["quick/sphere_mc"]["status"] = "invalid"
    assert ("quick/sphere_mc", "status") in _failed(_summary(), run)
    run = _summary()
    run["cells"]["quick/sphere_mc"]["flags"] = ["self_intersecting"]
    assert _failed(_summary(), run) == [("quick/sphere_mc", "flags")]
    assert _failed(_summary(), {"cells": {}}) == [("quick/sphere_mc", "(cell)")]
    # a metric that became NaN / missing in the run fails too
    run = _summary()
    run["cells"]["quick/sphere_mc"]["metrics"]["hausdorff_h"] = None
    assert _failed(_summary(), run) == [("quick/sphere_mc", "hausdorff_h")]
    # a new cell (not in the baseline) is reported, never failed
    run = _summary()
    run["cells"]["quick/new_cell"] = run["cells"]["quick/sphere_mc"]
    res = q.quality_gate(_summary(), run)
    assert res.passed and any(r["status"] == "new" for r in res.rows)


def test_cells_from_rows_reads_results_csv_values_and_drops_the_parameter_hash():
    rows = [{"cell_id": "sphere_sdf_n48_none_s0_marching_cubes_472f2740", "status": "ok", "flags": "a;b",
             "hausdorff_h": "0.25", "watertight": "True", "euler": 2, "wall_s": 9.0}]
    cells = q.cells_from_rows(rows, "quick")
    assert list(cells) == ["quick/sphere_sdf_n48_none_s0_marching_cubes"]
    c = cells["quick/sphere_sdf_n48_none_s0_marching_cubes"]
    assert c["flags"] == ["a", "b"] and c["metrics"]["hausdorff_h"] == 0.25 and c["metrics"]["watertight"] is True
    assert "wall_s" not in c["metrics"]      # time is the other gate's job


TINY = """
name = "tiny_quality"
[grid]
phantoms = ["sphere"]
variants = ["sdf"]
n = 20
extent = 2.5
seeds = [0]
noise = [{ kind = "none" }]
[[methods]]
name = "marching_cubes"
[metrics]
n_samples = 2000
"""


@pytest.fixture
def tiny_config(tmp_path, monkeypatch):
    p = tmp_path / "tiny.toml"
    p.write_text(TINY)
    monkeypatch.setattr(q, "QUALITY_CONFIGS", (str(p),))
    return p


def test_a_real_tiny_grid_round_trips_through_the_baseline_and_the_command_line(tiny_config, tmp_path, capsys):
    base = tmp_path / "quality.json"
    assert main(["perf", "--no-timing", "--save-quality", str(base)]) == 0
    saved = q.load_quality(base)
    (key,) = saved["cells"]
    assert key.startswith("tiny_quality/sphere_sdf_n20_none_s0_marching_cubes")
    assert 0 < saved["cells"][key]["metrics"]["hausdorff_h"] < 1
    # the same code again: identical values, the gate passes
    assert main(["perf", "--no-timing", "--quality", str(base)]) == 0
    assert "perf: passed" in capsys.readouterr().out
    # a baseline made more accurate than this code can be: exit 1, the cell and metric named
    better = json.loads(base.read_text())
    better["cells"][key]["metrics"]["hausdorff_h"] /= 2
    base.write_text(json.dumps(better))
    assert main(["perf", "--no-timing", "--quality", str(base)]) == 1
    err = capsys.readouterr().err
    assert "quality FAILED" in err and key in err and "hausdorff_h" in err


def test_a_bad_quality_baseline_is_one_line_and_exit_2(tmp_path, capsys):
    bad = tmp_path / "q.json"
    bad.write_text("[1, 2]")
    assert main(["perf", "--no-timing", "--quality", str(bad)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "not a quality summary" in err[0]


def _mc_summary(machine, **metrics) -> dict:
    s = _summary(**metrics)
    s["cells"]["quick/sphere_sdf_n48_none_s0_marching_cubes"] = dict(s["cells"].pop("quick/sphere_mc"),
                                                                      method="marching_cubes")
    s["machine"] = machine
    return s


def test_marching_cubes_rows_fail_on_any_change_on_the_baselines_machine():
    here = q.machine_fingerprint()
    key = "quick/sphere_sdf_n48_none_s0_marching_cubes"
    assert q.quality_gate(_mc_summary(here), _mc_summary(here)).passed
    # 1e-15 h better is still a change: the fixed point moved (volume or scoring code changed)
    res = q.quality_gate(_mc_summary(here), _mc_summary(here, hausdorff_h=0.5 - 1e-15))
    assert [(r["cell"], r["metric"], r["status"]) for r in res.failures] == [(key, "hausdorff_h", "changed")]
    # the same change passes the ordinary tolerance on a row of another method
    assert q.quality_gate(_summary(), _summary(hausdorff_h=0.5 - 1e-15)).passed


def test_marching_cubes_rows_allow_only_reassociation_on_another_machine():
    here, there = q.machine_fingerprint(), {**q.machine_fingerprint(), "cpu": "another CPU"}
    assert q.quality_gate(_mc_summary(there), _mc_summary(here, hausdorff_h=0.5 * (1 + 1e-12))).passed
    res = q.quality_gate(_mc_summary(there), _mc_summary(here, hausdorff_h=0.5 * (1 + 1e-6)))
    assert [r["metric"] for r in res.failures] == ["hausdorff_h"]
    # a row keyed by its label only (a baseline without the method field) is recognised by its suffix
    old = _mc_summary(here)
    del old["cells"]["quick/sphere_sdf_n48_none_s0_marching_cubes"]["method"]
    assert not q.quality_gate(old, _mc_summary(here, euler=0.0)).passed


def test_the_fingerprint_names_the_cpu_and_the_numerical_libraries():
    fp = q.machine_fingerprint()
    assert fp["libraries"]["numpy"] and fp["libraries"]["scikit-image"] and fp["python"]
    assert fp == q.machine_fingerprint()
