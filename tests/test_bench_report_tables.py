"""The report's summary tables (bench.report.tables): value formatting, best marks from the metric registry,
one table per phantom × noise."""

from __future__ import annotations

import re

import numpy as np
import pandas as pd

from bench.metrics.registry import METRICS
from bench.report import BEST_DIRECTION, summary_tables
from bench.report.tables import best_mask, best_rule, fmt_value


def _row(label: str, phantom: str = "sphere", noise: str = "none", **metrics) -> dict:
    return {"cell_id": f"{phantom}_{noise}_{label}", "phantom": phantom, "variant": "sdf", "N": 48, "noise": noise,
            "snr_requested": np.nan if noise == "none" else 40.0, "seed": 0, "method": label, "label": label,
            "parameters": "{}", "status": "ok", "error": "", **metrics}


def _marked(table_html: str) -> list[str]:
    return re.findall(r'<span class="best" title="best">([^<]*)</span>', table_html)


# ---------------------------------------------------------------------------------------------- formatting
def test_values_are_shown_by_their_registry_dtype():
    assert fmt_value(2.0, "euler") == "2" and fmt_value(12.0, "n_faces") == "12"       # int columns
    assert fmt_value(2.0, "hausdorff") == "2"                                             # 4 significant digits
    assert fmt_value(0.123456, "hausdorff") == "0.1235"
    assert fmt_value(1.0, "watertight") == "yes" and fmt_value(0.0, "watertight") == "no"
    assert fmt_value(0.5, "watertight") == "50 % yes"                                     # share of seeds
    assert fmt_value(2.5, "euler") == "2.5"                                               # a mean over seeds
    assert fmt_value(np.nan, "hausdorff") == "–" and fmt_value(float("inf"), "hausdorff") == "∞"
    assert fmt_value(True, "anything") == "yes" and fmt_value("<b>", "x") == "&lt;b&gt;"


# ---------------------------------------------------------------------------------------------- best marks
def test_best_rules_come_from_the_registry():
    assert BEST_DIRECTION == {k: m.best for k, m in METRICS.items() if m.best is not None}
    assert best_rule("hausdorff_h") == "min" and best_rule("fscore@h") == "max"
    assert best_rule("n_vertices") is None and best_rule("not_a_metric") is None
    assert best_rule("euler", genus=1) == ("target", 0) and best_rule("euler") == ("target", 2)
    assert best_rule("components") == ("target", 1)


def test_best_mask_min_max_target_and_too_few_values():
    """Only a unique best is marked: a tie (also within the metric's resolution) marks nobody."""
    s = pd.Series([3.0, 1.0, np.nan, 1.0])
    assert not best_mask(s, "min").any()
    assert best_mask(pd.Series([3.0, 1.0, np.nan, 2.0]), "min").tolist() == [False, True, False, False]
    assert best_mask(s, "max").tolist() == [True, False, False, False]
    assert not best_mask(pd.Series([0, 2, 4]), ("target", 3)).any()
    assert best_mask(pd.Series([0, 2, 5]), ("target", 3)).tolist() == [False, True, False]
    near = pd.Series([1.0, 1.02, 2.0])                      # 2 % apart: the same Hausdorff at its 5 % resolution
    assert not best_mask(near, "min", metric="hausdorff_h").any() and best_mask(near, "min").tolist()[0]
    assert not best_mask(pd.Series([1.0, np.nan]), "min").any()                           # one value: no mark
    assert best_mask(pd.Series([True, False]), "max").tolist() == [True, False]


# ---------------------------------------------------------------------------------------------- the tables
def test_one_table_per_phantom_and_noise_with_the_best_marked():
    df = pd.DataFrame([
        _row("a", hausdorff=0.2, normal_consistency=0.99, euler=2, n_vertices=100),
        _row("b", hausdorff=0.1, normal_consistency=0.90, euler=0, n_vertices=200),
        _row("a", noise="gaussian", hausdorff=0.3, normal_consistency=0.8, euler=2, n_vertices=100),
        _row("b", noise="gaussian", hausdorff=0.4, normal_consistency=0.7, euler=2, n_vertices=100),
    ])
    tables = summary_tables(df)
    assert [t["title"] for t in tables] == ["sphere — signed distance, clean",
                                            "sphere — signed distance, gaussian noise, SNR 40 dB"]
    assert [t["n_methods"] for t in tables] == [2, 2]
    # clean: b has the smaller distance, a the higher normal consistency and the sphere's Euler characteristic
    assert sorted(_marked(tables[0]["html"])) == sorted(["0.1", "0.99", "2"])
    assert "200" in tables[0]["html"] and "<span class=\"best\" title=\"best\">200" not in tables[0]["html"]
    # gaussian: both have Euler 2 → a shared best marks neither
    assert _marked(tables[1]["html"]).count("2") == 0 and sorted(_marked(tables[1]["html"])) == ["0.3", "0.8"]


