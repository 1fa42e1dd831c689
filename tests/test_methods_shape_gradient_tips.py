"""Tests of ``methods.shape_gradient.tips``: the tip extension moves sharply convex vertices out to the samples'
empty balls, no farther, and leaves smooth, concave and deep-inside vertices alone."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from geometry.operators import MeshOperators
from methods.shape_gradient import GridSampler, ShapeGradient
from methods.shape_gradient.tips import _gradient_scale, extend_tips
from phantoms import get_phantom


@pytest.fixture(scope="module")
def needle():
    """A prolate ellipsoid (semi-axes 1, 0.2, 0.2) at N = 32 and the flow's final mesh without the extension (nor
    the reach to the samples, which moves the same tip), its edges 0.4 voxel: a tip resolved finely enough for the
    extension's curvature test to find it, whatever the remesh cadence left there."""
    ph = get_phantom("ellipsoid", axes=(1.0, 0.2, 0.2))
    vol = ph.volume(n=32)
    m = ShapeGradient(extend_tips=False, reach_samples=False, edge_length=0.4).reconstruct(vol).mesh
    x, f = np.asarray(m.vertices, float), np.asarray(m.faces)
    return ph, vol, x, f, MeshOperators(f, len(x))




def test_a_needle_tip_moves_out_towards_the_true_tip_and_not_past_it(needle):
    """The sampled zero set of the needle stops 0.18 short of its tip (x = 1), and the flow with it; the
    extension brings the tip out, not past it, and the mesh nearer the true surface (Hausdorff)."""
    ph, vol, x, f, ops = needle
    out, stats = extend_tips(GridSampler(vol), ops, x, vol.h)
    assert stats["moved"] > 0 and stats["max_move_voxels"] <= 1.0 + 1e-9
    assert 1.0 - x[:, 0].max() > vol.h                             # short of the tip by more than a voxel ...
    assert x[:, 0].max() + 0.5 * vol.h < out[:, 0].max() <= 1.0 + 0.25 * vol.h   # ... now nearer, not past it
    tp = ph.sample_surface(20_000, seed=0)[0]

    def hausdorff(v):
        _, d, _ = trimesh.proximity.ProximityQuery(trimesh.Trimesh(v, f, process=False)).on_surface(tp)
        return max(d.max(), np.abs(ph.distance(v)).max())
    assert hausdorff(out) < 0.8 * hausdorff(x)


def test_moved_vertices_stay_out_of_every_outside_samples_empty_ball(needle):
    _, vol, x, f, ops = needle
    out, _ = extend_tips(GridSampler(vol), ops, x, vol.h, max_phi=np.inf)   # the balls alone
    moved = np.flatnonzero(np.any(out != x, axis=1))
    assert len(moved) > 0
    v = vol.values
    d = v                                                   # a distance volume: the scale is 1 ...
    assert abs(_gradient_scale(v, vol.origin, vol.spacing, x + 1.5 * vol.h * ops.geometry(x).vertex_normals)
               - 1.0) < 0.05                                # ... within 5 %: the gaps allow that much
    grid = np.stack(np.meshgrid(*[vol.origin[k] + vol.spacing[k] * np.arange(v.shape[k]) for k in range(3)],
                                indexing="ij"), -1)
    for i in moved:
        near = np.linalg.norm(grid - x[i], axis=-1) < 1.8 * vol.h   # inside the 4×4×4 block around x[i]
        q, r = grid[near & (v > 0)], d[near & (v > 0)]
        gap = np.linalg.norm(q - out[i], axis=1) - r
        # outside every ball (a moved vertex started outside them; vertices inside one do not move)
        assert gap.min() >= -0.05 * r.max() - 1e-9


def test_smooth_and_deep_inside_vertices_do_not_move():
    vol = get_phantom("sphere").volume(n=32)                       # radius 1: mean curvature h·H ≈ 0.16
    ico = trimesh.creation.icosphere(4, radius=1.0)               # edges ≈ half a voxel, as the flow's mesh
    x, ops = np.asarray(ico.vertices, float), MeshOperators(np.asarray(ico.faces), len(ico.vertices))
    out, stats = extend_tips(GridSampler(vol), ops, x, vol.h)
    assert stats["candidates"] == 0 and np.array_equal(out, x)
    tiny = trimesh.creation.icosphere(2, radius=0.05)              # deep inside (φ ≈ −6 h), sharply curved
    xs = np.asarray(tiny.vertices, float)
    ops_s = MeshOperators(np.asarray(tiny.faces), len(xs))
    out, stats = extend_tips(GridSampler(vol), ops_s, xs, vol.h)
    assert stats["candidates"] == 0 and np.array_equal(out, xs)


def test_the_flow_reports_it_and_the_paper_preset_has_it_off():
    vol = get_phantom("ellipsoid", axes=(1.0, 0.2, 0.2)).volume(n=32)
    r = ShapeGradient().reconstruct(vol)
    tips = r.info["tips"]
    assert tips["used"] and tips["moved"] > 0 and tips["kept_back"] >= 0 and "rejected" not in tips
    assert r.info["parameters"]["extend_tips"] is True
    assert ShapeGradient(preset="paper").config["extend_tips"] is False


def test_sample_gradients_are_exact_on_a_linear_field_and_clamped_at_the_grid_faces():
    """Central differences of a linear φ = a·p + c are a exactly, at inner and (clamped) boundary indices."""
    from methods.shape_gradient.tips import sample_gradients
    spacing = np.array([0.1, 0.2, 0.05])
    ijk = np.stack(np.meshgrid(*[np.arange(n) for n in (6, 7, 8)], indexing="ij"), -1)
    a = np.array([1.5, -2.0, 0.25])
    v = (ijk * spacing) @ a + 3.0
    idx = np.array([[2, 3, 4], [0, 0, 0], [5, 6, 7]])
    np.testing.assert_allclose(sample_gradients(v, idx, spacing), np.tile(a, (3, 1)), rtol=1e-12)
