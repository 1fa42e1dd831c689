"""Tests of ``geometry.curvature``: the tangent frames and the paraboloid fit (:func:`paraboloid_curvature`,
:func:`radius_curvature`) against the analytic mean and Gaussian curvature of spheres, a cylinder and an
exact paraboloid."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from geometry.curvature import paraboloid_curvature, radius_curvature, tangent_frames
from geometry.mesh import one_ring, vertex_normals


def test_tangent_frames_are_orthonormal_for_every_normal_including_minus_z():
    rng = np.random.default_rng(0)
    n = rng.normal(size=(500, 3))
    n = np.vstack([n, [[0, 0, -1], [0, 0, 1], [1, 0, 0]]])
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    t1, t2 = tangent_frames(n)
    for a, b in ((t1, t2), (t1, n), (t2, n)):
        np.testing.assert_allclose(np.einsum("ij,ij->i", a, b), 0.0, atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(t1, axis=1), 1.0)
    np.testing.assert_allclose(np.linalg.norm(t2, axis=1), 1.0)
    np.testing.assert_allclose(np.einsum("ij,ij->i", np.cross(t1, t2), n), 1.0)   # right-handed


@pytest.mark.parametrize("R", [0.5, 2.0])
def test_paraboloid_curvature_of_a_sphere_is_one_over_r_and_one_over_r_squared(R):
    m = trimesh.creation.icosphere(subdivisions=4, radius=R)
    v, f = np.asarray(m.vertices), np.asarray(m.faces)
    H, K = paraboloid_curvature(v, vertex_normals(v, f), one_ring(f, len(v)))
    np.testing.assert_allclose(H * R, 1.0, atol=0.01)          # outward normals: a sphere has H > 0
    np.testing.assert_allclose(K * R * R, 1.0, atol=0.02)


def test_paraboloid_fit_is_exact_on_a_paraboloid():
    """Neighbours on z = (a x² + 2b xy + c y²)/2 around a vertex at the origin with normal +z: H = (a + c)/2,
    K = ac − b² (the sign of H as seen from the side the normal points away from: inward bending positive)."""
    a, b, c = 1.2, 0.3, -0.4
    t = np.linspace(0, 2 * np.pi, 9)[:-1]
    ring = np.column_stack([0.05 * np.cos(t), 0.05 * np.sin(t)])
    ring = np.vstack([ring, 0.1 * ring / 0.05])
    z = 0.5 * (a * ring[:, 0] ** 2 + 2 * b * ring[:, 0] * ring[:, 1] + c * ring[:, 1] ** 2)
    v = np.vstack([[0.0, 0.0, 0.0], np.column_stack([ring, z])])
    normals = np.tile([0.0, 0.0, 1.0], (len(v), 1))
    nb = np.full((len(v), len(v) - 1), -1)
    nb[0] = np.arange(1, len(v))
    for linear in (True, False):
        H, K, coeffs = paraboloid_curvature(v, normals, nb, linear=linear, return_coeffs=True, rows=[0])
        assert abs(H[0]) == pytest.approx(abs(a + c) / 2, rel=1e-6)
        assert K[0] == pytest.approx(a * c - b * b, rel=1e-6)
    assert np.isnan(paraboloid_curvature(v, normals, nb)[0][1:]).all()    # no neighbours: NaN


def test_radius_curvature_of_a_cylinder():
    """An open tube with every vertex on the cylinder of radius r: H = 1/(2r), K = 0 away from its rims."""
    r, nt, nz = 0.8, 96, 61
    t, z = np.meshgrid(np.linspace(0, 2 * np.pi, nt, endpoint=False), np.linspace(-3, 3, nz), indexing="ij")
    v = np.column_stack([r * np.cos(t).ravel(), r * np.sin(t).ravel(), z.ravel()])
    i, j = np.meshgrid(np.arange(nt), np.arange(nz - 1), indexing="ij")
    a, b = (i * nz + j).ravel(), (((i + 1) % nt) * nz + j).ravel()
    f = np.vstack([np.column_stack([a, b, b + 1]), np.column_stack([a, b + 1, a + 1])])
    H, K = radius_curvature(v, f, 0.15)
    middle = np.abs(v[:, 2]) < 2.0
    np.testing.assert_allclose(H[middle], 1 / (2 * r), rtol=0.01)
    np.testing.assert_allclose(K[middle], 0.0, atol=0.01)


def test_radius_curvature_compiled_and_numpy_agree():
    m = trimesh.creation.icosphere(subdivisions=3, radius=1.5)
    v = np.asarray(m.vertices)
    H0, K0 = radius_curvature(v, m.faces, 0.3, compiled=False)
    H1, K1 = radius_curvature(v, m.faces, 0.3, compiled=True)
    np.testing.assert_allclose(H1, H0, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(K1, K0, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(H0, 1 / 1.5, rtol=0.01)
