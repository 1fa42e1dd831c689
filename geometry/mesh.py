"""Basic per-face and per-vertex quantities and vertex neighbourhoods of a triangle mesh, and
:class:`ScoredMesh`, one mesh with those quantities computed once and kept for every consumer."""

from __future__ import annotations

from functools import cached_property

import numpy as np
from scipy.spatial import cKDTree

from .topology import (connected_components, edge_adjacent_face_pairs, edge_groups, edges_unique,
                       euler_characteristic)


def _face_cross(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    v0, v1, v2 = (vertices[faces[:, k]] for k in range(3))
    return np.cross(v1 - v0, v2 - v0)


def signed_volume(vertices, faces) -> float:
    """The volume a closed mesh encloses, signed: positive when its faces face outward (counter-clockwise seen
    from outside), by the divergence theorem, Σ_f v0 · (v1 × v2) / 6 (origin-independent for a closed mesh).

    Parameters
    ----------
    vertices : (V, 3) float array.
    faces : (F, 3) int array (F may be 0: volume 0).

    Returns
    -------
    float
    """
    return float(face_signed_volumes(vertices, faces).sum())


def face_signed_volumes(vertices, faces) -> np.ndarray:
    """Each face's term v0 · (v1 × v2) / 6 of :func:`signed_volume` (F,): summed over a closed surface (one
    shell of a mesh, say) they give the volume it encloses, signed by its winding."""
    v = np.asarray(vertices, float)
    f = np.asarray(faces)
    if len(f) == 0:
        return np.zeros(0)
    v0, v1, v2 = (v[f[:, k]] for k in range(3))
    return np.einsum("ij,ij->i", v0, np.cross(v1, v2)) / 6.0


def _areas(cross: np.ndarray) -> np.ndarray:
    return 0.5 * np.linalg.norm(cross, axis=1)


def _unit_rows(cross: np.ndarray) -> np.ndarray:
    n = np.linalg.norm(cross, axis=1, keepdims=True)
    return cross / np.where(n > 0, n, 1.0)


def _vertex_normals(cross: np.ndarray, faces: np.ndarray, n_vertices: int) -> np.ndarray:
    """Σ of the incident faces' cross products (area × normal × 2: the area weighting), normalised."""
    acc = np.zeros((n_vertices, 3))
    for k in range(3):
        np.add.at(acc, faces[:, k], cross)
    return _unit_rows(acc)


def face_areas(vertices, faces) -> np.ndarray:
    """Area of every face, shape (F,)."""
    return _areas(_face_cross(np.asarray(vertices, float), np.asarray(faces)))


def face_normals(vertices, faces) -> np.ndarray:
    """Unit normal of every face (right-hand rule on the vertex order), shape (F, 3)."""
    return _unit_rows(_face_cross(np.asarray(vertices, float), np.asarray(faces)))


def vertex_normals(vertices, faces) -> np.ndarray:
    """Area-weighted average of the incident face normals, normalised, shape (V, 3)."""
    vertices = np.asarray(vertices, float)
    faces = np.asarray(faces)
    return _vertex_normals(_face_cross(vertices, faces), faces, len(vertices))


def lumped_vertex_areas(vertices, faces) -> np.ndarray:
    """One third of the area of the incident faces per vertex (barycentric lumped mass), shape (V,)."""
    a = face_areas(vertices, faces) / 3.0
    faces = np.asarray(faces)
    return np.bincount(faces.ravel(), weights=np.repeat(a, 3), minlength=len(vertices))


def sample_surface(vertices, faces, n: int, seed=0, areas=None) -> tuple[np.ndarray, np.ndarray]:
    """``n`` seeded, area-uniform i.i.d. points on a triangle mesh: (points (n, 3), face index (n,)).

    Faces are drawn with probability ∝ area (inverse CDF on the cumulative areas: one uniform per point),
    then a point uniformly inside the face by the square-root barycentric map (two more uniforms per
    point, r₁ then r₂): x = (1 − √r₁) a + √r₁(1 − r₂) b + √r₁ r₂ c.  ``seed`` is anything
    ``np.random.default_rng`` takes; the same seed gives the same points.  ``areas``: the faces' areas
    (:func:`geometry.mesh.face_areas`), when computed already.  Raises ValueError for a mesh of zero area.
    """
    v = np.asarray(vertices, float)
    f = np.asarray(faces, dtype=np.int64)
    t = v[f]
    if areas is None:
        areas = face_areas(v, f)
    cum = np.cumsum(areas)
    if not (len(cum) and cum[-1] > 0):
        raise ValueError("cannot sample a mesh of zero area")
    rng = np.random.default_rng(seed)
    u = rng.random(n) * cum[-1]
    fi = np.minimum(np.searchsorted(cum, u, side="right"), len(f) - 1)
    r1 = np.sqrt(rng.random(n))
    r2 = rng.random(n)
    w0, w1, w2 = 1.0 - r1, r1 * (1.0 - r2), r1 * r2
    tf = t[fi]
    pts = w0[:, None] * tf[:, 0] + w1[:, None] * tf[:, 1] + w2[:, None] * tf[:, 2]
    return pts, fi


class ScoredMesh:
    """A triangle mesh whose derived quantities are computed on first use and kept (``functools.cached_property``,
    as trimesh caches its own), so that every metric reads the same arrays and none recomputes them.

    The arrays are shared, not copied: treat them as read-only, and build a new object for a changed mesh.
    Orientation-dependent quantities (``face_normals``, ``vertex_normals``) point outward: they are flipped when
    the enclosed signed volume is negative, so H > 0 on a convex surface whatever the winding.

    Parameters
    ----------
    vertices : numpy.ndarray, shape (V, 3)
        Vertex positions (float64).
    faces : numpy.ndarray of int, shape (F, 3)
        Triangles; expected compacted (every vertex referenced) and without a repeated index in a face for the
        topology counts to mean what they say.
    """

    def __init__(self, vertices, faces):
        self.vertices = np.asarray(vertices, dtype=np.float64)
        self.faces = np.asarray(faces, dtype=np.int64)

    @cached_property
    def face_cross(self) -> np.ndarray:
        """(F, 3) cross products (v1 − v0) × (v2 − v0): twice the area times the right-hand normal."""
        return _face_cross(self.vertices, self.faces)

    @cached_property
    def face_areas(self) -> np.ndarray:
        """(F,) face areas."""
        return _areas(self.face_cross)

    @cached_property
    def area(self) -> float:
        """The total surface area."""
        return float(self.face_areas.sum())

    @cached_property
    def signed_volume(self) -> float:
        """The enclosed volume, positive for an outward winding (:func:`signed_volume`)."""
        return signed_volume(self.vertices, self.faces)

    @property
    def outward(self) -> bool:
        """Whether the faces are wound outward (signed volume ≥ 0)."""
        return self.signed_volume >= 0

    @cached_property
    def face_normals(self) -> np.ndarray:
        """(F, 3) unit outward face normals (zero for a face of zero area)."""
        n = _unit_rows(self.face_cross)
        return n if self.outward else -n

    @cached_property
    def vertex_normals(self) -> np.ndarray:
        """(V, 3) unit outward area-weighted vertex normals."""
        n = _vertex_normals(self.face_cross, self.faces, len(self.vertices))
        return n if self.outward else -n

    @cached_property
    def edge_groups(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """The face edges grouped by undirected edge (:func:`geometry.topology.edge_groups`)."""
        return edge_groups(self.faces, len(self.vertices))

    @cached_property
    def edges(self) -> np.ndarray:
        """(E, 2) unique undirected edges, ``a < b``, lexicographic (the order of :func:`edges_unique`)."""
        _, keys, start, _ = self.edge_groups
        nv = len(self.vertices)
        uniq = keys[start]
        return np.column_stack([uniq // nv, uniq % nv])

    @property
    def edge_face_counts(self) -> np.ndarray:
        """(E,) how many faces hold each edge of :attr:`edges`."""
        return self.edge_groups[3]

    @cached_property
    def edge_face_pairs(self) -> tuple[np.ndarray, np.ndarray]:
        """Edge → face adjacency of the edges in exactly two faces: their faces (P, 2) and vertices (P, 2)."""
        return edge_adjacent_face_pairs(self.faces, len(self.vertices), self.edge_groups)

    @cached_property
    def n_components(self) -> int:
        """Connected components through shared vertices."""
        return connected_components(self.faces, len(self.vertices), edges=self.edges)[0]

    @cached_property
    def face_components(self) -> tuple[int, np.ndarray]:
        """``(count, labels (F,))`` of the faces joined through the edges in exactly two faces (trimesh's face
        adjacency: faces that meet only at a non-manifold edge stay apart)."""
        return connected_components(self.faces, len(self.vertices), by="face", face_pairs=self.edge_face_pairs[0])

    @property
    def n_face_components(self) -> int:
        """How many :attr:`face_components` there are."""
        return self.face_components[0]

    @cached_property
    def euler(self) -> int:
        """Euler characteristic V − E + F."""
        return euler_characteristic(self.faces, len(self.vertices), n_edges=len(self.edges))

    @property
    def watertight(self) -> bool:
        """At least one face and every edge in exactly two faces."""
        counts = self.edge_face_counts
        return bool(len(counts) > 0 and np.all(counts == 2))


def scored_mesh(vertices, faces=None) -> ScoredMesh:
    """``vertices`` itself when it is a :class:`ScoredMesh` (``faces`` then None), else a new one of the arrays.

    Parameters
    ----------
    vertices : ScoredMesh or numpy.ndarray, shape (V, 3)
        The mesh, or its vertex positions.
    faces : numpy.ndarray of int, shape (F, 3), optional
        The triangles, when ``vertices`` is an array.

    Returns
    -------
    ScoredMesh
    """
    if isinstance(vertices, ScoredMesh):
        if faces is not None:
            raise TypeError("pass either a ScoredMesh or (vertices, faces), not both")
        return vertices
    if faces is None:
        raise TypeError("faces are needed with a vertex array")
    return ScoredMesh(vertices, faces)


def mesh_facts(mesh) -> dict:
    """The facts an adapter reports about its output mesh, as plain Python values: ``vertices``, ``faces``,
    ``watertight``, ``euler`` (V − E + F, every vertex counted), ``signed_volume`` and ``components`` (of faces,
    :attr:`ScoredMesh.n_face_components`).

    Parameters
    ----------
    mesh : trimesh.Trimesh or ScoredMesh
        Anything with ``vertices`` (V, 3) and ``faces`` (F, 3); a ScoredMesh's cached quantities are used.

    Returns
    -------
    dict
        An empty mesh is not watertight and has Euler characteristic 0 and no components.
    """
    m = mesh if isinstance(mesh, ScoredMesh) else ScoredMesh(mesh.vertices, np.reshape(mesh.faces, (-1, 3)))
    empty = len(m.faces) == 0
    return {"vertices": int(len(m.vertices)), "faces": int(len(m.faces)), "watertight": m.watertight,
            "euler": 0 if empty else int(m.euler), "signed_volume": m.signed_volume,
            "components": 0 if empty else int(m.n_face_components)}


def corner_angles(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """The interior angle at each corner of each triangle (F, 3), in degrees; a face with a zero-length edge gets
    0° at the affected corners.  atan2(|a×b|, a·b) is accurate for tiny and near-180° angles, unlike arccos."""
    t = np.asarray(vertices, dtype=np.float64)[np.asarray(faces)]
    out = np.empty((len(t), 3))
    for k in range(3):
        a = t[:, (k + 1) % 3] - t[:, k]
        b = t[:, (k + 2) % 3] - t[:, k]
        na = np.linalg.norm(a, axis=1)
        nb = np.linalg.norm(b, axis=1)
        ang = np.degrees(np.arctan2(np.linalg.norm(np.cross(a, b), axis=1), np.einsum("ij,ij->i", a, b)))
        out[:, k] = np.where((na > 0) & (nb > 0), ang, 0.0)
    return out


def padded_from_pairs(i: np.ndarray, j: np.ndarray, n: int, max_width: int | None = None) -> np.ndarray:
    """Padded neighbour array (n, W) from directed pairs i → j; empty slots are −1.

    With ``max_width`` each row keeps its first ``max_width`` neighbours in the given pair order.
    """
    i = np.asarray(i, dtype=np.int64)
    j = np.asarray(j, dtype=np.int64)
    order = np.argsort(i, kind="stable")
    i, j = i[order], j[order]
    counts = np.bincount(i, minlength=n)
    start = np.concatenate([[0], np.cumsum(counts)[:-1]])
    pos = np.arange(len(i)) - start[i]
    width = int(counts.max()) if len(counts) and counts.max() > 0 else 0
    if max_width is not None:
        width = min(width, int(max_width))
        keep = pos < width
        i, j, pos = i[keep], j[keep], pos[keep]
    out = np.full((n, width), -1, dtype=np.int64)
    out[i, pos] = j
    return out


def one_ring(faces, n_vertices: int) -> np.ndarray:
    """Padded 1-ring neighbour array (V, W), −1 where a row has fewer neighbours."""
    e = edges_unique(faces)
    return padded_from_pairs(np.concatenate([e[:, 0], e[:, 1]]), np.concatenate([e[:, 1], e[:, 0]]),
                             n_vertices)


#: most entries a :func:`radius_neighbors` row keeps: the 1-ring first, then the nearest other vertices within
#: the radius.  A marching-cubes mesh at N = 48..96 holds ≤ 24 vertices in a 2h ball (mean ~16), far below the
#: cap, so the cap only binds on meshes much denser than their grid (an 82k-face icosphere at N = 24: ~1,900),
#: where it bounds the cost of a neighbourhood query and fit to O(V · cap) whatever the density.
MAX_NEIGHBORS = 96

#: vertices per block of :func:`radius_neighbor_blocks` (the memory of one block is ~ block × cap × 8 bytes per
#: array: ~6 MB)
NEIGHBOR_BLOCK = 8192


#: the first query of a block asks for this many nearest vertices (a marching-cubes 2h ball holds ~20); the
#: rows it fills up are asked again for ``max_width`` + 1
_FIRST_K = 32


def _knn(tree, points, k, bound):
    d, j = tree.query(points, k=k, distance_upper_bound=bound)
    return d.reshape(len(points), k), j.reshape(len(points), k)


def radius_neighbor_blocks(vertices, faces, radius: float, max_width: int = MAX_NEIGHBORS,
                           block: int = NEIGHBOR_BLOCK, edges=None):
    """The rows of :func:`radius_neighbors` block by block: yields ``(start, stop, rows)``, ``rows`` the padded
    (stop − start, W) neighbour array of vertices start..stop−1 (W ≤ ``max_width``, the block's widest row).

    Each row is the vertex's 1-ring (in :func:`one_ring` order, at most ``max_width`` of it), then the other
    vertices within ``radius`` (distance ≤ radius) nearest first, up to ``max_width`` entries in all.  The
    neighbours within the radius come from a k-nearest query (k = ``max_width`` + 1, the vertex itself
    included) bounded by the radius, so a block costs O(block · max_width · log V) time and memory however
    many vertices the radius holds; the whole pass O(V · max_width) — never the number of pairs within the
    radius, which grows with the square of the mesh density.  ``edges``: :func:`edges_unique` of ``faces``,
    when computed already.
    """
    vertices = np.asarray(vertices, float)
    n = len(vertices)
    if n == 0:
        return
    r = float(radius)
    e = (edges_unique(faces) if edges is None else edges).astype(np.int64, copy=False)
    ring = padded_from_pairs(np.concatenate([e[:, 0], e[:, 1]]), np.concatenate([e[:, 1], e[:, 0]]), n,
                             max_width=max_width)
    nv = np.int64(n)
    ekey = e[:, 0] * nv + e[:, 1]                 # sorted: the edges are unique, a < b, lexicographic
    tree = cKDTree(vertices)
    k = int(min(max_width + 1, n))
    k0 = min(k, _FIRST_K)
    bound = np.nextafter(r, np.inf)               # the query keeps d < bound; the radius includes d = r
    first = k0
    for s in range(0, n, int(block)):
        t = min(s + int(block), n)
        d, j = _knn(tree, vertices[s:t], first, bound)
        full = d[:, -1] <= r if first < k else np.zeros(t - s, bool)
        if full.any():                            # the k0 nearest all lie within the radius: ask for k
            d = np.concatenate([d, np.full((t - s, k - first), np.inf)], axis=1)
            j = np.concatenate([j, np.full((t - s, k - first), n, dtype=j.dtype)], axis=1)
            d[full], j[full] = _knn(tree, vertices[s:t][full], k, bound)
        # most rows of this block filled up → the mesh is dense here: the next block asks for k at once
        first = k if full.mean() > 0.5 else k0
        i = np.arange(s, t, dtype=np.int64)[:, None]
        ok = (j < n) & (d <= r) & (j != i)
        rb = ring[s:t]
        if rb.shape[1] <= 16:                     # the 1-ring is in the row already: drop it from the rest
            for c in range(rb.shape[1]):
                ok &= j != rb[:, c:c + 1]
        elif len(ekey):
            key = np.minimum(i, j) * nv + np.maximum(i, j)
            pos = np.minimum(np.searchsorted(ekey, key), len(ekey) - 1)
            ok &= ekey[pos] != key
        cat = np.concatenate([rb, np.where(ok, j, -1)], axis=1)
        # left-justify: the 1-ring, then the others nearest first (the query's order), padding last
        cat = np.take_along_axis(cat, np.argsort(cat < 0, axis=1, kind="stable"), axis=1)
        width = int(min(max_width, (cat >= 0).sum(axis=1).max(initial=0)))
        yield s, t, cat[:, :width]


def radius_neighbors(vertices, faces, radius: float, max_width: int = MAX_NEIGHBORS) -> np.ndarray:
    """Padded array (V, W) of every vertex within ``radius`` of each vertex, always including its 1-ring;
    −1 where a row has fewer entries.

    Rows are capped at ``max_width`` entries (:data:`MAX_NEIGHBORS`: the 1-ring first, then the nearest others);
    see :func:`radius_neighbor_blocks`, which this concatenates — O(V · max_width) time and memory.
    """
    n = len(vertices)
    blocks = [b for _, _, b in radius_neighbor_blocks(vertices, faces, radius, max_width)]
    width = max((b.shape[1] for b in blocks), default=0)
    out = np.full((n, width), -1, dtype=np.int64)
    s = 0
    for b in blocks:
        out[s:s + len(b), :b.shape[1]] = b
        s += len(b)
    return out
