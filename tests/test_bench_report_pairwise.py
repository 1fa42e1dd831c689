"""bench/report/pairwise.py and the boards that use it: every pair tested on the inputs both methods have,
Holm's correction, usable meshes first, and the one verdict generated from the numbers."""

from __future__ import annotations

import math

import numpy as np
import pytest

from bench.report.pairwise import MIN_PAIRED, holm, pairwise, recommendation
from bench.report.verdicts import leaderboards


def _rows(values: dict[str, dict[int, float]], **extra) -> list[dict]:
    """One row per (method, input index): value = Hausdorff; the inputs are phantoms p0, p1, ..."""
    rows = []
    for label, vals in values.items():
        for i, v in vals.items():
            rows.append({"phantom": f"p{i}", "variant": "sdf", "N": 48, "noise": "none", "snr_requested": None,
                         "seed": 0, "label": label, "status": "ok", "flags": "", "wall_s": 1.0, "hausdorff_h": v,
                         "mean_dist_h": v / 4, **extra})
    return rows


def test_holm_matches_the_step_down_by_hand():
    ps = [0.01, 0.04, 0.03, math.nan, 0.2]
    # sorted: 0.01·4 = 0.04, 0.03·3 = 0.09, 0.04·2 = 0.08 → max(0.09, 0.08) = 0.09, 0.2·1 = 0.2
    assert holm(ps)[:3] == pytest.approx([0.04, 0.09, 0.09]) and math.isnan(holm(ps)[3])
    assert holm(ps)[4] == pytest.approx(0.2)
    assert holm([0.6, 0.5]) == pytest.approx([1.0, 1.0])


def test_a_pair_is_tested_on_the_inputs_both_have_even_when_a_third_method_shares_few():
    rng = np.random.default_rng(1)
    base = rng.uniform(0.5, 3.0, 20)
    vals = {"A": {i: base[i] for i in range(20)}, "B": {i: base[i] * 1.2 + 0.05 for i in range(20)},
            "C": {i: base[i] * 0.9 for i in range(6)}}               # C ran on 6 of the 20 inputs only
    board = leaderboards(_rows(vals))[0]
    assert board["n_blocks"] == 6 and board["n_inputs"] == 20
    assert board["significance"]["test"] is None                       # 6 inputs every method has: no Friedman
    ab = board["pairwise"]["pairs"][("A", "B")]
    assert (ab["n"], ab["wins"], ab["losses"]) == (20, 20, 0)
    assert ab["p_holm"] < 0.05 and ab["better"] == "A"
    ba = board["pairwise"]["pairs"][("B", "A")]
    assert (ba["wins"], ba["losses"], ba["better"]) == (0, 20, "A")
    ac = board["pairwise"]["pairs"][("A", "C")]
    assert ac["n"] == 6 and ac["losses"] == 6       # C is better where it ran, but 6 inputs give p ≥ 0.03 before Holm
    # the verdict rests on every pair's shared inputs: A beats B over all 20, C is not told apart from A on its 6
    v = board["verdict"]
    assert v["best"] == "A" and v["beats"] == ["B"] and v["as_good"] == ["C"]
    assert [r["label"] for r in board["rows"]] == ["A", "C", "B"]        # the verdict's order, not C's mean rank
    assert "Use A on hausdorff_h (better than B (20–0 of 20" in board["recommendation"]
    assert "C is as good (not told apart" in board["recommendation"]


def test_the_recommendation_names_who_is_beaten_and_who_is_not_told_apart():
    base = np.linspace(1.0, 3.0, 12)
    alternating = {i: v * (1.2 if i % 2 else 0.85) for i, v in enumerate(base)}
    vals = {"A": {i: v for i, v in enumerate(base)}, "B": {i: v * 1.5 for i, v in enumerate(base)},
            "C": alternating}
    board = leaderboards(_rows(vals))[0]
    text = board["recommendation"]
    assert text.startswith("On these 12 inputs (an invalid or unusable mesh loses to a usable one): Use A on "
                           "hausdorff_h (better than B (12–0 of 12")
    # C alternates around A: as good, and where — the inputs where C is at least as good (its 0.85 × A ones)
    assert "C is as good (not told apart, p = " in text
    assert "at least as good on every input of p0, p10, p2, p4, p6, p8)" in text
    assert "Holm" in text
    # nothing separates two methods that alternate: the sentence says so
    two = leaderboards(_rows({"A": vals["A"], "C": alternating}))[0]["recommendation"]
    assert "No method is clearly better on hausdorff_h (no pair differs significantly" in two
    assert "Use" not in two


