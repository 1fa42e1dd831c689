"""bench/report/colours.py: one colour per method label, the same in every chart of a report and across reports."""

from __future__ import annotations

import numpy as np

from bench.report.colours import PALETTE, method_colour
from bench.report.interactive import pareto_figure, robustness_figures
from bench.report.verdicts import cd_figure, leaderboards


def _rows():
    rows = []
    rng = np.random.default_rng(1)
    for i, label in enumerate(["marching_cubes", "shape_gradient", "my_plugin[beta=0.5]"]):
        for p in range(12):
            for noise, snr in (("none", None), ("gaussian", 20.0), ("gaussian", 30.0), ("gaussian", 40.0)):
                rows.append({"cell_id": f"{label}-{p}-{snr}", "phantom": f"shape{p}", "variant": "sdf", "N": 32,
                             "noise": noise, "snr_requested": snr, "seed": 0, "label": label, "status": "ok",
                             "flags": "not_converged" if p == 3 else "", "hausdorff_h": 0.2 + i + rng.random(),
                             "mean_dist_h": 0.1 + i, "sdf_rms_h": 0.1, "roughness_deg": 3.0, "wall_s": 0.1 * (i + 1)})
    return rows


def _trace_colours(fig) -> dict[str, set]:
    out: dict[str, set] = {}
    for tr in fig["data"]:
        name = tr.get("name")
        colour = (tr.get("marker") or {}).get("color") or (tr.get("line") or {}).get("color")
        if name and isinstance(colour, str):
            out.setdefault(name, set()).add(colour)
    return out


def test_every_chart_gives_a_method_the_same_colour():
    rows = _rows()
    figs = robustness_figures(rows) + [pareto_figure(rows)]
    boards = leaderboards(rows)
    figs.append(cd_figure(boards[0], {lab: method_colour(lab) for lab in {r["label"] for r in rows}}))
    seen: dict[str, set] = {}
    for fig in figs:
        for name, colours in _trace_colours(fig).items():
            seen.setdefault(name, set()).update(colours)
    assert set(seen) == {"marching_cubes", "shape_gradient", "my_plugin[beta=0.5]"}
    for name, colours in seen.items():
        assert colours == {method_colour(name)}, (name, colours)


def test_colours_are_fixed_by_name_and_distinct_for_the_builtins():
    builtins = ["shape_gradient", "marching_cubes", "mc_taubin", "distmesh", "poisson", "flying_edges",
                "reach_for_the_spheres", "dual_contouring", "reach_for_the_arcs"]
    assert len({method_colour(b) for b in builtins}) == len(builtins)
    assert method_colour("my_plugin") == method_colour("my_plugin") and method_colour("my_plugin") in PALETTE
