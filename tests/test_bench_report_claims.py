"""The paper's claims checked from a run's cells (bench.report.claims): each verdict from hand-made rows."""

from __future__ import annotations

import json

import numpy as np

from bench.report.claims import CLAIMS, check_claims, claims_section, is_paper_grid


def _row(method, phantom, noise, beta=None, status="ok", flags=None, **metrics):
    params = json.dumps({"beta": beta}) if beta is not None else "{}"
    label = method if beta is None else f"{method}_b{beta}"
    return {"cell_id": f"{phantom}_{noise}_{label}", "method": method, "label": label, "phantom": phantom,
            "variant": "sdf", "N": 48, "noise": noise, "seed": 0, "parameters": params, "status": status,
            "flags": flags, **metrics}


def _verdicts(rows, arrays=lambda c: None) -> dict:
    return {c.id: c.verdict for c in check_claims(rows, arrays)}


def test_every_claim_is_not_measured_without_cells():
    v = _verdicts([])
    assert list(v) == [cid for cid, _ in CLAIMS] and set(v.values()) == {"not measured"}


def test_smoothness_verdicts_follow_the_roughness_of_the_pairs():
    rows = [_row("shape_gradient", "sphere", "none", 1.0, roughness_deg=2.0),
            _row("shape_gradient", "sphere", "none", 0.0, roughness_deg=3.0),
            _row("shape_gradient", "cube", "none", 1.0, roughness_deg=4.0),
            _row("shape_gradient", "cube", "none", 0.0, roughness_deg=3.0)]
    assert _verdicts(rows)["smoother"] == "partly"
    assert _verdicts(rows[:2])["smoother"] == "holds"
    assert _verdicts(rows[2:])["smoother"] == "does not hold"


def test_noise_claims_use_only_valid_unflagged_results():
    sg = _row("shape_gradient", "sphere", "gaussian", 1.0, hausdorff_h=0.5, mean_dist_h=0.1)
    mc = _row("marching_cubes", "sphere", "gaussian", hausdorff_h=0.8, mean_dist_h=0.2)
    dm = _row("distmesh", "sphere", "gaussian", hausdorff_h=0.3, status="ok", flags="not_converged")
    dm_clean = _row("distmesh", "sphere", "none", hausdorff_h=0.2)
    v = _verdicts([sg, mc, dm, dm_clean])
    assert v["robust_noise"] == "holds" and v["beats_mc"] == "holds"
    # DistMesh's 0.3 h is flagged: it loses the comparison, and counts as unstable
    assert v["noise_vs_mc_distmesh"] == "holds" and v["distmesh_unstable"] == "holds"
    flagged = dict(sg, flags="self_intersecting")
    v = _verdicts([flagged, mc, dm, dm_clean])
    assert v["robust_noise"] == "does not hold" and v["noise_vs_mc_distmesh"] == "does not hold"
    assert v["diffeomorphic"] == "does not hold"
    stable_dm = dict(dm, flags=None, hausdorff_h=0.25)
    assert _verdicts([sg, mc, stable_dm, dm_clean])["distmesh_unstable"] == "does not hold"


def test_energy_verdict_reads_the_stored_history():
    rows = [_row("shape_gradient", "sphere", "none", 1.0), _row("shape_gradient", "torus", "none", 1.0)]
    hist = {rows[0]["cell_id"]: np.geomspace(1.0, 1e-4, 30),               # smooth, to ~zero
            rows[1]["cell_id"]: np.r_[np.geomspace(1.0, 0.2, 10), 0.3, 0.25]}  # a rise, and ends at 25 %
    v = check_claims(rows, lambda c: {"energy_history": hist[c]})
    energy = {c.id: c for c in v}["energy"]
    assert energy.verdict == "partly" and "1 rise(s)" in energy.numbers and energy.cells == [r["cell_id"]
                                                                                            for r in rows]
    assert _verdicts(rows[:1], lambda c: {"energy_history": hist[c]})["energy"] == "holds"


def test_ellipsoid_curvature_claim_from_a_mesh_of_the_true_ellipsoid_and_of_a_sphere():
    import trimesh

    row = _row("shape_gradient", "ellipsoid", "none", 1.0)
    row["N"] = 96
    sphere = trimesh.creation.icosphere(subdivisions=5, radius=1.0)
    ell = sphere.copy()
    ell.apply_scale([1.0, 2.0, 1.0])      # the phantom's semi-axes (1, 2, 1): K in [1/4, 4]
    got = check_claims([row], lambda c: {"vertices": ell.vertices, "faces": ell.faces})
    assert got[-1].id == "ellipsoid_K" and got[-1].verdict == "holds", got[-1].numbers
    big = sphere.copy()
    big.apply_scale(2.5)                   # K = 0.16 everywhere: outside the range
    assert _verdicts([row], lambda c: {"vertices": big.vertices, "faces": big.faces})["ellipsoid_K"] \
        == "does not hold"


