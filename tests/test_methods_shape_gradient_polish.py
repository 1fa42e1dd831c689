"""Tests of ``methods.shape_gradient.polish``: the crease polish on the fused spheres' groove and the Newton
projection onto φ = 0."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import trimesh

from _shape_gradient_common import SG, hausdorff, topology
from methods.shape_gradient import ShapeGradient
from phantoms import get_phantom


def test_crease_polish_fills_the_fused_spheres_groove():
    """The flow bridges the concave crease of the fused spheres; the crease polish (default on clean
    volumes) puts a chain of vertices on it (N = 64: ≈ 2.5 h → ≈ 0.6 h), moving only crease-zone vertices."""
    ph = get_phantom("fused_spheres")
    vol = ph.volume(n=64)
    flow = SG(projection="off").prepare(vol)
    flow.run()
    r = flow.result()
    x_flow = flow.state.x
    off = trimesh.Trimesh(x_flow, flow.ops.faces, process=False)
    p = r.info["polish"]
    assert p["used"] and p["crease_edges"] > 0 and p["snapped"] > 0
    moved = np.any(r.mesh.vertices != x_flow, axis=1)
    assert moved.sum() <= p["zone_vertices"]
    z = np.abs(r.mesh.vertices[moved, 2])
    assert z.max() < 0.3                                       # only around the crease (z = 0)
    assert hausdorff(r.mesh, ph) <= 1.0 * vol.h < hausdorff(off, ph)
    assert topology(r.mesh) == {"watertight": True, "euler": 2, "self_intersections": 0}
    assert r.info["polish"]["energy"] > r.info["energy_final"]  # the discrete energy prefers the bridge


def test_crease_polish_does_not_pull_a_convex_tip_in():
    """pymeshlab's airplane at N = 64: at the rounded nose the quadric's point of the 1-ring's planes lies inside
    the tip (towards its centre of curvature); snapping there pulled the nose in by 0.13 h (Hausdorff 0.85 →
    0.98 h).  A convex vertex is snapped only outwards of its tangent plane, so the tip stays where it was."""
    from geometry.operators import MeshOperators
    from methods.shape_gradient import GridSampler
    from methods.shape_gradient.polish import crease_polish, newton_project

    package = Path(importlib.util.find_spec("pymeshlab").submodule_search_locations[0])
    mesh = package / "tests/sample_meshes/airplane.obj"
    ph = get_phantom(f"mesh:{mesh}")
    vol = ph.volume(n=64)
    flow = ShapeGradient(polish="off", projection="off").prepare(vol)   # the defaults: genus-0 start, remeshing
    flow.run()
    x, faces = flow.state.x, flow.ops.faces
    field, ops = GridSampler(vol), MeshOperators(faces, len(x))
    out, stats = crease_polish(field, ops, x, vol.h)
    assert stats["snapped"] > 0
    before = hausdorff(trimesh.Trimesh(x, faces, process=False), ph)
    assert hausdorff(trimesh.Trimesh(out, faces, process=False), ph) <= before + 0.02 * vol.h
    # the rule itself: every vertex whose crease edges are all convex moved out of (or along) its tangent plane
    xp, nu = newton_project(field, x, max_step=2.0 * vol.h)
    e = ops.edges
    crease = np.einsum("ed,ed->e", nu[e[:, 0]], nu[e[:, 1]]) < np.cos(np.radians(45.0))
    concave_edge = np.einsum("ed,ed->e", nu[e[:, 0]] - nu[e[:, 1]], xp[e[:, 0]] - xp[e[:, 1]]) < 0
    concave = np.zeros(len(x), bool)
    concave[e[crease & concave_edge].ravel()] = True
    snapped = np.any(out != xp, axis=1) & np.any(out != x, axis=1)
    outward = np.einsum("ij,ij->i", nu, out - xp)
    assert snapped.any() and (outward[snapped & ~concave] >= 0.0).all()


def test_newton_project_puts_points_on_the_sphere_and_returns_the_unit_normal():
    from methods.shape_gradient import GridSampler
    from methods.shape_gradient.polish import newton_project

    vol = get_phantom("sphere").volume(n=32)
    rng = np.random.default_rng(0)
    u = rng.normal(size=(200, 3))
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    x = u * rng.uniform(0.8, 1.2, (200, 1))
    field = GridSampler(vol)
    p, nu = newton_project(field, x, steps=3)
    assert p.shape == x.shape and nu.shape == x.shape
    phi = field.sample_t(np.ascontiguousarray(p.T), 0)[0]
    assert np.abs(phi).max() < 1e-4 * vol.h                   # on the sampled field's zero level set ...
    np.testing.assert_allclose(np.linalg.norm(p, axis=1), 1.0, atol=0.1 * vol.h)   # ... within 0.1 h of the sphere
    np.testing.assert_allclose(np.linalg.norm(nu, axis=1), 1.0, atol=1e-9)
    assert (np.einsum("ij,ij->i", nu, u) > 0.99).all()         # ∇φ of the sphere's SDF: radial, outward
    capped, _ = newton_project(GridSampler(vol), x, steps=1, max_step=0.01)
    assert np.linalg.norm(capped - x, axis=1).max() <= 0.01 + 1e-12
