"""geometry/broadphase.py: exactly the box-overlapping, vertex-disjoint pairs (brute force), and the same
self-intersections as the numpy broad phase of geometry/intersections.py."""

from __future__ import annotations

import numpy as np
import pytest

from geometry import intersections as I
from geometry.broadphase import box_pairs
from geometry.sphere import fibonacci_sphere


def _reference(tri, faces):
    """By brute force over all pairs: closed boxes overlap, no vertex index shared."""
    lo, hi = tri.min(axis=1), tri.max(axis=1)
    i, j = np.triu_indices(len(tri), k=1)
    keep = np.ones(len(i), bool)
    for k in range(3):
        keep &= (lo[i, k] <= hi[j, k]) & (lo[j, k] <= hi[i, k])
    i, j = i[keep], j[keep]
    share = (faces[i][:, :, None] == faces[j][:, None, :]).any(axis=(1, 2))
    return {(int(a), int(b)) for a, b in zip(i[~share], j[~share])}


@pytest.mark.parametrize("seed", range(4))
def test_box_pairs_of_a_triangle_soup(seed):
    rng = np.random.default_rng(seed)
    n = 1500
    centers = rng.uniform(0, 1, (n, 3))
    size = np.where(rng.random(n) < 0.02, 0.3, 0.02)[:, None, None]     # a few huge faces among small ones
    tri = centers[:, None, :] + size * rng.normal(size=(n, 3, 3))
    tri[:5] = tri[:5, :1]                                               # degenerate: points (zero boxes)
    tri[5:10, :, 2] = 0.5                                               # flat in z: boxes that only touch
    faces = rng.integers(0, 800, (n, 3))                                # shared indices, some repeated
    got = box_pairs(tri.min(axis=1), tri.max(axis=1), faces)
    assert np.all(got[:, 0] < got[:, 1])
    assert len({tuple(r) for r in got}) == len(got)                      # each pair once
    assert {(int(a), int(b)) for a, b in got} == _reference(tri, faces)
    # the numpy broad phase (bounding spheres) finds a subset: spheres that touch have boxes that overlap
    lo, hi = tri.min(axis=1), tri.max(axis=1)
    c = I._candidate_pairs(tri)
    box = np.all((lo[c[:, 0]] <= hi[c[:, 1]]) & (lo[c[:, 1]] <= hi[c[:, 0]]), axis=1)
    share = (faces[c[:, 0]][:, :, None] == faces[c[:, 1]][:, None, :]).any(axis=(1, 2))
    assert {(int(a), int(b)) for a, b in np.sort(c[box & ~share], axis=1)} <= _reference(tri, faces)


def test_compiled_and_numpy_self_intersections_agree():
    x, f = fibonacci_sphere(4000, 1.0)
    x = np.array(x)
    rng = np.random.default_rng(0)
    moved = rng.choice(len(x), 80, replace=False)
    x[moved] += rng.normal(0.0, 0.05, (80, 3))                          # crumple a few places
    a = I.self_intersection_pairs(x, f, compiled=False)
    b = I.self_intersection_pairs(x, f, compiled=True)
    assert len(a) > 0
    np.testing.assert_array_equal(np.unique(a, axis=0), np.unique(b, axis=0))


def test_small_inputs():
    assert box_pairs(np.zeros((1, 3)), np.ones((1, 3)), np.array([[0, 1, 2]])).shape == (0, 2)
    lo = np.array([[0.0, 0, 0], [1.0, 1, 1]])
    hi = np.array([[1.0, 1, 1], [2.0, 2, 2]])                          # corners touch: overlapping boxes
    np.testing.assert_array_equal(box_pairs(lo, hi, np.array([[0, 1, 2], [3, 4, 5]])), [[0, 1]])
    assert len(box_pairs(lo, hi, np.array([[0, 1, 2], [2, 4, 5]]))) == 0   # shared vertex index
