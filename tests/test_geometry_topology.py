"""geometry/topology.py: edges, closed/manifold/oriented checks, Euler characteristic, genus, components, on
hand-built meshes with known answers."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from geometry.topology import (connected_components, directed_edge_repeats, edge_face_counts, edges_unique,
                               euler_characteristic, face_edge_keys, face_edges, genus, is_closed, is_manifold,
                               is_oriented)

TET_V = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]])
TET_F = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])      # outward


def _facts(f, nv):
    n_v, _ = connected_components(f, nv, by="vertex")
    n_f, _ = connected_components(f, nv, by="face")
    return dict(closed=is_closed(f, nv), manifold=is_manifold(f, nv), oriented=is_oriented(f, nv),
                euler=euler_characteristic(f, nv), vcomp=n_v, fcomp=n_f)


def test_tetrahedron():
    assert _facts(TET_F, 4) == dict(closed=True, manifold=True, oriented=True, euler=2, vcomp=1, fcomp=1)
    assert genus(2) == 0
    e = edges_unique(TET_F)
    assert e.tolist() == [[0, 1], [0, 2], [0, 3], [1, 2], [1, 3], [2, 3]]
    edges, counts = edge_face_counts(TET_F, 4)
    assert np.array_equal(edges, e) and (counts == 2).all()


def test_cube():
    m = trimesh.creation.box()
    f, nv = np.asarray(m.faces), len(m.vertices)
    assert _facts(f, nv) == dict(closed=True, manifold=True, oriented=True, euler=2, vcomp=1, fcomp=1)
    assert len(edges_unique(f)) == 18                      # 12 cube edges + 6 face diagonals


def test_torus_has_genus_one():
    m = trimesh.creation.torus(1.0, 0.3)
    f, nv = np.asarray(m.faces), len(m.vertices)
    facts = _facts(f, nv)
    assert facts["closed"] and facts["oriented"] and facts["euler"] == 0
    assert genus(facts["euler"], facts["vcomp"]) == 1


def test_open_mesh():
    f = TET_F[:-1]
    facts = _facts(f, 4)
    assert not facts["closed"] and facts["manifold"] and facts["oriented"]
    _, counts = edge_face_counts(f, 4)
    assert int((counts == 1).sum()) == 3                    # the missing face's rim
    assert facts["euler"] == 4 - 6 + 3


def test_flipped_face():
    f = TET_F.copy()
    f[0] = f[0, ::-1]
    assert is_closed(f, 4) and not is_oriented(f, 4)
    assert directed_edge_repeats(f, 4) == 3                # each edge of the flipped face runs twice one way


def test_two_components():
    f = np.vstack([TET_F, TET_F + 4])
    assert _facts(f, 8) == dict(closed=True, manifold=True, oriented=True, euler=4, vcomp=2, fcomp=2)
    assert genus(4, 2) == 0
    n, labels = connected_components(f, 8, by="vertex")
    assert n == 2 and len(set(labels[:4])) == 1 and labels[0] != labels[4]


def test_touching_at_a_vertex_is_one_by_vertex_two_by_face():
    f = np.vstack([TET_F, TET_F + 3])                      # vertex 3 shared
    assert connected_components(f, 7, by="vertex")[0] == 1
    assert connected_components(f, 7, by="face")[0] == 2


def test_non_manifold_edge():
    # three triangles on the edge (0, 1)
    f = np.array([[0, 1, 2], [1, 0, 3], [0, 1, 4]])
    assert not is_manifold(f, 5) and not is_closed(f, 5)
    edges, counts = edge_face_counts(f, 5)
    assert counts[(edges[:, 0] == 0) & (edges[:, 1] == 1)].tolist() == [3]


def test_unreferenced_vertex_is_its_own_vertex_component():
    assert connected_components(TET_F, 5, by="vertex")[0] == 2
    with pytest.raises(ValueError):
        connected_components(TET_F, 4, by="edge")


def test_face_edges_and_keys_agree():
    m = trimesh.creation.icosphere(1)
    f, nv = np.asarray(m.faces), len(m.vertices)
    edges, fe = face_edges(f, nv)
    assert np.array_equal(edges, edges_unique(f))
    for k, (a, b) in enumerate(((0, 1), (1, 2), (2, 0))):
        e = edges[fe[:, k]]
        assert np.array_equal(e, np.sort(f[:, [a, b]], axis=1))
    keys = face_edge_keys(f, nv)
    assert np.array_equal(np.unique(keys), edges[:, 0] * nv + edges[:, 1])


def test_component_euler_counts_each_surface_of_a_mesh_apart():
    """A sphere and a torus side by side: χ 2 and 0, both closed; without one face the sphere has 3 open edges."""
    from geometry.topology import component_euler

    s = trimesh.creation.icosphere(2)
    t = trimesh.creation.torus(1.0, 0.3)
    v = np.vstack([s.vertices, t.vertices + [4.0, 0, 0]])
    f = np.vstack([s.faces, t.faces + len(s.vertices)])
    n, labels = connected_components(f, len(v), by="face")
    euler, open_edges = component_euler(f, len(v), labels, n)
    assert n == 2 and sorted(euler.tolist()) == [0, 2] and open_edges.tolist() == [0, 0]
    euler, open_edges = component_euler(f[1:], len(v), labels[1:], n)
    assert euler[labels[0]] == 1 and open_edges[labels[0]] == 3 and open_edges[labels[-1]] == 0