def test_euler_target_follows_the_phantom_genus():
    df = pd.DataFrame([_row("a", phantom="torus", euler=0), _row("b", phantom="torus", euler=2)])
    html = summary_tables(df)[0]["html"]
    assert _marked(html) == ["0"]


def test_seeds_are_averaged_over_ok_cells_and_the_status_says_so():
    rows = [_row("a", hausdorff=0.1, watertight=True), _row("a", hausdorff=0.3, watertight=False),
            dict(_row("a", hausdorff=9.0, watertight=False), status="failed")]
    for i, r in enumerate(rows):
        r["seed"] = i
    t = summary_tables(pd.DataFrame(rows))[0]
    assert "<td>0.2 <span class=\"ci\"" in t["html"] and "<td>50 % yes</td>" in t["html"]
    assert "failed×1, ok×2 (mean of 2/3 seeds)" in t["html"]


def test_flags_and_invalid_rows_are_badges_named_in_text():
    from bench.report.tables import status_badges, summary_tables

    rows = [_row("good", hausdorff=1.0), dict(_row("odd", hausdorff=0.5), flags="self_intersecting;not_converged"),
            dict(_row("bad", hausdorff=0.1), status="invalid", error="invalid: inward")]
    html = summary_tables(pd.DataFrame(rows))[0]["html"]
    assert '<span class="badge badge-flag" title="some non-adjacent faces intersect">self_intersecting</span>' in html
    assert ">not_converged</span>" in html and "⚑" not in html
    assert '<span class="badge badge-invalid"' in html and ">invalid</span>" in html
    # validity first: good (valid, unflagged), odd (valid, flagged), bad (invalid) — bad's 0.1 is never best
    assert html.index("<td>good</td>") < html.index("<td>odd</td>") < html.index("<td>bad</td>")
    bad_row = html[html.index("<td>bad</td>"):].split("</tr>")[0]
    assert 'class="best"' not in bad_row
    assert status_badges("failed", [], False).startswith('<span class="badge badge-failed"')
    assert (status_badges("ok", ["x<y"], True)
            == 'ok <span class="badge badge-flag" title="suspect result">x&lt;y</span>')


def test_several_seeds_show_the_mean_and_a_95_percent_interval():
    rows = [_row("a", noise="gaussian", hausdorff=h, normal_consistency=0.9, euler=2, n_vertices=100)
            for h in (0.1, 0.2, 0.3)]
    for i, r in enumerate(rows):
        r["seed"] = i
    html_text = summary_tables(pd.DataFrame(rows))[0]["html"]
    # mean 0.2, sd 0.1, t(0.975, 2) = 4.303: half-width 0.2484
    assert "0.2 <span class=\"ci\"" in html_text and "± 0.2484" in html_text


def test_a_file_phantom_is_named_by_its_stem_and_options_in_titles():
    from bench.report.tables import phantom_label

    assert phantom_label("volume:/scans/patient_01/ct_0001.nii.gz") == "ct_0001"
    assert phantom_label("volume:/scans/seg.nrrd?label=3&spacing=1,1,3") == "seg (label=3, spacing=1,1,3)"
    assert phantom_label("mesh:/models/Stanford Bunny.obj") == "Stanford Bunny"
    assert phantom_label("sphere") == "sphere"


def test_a_cell_that_ended_before_reading_its_volume_joins_its_inputs_table():
    import pandas as pd

    from bench.report.tables import complete_inputs, summary_tables

    base = {"phantom": "volume:/s/ct.nii.gz", "variant": "sdf", "degrade": "none", "noise": "none",
            "snr_requested": None, "seed": 0, "flags": "", "error": ""}
    df = pd.DataFrame([dict(base, cell_id="a", label="mc", method="mc", N=40, input_kind="mask", status="ok",
                            sdf_rms_h=0.1, has_truth=False),
                       dict(base, cell_id="b", label="sg", method="sg", N=0, input_kind="sdf", status="timeout",
                            sdf_rms_h=None, has_truth=False)])
    done = complete_inputs(df)
    assert done.loc[1, "N"] == 40 and done.loc[1, "input_kind"] == "mask" and df.loc[1, "N"] == 0
    (table,) = summary_tables(df)                             # one table, not a second "sdf, N = 0" one
    assert table["title"].startswith("ct — mask") and table["n_methods"] == 2


def test_the_topology_targets_count_every_surface_of_the_truth():
    """A truth of several surfaces (the anatomy tier's spine_parts: 5 bodies, genus 0): its components and Euler
    characteristic targets are 5 and 10, not one surface's 1 and 2 — the mesh that has them is the one marked."""
    from bench.report.tables import phantom_topology

    assert best_rule("euler", genus=0, components=5) == ("target", 10)
    assert best_rule("components", components=5) == ("target", 5)
    components, genus = phantom_topology("spine_parts")
    assert (components, genus) == (5, 0)
    df = pd.DataFrame([_row("a", phantom="spine_parts", euler=2), _row("b", phantom="spine_parts", euler=10)])
    assert _marked(summary_tables(df)[0]["html"]) == ["10"]
