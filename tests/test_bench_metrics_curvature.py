"""Tests of ``bench.metrics.curvature``: :func:`vertex_curvature` (H = 1/R, K = 1/R² on a sphere, the sign with
``outward``), :func:`curvature_metrics` against a phantom's truth, :func:`constant_curvature_value` and
:func:`roughness_deg` (the dihedral angle of an icosphere, zero on a flat patch)."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from bench.metrics.curvature import constant_curvature_value, curvature_metrics, roughness_deg, vertex_curvature
from geometry import face_normals
from phantoms import get_phantom


@pytest.fixture(scope="module")
def sphere_mesh():
    m = trimesh.creation.icosphere(subdivisions=4, radius=1.0)
    return np.asarray(m.vertices), np.asarray(m.faces)


def test_vertex_curvature_of_the_unit_sphere(sphere_mesh):
    v, f = sphere_mesh
    H, K, n = vertex_curvature(v, f, spacing=0.05)
    np.testing.assert_allclose(H, 1.0, atol=0.01)
    np.testing.assert_allclose(K, 1.0, atol=0.02)
    assert (np.einsum("ij,ij->i", n, v) > 0.99).all()
    H_in, _, n_in = vertex_curvature(v, f, spacing=0.05, outward=False)
    np.testing.assert_allclose(H_in, -H, atol=1e-9) and np.testing.assert_allclose(n_in, -n)


def test_curvature_metrics_against_the_sphere_phantoms_truth(sphere_mesh):
    v, f = sphere_mesh
    ph = get_phantom("sphere")
    H, K, _ = vertex_curvature(v, f, spacing=0.05)
    out = curvature_metrics(H, K, ph.truth(v), ph)
    assert set(out) == {"H_rms_err", "H_max_err", "K_rms_err", "H_std"}
    assert out["H_rms_err"] < 0.01 and out["H_max_err"] < 0.02 and out["K_rms_err"] < 0.02
    assert out["H_rms_err"] <= out["H_max_err"]
    assert out["H_std"] == pytest.approx(np.std(H))
    bumped = curvature_metrics(H + 0.1, K, ph.truth(v), ph)
    assert bumped["H_rms_err"] == pytest.approx(np.sqrt(np.mean((H + 0.1 - 1.0) ** 2)))
    only_std = curvature_metrics(np.array([1.0, 2.0, np.nan]), np.zeros(3))
    assert only_std == {"H_std": pytest.approx(0.5)}


def test_constant_curvature_value():
    ok = np.ones(3, bool)
    assert constant_curvature_value(get_phantom("sphere"), np.zeros(3), ok) == pytest.approx(1.0)
    assert constant_curvature_value(get_phantom("ellipsoid"), np.ones(3), ok) is None

    class Unnamed:
        name = "mine"

    assert constant_curvature_value(Unnamed(), np.array([0.5, 0.5, 9.0]), np.array([True, True, False])) == 0.5
    assert constant_curvature_value(Unnamed(), np.array([0.5, 0.6]), np.ones(2, bool)) is None


def test_roughness_of_an_icosahedron_is_its_dihedral_angle_and_a_plane_has_none():
    ico = trimesh.creation.icosahedron()
    v, f = np.asarray(ico.vertices), np.asarray(ico.faces)
    # the icosahedron's dihedral angle is 138.19°: neighbouring face normals 41.81° apart
    assert roughness_deg(v, f, face_normals(v, f)) == pytest.approx(180 - 138.1897, abs=1e-3)
    assert np.isnan(roughness_deg(v, f, face_normals(v, f), vertex_ok=np.zeros(len(v), bool)))
    sq = np.array([[0.0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]])   # a flat square of two triangles
    flat = np.array([[0, 1, 2], [0, 2, 3]])
    assert roughness_deg(sq, flat, face_normals(sq, flat)) == pytest.approx(0.0, abs=1e-9)
    folded = sq.copy()
    folded[3, 2] = 1.0                                          # lift one corner: normals arctan(√2) = 54.7° apart
    assert roughness_deg(folded, flat, face_normals(folded, flat)) == pytest.approx(
        np.degrees(np.arctan2(np.sqrt(2), 1)), abs=1e-6)
