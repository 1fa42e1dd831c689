"""Manifold dual contouring (methods/dc_manifold.py): the patch table on marching-cubes cases with known
answers; hand-built volumes whose one cell holds two patches (two cavities), two patches joined by two
segments (a thin tube through a face) and a tunnel (inside corners touching only through the cell) — each
with the known vertex count and topology, where one vertex per cell (the library's mesh) is not a manifold;
random fields full of such cells stay closed 2-manifolds."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh
from _peers_common import edge_and_vertex_manifold
from scipy import ndimage

from methods import get_method
from methods.dc_manifold import EDGE_AXIS, EDGE_CORNERS, TUNNEL_CUBES, _patches_of, cell_patches, patch_centroids
from phantoms import Volume


def patches(cube: int, joined: int = 63) -> list[set[int]]:
    p = _patches_of(cube, joined)
    return [set(np.flatnonzero(p == k).tolist()) for k in range(p.max() + 1)]


def edges_at(corner: int) -> set[int]:
    return set(np.flatnonzero((EDGE_CORNERS == corner).any(axis=1)).tolist())


def test_edge_table():
    """12 edges, 4 per axis, each joining two corners that differ in exactly its axis bit."""
    assert np.bincount(EDGE_AXIS).tolist() == [4, 4, 4]
    assert ((EDGE_CORNERS[:, 0] ^ EDGE_CORNERS[:, 1]) == 1 << EDGE_AXIS).all()
    assert len({tuple(e) for e in EDGE_CORNERS.tolist()}) == 12


@pytest.mark.parametrize("corner", range(8))
def test_one_corner_one_patch_of_its_three_edges(corner):
    assert patches(1 << corner) == [edges_at(corner)]
    assert patches(255 ^ (1 << corner)) == [edges_at(corner)]        # the complement: the same triangle


def test_opposite_corners_two_patches():
    """Marching cubes' case 4 (corners 0 and 7): two triangles, whatever the face rule (no face is ambiguous);
    its complement (all but 0 and 7 inside) likewise."""
    for cube in (1 | 1 << 7, 255 ^ (1 | 1 << 7)):
        assert sorted(map(sorted, patches(cube))) == sorted(map(sorted, [edges_at(0), edges_at(7)]))
    assert (1 | 1 << 7) in TUNNEL_CUBES and (255 ^ (1 | 1 << 7)) not in TUNNEL_CUBES


def test_ambiguous_face_joined_or_separated():
    """Corners 0 and 3 inside (diagonal on the face z = 0): joined across the face, one patch of all six
    crossed edges; separated, two triangles."""
    cube = 1 | 1 << 3
    assert patches(cube) == [edges_at(0) | edges_at(3)]
    assert len(edges_at(0) | edges_at(3)) == 6
    assert sorted(map(sorted, patches(cube, joined=0))) == sorted(map(sorted, [edges_at(0), edges_at(3)]))


def block(inside=(), outside=(), n: int = 8) -> Volume:
    """A grid of +1 with the samples ``inside`` at −1, or a solid block of −1 (one sample in from the
    border) with the samples ``outside`` at +1 — unit spacing, origin 0."""
    if outside:
        v = np.ones((n, n, n))
        v[1:-1, 1:-1, 1:-1] = -1.0
        for p in outside:
            v[p] = 1.0
    else:
        v = np.ones((n, n, n))
        for p in inside:
            v[p] = -1.0
    return Volume(v, origin=np.zeros(3), spacing=np.ones(3))


def library_is_manifold(vol: Volume) -> bool:
    from gpytoolbox import dual_contouring_of_signed_distance_data

    idx = np.stack(np.meshgrid(*[np.arange(s) for s in vol.shape], indexing="ij"), axis=-1).reshape(-1, 3, order="F")
    V, Q = dual_contouring_of_signed_distance_data(vol.values.ravel(order="F"), idx.astype(float), *vol.shape,
                                                   outer_iters=0)
    mesh = trimesh.Trimesh(V, np.concatenate([Q[:, [0, 1, 2]], Q[:, [0, 2, 3]]]), process=False)
    trimesh.repair.fix_winding(mesh)           # the library winds its quads from the geometry: not the point here
    return edge_and_vertex_manifold(mesh)


def reconstruct(vol: Volume):
    rec = get_method("dual_contouring", iterations=0, samples="all").reconstruct(vol)
    assert rec.mesh.is_watertight and rec.mesh.is_winding_consistent and edge_and_vertex_manifold(rec.mesh)
    assert rec.mesh.volume > 0
    return rec


def test_two_cavities_in_one_cell():
    """A solid block with two outside samples at opposite corners of one cell: two cavities that share that
    cell.  The cell has two patches and gets two vertices, each cavity is closed (8 vertices, 6 quads: an
    octahedron's dual), the mesh is the block's outer surface and the two cavities: 3 components, χ = 6.
    One vertex per cell joins the two cavities at the shared vertex (not a manifold)."""
    vol = block(outside=[(3, 3, 3), (4, 4, 4)])
    assert not library_is_manifold(vol)
    p = cell_patches(vol.values)
    two = np.flatnonzero(p.count == 2)
    assert p.cells[two].tolist() == [[3, 3, 3]]
    rec = reconstruct(vol)
    assert rec.info["split_cells"] == 1 and rec.info["patch_vertices"] == 2
    parts = sorted(rec.mesh.split(only_watertight=False), key=lambda m: len(m.faces))
    assert [len(m.vertices) for m in parts[:2]] == [8, 8] and [len(m.faces) for m in parts[:2]] == [12, 12]
    assert all(m.volume < 0 for m in parts[:2])          # cavities: their faces point into the hole
    assert rec.info["mesh_components"] == 3 and rec.info["mesh_euler"] == 6
    # each cavity's vertex in the shared cell is its own patch's: the mean of the three crossings around it
    centroids = patch_centroids(vol.values, p, two)[0, :2]
    assert sorted(centroids.round(6).tolist()) == [[3.166667] * 3, [3.833333] * 3]


def test_a_thin_tube_through_a_face():
    """Two inside samples diagonal on one face (x = 3): joined across it, each of the two cells sharing the face
    has one patch holding both of its contour segments.  Their two vertices would be joined twice (four faces
    on one edge, as in the library's mesh); each segment gets a vertex on the face: one closed genus-0 surface."""
    vol = block(inside=[(3, 3, 3), (3, 4, 4)])
    assert not library_is_manifold(vol)
    rec = reconstruct(vol)
    assert rec.info["segment_vertices"] == 2 and rec.info["split_cells"] == 0
    assert rec.info["mesh_components"] == 1 and rec.info["mesh_euler"] == 2
    on_face = rec.mesh.vertices[np.isclose(rec.mesh.vertices[:, 0], 3.0)]
    assert len(on_face) == 2                              # the two inserted vertices, on the face x = 3


def test_a_tunnel_through_a_cell():
    """Two inside samples at opposite corners of one cell only: the cell's two patches are joined into a tube
    (the inside is 26-connected): one closed genus-0 surface, not two."""
    vol = block(inside=[(3, 3, 3), (4, 4, 4)])
    rec = reconstruct(vol)
    assert rec.info["tunnels"] == 1
    assert rec.info["mesh_components"] == 1 and rec.info["mesh_euler"] == 2


@pytest.mark.parametrize("seed", range(6))
def test_random_fields_stay_manifold(seed):
    """Smoothed random fields (σ 1–2 samples) on 20³: tens of split cells, segment vertices and tunnels per
    field; the mesh is always closed, edge- and vertex-manifold and consistently wound."""
    rng = np.random.default_rng(seed)
    f = ndimage.gaussian_filter(rng.normal(size=(20, 20, 20)), 1.0 + 0.5 * (seed % 3))
    f = f / f.std() + 0.5
    f[[0, -1]] = f[:, [0, -1]] = f[:, :, [0, -1]] = 1.0
    rec = reconstruct(Volume(f, origin=np.zeros(3), spacing=np.ones(3)))
    assert rec.info["split_cells"] > 0


def test_heavy_noise_stays_manifold_and_cheap():
    """The torus at N = 48 with Gaussian noise at 20 dB: hundreds of split cells, tens of tunnels, hundreds of
    segment vertices — a closed 2-manifold, and the manifold step stays a fraction of a second (0.08 s
    measured at load 4; it took 11 s when every tunnel re-indexed the whole mesh, hence the generous bound)."""
    from bench.metrics.validity import check_mesh
    from phantoms import add_noise, get_phantom

    vol, _ = add_noise(get_phantom("torus").volume(n=48), "gaussian", 20.0, seed=1)
    rec = get_method("dual_contouring", iterations=0).reconstruct(vol)
    assert rec.info["split_cells"] > 300 and rec.info["tunnels"] > 30 and rec.info["segment_vertices"] > 100
    assert check_mesh(rec.mesh, vol) == [] and edge_and_vertex_manifold(rec.mesh)
    assert rec.info["wall_manifold_s"] < 3.0
