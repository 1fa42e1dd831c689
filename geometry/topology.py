"""Mesh topology: edges, closedness, orientation, Euler characteristic, components, surface sampling.

One toolkit for every package that checks or measures a triangle mesh (the mesh phantoms validate their
input with it, the methods their initial meshes and output, the metrics score with it).  Meshes are plain
arrays: faces (F, 3) int, vertices (V, 3) float where positions matter.

An undirected edge {a, b} is identified by the int64 key ``min·V + max``: one 1-D ``np.unique`` over the
keys is ~4× faster than ``np.unique(axis=0)`` over index pairs and gives the same lexicographic order.
The 3F face edges are always listed slot by slot — every face's edge (0, 1), then every (1, 2), then every
(2, 0) — so face ``f``'s edge in slot ``k`` is entry ``k·F + f``.
"""

from __future__ import annotations

import numpy as np

from .arrays import count_distinct, unique_ints

__all__ = [
    "edges_unique", "face_edge_keys", "face_edges", "edge_face_counts", "directed_edge_repeats",
    "is_closed", "is_manifold", "is_oriented", "euler_characteristic", "genus", "connected_components",
    "is_sphere_like",
    "sample_surface",
]


def _directed(faces: np.ndarray) -> np.ndarray:
    """The 3F directed face edges (3F, 2), slot by slot (see the module docstring)."""
    f = np.asarray(faces)
    return np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])


def face_edge_keys(faces, n_vertices: int) -> np.ndarray:
    """Undirected key ``min·V + max`` of each of the 3F face edges (3F,), slot by slot."""
    e = _directed(faces).astype(np.int64, copy=False)
    e.sort(axis=1)
    return e[:, 0] * np.int64(n_vertices) + e[:, 1]


