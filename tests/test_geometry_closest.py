"""geometry/closest.py: exact point-to-mesh distance, against brute force (numpy) and pymeshlab."""

from __future__ import annotations

import numpy as np
import pymeshlab
import pytest
import trimesh

from geometry.closest import point_mesh_distance
from phantoms import get_phantom
from phantoms.mesh.closest import closest_point_on_triangles


def _brute(points, v, f):
    """Every point against every triangle (numpy reference)."""
    a, b, c = v[f[:, 0]], v[f[:, 1]], v[f[:, 2]]
    out = np.empty(len(points))
    for i, p in enumerate(points):
        bary, _ = closest_point_on_triangles(np.broadcast_to(p, a.shape), a, b, c)
        q = bary[:, :1] * a + bary[:, 1:2] * b + bary[:, 2:] * c
        out[i] = np.sqrt(((q - p) ** 2).sum(1).min())
    return out


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
    np.testing.assert_allclose(point_mesh_distance(pts, v, f), _brute(pts, v, f), rtol=1e-12, atol=1e-14)


@pytest.mark.parametrize("cells", [1, 4, 16])
def test_a_coarse_grid_gives_the_same_exact_distances(cells):
    """cells_per_axis only changes how far a query searches, not the answer: grid points over a box four times
    the mesh's, as the SDF energy queries them."""
    m = trimesh.creation.torus(1.0, 0.3)
    v, f = np.asarray(m.vertices), np.asarray(m.faces)
    ax = np.linspace(-2.5, 2.5, 9)
    pts = np.stack(np.meshgrid(ax, ax, ax, indexing="ij"), -1).reshape(-1, 3)
    np.testing.assert_allclose(point_mesh_distance(pts, v, f, cells_per_axis=cells), _brute(pts, v, f),
                               rtol=1e-12, atol=1e-14)


def test_a_mesh_of_very_uneven_triangles_and_degenerate_faces():
    """Long slivers beside tiny triangles (the grid's cell follows the median) and zero-area faces."""
    m = trimesh.creation.icosphere(3)
    v = np.asarray(m.vertices) * [6.0, 1.0, 0.2]
    f = np.vstack([m.faces, [[0, 0, 1], [5, 5, 5]]])
    pts = np.random.default_rng(4).normal(size=(500, 3)) * [5, 1, 1]
    np.testing.assert_allclose(point_mesh_distance(pts, v, f), _brute(pts, v, f), rtol=1e-12, atol=1e-14)


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
