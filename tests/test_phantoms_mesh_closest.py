"""Tests of ``phantoms.mesh.closest``: the generalised winding number of a closed mesh, the point-segment distance
and the per-key argmin (the closest point on a triangle: test_geometry_closest.py)."""

from __future__ import annotations

import numpy as np
import trimesh

from phantoms.mesh import winding_number
from phantoms.mesh.closest import point_segment_distance, segments_min


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
