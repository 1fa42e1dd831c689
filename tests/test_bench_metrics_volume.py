"""Volumetric IoU of the inside regions (bench/metrics/volume.py): known answers."""

from __future__ import annotations

import math

import numpy as np
import pytest
import trimesh

from bench.metrics import evaluate
from bench.metrics.volume import iou
from phantoms import MeshPhantom, get_phantom
from phantoms.analytic import Sphere

H = 0.05


def _sphere_mesh(subdivisions: int = 5, radius: float = 1.0) -> trimesh.Trimesh:
    return trimesh.creation.icosphere(subdivisions=subdivisions, radius=radius)


def _iou(mesh, phantom, seed=0):
    pts, _ = phantom.sample_surface(20_000, seed)
    return iou(np.asarray(mesh.vertices), np.asarray(mesh.faces), phantom, H, pts, seed=seed)


def test_fine_sphere_mesh_has_iou_one_to_its_discretisation():
    """An inscribed icosphere (20,480 faces) bounds V_p < V_s; its exact IoU with the ball is V_p / V_s =
    1 − 5.4e-4.  Only sample points inside the thin shell between the two count against it: about
    (V_s − V_p) / cell volume = 2.3e-3 / (2.2/48)³ ≈ 23 of the ~43.5k in the ball (Poisson σ ≈ 4.8), so the
    estimate is within ± 4σ ≈ ± 19 points = ± 4.5e-4 of V_p / V_s."""
    mesh = _sphere_mesh(5)
    exact = mesh.volume / (4 / 3 * math.pi)
    assert 1 - exact == pytest.approx(5.4e-4, rel=0.02)
    for seed in (0, 1):
        assert _iou(mesh, Sphere(1.0), seed) == pytest.approx(exact, abs=4.5e-4)


def test_two_offset_spheres_give_the_lens_formula():
    """Unit balls with centres d apart: lens volume V_L = π (4r + d)(2r − d)² / 12, IoU = V_L / (2V − V_L)."""
    d = 0.6
    mesh = _sphere_mesh(5)
    mesh.apply_translation([d, 0.0, 0.0])
    V = 4 / 3 * math.pi
    lens = math.pi * (4 + d) * (2 - d) ** 2 / 12
    expected = lens / (2 * V - lens)                         # 0.4418...
    # discretisation: the icosphere is 5.4e-4 smaller than the ball (≈ 2e-4 on this ratio); sampling: the
    # ~8k cells the two surfaces cut decide at most ± √8k ≈ 90 points of the ~51k in the union (± 1.8e-3;
    # jittered sampling does better: within 1e-3 over seeds 0-5)
    assert _iou(mesh, Sphere(1.0)) == pytest.approx(expected, abs=3e-3)
    # disjoint balls: nothing in common
    far = _sphere_mesh(3)
    far.apply_translation([2.5, 0.0, 0.0])
    assert _iou(far, Sphere(1.0)) == 0.0


def test_inward_mesh_bounds_the_same_solid():
    mesh = _sphere_mesh(4)
    flipped = trimesh.Trimesh(mesh.vertices, mesh.faces[:, ::-1], process=False)
    assert _iou(flipped, Sphere(1.0)) == _iou(mesh, Sphere(1.0))


def test_mesh_phantom_against_its_own_mesh_is_exactly_one():
    torus = trimesh.creation.torus(major_radius=1.0, minor_radius=0.35)
    ph = MeshPhantom(torus.vertices, torus.faces)
    assert _iou(trimesh.Trimesh(ph.vertices, ph.faces, process=False), ph) == 1.0


def test_evaluate_reports_iou_for_the_analytic_truth():
    out = evaluate(_sphere_mesh(4), get_phantom("sphere"), H, n_samples=5000)
    assert 0.99 < out["iou"] <= 1.0


def test_an_open_mesh_is_judged_by_the_generalised_winding_number():
    """A sphere with one face removed is not closed: the column count would leak along the hole's columns;
    the generalised winding number still calls its inside inside (IoU as for the closed sphere, ± the hole's
    cells), and the closed-mesh path and the winding-number path agree on the closed sphere."""
    mesh = _sphere_mesh(4)
    pts, _ = Sphere(1.0).sample_surface(20_000, 0)
    v, f = np.asarray(mesh.vertices), np.asarray(mesh.faces)
    closed = iou(v, f, Sphere(1.0), H, pts)
    assert iou(v, f, Sphere(1.0), H, pts, closed=False) == pytest.approx(closed, abs=2e-4)
    assert iou(v, f[1:], Sphere(1.0), H, pts) == pytest.approx(closed, abs=2e-3)
