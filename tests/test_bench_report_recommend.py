"""bench/report/recommend.py: the first screen's recommendation per shape kind × input — a different method where
a different one wins, "no method is clearly better" on ties, unusable results counted against their method, and
rows of a run from before the shape kind was recorded."""

from __future__ import annotations

import numpy as np
import pytest

from bench.report.recommend import (UNCLASSIFIED, YOUR_DATA, input_class, recommendation_html,
                                    recommendation_markdown, recommendation_table, shape_class)


def _rows(kind: str | None, degrade: str, factors: dict[str, float | list[float]], n_phantoms: int = 8,
          prefix: str = "p", **extra) -> list[dict]:
    """One row per (phantom, N, method): Hausdorff = the phantom's difficulty × the method's factor (a list: one
    factor per input, in phantom-then-N order)."""
    rng = np.random.default_rng(len(prefix) + n_phantoms)
    rows = []
    for i in range(n_phantoms):
        for j, n in enumerate((48, 64)):
            base = rng.uniform(0.5, 2.5)
            for label, f in factors.items():
                f = f[2 * i + j] if isinstance(f, list) else f
                rows.append({"phantom": f"{prefix}{i}", "variant": "sdf", "N": n, "noise": "none",
                             "snr_requested": None, "seed": 0, "label": label, "status": "ok", "flags": "",
                             "wall_s": 1.0, "hausdorff_h": base * f, "degrade": degrade, "shape_kind": kind,
                             "has_truth": True, **extra})
    return rows


def test_a_method_best_on_one_kind_and_another_on_another_gives_two_recommendations_and_ties_none():
    # on clean φ the three alternate: each is ahead on half the inputs by as much as it is behind on the others
    odd = [k % 2 == 1 for k in range(16)]
    ties = {"A": [1.0 if o else 1.25 for o in odd], "B": [1.25 if o else 1.0 for o in odd],
            "C": [1.15 if o else 1.1 for o in odd]}
    rows = (_rows("smooth solid", "mask", {"A": 1.0, "B": 1.4, "C": 1.6}, prefix="ball")
            + _rows("thin shell", "mask", {"A": 1.5, "B": 1.0, "C": 1.3}, prefix="vault")
            + _rows("smooth solid", "none", ties, prefix="ball"))
    t = recommendation_table(rows)
    assert t["shapes"] == ["smooth solid", "thin shell", "every shape kind"]
    assert t["inputs"] == ["mask", "clean φ", "every input"]
    solid, shell = t["cells"][("smooth solid", "mask")], t["cells"][("thin shell", "mask")]
    assert solid["best"] == "A" and shell["best"] == "B"
    assert solid["text"].startswith("use A on hausdorff_h (better than B (16–0 of 16, p < 0.001) and C (16–0")
    assert shell["text"].startswith("use B on hausdorff_h (better than C (16–0 of 16")
    # each names what it rests on: its inputs, phantoms and results
    assert solid["basis"] == "16 inputs (ball0, ball1, ball2, ball3, ball4, ball5, ball6, ball7), 48 results"
    assert ("thin shell", "clean φ") not in t["cells"]
    tie = t["cells"][("smooth solid", "clean φ")]
    assert tie["best"] is None and tie["text"].startswith("no method is clearly better on hausdorff_h")
    html = recommendation_html(t)
    assert html.count("<tr>") == 4 and "use A on hausdorff_h" in html and "not run" in html
    md = recommendation_markdown(t)
    assert "| smooth solid | **use A on hausdorff_h" in md and "| thin shell |" in md and "not run" in md


def test_unusable_and_invalid_results_count_against_their_method():
    rows = _rows("tubes", "partial_volume", {"A": 0.5, "B": 1.0, "C": 1.3})
    for k, r in enumerate(r for r in rows if r["label"] == "A"):
        if k % 2:
            r["flags"] = "dropped_components"                 # closest, but in pieces on half of the inputs
        elif k % 4 == 0:
            r.update(status="invalid", hausdorff_h=0.1)        # and invalid on a quarter: never its value
    cell = recommendation_table(rows)["cells"][("tubes", "partial volume")]
    assert cell["best"] == "B" and cell["not_usable"] == {"A": 12}
    assert "A (12–4 of 16" in cell["text"].split("better than")[1]     # B beats A on the 12 A could not deliver
    assert cell["basis"].endswith("48 results; not usable or invalid, counted as losses: A 12")
    # the same values with every result usable: A is the recommendation
    for r in rows:
        r.update(status="ok", flags="")
    assert recommendation_table(rows)["cells"][("tubes", "partial volume")]["best"] == "A"