def test_the_report_page_shows_every_claim_with_its_verdict_from_a_real_run(tmp_path):
    from bench.config import config_from_dict
    from bench.report import write_report
    from bench.run import run_grid

    cfg = config_from_dict({"name": "claims", "grid": {"phantoms": ["sphere"], "variants": ["sdf"], "n": 24,
                                                        "seeds": [0], "noise": [{"kind": "none"}]},
                            "methods": [{"name": "shape_gradient", "params": {"beta": 1.0, "max_iter": 40}},
                                        {"name": "marching_cubes"}],
                            "metrics": {"n_samples": 2000}})
    out = tmp_path / "run"
    run_grid(cfg, out, jobs=1, progress=False)
    page = write_report(out).read_text(encoding="utf-8")
    assert 'id="claims"' in page
    # not the paper's grid: only the claims its cells can test are rows; the others are named in one note
    assert "The paper's claims this run can test" in page
    untested = ("smoother", "robust_noise", "noise_vs_mc_distmesh", "distmesh_unstable", "ellipsoid_K")
    for cid, _ in CLAIMS:
        assert (f'id="claim-{cid}"' in page) == (cid not in untested), cid
    assert "the others (smoother, robust_noise, noise_vs_mc_distmesh, distmesh_unstable, ellipsoid_K)" in page
    # one clean phantom, no noise, no β = 0 and no DistMesh: those claims are not measured; the others are
    import re

    verdicts = dict(re.findall(r'id="claim-(\w+)".*?data-variant="(?:default|all)"><span class="verdict v-[\w-]+">'
                               r'([\w ]+)<', page, re.S))
    assert verdicts["beats_mc"] in ("holds", "does not hold") and verdicts["diffeomorphic"] != "not measured"
    assert verdicts["energy"] != "not measured"
    printed = dict(re.findall(r'id="claim-(\w+)".*?data-variant="printed"><span class="verdict v-[\w-]+">([\w ]+)<',
                              page, re.S))
    assert set(printed.values()) == {"not measured"}           # the run has no preset=paper cells
    assert "The paper ran its algorithm as printed" in page


def test_cells_are_compared_only_at_the_same_snr_and_n():
    sg40 = dict(_row("shape_gradient", "sphere", "gaussian", 1.0, mean_dist_h=0.1), snr_requested=40.0)
    mc20 = dict(_row("marching_cubes", "sphere", "gaussian", mean_dist_h=0.5), snr_requested=20.0)
    assert _verdicts([sg40, mc20])["beats_mc"] == "not measured"
    mc40 = dict(mc20, snr_requested=40.0, cell_id="mc40")
    got = {c.id: c for c in check_claims([sg40, mc20, mc40])}["beats_mc"]
    assert got.verdict == "holds" and "40 dB" in got.numbers and got.cells == [sg40["cell_id"], "mc40"]


def _variant_row(variant, phantom, noise, beta=1.0, **metrics):
    preset = {"printed": "paper", "corrected": "paper+fixes", "default": "none"}[variant]
    r = _row("shape_gradient", phantom, noise, beta, **metrics)
    r.update(parameters=json.dumps({"beta": beta, "preset": preset}), cell_id=f"{phantom}_{noise}_{variant}_{beta}",
             label=f"sg_{variant}_{beta}")
    return r


