"""Tests of ``bench.perf.cost_models``: :func:`fit_power_law` recovers the constants of a known power law (and
its floor), leaves out failed and non-default runs, needs two sizes; :func:`measure_point` records one run;
``--fit`` prints one fit per method."""

from __future__ import annotations

import json

import pytest

from bench.perf.cost_models import fit_power_law, main, measure_point


def _points(a, p, floor=0.0, ns=(24, 32, 48, 64, 96), method="m"):
    return [{"method": method, "n": n, "cpu_s": floor + a * (n / 64) ** p, "wall_s": 0.0, "iterations": 10,
             "params": {}} for n in ns]


def test_fit_power_law_recovers_a_known_law():
    fit = fit_power_law(_points(0.8, 2.5))
    assert fit["a"] == pytest.approx(0.8, rel=1e-3) and fit["p"] == pytest.approx(2.5, abs=0.01)
    assert fit["points"] == 5 and fit["worst_ratio"] == pytest.approx(1.0, abs=0.01) and fit["floor"] == 0.0
    with_floor = fit_power_law(_points(0.8, 2.5, floor=0.3), floor=True)
    assert with_floor["floor"] == pytest.approx(0.3, rel=0.05) and with_floor["p"] == pytest.approx(2.5, abs=0.05)
    per_it = fit_power_law(_points(8.0, 3.0), per_iteration=True)
    assert per_it["a"] == pytest.approx(0.8, rel=1e-3)


def test_fit_power_law_leaves_out_failed_and_non_default_runs_and_needs_two_sizes():
    pts = _points(1.0, 2.0) + [{"method": "m", "n": 128, "cpu_s": 1e6, "wall_s": 0, "params": {}, "error": "x"},
                               {"method": "m", "n": 128, "cpu_s": 1e6, "wall_s": 0, "params": {"k": 1}}]
    assert fit_power_law(pts)["points"] == 5
    assert fit_power_law(_points(1.0, 2.0, ns=(32, 32))) is None
    assert fit_power_law(_points(1.0, 2.0), n_min=96) is None


def test_measure_point_records_one_run():
    pt = measure_point("marching_cubes", "sphere", 16)
    assert pt["method"] == "marching_cubes" and pt["n"] == 16 and pt["noise"] == "none"
    assert pt["crossing_cells"] > 0 and pt["wall_s"] >= 0 and pt["iterations"] == 0 and "error" not in pt
    noisy = measure_point("marching_cubes", "sphere", 16, noise="gaussian@30")
    assert noisy["noise"] == "gaussian@30" and noisy["crossing_cells"] != pt["crossing_cells"]


def test_main_fit_prints_a_fit_per_method(tmp_path, capsys):
    f = tmp_path / "points.jsonl"
    f.write_text("\n".join(json.dumps(q) for q in _points(1.0, 2.0) + _points(2.0, 3.0, ns=(32,), method="b")))
    assert main(["--fit", str(f)]) == 0
    lines = [json.loads(x) for x in capsys.readouterr().out.splitlines()]
    assert lines[0]["method"] == "m" and lines[0]["p"] == pytest.approx(2.0, abs=0.01)
    assert lines[1] == {"method": "b", "fit": "fewer than two sizes"}
