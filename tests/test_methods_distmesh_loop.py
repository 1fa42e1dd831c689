"""Tests of ``methods.distmesh_loop``: the compiled DistMesh iterations — :func:`flip_candidates` equals the
numpy flip test, its compiled trilinear sample equals the one trilinear reference, and a DistMesh run
through :func:`relax` (``compiled=True``) ends where the numpy iterations end, to rounding."""

from __future__ import annotations

import numpy as np
import pytest

from geometry import kernels
from geometry.trilinear import trilinear_channels
from methods import distmesh_loop
from methods.distmesh import DistMesh, _flip_candidates
from phantoms import get_phantom

pytestmark = pytest.mark.skipif(not distmesh_loop.AVAILABLE, reason="numba is not installed")


def test_flip_candidates_equal_the_numpy_flip_test():
    rng = np.random.default_rng(0)
    p = rng.normal(size=(400, 3))
    p[:, 2] *= 0.1                                              # nearly flat quads: flips are common
    a, b, c, d = (rng.integers(0, 400, 3000) for _ in range(4))
    ok = (a != b) & (a != c) & (a != d) & (b != c) & (b != d) & (c != d)
    a, b, c, d = a[ok], b[ok], c[ok], d[ok]
    cand, improve = distmesh_loop.flip_candidates(p, a, b, c, d, 0.9, 0.01)
    ref_cand, ref_improve = _flip_candidates(p, a, b, c, d, 0.9, 0.01)
    assert 0 < cand.sum() < len(cand)
    np.testing.assert_array_equal(cand, ref_cand)
    np.testing.assert_allclose(improve[cand], ref_improve[cand], rtol=1e-9, atol=1e-12)


def test_a_thin_quad_flips_to_its_short_diagonal():
    # a rhombus split along its long diagonal (a, b): two slivers; the short diagonal (c, d) is much better
    p = np.array([[-1.0, 0, 0], [1.0, 0, 0], [0, 0.2, 0], [0, -0.2, 0]])
    a, b, c, d = (np.array([i]) for i in (0, 1, 2, 3))
    cand, improve = distmesh_loop.flip_candidates(p, b, a, c, d, 0.9, 0.01)
    assert cand[0] and improve[0] > 0.3
    p_good = np.array([[-0.2, 0, 0], [0.2, 0, 0], [0, 1.0, 0], [0, -1.0, 0]])   # (a, b) already the short diagonal
    cand, _ = distmesh_loop.flip_candidates(p_good, b, a, c, d, 0.9, 0.01)
    assert not cand[0]


def test_the_compiled_sample_is_the_trilinear_reference_clamped_onto_the_grid():
    """``_sample`` inlines the compiled trilinear sum (geometry.kernels.trilinear_point) into the jitted loop: bit
    for bit the compiled kernel's sum at the clamped grid indices, and geometry.trilinear.trilinear_channels'
    numpy reference to rounding."""
    vol = get_phantom("ellipsoid").volume(n=20)
    sampler = vol.sampler(1)
    flat, shape = sampler.flat, np.asarray(sampler.shape)
    origin, spacing = np.asarray(sampler.origin, float), np.asarray(sampler.spacing, float)
    rng = np.random.default_rng(3)
    pts = rng.uniform(vol.lower - 0.3, vol.upper + 0.3, size=(2000, 3))    # some outside: clamped
    pts[:3] = [vol.lower, vol.upper, (vol.lower + vol.upper) / 2]
    got = np.empty((len(pts), 4))
    for i, (x, y, z) in enumerate(pts):
        distmesh_loop._sample(flat, *map(int, shape), origin, spacing, x, y, z, got[i])
    idx_t = np.ascontiguousarray(np.clip((pts - origin) / spacing, 0.0, shape - 1).T)
    np.testing.assert_array_equal(got.T, kernels.trilinear(flat, shape, idx_t))
    ref = trilinear_channels(flat, shape, idx_t, reference=True)
    np.testing.assert_allclose(got.T, ref, rtol=1e-14, atol=1e-14 * np.abs(ref).max())


def test_the_compiled_iterations_end_where_the_numpy_ones_end():
    vol = get_phantom("sphere").volume(n=24)
    fast = DistMesh(max_iter=40, compiled=True).reconstruct(vol)
    slow = DistMesh(max_iter=40, compiled=False).reconstruct(vol)
    assert fast.info["iterations"] == slow.info["iterations"]
    assert fast.info["stop_reason"] == slow.info["stop_reason"]
    np.testing.assert_array_equal(fast.mesh.faces, slow.mesh.faces)
    np.testing.assert_allclose(fast.mesh.vertices, slow.mesh.vertices, atol=1e-8)
    assert fast.mesh.is_watertight and fast.mesh.volume > 0