def test_each_variant_gets_its_own_verdict_and_the_row_says_why_they_differ():
    """A results table in which the printed algorithm loses to marching cubes, the corrected experiment beats it,
    and the suite default beats it on one phantom of two: three columns, three verdicts."""
    mc = [_row("marching_cubes", ph, "none", mean_dist_h=0.1) for ph in ("sphere", "cube")]
    rows = mc + [
        _variant_row("printed", "sphere", "none", mean_dist_h=0.3),
        _variant_row("printed", "cube", "none", mean_dist_h=0.2),
        _variant_row("corrected", "sphere", "none", mean_dist_h=0.05),
        _variant_row("corrected", "cube", "none", mean_dist_h=0.08),
        _variant_row("default", "sphere", "none", mean_dist_h=0.09),
        _variant_row("default", "cube", "none", mean_dist_h=0.2),
        _variant_row("printed", "sphere", "gaussian", hausdorff_h=2.0, status="invalid"),
        _variant_row("corrected", "sphere", "gaussian", hausdorff_h=0.6)]
    claims = {c.id: c for c in check_claims(rows)}
    beats = claims["beats_mc"]
    assert {k: v.verdict for k, v in beats.by_variant.items()} == {
        "printed": "does not hold", "corrected": "holds", "default": "partly"}
    assert "0.300 h vs 0.100 h" in beats.by_variant["printed"].numbers
    assert beats.verdict == "does not hold"                      # the paper's own variant comes first
    assert "marching cubes' surface" in beats.why and beats.why.count(";") == 2
    robust = claims["robust_noise"]
    assert {k: v.verdict for k, v in robust.by_variant.items()} == {
        "printed": "does not hold", "corrected": "holds", "default": "not measured"}
    assert "no cell of this variant can test it" in robust.why
    same = claims["distmesh_unstable"]                           # no shape-gradient variant involved
    assert same.shared and same.why == "" and len({id(v) for v in same.by_variant.values()}) == 1
    agree = check_claims(mc + [_variant_row(v, "sphere", "none", mean_dist_h=0.05)
                               for v in ("printed", "corrected", "default")])
    assert {c.id: c for c in agree}["beats_mc"].why == ""          # all three hold: nothing to explain


def test_the_paper_variants_may_stop_on_their_iteration_count_or_line_search_other_flags_still_count():
    ok = dict(_variant_row("corrected", "sphere", "gaussian", hausdorff_h=0.1), flags="not_converged",
              stop_reason="line_search_floor")
    assert _verdicts([ok])["robust_noise"] == "holds"
    assert _verdicts([dict(ok, flags="not_converged;self_intersecting")])["robust_noise"] == "does not hold"
    default = dict(_variant_row("default", "sphere", "gaussian", hausdorff_h=0.1), flags="not_converged",
                   stop_reason="line_search_floor")
    assert {c.id: c for c in check_claims([default])}["robust_noise"].by_variant["default"].verdict == "does not hold"


def test_a_claim_without_values_to_judge_is_not_measured_never_does_not_hold():
    """A user's scan without truth: every distance is NaN; the comparisons cannot be made."""
    nan = float("nan")
    rows = [_row("shape_gradient", "scan", "gaussian", 1.0, hausdorff_h=nan, mean_dist_h=nan),
            _row("marching_cubes", "scan", "gaussian", hausdorff_h=nan, mean_dist_h=nan),
            _row("distmesh", "scan", "gaussian", hausdorff_h=nan),
            _row("distmesh", "scan", "none", hausdorff_h=nan)]
    v = _verdicts(rows)
    for cid in ("robust_noise", "beats_mc", "noise_vs_mc_distmesh", "distmesh_unstable"):
        assert v[cid] == "not measured", (cid, v[cid])
    failed = dict(rows[0], status="failed")                      # a failed cell is judged: it is the verdict
    assert _verdicts([failed] + rows[1:])["robust_noise"] == "does not hold"


def test_the_paper_grid_shows_every_claim_and_another_grid_only_those_it_can_test():
    from bench.config import builtin_config

    paper = builtin_config("paper").to_dict()
    custom = {**paper, "grid": {**paper["grid"], "phantoms": ["volume:liver.nii.gz?labels=all"]}}
    assert is_paper_grid(paper) and not is_paper_grid(custom) and not is_paper_grid({"name": "paper"})
    rows = [_row("shape_gradient", "sphere", "none", 1.0, roughness_deg=2.0),
            _row("shape_gradient", "sphere", "none", 0.0, roughness_deg=3.0)]
    on_paper = claims_section(rows, config=paper)
    assert on_paper.paper_grid and [c.id for c in on_paper.claims] == [cid for cid, _ in CLAIMS]
    custom_section = claims_section(rows, config=custom)
    assert not custom_section.paper_grid
    assert [c.id for c in custom_section.claims] == ["smoother", "diffeomorphic"]
    assert "beats_mc" in custom_section.untested and "smoother" not in custom_section.untested
    # nothing a claim can judge (one marching-cubes row): no claims, the section is left out
    nothing = claims_section([_row("marching_cubes", "liver_label1", "none")], config=custom)
    assert nothing.claims == [] and len(nothing.untested) == len(CLAIMS)
