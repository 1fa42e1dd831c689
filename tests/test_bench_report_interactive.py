"""Tests of ``bench.report.interactive``: the breakdown point of a curve, the robustness figures (only the axes a
run varies), the accuracy-against-cost figure (a mean point per method, phantom and noise; failed cells left
out) and the viewers' packed meshes with their shared colour ranges."""

from __future__ import annotations

import base64

import numpy as np
import pytest
import trimesh

from bench.report.interactive import breakdown, pareto_figure, robustness_figures, viewer_payload


def _row(label, N=32, noise="none", snr=None, hd=0.3, status="ok", flags="", wall=1.0, seed=0, phantom="sphere"):
    return {"cell_id": f"{phantom}_{label}_{N}_{noise}_{snr}_{seed}", "phantom": phantom, "label": label, "N": N,
            "noise": noise, "snr_requested": snr, "hausdorff_h": hd, "status": status, "flags": flags,
            "wall_s": wall, "seed": seed, "h": 5.0 / (N - 1)}


def test_breakdown_is_the_last_good_x_from_the_top():
    assert breakdown([(40, True), (30, True), (20, False), (10, True)]) == 30
    assert breakdown([(40, False), (30, True)]) is None
    assert breakdown([(10, True), (40, True)]) == 10
    assert breakdown([]) is None


def test_robustness_figures_draw_only_the_axes_the_run_varies():
    noisy = [_row(m, noise="gaussian", snr=s, hd=hd) for m in ("a", "b")
             for s, hd in ((40, 0.2), (30, 0.5), (20, 2.0))]
    figs = robustness_figures(noisy)
    assert len(figs) == 1 and "against SNR" in figs[0]["layout"]["title"]["text"]
    names = {t.get("name") for t in figs[0]["data"] if t.get("name")}
    assert names == {"a", "b"}
    diamonds = [t for t in figs[0]["data"] if t.get("marker", {}).get("symbol") == "diamond-open"]
    assert diamonds and all(t["x"] == [30] for t in diamonds)   # 20 dB is over 1 h: the breakdown point is 30
    clean = [_row("a", N=n) for n in (24, 32, 48)]
    figs = robustness_figures(clean)
    assert len(figs) == 1 and "against N" in figs[0]["layout"]["title"]["text"]
    assert robustness_figures([_row("a", N=n) for n in (24, 32)]) == []         # two values: no curve


def test_pareto_figure_means_over_seeds_and_leaves_out_failed_cells():
    rows = [_row("a", seed=0, wall=1.0, hd=0.2), _row("a", seed=1, wall=3.0, hd=0.4),
            _row("a", noise="gaussian", snr=30, wall=2.0, hd=0.5, flags="not_converged"),
            _row("b", wall=10.0, hd=0.1), _row("b", seed=1, status="failed", wall=99.0, hd=9.0)]
    fig = pareto_figure(rows)
    traces = {t["name"]: t for t in fig["data"]}
    assert set(traces) == {"a", "b"}
    a = traces["a"]
    assert sorted(zip(a["x"], a["y"])) == [pytest.approx((2.0, 0.3)), pytest.approx((2.0, 0.5))]
    assert sorted(a["marker"]["symbol"]) == ["circle", "diamond-open"]             # hollow: flagged
    assert traces["b"]["x"] == [10.0] and traces["b"]["y"] == [0.1]
    assert pareto_figure([_row("a", status="failed")]) is None


def test_viewer_payload_packs_each_mesh_and_shares_colour_ranges_per_phantom_and_noise():
    m = trimesh.creation.icosphere(subdivisions=3, radius=1.0)
    v, f = np.asarray(m.vertices), np.asarray(m.faces)
    arrays = {"sphere_a_32_none_None_0": {"vertices": v * 1.05, "faces": f, "H": np.full(len(v), 1.0)},
              "sphere_b_32_none_None_0": {"vertices": v, "faces": f, "H": np.full(len(v), 2.0)},
              "sphere_c_32_none_None_0": {}}
    rows = [_row(k) for k in ("a", "b", "c")]
    out = viewer_payload(rows, arrays.get, faces=200)
    assert set(out["cells"]) == {"sphere_a_32_none_None_0", "sphere_b_32_none_None_0"}     # c has no mesh
    cell = out["cells"]["sphere_a_32_none_None_0"]
    # decimated from 200 faces up to what keeps the sphere within the viewer's tolerance (not the 1,280 of the mesh)
    assert 200 <= cell["nf"] < len(f) and cell["faces_full"] == len(f) and not cell["f32"]
    q = np.frombuffer(base64.b64decode(cell["v"]), "<u2").reshape(cell["n"], 3)
    verts = np.asarray(cell["lo"]) + q / 65535.0 * (np.asarray(cell["hi"]) - np.asarray(cell["lo"]))
    np.testing.assert_allclose(np.linalg.norm(verts, axis=1), 1.05, atol=0.05)   # decimated: off by a little
    rng = out["ranges"]["sphere|none"]
    assert rng["H"][0] == pytest.approx(1.0) and rng["H"][1] == pytest.approx(2.0)
    assert rng["d"][1] > 0 and rng["d"][0] == -rng["d"][1]        # signed distance: a symmetric range
    d = np.frombuffer(base64.b64decode(cell["d"]), np.uint8)
    assert d.min() == 255                                         # a, 0.05 outside: the top of the range
