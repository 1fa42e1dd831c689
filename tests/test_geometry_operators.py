"""P1 operators (geometry/operators.py) and the initial Fibonacci sphere (geometry/sphere.py)."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp
import trimesh

from geometry.curvature import paraboloid_curvature
from geometry.mesh import lumped_vertex_areas, vertex_normals
from geometry.operators import (
    MeshOperators,
    cotangent_stiffness,
    divergence,
    face_gradient,
    face_gradient_basis,
    gradient_operator,
    jacobi_cg,
    lumped_mass,
)
from geometry.sphere import fibonacci_points, fibonacci_sphere


@pytest.fixture(scope="module")
def bumpy():
    """A closed, irregular, non-convex test mesh (a Fibonacci sphere with a smooth radial bump)."""
    u, f = fibonacci_sphere(1896, 1.0)
    r = 1.0 + 0.15 * np.sin(3 * u[:, 0]) * np.cos(2 * u[:, 1]) + 0.1 * u[:, 2] ** 2
    return u * r[:, None], f


# ---------------------------------------------------------------------------- the initial sphere
def test_paper_sphere_has_1896_vertices_and_3788_triangles():
    v, f = fibonacci_sphere()
    assert v.shape == (1896, 3) and f.shape == (3788, 3)
    np.testing.assert_allclose(np.linalg.norm(v, axis=1), 2.0, rtol=0, atol=1e-12)
    m = trimesh.Trimesh(v, f, process=False)
    assert m.is_watertight and m.is_winding_consistent and m.euler_number == 2
    assert m.volume > 0  # outward
    # every face normal points away from the centre
    assert (np.einsum("ij,ij->i", m.face_normals, m.triangles_center) > 0).all()


@pytest.mark.parametrize("n", [12, 100, 7584])
def test_sphere_is_configurable(n):
    c = np.array([0.3, -0.2, 0.5])
    v, f = fibonacci_sphere(n, radius=0.7, center=c)
    assert len(v) == n and len(f) == 2 * n - 4
    np.testing.assert_allclose(np.linalg.norm(v - c, axis=1), 0.7, atol=1e-12)
    m = trimesh.Trimesh(v, f, process=False)
    assert m.is_watertight and m.volume > 0


def test_sphere_bad_arguments():
    with pytest.raises(ValueError):
        fibonacci_points(3)
    with pytest.raises(ValueError):
        fibonacci_sphere(100, radius=-1.0)


# ---------------------------------------------------------------------------- stiffness and mass
def test_stiffness_is_symmetric_psd_with_zero_row_sums(bumpy):
    v, f = bumpy
    K = cotangent_stiffness(v, f)
    assert abs(K - K.T).max() < 1e-12
    np.testing.assert_allclose(K @ np.ones(len(v)), 0.0, atol=1e-12)
    rng = np.random.default_rng(0)
    u = rng.standard_normal(len(v))
    assert u @ (K @ u) > 0
    # off-diagonal entries are −(cot α + cot β)/2: check one edge against the angles directly
    i, j = f[0, 0], f[0, 1]
    faces_ij = [face for face in f if i in face and j in face]
    cots = []
    for face in faces_ij:
        k = [w for w in face if w not in (i, j)][0]
        a, b = v[i] - v[k], v[j] - v[k]
        cots.append(np.dot(a, b) / np.linalg.norm(np.cross(a, b)))
    assert K[i, j] == pytest.approx(-0.5 * sum(cots), rel=1e-12)


def test_dirichlet_energy_identity(bumpy):
    """uᵀKu = Σ_f a_f |∇u|_f² for any vertex function u."""
    v, f = bumpy
    rng = np.random.default_rng(1)
    u = rng.standard_normal(len(v))
    K = cotangent_stiffness(v, f)
    g = face_gradient(v, f, u)
    a = trimesh.Trimesh(v, f, process=False).area_faces
    assert u @ (K @ u) == pytest.approx(float((a * (g * g).sum(1)).sum()), rel=1e-10)


def test_lumped_mass_sums_to_area(bumpy):
    v, f = bumpy
    M = lumped_mass(v, f)
    assert M.diagonal().sum() == pytest.approx(trimesh.Trimesh(v, f, process=False).area, rel=1e-12)
    np.testing.assert_allclose(M.diagonal(), lumped_vertex_areas(v, f))


# ---------------------------------------------------------------------------- gradient and divergence
def test_face_gradient_of_a_linear_function_is_its_tangential_part(bumpy):
    v, f = bumpy
    c = np.array([0.3, -1.2, 0.7])
    g = face_gradient(v, f, v @ c)
    n = trimesh.Trimesh(v, f, process=False).face_normals
    expected = c - (n @ c)[:, None] * n
    np.testing.assert_allclose(g, expected, atol=1e-10)
    # the basis sums to zero on every face (constants have no gradient)
    np.testing.assert_allclose(face_gradient_basis(v, f).sum(1), 0.0, atol=1e-9)
    # the sparse operator agrees
    D = gradient_operator(v, f)
    np.testing.assert_allclose((D @ (v @ c)).reshape(-1, 3), g, atol=1e-10)


def test_divergence_is_the_negative_transpose_of_the_gradient(bumpy):
    """Σ_i A_i u_i (div X)_i = −Σ_f a_f X_f·(∇u)_f, and div ∇u = −M⁻¹Ku."""
    v, f = bumpy
    rng = np.random.default_rng(2)
    u = rng.standard_normal(len(v))
    X = rng.standard_normal((len(f), 3))
    A = lumped_vertex_areas(v, f)
    a = trimesh.Trimesh(v, f, process=False).area_faces
    lhs = float((A * u * divergence(v, f, X)).sum())
    rhs = -float((a * (X * face_gradient(v, f, u)).sum(1)).sum())
    assert lhs == pytest.approx(rhs, rel=1e-10)
    np.testing.assert_allclose(divergence(v, f, face_gradient(v, f, u)),
                               -(cotangent_stiffness(v, f) @ u) / A, rtol=1e-9, atol=1e-9)
    # the normal component of X does not count
    n = trimesh.Trimesh(v, f, process=False).face_normals
    np.testing.assert_allclose(divergence(v, f, X + 3.0 * n), divergence(v, f, X), atol=1e-9)


def test_divergence_converges_on_a_sphere():
    """div_Γ ∇_Γ z = Δ_Γ z = −2z/R² on a sphere of radius R (∇_Γ z = e_z − n_z n, a tangent field).

    Pointwise, div (like the cotangent Laplacian) is only first-order on irregular meshes (~5 % RMS at
    1,896 vertices); weighted by a smooth function it converges at second order: Σ A_i z_i (div X)_i →
    ∫ z Δz = −8πR²/3.
    """
    errs, rms = [], []
    R = 1.3
    for n in (1896, 7584):
        v, f = fibonacci_sphere(n, R)
        nf = trimesh.Trimesh(v, f, process=False).face_normals
        X = np.array([0.0, 0.0, 1.0]) - nf[:, 2:3] * nf
        d = divergence(v, f, X)
        A = lumped_vertex_areas(v, f)
        errs.append(abs((A * v[:, 2] * d).sum() / (-8 * np.pi * R ** 2 / 3) - 1))
        rms.append(np.sqrt(np.mean((d + 2 * v[:, 2] / R ** 2) ** 2)) / (2 / R))
    assert rms[0] < 0.06 and rms[1] < rms[0]
    assert errs[0] < 2e-3 and errs[1] < errs[0] / 3


# ---------------------------------------------------------------------------- MeshOperators fast paths
def test_mesh_operators_agree_with_the_plain_functions(bumpy):
    v, f = bumpy
    ops = MeshOperators(f, len(v))
    geo = ops.geometry(v)
    assert abs(ops.stiffness(geo) - cotangent_stiffness(v, f)).max() < 1e-12
    np.testing.assert_allclose(ops.stiffness_diagonal(ops.stiffness(geo)), cotangent_stiffness(v, f).diagonal())
    np.testing.assert_allclose(geo.vertex_areas, lumped_vertex_areas(v, f), rtol=1e-12)
    np.testing.assert_allclose(geo.vertex_normals, vertex_normals(v, f), atol=1e-12)
    np.testing.assert_allclose(geo.basis, face_gradient_basis(v, f), atol=1e-10)
    X = np.random.default_rng(3).standard_normal((len(f), 3))
    np.testing.assert_allclose(ops.divergence(geo, X), divergence(v, f, X), rtol=1e-9, atol=1e-9)
    ring_mean = ops.ring_mean(v)
    i = 17
    nbrs = ops.ring[i][ops.ring[i] >= 0]
    np.testing.assert_allclose(ring_mean[i], v[nbrs].mean(0))


def _lstsq_curvature(v, normals, ring, linear):
    """Oracle: the paraboloid fit vertex by vertex with np.linalg.lstsq, in a frame built another way
    (Gram–Schmidt against the coordinate axis least aligned with the normal)."""
    H = np.full(len(v), np.nan)
    K = np.full(len(v), np.nan)
    for i in range(len(v)):
        nb = ring[i][ring[i] >= 0]
        n = normals[i]
        e = np.eye(3)[np.argmin(np.abs(n))]
        t1 = e - (e @ n) * n
        t1 /= np.linalg.norm(t1)
        t2 = np.cross(n, t1)
        d = v[nb] - v[i]
        u, w, z = d @ t1, d @ t2, d @ n
        cols = [0.5 * u * u, u * w, 0.5 * w * w] + ([u, w] if linear and len(nb) >= 5 else [])
        c = np.linalg.lstsq(np.stack(cols, 1), z, rcond=None)[0]
        A, B, C = c[:3]
        fx, fy = (c[3], c[4]) if len(c) == 5 else (0.0, 0.0)
        g = 1.0 + fx * fx + fy * fy
        H[i] = -((1 + fy * fy) * A - 2 * fx * fy * B + (1 + fx * fx) * C) / (2.0 * g ** 1.5)
        K[i] = (A * C - B * B) / (g * g)
    return H, K


@pytest.mark.parametrize("linear", [True, False])
def test_closed_form_curvature_equals_a_direct_least_squares_fit(bumpy, linear):
    v, f = bumpy
    ops = MeshOperators(f, len(v))
    geo = ops.geometry(v)
    H1, K1 = ops.curvature(geo, linear=linear)
    H2, K2 = paraboloid_curvature(v, geo.vertex_normals, ops.ring, linear=linear)
    H3, K3 = _lstsq_curvature(v, geo.vertex_normals, ops.ring, linear)
    np.testing.assert_allclose(H1, H2, rtol=1e-12, atol=1e-12)      # the 1-ring path and the general one
    np.testing.assert_allclose(K1, K2, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(H2, H3, rtol=1e-8, atol=1e-8)        # against the oracle
    np.testing.assert_allclose(K2, K3, rtol=1e-7, atol=1e-7)


def test_fast_curvature_flags_degenerate_fits():
    v, f = fibonacci_sphere(100, 1.0)
    v = v.copy()
    ops = MeshOperators(f, len(v))
    ring = ops.ring[0][ops.ring[0] >= 0]
    v[ring] = v[0]              # collapse the 1-ring onto the vertex: the fit is undetermined
    H, K = ops.curvature(ops.geometry(v))
    assert np.isnan(H[0]) and np.isnan(K[0])


def test_jacobi_cg_solves_an_spd_system(bumpy):
    v, f = bumpy
    K = cotangent_stiffness(v, f)
    m = lumped_vertex_areas(v, f)
    A = sp.diags(m) + 0.1 * K
    b = np.random.default_rng(4).standard_normal(len(v))
    x, it, res = jacobi_cg(lambda p: A @ p, b, A.diagonal(), rtol=1e-10, maxiter=1000)
    assert res <= 1e-10 and 0 < it < 1000
    np.testing.assert_allclose(A @ x, b, atol=1e-8 * np.linalg.norm(b))
    # a warm start at the solution needs no iteration; a zero right-hand side gives zero
    x2, it2, _ = jacobi_cg(lambda p: A @ p, b, A.diagonal(), x0=x, rtol=1e-8)
    assert it2 == 0
    z, it3, _ = jacobi_cg(lambda p: A @ p, np.zeros(len(v)), A.diagonal())
    assert it3 == 0 and not z.any()
