"""bench.report.compare: matching, the quality gate's verdicts, status / flag changes, unmatched cells, escaping."""

from __future__ import annotations

import re
import zlib

import numpy as np
import pytest

from bench.perf.quality import TOLERANCES, cells_from_rows, quality_gate
from bench.report.compare import compare_frames, compare_runs, comparison_html, format_comparison
from bench.run.row import ResultRow
from bench.run.results import read_results, write_results_csv


def _row(label="mc", seed=0, params='{"k":1}', **metrics) -> dict:
    cid = f"sphere_sdf_n24_none_s{seed}_{label}_{zlib.crc32(params.encode()):08x}"
    return {"cell_id": cid, "phantom": "sphere", "variant": "sdf", "N": 24, "noise": "none", "snr_requested": None,
            "seed": seed, "method": "mc", "label": label, "parameters": params, "hausdorff_h": 1.0,
            "self_intersections": 0, "watertight": True, "euler": 2, "flags": "", "status": "ok", "error": "",
            **metrics}


def _seed(name: str) -> str:
    return re.search(r"/s(\d+)/", name).group(1)


def _run(folder, rows):
    """A run folder's results table written by the store itself, read back as compare reads it."""
    folder.mkdir(parents=True, exist_ok=True)
    write_results_csv(folder, [r["cell_id"] for r in rows],
                      {r["cell_id"]: {"row": ResultRow.from_dict(r)} for r in rows})
    return read_results(folder)


@pytest.mark.parametrize("b_value, verdict", [
    (1.0 + 0.05 * 1.0 + 0.01 - 1e-9, "same"),      # just inside the gate's 5 % + 0.01 h
    (1.0 + 0.05 * 1.0 + 0.01 + 1e-9, "worse"),     # just outside
    (1.0 - 0.05 * 1.0 - 0.01 - 1e-9, "better"),
])
def test_a_distance_is_judged_with_the_quality_gates_tolerance(tmp_path, b_value, verdict):
    a = _run(tmp_path / "a", [_row()])
    b = _run(tmp_path / "b", [_row(hausdorff_h=b_value)])
    cmp = compare_frames(a, b)
    got = {v["metric"]: v["verdict"] for v in cmp.values}
    assert got["hausdorff_h"] == verdict and set(got) <= set(TOLERANCES)
    # the gate itself says the same of these two cells
    gate = quality_gate({"cells": cells_from_rows([_row()], "q")},
                        {"cells": cells_from_rows([_row(hausdorff_h=b_value)], "q")})
    row = [r for r in gate.rows if r["metric"] == "hausdorff_h"][0]
    assert (row["status"] == "worse") == (verdict == "worse") and (row["status"] == "better") == (verdict == "better")
    assert cmp.worse == (verdict == "worse")


def test_a_changed_parameter_is_matched_by_label_and_listed(tmp_path):
    a = _run(tmp_path / "a", [_row(params='{"k":1}')])
    b = _run(tmp_path / "b", [_row(params='{"k":2}')])
    cmp = compare_frames(a, b)
    assert cmp.matched == 1 and not cmp.only_a and not cmp.only_b
    assert cmp.parameters == [{"label": "mc", "method": "mc", "change": "k: 1 → 2", "cells": 1}]
    assert not cmp.unchanged and not cmp.worse


def test_status_and_flag_changes_and_unmatched_cells_are_listed(tmp_path):
    a = _run(tmp_path / "a", [_row(seed=0), _row(seed=1), _row(seed=2), _row(seed=3, status="invalid")])
    b = _run(tmp_path / "b", [_row(seed=0, status="failed", hausdorff_h=None), _row(seed=1, flags="self_intersecting"),
                              _row(seed=3), _row(seed=4)])
    cmp = compare_frames(a, b, "A", "B")
    states = {_seed(s["cell"]): (s["status"], s["flags"], s["verdict"]) for s in cmp.states}
    assert states == {"0": ("ok → failed", "", "worse"), "1": ("ok → ok", "+self_intersecting", "worse"),
                      "3": ("invalid → ok", "", "better")}
    assert [_seed(c) for c in cmp.only_a] == ["2"] and [_seed(c) for c in cmp.only_b] == ["4"]
    assert cmp.worse
    text = format_comparison(cmp)
    assert "only in A (1 cells):" in text and "only in B (1 cells):" in text
    assert text.splitlines()[-1] == cmp.summary_line() and "3 status / flag changes" in cmp.summary_line()


def test_the_same_table_twice_is_no_change(tmp_path):
    a = _run(tmp_path / "a", [_row(seed=0), _row(seed=1, hausdorff_h=float("nan"))])
    cmp = compare_runs(tmp_path / "a", tmp_path / "a")
    assert cmp.unchanged and not cmp.worse and cmp.summary_line().startswith("no change: 2 cells matched")
    assert len(a) == 2


def test_the_html_page_escapes_every_text(tmp_path):
    label = "<script>alert(1)</script>"
    a = _run(tmp_path / "a", [_row(label=label)])
    b = _run(tmp_path / "b", [_row(label=label, hausdorff_h=9.0)])
    page = comparison_html(compare_frames(a, b, "A<b>", "B"))
    assert "<script>" not in page and "&lt;script&gt;" in page and "A&lt;b&gt;" in page
    assert "hausdorff_h" in page


