"""The compiled kernels (geometry/kernels.py) against their numpy references: the Jacobi-CG on a CSR
matrix, the 1-ring paraboloid fit and the trilinear gather must give the numpy results to rounding."""

from __future__ import annotations

import numpy as np
import pytest

from geometry import compiled, kernels
from geometry.operators import MeshOperators, jacobi_cg
from geometry.sphere import fibonacci_sphere
from geometry.trilinear import trilinear_channels
from phantoms import get_phantom

pytestmark = pytest.mark.skipif(not compiled.AVAILABLE, reason="numba is not installed")


@pytest.fixture(autouse=True)
def kernels_on_small_arrays(monkeypatch):
    """The test meshes are below the size from which the suite uses the kernels: use them anyway."""
    monkeypatch.setattr(compiled, "MIN_SIZE", 0)


@pytest.fixture(scope="module")
def bumpy():
    u, f = fibonacci_sphere(4000, 1.0)
    r = 1.0 + 0.15 * np.sin(3 * u[:, 0]) * np.cos(2 * u[:, 1]) + 0.1 * u[:, 2] ** 2
    x = u * r[:, None]
    ops = MeshOperators(f, len(x))
    return ops, ops.geometry(x)


@pytest.mark.parametrize("warm", [False, True])
def test_cg_kernel_equals_numpy_cg(bumpy, warm):
    ops, geo = bumpy
    s = 0.05
    M = geo.vertex_areas
    K = ops.stiffness(geo)
    A, diag = ops.h1_matrix(geo, s, K)
    np.testing.assert_array_equal(diag, M + s * ops.stiffness_diagonal(K))
    rng = np.random.default_rng(1)
    b = M * rng.normal(size=len(M))
    x0 = rng.normal(size=len(M)) if warm else None
    ref = jacobi_cg(lambda p: M * p + s * (K @ p), b, diag, x0=x0, rtol=1e-6, maxiter=300)   # numpy
    got = jacobi_cg(A, b, diag, x0=x0, rtol=1e-6, maxiter=300)                               # kernel
    assert got[1] == ref[1] > 5
    np.testing.assert_allclose(got[0], ref[0], rtol=0, atol=1e-11 * np.abs(ref[0]).max())
    assert got[2] == pytest.approx(ref[2], rel=1e-8)
    assert jacobi_cg(A, np.zeros_like(b), diag)[1:] == (0, 0.0)


@pytest.mark.parametrize("linear", [True, False])
def test_curvature_kernel_equals_numpy_fit(bumpy, linear):
    ops, geo = bumpy
    H0, K0 = ops.curvature(geo, linear=linear, reference=True)
    H1, K1 = ops.curvature(geo, linear=linear)
    np.testing.assert_allclose(H1, H0, rtol=1e-12, atol=0)
    np.testing.assert_allclose(K1, K0, rtol=1e-12, atol=0)


def test_curvature_kernel_flags_the_same_degenerate_fits():
    # a flat fan (all ring points in the tangent plane) and a vertex with fewer than 3 neighbours
    x = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [-1, 0, 0], [0, -1, 0], [0, 0, 1.0]])
    f = np.array([[0, 1, 2], [0, 2, 3], [0, 3, 4], [0, 4, 1], [5, 2, 1], [5, 3, 2], [5, 4, 3], [5, 1, 4]])
    ops = MeshOperators(f, len(x))
    geo = ops.geometry(x)
    for linear in (True, False):
        H0, K0 = ops.curvature(geo, linear=linear, reference=True)
        H1, K1 = ops.curvature(geo, linear=linear)
        np.testing.assert_array_equal(np.isnan(H1), np.isnan(H0))
        np.testing.assert_allclose(H1, H0, rtol=1e-12, atol=1e-15)
        np.testing.assert_allclose(K1, K0, rtol=1e-12, atol=1e-15)


@pytest.mark.parametrize("order", [0, 1, 2])
def test_trilinear_kernel_equals_numpy_gather(order):
    vol = get_phantom("ellipsoid").volume(n=24)
    ch = vol.channels(order)
    flat = ch.reshape(-1, ch.shape[-1])
    n = np.asarray(vol.shape)
    rng = np.random.default_rng(2)
    idx = rng.uniform(0, 1, size=(3, 5000)) * (n[:, None] - 1)
    idx[:, :6] = np.array([[0, 0, 0], n - 1, [0, n[1] - 1, 0], [n[0] - 1, 0, 0.5], [0.5, 0.5, n[2] - 1],
                           [1, 2, 3]], float).T                     # corners and faces of the box
    ref = trilinear_channels(flat, vol.shape, idx, reference=True)
    got = trilinear_channels(flat, vol.shape, idx)
    np.testing.assert_allclose(got, ref, rtol=1e-14, atol=1e-14 * np.abs(ref).max())
    bad = idx.copy()
    bad[1, 7] = np.nan
    for reference in (True, False):
        with pytest.raises(IndexError):
            trilinear_channels(flat, vol.shape, bad, reference=reference)


def test_geometry_kernels_equal_the_numpy_geometry(bumpy):
    ops, geo = bumpy
    ref = ops.geometry(geo.vertices, reference=True)
    got = ops.geometry(geo.vertices)
    for name in ("cross_t", "normals_t", "face_areas", "centroids_t", "vertex_areas", "vertex_normals_t",
                 "corners_t", "edges_t", "basis"):
        np.testing.assert_allclose(getattr(got, name), getattr(ref, name), rtol=1e-14, atol=1e-15,
                                   err_msg=name)


def test_ring_mean_kernel_equals_numpy(bumpy):
    ops, geo = bumpy
    np.testing.assert_allclose(ops.ring_mean_t(geo.vertices_t), ops.ring_mean_t(geo.vertices_t, reference=True),
                               rtol=1e-14, atol=1e-15)


def test_trilinear_reads_only_the_first_channels_when_asked_equal_to_a_copy_of_them():
    from geometry.trilinear import trilinear_channels

    rng = np.random.default_rng(5)
    flat = rng.normal(size=(6 * 7 * 8, 10))
    idx = np.stack([rng.uniform(0, 5, 2000), rng.uniform(0, 6, 2000), rng.uniform(0, 7, 2000)])
    full = kernels.trilinear(flat, (6, 7, 8), idx)
    first4 = kernels.trilinear(flat, (6, 7, 8), idx, 4)
    assert first4.shape == (4, 2000) and np.array_equal(first4, full[:4])
    assert np.array_equal(first4, kernels.trilinear(np.ascontiguousarray(flat[:, :4]), (6, 7, 8), idx))
    np.testing.assert_allclose(trilinear_channels(flat, (6, 7, 8), idx, channels=4, reference=True), first4,
                               rtol=1e-13, atol=1e-13)
    with pytest.raises(ValueError, match="channels"):
        kernels.trilinear(flat, (6, 7, 8), idx, 11)
