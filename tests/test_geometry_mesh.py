"""Tests of ``geometry.mesh``: area-uniform surface sampling and the scored mesh's cached quantities against the
direct computations, on small hand-built meshes; signed volume, face areas and normals, vertex normals, lumped
vertex areas and the padded neighbour arrays against analytic values.  (The radius neighbourhoods:
``test_geometry_neighbors.py``.)"""

from __future__ import annotations

import numpy as np
import pytest

from geometry.mesh import sample_surface


def test_sample_surface_is_seeded_area_uniform_and_on_the_faces():
    # two triangles of areas 1/2 and 3/2 in the plane z = 0
    v = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [3, 0, 0], [3, 1, 0], [0, 2, 0]])
    f = np.array([[0, 1, 2], [3, 4, 5]])
    p1, fi1 = sample_surface(v, f, 40000, 7)
    p2, fi2 = sample_surface(v, f, 40000, np.random.default_rng(7))
    assert np.array_equal(p1, p2) and np.array_equal(fi1, fi2)
    assert abs(np.mean(fi1 == 1) - 0.75) < 0.01
    assert np.all(p1[:, 2] == 0)
    # inside the first triangle: x, y >= 0 and x + y <= 1
    q = p1[fi1 == 0]
    assert (q[:, :2] >= 0).all() and (q.sum(1) <= 1 + 1e-12).all()
    # the same random numbers in the same order as a hand-written draw
    rng = np.random.default_rng(3)
    u, r1, r2 = rng.random(5), rng.random(5), rng.random(5)
    p, fi = sample_surface(v, f, 5, 3)
    assert np.array_equal(fi, np.minimum(np.searchsorted(np.cumsum([0.5, 1.5]), u * 2.0, side="right"), 1))
    s = np.sqrt(r1)
    t = v[f[fi]]
    assert np.allclose(p, (1 - s)[:, None] * t[:, 0] + (s * (1 - r2))[:, None] * t[:, 1] + (s * r2)[:, None] * t[:, 2])


def test_sample_surface_of_zero_area_raises():
    with pytest.raises(ValueError):
        sample_surface(np.zeros((3, 3)), np.array([[0, 1, 2]]), 10, 0)


# ------------------------------------------------------------------------------------------------ the scored mesh
import trimesh  # noqa: E402

from geometry.mesh import ScoredMesh, face_areas, face_normals, scored_mesh, signed_volume, vertex_normals  # noqa: E402
from geometry.topology import (connected_components, edge_adjacent_face_pairs, edge_face_counts,  # noqa: E402
                               edges_unique, euler_characteristic)


def _small_meshes():
    box = trimesh.creation.box()
    open_box = (box.vertices, box.faces[2:])                    # two faces gone: boundary edges
    two = trimesh.util.concatenate([box, trimesh.creation.icosphere(1).apply_translation([3, 0, 0])])
    return [(box.vertices, box.faces), (box.vertices, box.faces[:, ::-1]), open_box, (two.vertices, two.faces)]


@pytest.mark.parametrize("k", range(4))
def test_scored_mesh_caches_what_the_direct_computations_give(k):
    v, f = _small_meshes()[k]
    v, f = np.asarray(v, float), np.asarray(f, np.int64)
    m = ScoredMesh(v, f)
    vol = signed_volume(v, f)
    sign = 1.0 if vol >= 0 else -1.0
    assert m.signed_volume == vol and m.outward == (vol >= 0)
    assert np.array_equal(m.face_areas, face_areas(v, f)) and m.area == float(face_areas(v, f).sum())
    assert np.array_equal(m.face_normals, sign * face_normals(v, f))
    assert np.array_equal(m.vertex_normals, sign * vertex_normals(v, f))
    edges, counts = edge_face_counts(f, len(v))
    assert np.array_equal(m.edges, edges_unique(f)) and np.array_equal(m.edges, edges)
    assert np.array_equal(m.edge_face_counts, counts)
    for a, b in zip(m.edge_face_pairs, edge_adjacent_face_pairs(f, len(v))):
        assert np.array_equal(a, b)
    assert m.euler == euler_characteristic(f, len(v))
    assert m.n_components == connected_components(f, len(v))[0]
    assert m.watertight == bool(np.all(counts == 2))
    assert m.watertight == trimesh.Trimesh(v, f, process=False).is_watertight


