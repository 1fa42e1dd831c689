"""Tests of ``phantoms.mesh.closest``: the exact closest point on triangles (against dense sampling) and the
generalised winding number of a closed mesh, the point-segment distance and the per-key argmin."""

from __future__ import annotations

import numpy as np
import trimesh

from phantoms.mesh import closest_point_on_triangles, winding_number
from phantoms.mesh.closest import point_segment_distance, segments_min


def test_closest_point_on_triangles_matches_dense_sampling():
    rng = np.random.default_rng(0)
    a, b, c = (rng.normal(size=(300, 3)) for _ in range(3))
    p = rng.normal(size=(300, 3)) * 2
    bary, feat = closest_point_on_triangles(p, a, b, c)
    assert np.all(bary >= -1e-12) and np.allclose(bary.sum(1), 1.0)
    x = bary[:, :1] * a + bary[:, 1:2] * b + bary[:, 2:] * c
    d = np.linalg.norm(p - x, axis=1)
    # dense barycentric sampling never beats the exact closest point
    s = np.linspace(0, 1, 81)
    uu, vv = np.meshgrid(s, s)
    keep = uu + vv <= 1
    uu, vv = uu[keep], vv[keep]
    pts = (1 - uu - vv)[None, :, None] * a[:, None] + uu[None, :, None] * b[:, None] + vv[None, :, None] * c[:, None]
    dense = np.linalg.norm(pts - p[:, None], axis=2).min(1)
    assert np.all(d <= dense + 1e-12)
    assert np.all(dense - d < 0.05 * np.linalg.norm(b - a, axis=1).max())
    assert set(np.unique(feat)) <= set(range(7))


def test_winding_number_of_a_closed_mesh():
    m = trimesh.creation.icosphere(subdivisions=2, radius=1.0)
    v, f = np.asarray(m.vertices), np.asarray(m.faces)
    w = winding_number(v, f, np.array([[0, 0, 0], [0.5, 0.2, 0.1], [2, 0, 0], [0, 0, -5.0]]))
    assert np.allclose(w, [1, 1, 0, 0], atol=1e-9)
    inward = winding_number(v, f[:, ::-1], np.array([[0.0, 0.0, 0.0]]))
    assert np.allclose(inward, -1, atol=1e-9)                 # inward faces: −1 inside
    assert np.allclose(winding_number(v, f, np.zeros((0, 3))), [])


def test_point_segment_distance_interior_ends_and_degenerate():
    a = np.array([[0.0, 0, 0]] * 4)
    b = np.array([[2.0, 0, 0]] * 3 + [[0.0, 0, 0]])
    p = np.array([[1.0, 3, 0], [-3.0, 4, 0], [5.0, 0, 4], [3.0, 4, 0]])
    np.testing.assert_allclose(point_segment_distance(p, a, b), [3.0, 5.0, 5.0, 5.0])


def test_segments_min_picks_the_smallest_value_of_each_key():
    keys = np.array([3, 0, 3, 1, 0, 3])
    values = np.array([5.0, 2.0, 1.0, 7.0, 2.0, 1.0])
    best = segments_min(keys, values, 5)
    np.testing.assert_array_equal(best, [1, 3, -1, 2, -1])     # ties: the first; absent keys: −1
    sorted_best = segments_min(np.sort(keys), values[np.argsort(keys, kind="stable")], 5)
    np.testing.assert_array_equal(sorted_best, [0, 2, -1, 4, -1])
    np.testing.assert_array_equal(segments_min(np.zeros(0, int), np.zeros(0), 2), [-1, -1])