def test_a_method_in_pieces_leads_the_raw_values_and_loses_the_verdict_which_says_why():
    base = np.linspace(1.0, 2.0, 12)
    rows = _rows({"pieces": {i: v * 0.5 for i, v in enumerate(base)},
                  "one": {i: v for i, v in enumerate(base)}, "other": {i: v * 1.3 for i, v in enumerate(base)}})
    for r in rows:
        if r["label"] == "pieces":
            r["flags"] = "topology_mismatch"                           # e.g. 3–18 components of a one-piece shape
    board = leaderboards(rows)[0]
    assert [r["label"] for r in board["rows"]] == ["one", "other", "pieces"]
    assert board["rows"][0]["usable_pct"] == 100.0 and board["rows"][2]["hausdorff_h"] == 3.0
    text = board["recommendation"]
    assert text.startswith("On these 12 inputs (an invalid or unusable mesh loses to a usable one): Use one")
    assert "pieces (12–0 of 12" in text and "other (12–0 of 12" in text
    raw = board["raw_board"]
    assert raw["rows"][0]["label"] == "pieces" and raw["rows"][0]["usable_pct"] == 0.0
    # the raw ranking is not a second verdict: the board says why it differs
    assert board["tests_differ"][0] == ("Ranking the raw values, usable or not, pieces would come first (0 % of "
                                        "its 12 meshes usable): the verdict counts a mesh that cannot be used as "
                                        "a loss")


def test_an_invalid_cell_loses_to_a_valid_one_and_two_invalid_cells_tie():
    a = {("x", i): 1.0 + i for i in range(MIN_PAIRED)}
    b = dict(a)
    b[("x", 0)] = math.nan
    a[("x", 1)] = math.nan
    b[("x", 1)] = math.nan
    pw = pairwise({"A": a, "B": b}, "hausdorff_h")
    rec = pw["pairs"][("A", "B")]
    assert (rec["wins"], rec["ties"], rec["losses"]) == (1, MIN_PAIRED - 1, 0)
    few = pairwise({"A": {1: 1.0}, "B": {1: 2.0}}, "hausdorff_h")["pairs"][("A", "B")]
    assert math.isnan(few["p"]) and few["better"] is None and few["wins"] == 1


def test_no_input_in_common_still_gives_a_board_with_its_pairs():
    rows = _rows({"A": {i: 1.0 for i in range(8)}, "B": {i: 2.0 for i in range(8)},
                  "C": {i: 0.5 for i in range(8, 16)}})
    board = leaderboards(rows)[0]
    assert board["n_blocks"] == 0 and board["n_inputs"] == 16
    assert board["rows"][0]["label"] == "A"                             # the only pair with inputs in common
    assert "not tested against C (only 0 shared inputs; a test needs 6)" in recommendation(board)


def test_a_skipped_input_is_left_out_not_counted_against_the_method():
    base = {i: 1.0 + i for i in range(8)}
    rows = _rows({"A": base, "B": {i: v * 1.2 for i, v in base.items()}})
    for r in rows:
        if r["label"] == "B" and r["phantom"] in ("p0", "p1"):
            r.update(status="skipped", hausdorff_h=None)               # B declines two inputs
    board = leaderboards(rows)[0]
    b = next(r for r in board["rows"] if r["label"] == "B")
    assert b["cells"] == 6 and b["valid_pct"] == 100.0 and b["usable_pct"] == 100.0
    assert board["n_blocks"] == 6 and board["pairwise"]["pairs"][("A", "B")]["n"] == 6