def edges_unique(faces) -> np.ndarray:
    """Unique undirected edges (E, 2) with ``e[:, 0] < e[:, 1]``, in lexicographic order."""
    faces = np.asarray(faces)
    e = _directed(faces)
    if len(e) == 0:
        return e.reshape(0, 2)
    e.sort(axis=1)
    e64 = e.astype(np.int64, copy=False)
    n = np.int64(e64.max()) + 1
    u = unique_ints(e64[:, 0] * n + e64[:, 1])
    return np.column_stack([u // n, u % n]).astype(e.dtype, copy=False)


def face_edges(faces, n_vertices: int) -> tuple[np.ndarray, np.ndarray]:
    """Unique undirected edges (E, 2) and, per face, the ids of its edges (F, 3).

    Column k of the second array is the edge from corner k to corner k + 1 (ab, bc, ca).
    """
    f = np.asarray(faces, np.int64)
    e = np.stack([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]], axis=1)      # (F, 3, 2)
    es = np.sort(e, axis=2).reshape(-1, 2)
    uniq, inv = np.unique(es[:, 0] * n_vertices + es[:, 1], return_inverse=True)
    return np.column_stack([uniq // n_vertices, uniq % n_vertices]), inv.reshape(-1, 3)


def edge_face_counts(faces, n_vertices: int) -> tuple[np.ndarray, np.ndarray]:
    """Unique undirected edges (E, 2) and the number of faces containing each (E,)."""
    u, counts = np.unique(face_edge_keys(faces, n_vertices), return_counts=True)
    return np.column_stack([u // n_vertices, u % n_vertices]), counts


def directed_edge_repeats(faces, n_vertices: int) -> int:
    """How many directed edges occur in more than one face (0 for a consistently oriented mesh)."""
    d = _directed(faces).astype(np.int64, copy=False)
    _, counts = np.unique(d[:, 0] * n_vertices + d[:, 1], return_counts=True)
    return int((counts > 1).sum())


def is_closed(faces, n_vertices: int) -> bool:
    """Watertight: at least one face and every undirected edge in exactly two faces."""
    _, counts = edge_face_counts(faces, n_vertices)
    return bool(len(counts) > 0 and np.all(counts == 2))


def is_manifold(faces, n_vertices: int) -> bool:
    """Edge-manifold: no undirected edge in more than two faces."""
    _, counts = edge_face_counts(faces, n_vertices)
    return bool(np.all(counts <= 2))


def is_oriented(faces, n_vertices: int) -> bool:
    """Consistently oriented: every directed edge occurs at most once (neighbours traverse a shared edge
    in opposite directions)."""
    return directed_edge_repeats(faces, n_vertices) == 0


def euler_characteristic(faces, n_vertices: int) -> int:
    """χ = V − E + F (V counts every vertex, referenced or not)."""
    edges, _ = edge_face_counts(faces, n_vertices)
    return int(n_vertices - len(edges) + len(faces))


def genus(euler: int, n_components: int = 1) -> int:
    """Genus of a closed orientable surface from χ = Σ (2 − 2gᵢ): g = (2c − χ) / 2 (summed over components)."""
    return int((2 * n_components - euler) // 2)


def connected_components(faces, n_vertices: int | None = None, *, by: str = "vertex") -> tuple[int, np.ndarray]:
    """``(count, labels)`` of the connected components.

    ``by='vertex'``: vertices joined by face edges, labels (V,) over all ``n_vertices`` (an unreferenced
    vertex is a component of its own).  ``by='face'``: faces joined when they share an undirected edge,
    labels (F,); two surfaces touching at a single vertex are two components here, one by vertex.
    """
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components as _cc

    f = np.asarray(faces, np.int64)
    if by == "vertex":
        nv = int(f.max()) + 1 if n_vertices is None else int(n_vertices)
        e = edges_unique(f)
        g = coo_matrix((np.ones(len(e)), (e[:, 0], e[:, 1])), shape=(nv, nv))
    elif by == "face":
        nf = len(f)
        key = face_edge_keys(f, int(f.max()) + 1 if len(f) else 0)
        order = np.argsort(key, kind="stable")
        ks = key[order]
        same = np.flatnonzero(ks[1:] == ks[:-1])                 # consecutive face edges on one edge
        face_of = order % nf
        g = coo_matrix((np.ones(len(same)), (face_of[same], face_of[same + 1])), shape=(nf, nf))
    else:
        raise ValueError(f"by must be 'vertex' or 'face'; got {by!r}")
    n, labels = _cc(g, directed=False)
    return int(n), labels


def is_sphere_like(faces, n_vertices: int) -> bool:
    """One closed, consistently oriented surface with Euler characteristic 2 that uses every vertex."""
    f = np.asarray(faces, np.int64)
    if len(f) == 0 or f.min() < 0 or f.max() >= n_vertices or count_distinct(f, n_vertices) != n_vertices:
        return False
    return (is_closed(f, n_vertices) and is_oriented(f, n_vertices)
            and euler_characteristic(f, n_vertices) == 2
            and connected_components(f, n_vertices, by="face")[0] == 1)


def sample_surface(vertices, faces, n: int, seed=0) -> tuple[np.ndarray, np.ndarray]:
    """``n`` seeded, area-uniform i.i.d. points on a triangle mesh: (points (n, 3), face index (n,)).

    Faces are drawn with probability ∝ area (inverse CDF on the cumulative areas: one uniform per point),
    then a point uniformly inside the face by the square-root barycentric map (two more uniforms per
    point, r₁ then r₂): x = (1 − √r₁) a + √r₁(1 − r₂) b + √r₁ r₂ c.  ``seed`` is anything
    ``np.random.default_rng`` takes; the same seed gives the same points.  Raises ValueError for a mesh
    of zero area.
    """
    v = np.asarray(vertices, float)
    f = np.asarray(faces, dtype=np.int64)
    t = v[f]
    area = 0.5 * np.linalg.norm(np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0]), axis=1)
    cum = np.cumsum(area)
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