@pytest.mark.parametrize("degrade, noise, expected", [
    ("mask", "none", "mask"), ("mask+label_noise@0.1", "none", "mask"), ("blur@1+mask", "none", "mask"),
    ("partial_volume", "none", "partial volume"), ("thick_slices@3+mask", "none", "thick slices"),
    ("thick_slices@3+partial_volume", "none", "thick slices"), ("none", "gaussian", "noisy φ"),
    ("none", "none", "clean φ"), (None, None, "clean φ"), ("melt@2", "none", "other input (melt@2)"),
])
def test_the_input_column_comes_from_the_degradation_and_the_noise(degrade, noise, expected):
    assert input_class({"degrade": degrade, "noise": noise}) == expected


def test_the_shape_row_of_user_data_of_unclassified_phantoms_and_of_a_cell_that_failed_early():
    assert shape_class({"shape_kind": "thin_shell", "has_truth": True}) == "thin shell"
    assert shape_class({"phantom": "ct_01", "source": "volume:/s/ct_01.nii", "has_truth": False}) == (
        f"{YOUR_DATA} (no truth)")
    assert shape_class({"phantom": "sphere", "shape_kind": float("nan")}) == UNCLASSIFIED
    # a failed row without the column takes its phantom's kind from the others
    assert shape_class({"phantom": "vault", "status": "failed"}, {"vault": "thin shell"}) == "thin shell"


def test_rows_of_a_run_from_before_the_shape_kind_column_are_unclassified_not_lost():
    rows = _rows(None, "mask", {"A": 1.0, "B": 1.5})
    for r in rows:
        del r["shape_kind"]
    t = recommendation_table(rows)
    assert t["shapes"] == [UNCLASSIFIED] and t["cells"][(UNCLASSIFIED, "mask")]["best"] == "A"


def test_the_pooled_row_and_column_give_a_verdict_where_each_cell_has_too_few_inputs():
    """Two phantoms per kind (4 inputs: too few for a test) in three kinds, A ahead everywhere: every cell says no
    test can be made, the pooled 'every shape kind' row (12 inputs per input) and 'every input' column (8 inputs
    per kind) recommend A, naming their scope; a kind where every result is unusable says so."""
    rows = []
    for kind in ("thin shell", "tubes", "cavities"):
        for degrade in ("mask", "partial_volume"):
            rows += _rows(kind, degrade, {"A": 1.0, "B": 1.3, "C": 1.6}, n_phantoms=2, prefix=kind[:4])
    bad = _rows("touching parts", "mask", {"A": 1.0, "B": 1.3}, n_phantoms=4, prefix="pair")
    for r in bad:
        r["status"] = "invalid"
    t = recommendation_table(rows + bad)
    assert t["shapes"][-1] == "every shape kind" and t["inputs"][-1] == "every input"
    cell = t["cells"][("tubes", "mask")]
    assert cell["best"] is None and "no pair shares enough inputs" in cell["text"]
    for key in (("every shape kind", "mask"), ("every shape kind", "partial volume"), ("tubes", "every input"),
                ("every shape kind", "every input")):
        assert t["cells"][key]["best"] == "A", (key, t["cells"][key]["text"])
    assert t["cells"][("every shape kind", "mask")]["n_inputs"] == 20     # (3 kinds x 2 + 4) phantoms x 2 N
    assert t["cells"][("touching parts", "mask")]["text"] == ("no method gives a usable mesh here: every result is "
                                                               "invalid or unusable")    # invalid: no raw values
    for r in bad:                                  # valid but unusable (merged): the raw values still rank them
        r["status"], r["flags"] = "ok", "topology_mismatch"
    cell = recommendation_table(rows + bad)["cells"][("touching parts", "mask")]
    assert cell["best"] is None
    assert cell["text"].startswith("no method gives a usable mesh here: every result is invalid or unusable; closest "
                                   "to the truth, usable or not: use A on hausdorff_h (better than B (8–0 of 8")