@pytest.mark.parametrize("phantom, b_euler, verdict", [
    ("sphere", 2, "better"),     # back to the sphere's 2 − 2·0
    ("sphere", 1, "better"),
    ("sphere", -2, "worse"),
    ("torus", 0, "better"),      # the torus's target is 0 (2 − 2·1), not the sphere's 2
    ("torus", 4, "worse"),
])
def test_a_topology_flagged_baseline_is_judged_against_the_phantoms_own_euler(tmp_path, phantom, b_euler, verdict):
    a = _run(tmp_path / "a", [_row(phantom=phantom, euler=-1, flags="topology_mismatch")])
    b = _run(tmp_path / "b", [_row(phantom=phantom, euler=b_euler, flags="topology_mismatch")])
    got = {v["metric"]: v["verdict"] for v in compare_frames(a, b).values}
    assert got["euler"] == verdict


def _seeds(label: str, values, params='{"k":1}') -> list[dict]:
    return [_row(label=label, seed=i, params=params, hausdorff_h=float(v), mean_dist_h=float(v) / 4)
            for i, v in enumerate(values)]


def test_a_real_worsening_is_significant_and_seed_noise_is_not(tmp_path):
    """Two runs of 10 seeds × 3 methods: `worse` got worse on every seed, `noisy` moved both ways by more than the
    per-cell tolerance but with no direction, `same` did not move."""
    rng = np.random.default_rng(3)
    base = {lab: rng.uniform(1.0, 2.0, 10) for lab in ("worse", "noisy", "same")}
    shift = rng.uniform(0.2, 0.4, 10) * np.where(np.arange(10) % 2, 1.0, -1.0)        # ±, alternating seeds
    a = _run(tmp_path / "a", [r for lab in base for r in _seeds(lab, base[lab])])
    b = _run(tmp_path / "b", _seeds("worse", base["worse"] * 1.3, params='{"k":2}')
             + _seeds("noisy", base["noisy"] + shift) + _seeds("same", base["same"]))
    cmp = compare_frames(a, b, "A", "B")
    got = {(c["label"], c["metric"]): c for c in cmp.changes}
    w = got[("worse", "hausdorff_h")]
    assert w["verdict"] == "significantly worse" and (w["n"], w["worse_n"], w["better_n"]) == (10, 10, 0)
    assert w["p_holm"] < 0.05 and w["median"] > 0 and min(w["interval"]) > 0
    n = got[("noisy", "hausdorff_h")]
    assert n["verdict"] == "no significant change" and n["worse_n"] and n["better_n"] and n["p"] > 0.05
    assert got[("same", "hausdorff_h")]["verdict"] == "no change"
    assert cmp.changes[0]["verdict"] == "significantly worse"                            # the worst news first
    assert cmp.worse                                       # --fail-on-worse: the real worsening fails the run ...
    b2 = _run(tmp_path / "b2", _seeds("worse", base["worse"]) + _seeds("noisy", base["noisy"] + shift)
              + _seeds("same", base["same"]))
    quiet = compare_frames(a, b2)
    assert not quiet.worse and any(v["verdict"] == "worse" for v in quiet.values)    # ... seed noise alone does not
    text = format_comparison(cmp)
    assert "worse: hausdorff_h significantly worse — worse on 10, better on 0, the same on 0 of 10 inputs" in text
    assert "noisy: hausdorff_h no significant change" in text
    assert "sphere/N24/none/s3/worse" in text                          # readable cell names in the per-cell list


def test_a_label_with_too_few_inputs_is_judged_per_cell(tmp_path):
    a = _run(tmp_path / "a", _seeds("m", [1.0, 1.1, 1.2]))
    b = _run(tmp_path / "b", _seeds("m", [1.0, 1.1, 1.5]))
    cmp = compare_frames(a, b)
    assert {c["verdict"] for c in cmp.changes if c["metric"] == "hausdorff_h"} == {"not tested"}
    assert cmp.worse and "too few inputs to test" in format_comparison(cmp)


def test_a_cell_a_method_now_declines_is_not_a_worsening(tmp_path):
    a = _run(tmp_path / "a", [_row(seed=0)])
    b = _run(tmp_path / "b", [_row(seed=0, status="skipped", hausdorff_h=None)])
    cmp = compare_frames(a, b)
    assert [s["verdict"] for s in cmp.states] == ["changed"] and not cmp.worse


def test_renamed_labels_of_one_method_pair_by_their_parameters_and_nothing_matched_says_why(tmp_path):
    """Two labels of one method in each run, renamed: each pairs with the label of the same parameters; when no
    label can be paired (or no input is shared), nothing matched and the reason says so and how to pair them."""
    a = _run(tmp_path / "a", [_row("mc1", params='{"k":1}'), _row("mc2", params='{"k":2}')])
    b = _run(tmp_path / "b", [_row("mcB", params='{"k":2}'), _row("mcA", params='{"k":1}')])
    cmp = compare_frames(a, b)
    assert cmp.matched == 2 and not cmp.only_a and not cmp.unmatched_reason
    assert {p["label"] for p in cmp.parameters} == {"mc1 → mcA", "mc2 → mcB"}
    c = _run(tmp_path / "c", [_row("x1", params='{"k":3}'), _row("x2", params='{"k":4}')])
    cmp = compare_frames(a, c)
    assert cmp.matched == 0
    assert "share 1 input(s) but no method label (A: mc1, mc2; B: x1, x2)" in cmp.unmatched_reason
    assert "--method LABEL=NAME" in cmp.unmatched_reason
    d = _run(tmp_path / "d", [{**_row("mc1"), "phantom": "torus", "cell_id": "torus_mc1"}])
    assert "no input (phantom, variant, N, noise, SNR, seed) is in both runs" in compare_frames(a, d).unmatched_reason
