"""geometry/bvh.py: the far-point distance through a bounding-volume hierarchy equals the brute-force minimum of
the point–triangle kernel bit for bit (and so the grid search), near, inside and far, on degenerate triangles; the
hierarchy's boxes hold their triangles and its leaves partition them."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from geometry.bvh import build_bvh, point_mesh_distance_far
from geometry.closest import closest_point_on_triangles, point_mesh_distance


def _brute(points, v, f):
    """Every point against every triangle (the kernel's numpy reference)."""
    a, b, c = v[f[:, 0]], v[f[:, 1]], v[f[:, 2]]
    return np.array([np.sqrt(closest_point_on_triangles(np.broadcast_to(p, a.shape), a, b, c)[0].min())
                     for p in points])


@pytest.mark.parametrize("mesh", [trimesh.creation.icosphere(2), trimesh.creation.torus(1.0, 0.3),
                                  trimesh.creation.box((1.0, 0.2, 3.0))], ids=["sphere", "torus", "box"])
def test_the_hierarchy_gives_the_brute_force_minimum_bit_for_bit(mesh):
    """Points near, on, inside and far (a grid over a box four times the mesh's, as the SDF energy queries it):
    the kernel's minimum over every triangle, exactly — and so the grid search's numbers."""
    v, f = np.asarray(mesh.vertices), np.asarray(mesh.faces)
    rng = np.random.default_rng(5)
    ax = np.linspace(-2.5, 2.5, 9)
    pts = np.concatenate([np.stack(np.meshgrid(ax, ax, ax, indexing="ij"), -1).reshape(-1, 3),
                          rng.normal(size=(200, 3)) * 0.4, mesh.sample(200, seed=2) + rng.normal(size=(200, 3)) * 1e-3,
                          v[:30], (v[f[:20, 0]] + v[f[:20, 1]]) / 2])
    d = point_mesh_distance_far(pts, v, f)
    np.testing.assert_array_equal(d, _brute(pts, v, f))
    np.testing.assert_array_equal(d, point_mesh_distance(pts, v, f))


def test_the_hierarchy_on_uneven_and_degenerate_triangles_and_a_single_one(uneven_mesh):
    v, f, pts = uneven_mesh
    np.testing.assert_array_equal(point_mesh_distance_far(pts, v, f), _brute(pts, v, f))
    np.testing.assert_array_equal(point_mesh_distance_far(pts, v, f[:1]), _brute(pts, v, f[:1]))
    assert point_mesh_distance_far(np.zeros((0, 3)), v, f).shape == (0,)
    with pytest.raises(ValueError, match="no faces"):
        point_mesh_distance_far(pts, v, f[:0])


@pytest.mark.parametrize("leaf", [1, 2, 4, 7])
def test_build_bvh_boxes_hold_their_triangles_and_leaves_split_them_all(leaf):
    """Every triangle in exactly one leaf of at most ``leaf`` triangles; each node's box is the union of its
    triangles' boxes and its children split its span."""
    m = trimesh.creation.icosphere(2)
    tri = np.asarray(m.vertices)[np.asarray(m.faces)]
    tmin, tmax = tri.min(1), tri.max(1)
    bmin, bmax, child, span, order = build_bvh(tmin, tmax, leaf)
    assert sorted(order) == list(range(len(tri)))
    leaves = child < 0
    assert (span[leaves, 1] - span[leaves, 0]).max() <= leaf and (span[leaves, 1] > span[leaves, 0]).all()
    assert (span[leaves, 1] - span[leaves, 0]).sum() == len(tri)
    for n in range(len(child)):
        t = order[span[n, 0]:span[n, 1]]
        np.testing.assert_array_equal(bmin[n], tmin[t].min(0))
        np.testing.assert_array_equal(bmax[n], tmax[t].max(0))
        if child[n] >= 0:
            a = child[n]
            assert span[a, 0] == span[n, 0] and span[a, 1] == span[a + 1, 0] and span[a + 1, 1] == span[n, 1]
