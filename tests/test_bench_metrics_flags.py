"""bench.metrics.flags: suspect but valid results, against the truth's topology and the method's stop."""

from __future__ import annotations

import pytest

from bench.metrics.flags import result_flags
from bench.run import expand_grid, run_cell
from bench.config import config_from_dict
from phantoms import get_phantom


def test_each_flag_from_a_row():
    sphere, torus = get_phantom("sphere"), get_phantom("torus")
    clean = {"euler": 2, "components": 1, "self_intersections": 0, "stop_reason": "converged"}
    assert result_flags(clean, sphere) == []
    assert result_flags(clean, torus) == ["topology_mismatch"]                   # a sphere for a torus
    assert result_flags({**clean, "euler": 0}, torus) == []
    assert result_flags({**clean, "self_intersections": 3}, sphere) == ["self_intersecting"]
    for stop in ("max_iter", "line_search_floor", "diverged", "sign_guard"):
        assert result_flags({**clean, "stop_reason": stop}, sphere) == ["not_converged"]
    assert result_flags(clean, None) == []                                       # no truth: no topology flag


def test_dropped_components_against_a_two_component_truth():
    class TwoSpheres:
        genus, n_components = 0, 2

    row = {"euler": 2, "components": 1, "self_intersections": 0, "stop_reason": None}
    assert result_flags(row, TwoSpheres()) == ["topology_mismatch", "dropped_components"]
    assert result_flags({**row, "euler": 4, "components": 2}, TwoSpheres()) == []


@pytest.mark.parametrize("method, params, flag, stop", [
    ("shape_gradient", {"max_iter": 40}, "topology_mismatch", None),     # one genus-0 surface for a torus
    ("distmesh", {"max_iter": 3}, "not_converged", "max_iter"),          # stopped early: max_iter
    # Δt = 1 with Fscale = 3 blows the bars up at once: the divergence guard stops it (iteration 2)
    ("distmesh", {"deltat": 1.0, "fscale": 3.0, "max_growth": 1.01}, "not_converged", "diverged"),
])
def test_grid_rows_carry_their_flags(method, params, flag, stop):
    cfg = config_from_dict({"grid": {"phantoms": ["torus"], "n": 40}, "methods": [{"name": method, "params": params}],
                            "metrics": {"n_samples": 2000}})
    cfg.validate()
    row = run_cell(expand_grid(cfg)[0]).row.to_dict()
    assert flag in row["flags"].split(";"), (row["status"], row["error"], row["flags"])
    if stop is not None:
        assert row["stop_reason"] == stop


def test_poisson_drops_the_inner_surface_of_nested_spheres(tmp_path):
    """A hollow ball (an outer sphere and an inward-facing inner one) as a mesh phantom: screened Poisson keeps
    one surface — flagged dropped_components — while marching cubes keeps both."""
    import trimesh

    outer = trimesh.creation.icosphere(3, radius=1.4)
    inner = trimesh.creation.icosphere(3, radius=0.7)
    inner.invert()
    path = tmp_path / "shell.ply"
    trimesh.util.concatenate([outer, inner]).export(path)
    cfg = config_from_dict({"grid": {"phantoms": [f"mesh:{path}"], "n": 40},
                            "methods": [{"name": "poisson"}, {"name": "marching_cubes"}],
                            "metrics": {"n_samples": 2000}})
    cfg.validate()
    rows = {c.label: run_cell(c).row.to_dict() for c in expand_grid(cfg)}
    assert "dropped_components" in rows["poisson"]["flags"].split(";"), rows["poisson"]
    assert rows["marching_cubes"]["flags"] == "" and rows["marching_cubes"]["components"] == 2


def test_a_mesh_missing_a_part_is_flagged_whatever_the_method_reports():
    """One ball of the fused spheres scored against both: a third of the true surface is uncovered."""
    import trimesh

    from bench.metrics import evaluate
    from bench.metrics.flags import result_flags
    from phantoms import get_phantom

    ph = get_phantom("fused_spheres")
    upper = trimesh.creation.icosphere(subdivisions=4, radius=0.8)
    upper.apply_translation([0, 0, 0.7])
    row = evaluate(upper, ph, 0.05, n_samples=5000)
    assert row["coverage_pct"] < 60 and "missing_parts" in result_flags(row, ph)
    whole = get_phantom("sphere")
    ball = trimesh.creation.icosphere(subdivisions=5, radius=1.0)
    row = evaluate(ball, whole, 0.05, n_samples=5000)
    assert row["coverage_pct"] == 100.0 and "missing_parts" not in result_flags(row, whole)


def test_the_shape_gradient_dropping_one_of_two_balls_is_flagged_missing_parts(tmp_path):
    """Two balls 0.6 apart: the shape gradient's genus-0 start keeps one; the suite's flag says so."""
    import trimesh

    from bench.run.cell import run_cell

    a = trimesh.creation.icosphere(subdivisions=3, radius=0.7)
    b = a.copy()
    a.apply_translation([-0.95, 0, 0])
    b.apply_translation([0.95, 0, 0])
    (a + b).export(str(tmp_path / "two.obj"))
    cell = {"phantom": f"mesh:{tmp_path / 'two.obj'}", "variant": "sdf", "n": 32, "extent": 2.5, "noise": "none",
            "snr_requested": None, "seed": 0, "method": "shape_gradient", "label": "shape_gradient", "params": {},
            "n_samples": 5000, "imports": [], "cell_id": "two"}
    row = run_cell(cell).row.to_dict()
    assert row["status"] in ("ok", "invalid"), row["error"]
    assert row["coverage_pct"] < 70 and "missing_parts" in row["flags"].split(";")


def test_without_truth_a_mesh_whose_inside_disagrees_with_the_data_is_flagged_and_unusable():
    from bench.metrics.flags import MAX_SIGN_ERR_PCT, is_usable

    row = {"status": "ok", "euler": 2, "components": 1, "sign_err_pct": 8.5}   # Poisson filling a vault
    assert result_flags(row, None) == ["inside_disagrees"]
    assert result_flags(dict(row, sign_err_pct=MAX_SIGN_ERR_PCT * 0.99), None) == []
    # with a truth the truth's own flags speak: the sign error alone does not flag
    assert "inside_disagrees" not in result_flags(row, object())
    assert not is_usable(dict(row, flags="inside_disagrees")) and is_usable(dict(row, flags="not_converged"))
    assert not is_usable(dict(row, status="invalid", flags=""))