def test_scored_mesh_computes_each_quantity_once():
    m = ScoredMesh(trimesh.creation.icosphere(2).vertices, trimesh.creation.icosphere(2).faces)
    assert m.face_normals is m.face_normals and m.edges is m.edges and m.vertex_normals is m.vertex_normals
    assert m.edge_face_pairs is m.edge_face_pairs and m.face_areas is m.face_areas


def test_scored_mesh_of_arrays_or_of_itself():
    v, f = _small_meshes()[0]
    m = scored_mesh(v, f)
    assert scored_mesh(m) is m
    with pytest.raises(TypeError):
        scored_mesh(m, f)
    with pytest.raises(TypeError):
        scored_mesh(v)


def test_mesh_facts_agree_with_trimesh():
    """The facts adapters report: trimesh's watertight / Euler number / face-adjacency components."""
    from geometry.mesh import mesh_facts

    box = trimesh.creation.box()
    v = np.vstack([box.vertices, [[0, 0, 3.0]]])
    e = box.faces[0, :2]
    fin = trimesh.Trimesh(v, np.vstack([box.faces, [[e[0], e[1], 8]]]), process=False)   # a non-manifold edge
    for mesh in (box, trimesh.Trimesh(box.vertices, box.faces[2:], process=False), fin):
        facts = mesh_facts(mesh)
        labels = trimesh.graph.connected_component_labels(mesh.face_adjacency, node_count=len(mesh.faces))
        assert facts == {"vertices": len(mesh.vertices), "faces": len(mesh.faces), "watertight": mesh.is_watertight,
                         "euler": mesh.euler_number, "signed_volume": signed_volume(mesh.vertices, mesh.faces),
                         "components": int(labels.max()) + 1}
    assert mesh_facts(ScoredMesh(box.vertices, box.faces)) == mesh_facts(box)
    empty = mesh_facts(trimesh.Trimesh(np.zeros((0, 3)), np.zeros((0, 3), int), process=False))
    assert empty == {"vertices": 0, "faces": 0, "watertight": False, "euler": 0, "signed_volume": 0.0, "components": 0}


# ------------------------------------------------------------------------------------------------ primitives
from geometry.mesh import lumped_vertex_areas, one_ring, padded_from_pairs  # noqa: E402
from geometry.sphere import fibonacci_sphere  # noqa: E402


@pytest.fixture(scope="module")
def cube():
    box = trimesh.creation.box(extents=(2.0, 3.0, 4.0))
    return np.asarray(box.vertices), np.asarray(box.faces)


def test_signed_volume_of_a_box_is_its_volume_positive_outward_negative_inward(cube):
    v, f = cube
    assert signed_volume(v, f) == pytest.approx(24.0)
    assert signed_volume(v, f[:, ::-1]) == pytest.approx(-24.0)
    assert signed_volume(v + [10.0, -5.0, 3.0], f) == pytest.approx(24.0)     # origin-independent (closed)
    assert signed_volume(v, np.zeros((0, 3), int)) == 0.0


def test_face_signed_volumes_sum_per_shell_to_each_shells_volume(cube):
    """Two boxes, the second wound inward: the terms of each box's faces sum to +24 and −24."""
    from geometry.mesh import face_signed_volumes

    v, f = cube
    both_v = np.vstack([v, v + [5.0, 0, 0]])
    both_f = np.vstack([f, f[:, ::-1] + len(v)])
    terms = face_signed_volumes(both_v, both_f)
    assert terms.shape == (len(both_f),) and terms[:len(f)].sum() == pytest.approx(24.0)
    assert terms[len(f):].sum() == pytest.approx(-24.0) and face_signed_volumes(v, np.zeros((0, 3), int)).size == 0


