"""geometry/closest.py: the point–triangle kernel (compiled) equal to its numpy reference bit for bit, against dense
sampling, its features and barycentrics, the one rule for degenerate triangles; the exact point-to-mesh distance,
against brute force (numpy) and pymeshlab."""

from __future__ import annotations

import numpy as np
import pymeshlab
import pytest
import trimesh

from geometry.closest import (
    EAB,
    EBC,
    ECA,
    FACE,
    VA,
    VB,
    VC,
    bucket_triangles,
    closest_on_faces,
    closest_point_on_triangles,
    point_mesh_distance,
    triangle_boxes,
)
from phantoms import get_phantom


def _brute(points, v, f):
    """Every point against every triangle (numpy reference)."""
    a, b, c = v[f[:, 0]], v[f[:, 1]], v[f[:, 2]]
    out = np.empty(len(points))
    for i, p in enumerate(points):
        d2, _, _, _ = closest_point_on_triangles(np.broadcast_to(p, a.shape), a, b, c)
        out[i] = np.sqrt(d2.min())
    return out


def _triangles(m, seed=0):
    """Random triangles with every tenth one collinear, a segment (a = b), a point, or of 1e-200 area."""
    rng = np.random.default_rng(seed)
    a, b, c = (rng.normal(size=(m, 3)) for _ in range(3))
    c[0::10] = a[0::10] + 0.25 * (b[0::10] - a[0::10])
    b[1::10] = a[1::10]
    b[2::10] = c[2::10] = a[2::10]
    c[3::10] = a[3::10] + 1e-200 * (b[3::10] - a[3::10])
    return rng.normal(size=(m, 3)) * 2, a, b, c


def test_the_kernel_equals_its_numpy_reference_bit_for_bit():
    p, a, b, c = _triangles(5000)
    d, x, bary, feat = closest_on_faces(p, np.stack([a, b, c], 1), np.arange(len(p)))
    d2, feat_ref, bary_ref, x_ref = closest_point_on_triangles(p, a, b, c)
    np.testing.assert_array_equal(d, np.sqrt(d2))
    np.testing.assert_array_equal(feat, feat_ref)
    np.testing.assert_array_equal(bary, bary_ref)
    np.testing.assert_array_equal(x, x_ref)
    assert set(np.unique(feat)) == set(range(7))


def test_closest_point_on_triangles_matches_dense_sampling():
    rng = np.random.default_rng(0)
    a, b, c = (rng.normal(size=(300, 3)) for _ in range(3))
    p = rng.normal(size=(300, 3)) * 2
    d2, feat, bary, x = closest_point_on_triangles(p, a, b, c)
    assert np.all(bary >= -1e-12) and np.allclose(bary.sum(1), 1.0)
    np.testing.assert_allclose(bary[:, :1] * a + bary[:, 1:2] * b + bary[:, 2:] * c, x, atol=1e-12)
    d = np.sqrt(d2)
    np.testing.assert_allclose(d, np.linalg.norm(p - x, axis=1), rtol=1e-12)
    # dense barycentric sampling never beats the exact closest point
    s = np.linspace(0, 1, 81)
    uu, vv = np.meshgrid(s, s)
    keep = uu + vv <= 1
    uu, vv = uu[keep], vv[keep]
    pts = (1 - uu - vv)[None, :, None] * a[:, None] + uu[None, :, None] * b[:, None] + vv[None, :, None] * c[:, None]
    dense = np.linalg.norm(pts - p[:, None], axis=2).min(1)
    assert np.all(d <= dense + 1e-12)
    assert np.all(dense - d < 0.05 * np.linalg.norm(b - a, axis=1).max())
    # the feature agrees with the barycentrics: zero where the closest point is off that corner
    on = bary > 0
    expect = {FACE: (1, 1, 1), VA: (1, 0, 0), VB: (0, 1, 0), VC: (0, 0, 1), EAB: (1, 1, 0), EBC: (0, 1, 1),
              ECA: (1, 0, 1)}
    for code, corners in expect.items():
        assert np.all(on[feat == code] == np.array(corners, bool)), code


def test_a_degenerate_triangle_is_its_three_edges():
    """Zero area: a collinear triangle, a segment (a = b) and a point give the distance to their edges, with the
    edge or corner as the feature — one rule, whichever the caller."""
    a, b, c = np.array([[0.0, 0, 0]]), np.array([[2.0, 0, 0]]), np.array([[1.0, 0, 0]])
    p = np.array([[1.5, 3.0, 0.0], [-3.0, 4.0, 0.0], [5.0, 0.0, 4.0]])
    d2, feat, bary, x = closest_point_on_triangles(p, *(np.repeat(t, 3, 0) for t in (a, b, c)))
    np.testing.assert_array_equal(d2, [9.0, 25.0, 25.0])
    np.testing.assert_array_equal(x, [[1.5, 0, 0], [0, 0, 0], [2.0, 0, 0]])
    assert feat.tolist() == [EAB, VA, VB]                       # on ab and bc: the first edge, ab
    np.testing.assert_array_equal(bary, [[0.25, 0.75, 0], [1, 0, 0], [0, 1, 0]])
    d2, feat, _, x = closest_point_on_triangles(p[:1], a, a, a)
    assert d2[0] == 1.5 ** 2 + 9.0 and feat[0] == VA and np.array_equal(x, a)


