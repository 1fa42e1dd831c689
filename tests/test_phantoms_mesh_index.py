"""Tests of ``phantoms.mesh.index``: :class:`TriangleIndex` — the certified closest-point query equals brute
force over every face (near, far, on a box's edges and corners), chunking and candidate splitting change
nothing, and the pseudonormal sign is the exact inside/outside test."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from geometry.closest import closest_point_on_triangles
from phantoms.mesh.index import TriangleIndex


def _brute(v, f, p):
    a, b, c = (np.repeat(v[f[:, k]][None], len(p), 0).reshape(-1, 3) for k in range(3))
    q = np.repeat(p, len(f), 0)
    d2, _, _, _ = closest_point_on_triangles(q, a, b, c)
    return np.sqrt(d2).reshape(len(p), len(f)).min(1)


@pytest.fixture(scope="module")
def bumpy():
    m = trimesh.creation.icosphere(subdivisions=3, radius=1.0)
    v = np.asarray(m.vertices) * (1 + 0.2 * np.sin(3 * np.asarray(m.vertices)[:, :1]))   # not convex
    return v, np.asarray(m.faces)


def test_closest_equals_brute_force_near_and_far(bumpy):
    v, f = bumpy
    rng = np.random.default_rng(1)
    p = rng.normal(size=(300, 3)) * np.concatenate([np.full(150, 0.6), np.full(150, 3.0)])[:, None]
    idx = TriangleIndex(v, f)
    x, d, face, bary, feat = idx.closest(p)
    np.testing.assert_allclose(d, _brute(v, f, p), rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(p - x, axis=1), d, atol=1e-12)
    np.testing.assert_allclose(np.einsum("ij,ijk->ik", bary, v[f[face]]), x, atol=1e-12)
    small = idx.closest(p, chunk=7, max_pairs=50)               # chunking and splitting: the same answer
    np.testing.assert_allclose(small[1], d, rtol=0, atol=1e-15)


def test_sign_is_inside_outside_even_at_a_boxs_edges_and_corners():
    box = trimesh.creation.box(extents=(2.0, 2.0, 2.0))
    idx = TriangleIndex(np.asarray(box.vertices), np.asarray(box.faces))
    p = np.array([[0.0, 0, 0], [0.9, 0.9, 0.9], [1.5, 1.5, 1.5], [1.5, 1.5, 0.0], [0.0, 0.0, 1.2],
                  [0.95, 0.95, 0.0], [-3.0, 0.2, 0.1]])
    x, d, face, _, feat = idx.closest(p)
    np.testing.assert_allclose(d, [1.0, 0.1, np.sqrt(3 * 0.25), np.sqrt(0.5), 0.2, 0.05, 2.0], atol=1e-12)
    np.testing.assert_array_equal(idx.sign(p, x, face, feat), [-1, -1, 1, 1, 1, -1, 1])
    assert idx.upper_bound(p).min() >= 0 and (idx.upper_bound(p) >= d - 1e-12).all()