def test_signed_volume_of_a_fine_sphere_converges_to_four_thirds_pi():
    v, f = fibonacci_sphere(4000, 1.5)
    assert signed_volume(v, f) == pytest.approx(4 / 3 * np.pi * 1.5 ** 3, rel=2e-3)


def test_face_areas_and_normals_of_a_right_triangle_and_a_box(cube):
    v = np.array([[0, 0, 0], [3, 0, 0], [0, 4, 0.0]])
    f = np.array([[0, 1, 2]])
    assert face_areas(v, f) == pytest.approx([6.0])
    np.testing.assert_allclose(face_normals(v, f), [[0, 0, 1]])
    np.testing.assert_allclose(face_normals(v, f[:, ::-1]), [[0, 0, -1]])   # right-hand rule
    bv, bf = cube
    assert face_areas(bv, bf).sum() == pytest.approx(2 * (6 + 8 + 12))
    n = face_normals(bv, bf)
    centroid_dir = bv[bf].mean(axis=1)
    assert (np.einsum("ij,ij->i", n, centroid_dir) > 0).all()              # outward
    np.testing.assert_allclose(np.abs(n).max(axis=1), 1.0)                 # axis-aligned unit normals


def test_degenerate_faces_get_a_zero_normal_not_nan():
    v = np.array([[0, 0, 0], [1, 0, 0], [2, 0, 0.0]])
    n = face_normals(v, np.array([[0, 1, 2]]))
    assert np.isfinite(n).all() and (n == 0).all()


def test_vertex_normals_of_a_sphere_are_radial_and_lumped_areas_sum_to_the_area():
    v, f = fibonacci_sphere(800, 2.0)
    n = vertex_normals(v, f)
    np.testing.assert_allclose(np.linalg.norm(n, axis=1), 1.0)
    assert (np.einsum("ij,ij->i", n, v / 2.0) > 0.999).all()
    a = lumped_vertex_areas(v, f)
    assert a.shape == (800,) and (a > 0).all()
    assert a.sum() == pytest.approx(face_areas(v, f).sum())
    assert a.sum() == pytest.approx(4 * np.pi * 4.0, rel=5e-3)


def test_padded_from_pairs_groups_by_source_keeps_order_and_pads():
    out = padded_from_pairs([2, 0, 2, 2, 0], [5, 6, 7, 8, 9], 4)
    np.testing.assert_array_equal(out, [[6, 9, -1], [-1, -1, -1], [5, 7, 8], [-1, -1, -1]])
    np.testing.assert_array_equal(padded_from_pairs([2, 0, 2, 2, 0], [5, 6, 7, 8, 9], 4, max_width=2),
                                  [[6, 9], [-1, -1], [5, 7], [-1, -1]])
    assert padded_from_pairs([], [], 3).shape == (3, 0)


def test_one_ring_of_a_tetrahedron_and_an_icosahedron():
    tet = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
    ring = one_ring(tet, 4)
    for i in range(4):
        assert sorted(ring[i]) == sorted(set(range(4)) - {i})
    ico = trimesh.creation.icosahedron()
    ring = one_ring(ico.faces, 12)
    assert ring.shape == (12, 5) and (ring >= 0).all()                     # every vertex: valence 5
    for i in range(12):
        assert set(ring[i]) == set(ico.vertex_neighbors[i])


def test_corner_angles_against_known_triangles():
    from geometry.mesh import corner_angles

    v = np.array([[0, 0, 0], [1, 0, 0], [0.5, np.sqrt(3) / 2, 0], [0, 1, 0], [2, 0, 0]], float)
    f = np.array([[0, 1, 2], [0, 1, 3], [0, 0, 1]])             # equilateral, right isosceles, degenerate
    a = corner_angles(v, f)
    np.testing.assert_allclose(a[0], [60, 60, 60], atol=1e-12)
    np.testing.assert_allclose(a[1], [90, 45, 45], atol=1e-12)
    assert a[2, 0] == a[2, 1] == 0.0                            # a zero-length edge: 0° at its corners