def _pymeshlab(points, v, f):
    ms = pymeshlab.MeshSet()
    ms.add_mesh(pymeshlab.Mesh(vertex_matrix=np.asarray(v, float), face_matrix=np.asarray(f, np.int32)), "m")
    ms.add_mesh(pymeshlab.Mesh(vertex_matrix=np.asarray(points, float)), "p")
    bound = float(np.sqrt(((points - v[f[0, 0]]) ** 2).sum(1).max())) * 1.01 + 1e-9
    ms.compute_scalar_by_distance_from_another_mesh_per_vertex(measuremesh=1, refmesh=0, signeddist=False,
                                                               maxdist=pymeshlab.PureValue(bound))
    return np.asarray(ms.mesh(1).vertex_scalar_array(), float)


@pytest.mark.parametrize("mesh", [trimesh.creation.icosphere(2), trimesh.creation.torus(1.0, 0.3),
                                  trimesh.creation.box((1.0, 0.2, 3.0))], ids=["sphere", "torus", "box"])
def test_equals_brute_force_near_on_inside_and_far(mesh):
    v, f = np.asarray(mesh.vertices), np.asarray(mesh.faces)
    rng = np.random.default_rng(3)
    pts = np.concatenate([rng.normal(size=(200, 3)) * 0.4, rng.normal(size=(200, 3)) * 6.0,
                          mesh.sample(200, seed=1) + rng.normal(size=(200, 3)) * 1e-3, v[:30]])
    np.testing.assert_array_equal(point_mesh_distance(pts, v, f), _brute(pts, v, f))


@pytest.mark.parametrize("cells", [1, 4, 16])
def test_a_coarse_grid_gives_the_same_exact_distances(cells):
    """cells_per_axis only changes how far a query searches, not the answer: grid points over a box four times
    the mesh's, as the SDF energy queries them."""
    m = trimesh.creation.torus(1.0, 0.3)
    v, f = np.asarray(m.vertices), np.asarray(m.faces)
    ax = np.linspace(-2.5, 2.5, 9)
    pts = np.stack(np.meshgrid(ax, ax, ax, indexing="ij"), -1).reshape(-1, 3)
    np.testing.assert_array_equal(point_mesh_distance(pts, v, f, cells_per_axis=cells), _brute(pts, v, f))


def test_a_mesh_of_very_uneven_triangles_and_degenerate_faces(uneven_mesh):
    """Long slivers beside tiny triangles (the grid's cell follows the median) and zero-area faces."""
    v, f, pts = uneven_mesh
    np.testing.assert_array_equal(point_mesh_distance(pts, v, f), _brute(pts, v, f))


def test_equals_pymeshlab_on_the_metrics_workload():
    """100,000 samples of the true ellipsoid against marching cubes' mesh at N = 64: pymeshlab's float32."""
    from skimage.measure import marching_cubes

    ph = get_phantom("ellipsoid")
    vol = ph.volume(n=64)
    v, f, _, _ = marching_cubes(vol.values, 0.0, spacing=tuple(vol.spacing))
    v += vol.origin
    pts = ph.sample_surface(100_000, 0)[0]
    d = point_mesh_distance(pts, v, f)
    ref = _pymeshlab(pts, v, f)
    assert np.abs(d - ref).max() <= 1e-7 * max(ref.max(), 1e-9) + 1e-12
    assert 0 < np.median(d) < vol.h


def test_no_points_and_no_faces():
    m = trimesh.creation.icosphere(1)
    assert point_mesh_distance(np.zeros((0, 3)), m.vertices, m.faces).shape == (0,)
    with pytest.raises(ValueError, match="no faces"):
        point_mesh_distance(np.zeros((2, 3)), m.vertices, m.faces[:0])


def test_bucket_triangles_bins_every_triangle_into_the_cells_its_box_overlaps():
    m = trimesh.creation.icosphere(subdivisions=2, radius=1.0)
    v, f = np.asarray(m.vertices), np.asarray(m.faces)
    tri = v[f]
    lo_t, hi_t = tri.min(axis=1), tri.max(axis=1)
    lo, c = v.min(axis=0), 0.4
    dims = np.maximum(np.ceil((v.max(axis=0) - lo) / c).astype(np.int64), 1)
    start, faces = bucket_triangles(lo, c, dims, lo_t, hi_t)
    assert len(start) == int(np.prod(dims)) + 1 and start[-1] == len(faces)
    i0 = np.maximum(((lo_t - lo) / c).astype(int), 0)
    i1 = np.minimum(((hi_t - lo) / c).astype(int), dims - 1)
    for q in range(int(np.prod(dims))):
        i, j, k = q // (dims[1] * dims[2]), (q // dims[2]) % dims[1], q % dims[2]
        want = np.flatnonzero((i0[:, 0] <= i) & (i <= i1[:, 0]) & (i0[:, 1] <= j) & (j <= i1[:, 1])
                              & (i0[:, 2] <= k) & (k <= i1[:, 2]))
        np.testing.assert_array_equal(np.sort(faces[start[q]:start[q + 1]]), want)


def test_triangle_boxes_are_the_corners_and_their_min_and_max():
    m = trimesh.creation.torus(1.0, 0.3)
    v, f = np.asarray(m.vertices), np.asarray(m.faces)
    tri, tmin, tmax = triangle_boxes(v, f)
    np.testing.assert_array_equal(tri, v[f])
    np.testing.assert_array_equal(tmin, v[f].min(1))
    np.testing.assert_array_equal(tmax, v[f].max(1))
    with pytest.raises(ValueError, match="do not exist"):
        triangle_boxes(v, np.vstack([f, [[0, 1, len(v)]]]))
