"""geometry.intersections: exact pairwise triangle intersection tests, against hand-built pairs and an LP."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from geometry.intersections import crossing_pairs, intersecting_faces, self_intersection_pairs


def icosphere(sub: int, radius: float = 1.0) -> trimesh.Trimesh:
    return trimesh.creation.icosphere(subdivisions=sub, radius=radius)


def _two_triangles(t1, t2):
    return np.array(t1 + t2, float), np.array([[0, 1, 2], [3, 4, 5]])


@pytest.mark.parametrize("t2, expected", [
    ([[0.2, 0.2, -1], [0.2, 0.2, 1], [2, 2, 0.5]], 1),            # piercing
    ([[0.2, 0.2, 0], [3, 0.1, 1], [3, 0.1, -1]], 1),              # vertex touching the face interior
    ([[0.2, 0.2, 0.5], [3, 0.1, 1], [3, 0.1, 2]], 0),             # above, apart
    ([[0.2, 0.2, 0.0], [2, 0.2, 0.0], [0.2, 2, 0.0]], 1),         # coplanar, overlapping
    ([[2, 2, 0.0], [3, 2, 0.0], [2, 3, 0.0]], 0),                 # coplanar, apart
    ([[0.0, 0.0, 1e-3], [1, 0, 1e-3], [0, 1, 1e-3]], 0),          # parallel copy just above
])
@pytest.mark.parametrize("rotate", [False, True])
def test_triangle_pairs(t2, expected, rotate):
    v, f = _two_triangles([[0, 0, 0], [1, 0, 0], [0, 1, 0]], t2)
    if rotate:   # a generic orientation: coplanar pairs are then coplanar only up to rounding
        rot = trimesh.transformations.random_rotation_matrix(np.random.default_rng(5).random(3))[:3, :3]
        v = v @ rot.T + [0.3, -1.7, 2.2]
    assert len(self_intersection_pairs(v, f)) == expected


def test_self_intersections_match_an_independent_lp_check():
    """Every non-adjacent pair of a crumpled sphere, decided by a feasibility LP (a point with barycentric
    coordinates in both triangles), gives exactly our pairs."""
    from scipy.optimize import linprog

    m = icosphere(2)
    v = m.vertices + np.random.default_rng(1).normal(scale=0.15, size=m.vertices.shape)
    f = np.asarray(m.faces)
    t = v[f]
    lo, hi = t.min(1), t.max(1)
    i, j = np.triu_indices(len(f), 1)
    ok = np.all((lo[i] <= hi[j]) & (lo[j] <= hi[i]), axis=1) & ~(f[i][:, :, None] == f[j][:, None, :]).any((1, 2))
    ref = set()
    for a, b in zip(i[ok], j[ok]):
        A = np.zeros((5, 6))
        A[:3, :3], A[:3, 3:], A[3, :3], A[4, 3:] = t[a].T, -t[b].T, 1, 1
        if linprog(np.zeros(6), A_eq=A, b_eq=[0, 0, 0, 1, 1], bounds=[(0, None)] * 6, method="highs").status == 0:
            ref.add((int(a), int(b)))
    mine = set(map(tuple, self_intersection_pairs(v, f).tolist()))
    assert len(ref) > 10
    assert mine == ref


def test_intersecting_faces_are_the_faces_of_the_pairs():
    a = icosphere(2)
    b = icosphere(2)
    b.apply_translation([1.2, 0.0, 0.0])
    both = trimesh.util.concatenate([a, b])
    faces = intersecting_faces(both.vertices, both.faces)
    assert len(faces) > 0 and np.array_equal(faces, np.unique(self_intersection_pairs(both.vertices, both.faces)))
    assert len(intersecting_faces(a.vertices, a.faces)) == 0


@pytest.mark.parametrize("t2, crosses", [
    ([[0.2, 0.2, -1], [0.2, 0.2, 1], [2, 2, 0.5]], True),         # piercing
    ([[0.2, 0.2, 0], [3, 0.1, 1], [3, 0.5, 2]], False),           # a vertex touching the face interior
    ([[0.2, 0.2, -1e-9], [3, 0.1, 1], [3, 0.5, 2]], False),       # ... and past it by rounding
    ([[0.2, 0.2, -0.05], [3, 0.1, 1], [3, 0.5, 2]], True),        # ... and through it by a few % of its size
    ([[1, 0, 0], [2, 0, 0.5], [2, 0, -0.5]], False),              # corners meeting
    ([[0.2, 0.2, 0.0], [2, 0.2, 0.0], [0.2, 2, 0.0]], True),      # coplanar, overlapping
])
def test_crossing_pairs_leave_out_faces_that_only_touch(t2, crosses):
    v, f = _two_triangles([[0, 0, 0], [1, 0, 0], [0, 1, 0]], t2)
    assert len(self_intersection_pairs(v, f)) == 1 or not crosses
    assert len(crossing_pairs(v, f)) == int(crosses)
