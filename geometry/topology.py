"""Mesh topology: edges, closedness, orientation, Euler characteristic, components.

One toolkit for every package that checks or measures a triangle mesh (the mesh phantoms validate their
input with it, the methods their initial meshes and output, the metrics score with it).  Meshes are plain
arrays: faces (F, 3) int, vertices (V, 3) float where positions matter.

An undirected edge {a, b} is identified by the int64 key ``min·V + max``: one 1-D ``np.unique`` over the
keys is faster than ``np.unique(axis=0)`` over index pairs and gives the same lexicographic order.
The 3F face edges are always listed slot by slot — every face's edge (0, 1), then every (1, 2), then every
(2, 0) — so face ``f``'s edge in slot ``k`` is entry ``k·F + f``.
"""

from __future__ import annotations

import numpy as np

from .arrays import count_distinct, unique_ints

__all__ = [
    "edges_unique", "face_edge_keys", "face_edges", "edge_face_counts", "edge_groups", "edge_adjacent_face_pairs",
    "directed_edge_repeats",
    "is_closed", "is_manifold", "is_oriented", "euler_characteristic", "genus", "connected_components",
    "component_euler",
    "is_sphere_like",
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


def edge_groups(faces, n_vertices: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The 3F face edges grouped by undirected edge, by one stable sort of their keys.

    Parameters
    ----------
    faces : numpy.ndarray of int, shape (F, 3)
    n_vertices : int
        The number of vertices (the key's base).

    Returns
    -------
    order : numpy.ndarray of int, shape (3F,)
        The face edges (slot by slot, see the module docstring) in key order, ties in slot order.
    keys : numpy.ndarray of int64, shape (3F,)
        Their sorted keys ``min·V + max``.
    start, counts : numpy.ndarray of int, shape (E,)
        Where each unique edge's run starts in ``keys`` and how many faces hold it (E unique edges, in
        lexicographic order).
    """
    key = face_edge_keys(faces, n_vertices)
    order = np.argsort(key, kind="stable")
    ks = key[order]
    if len(ks) == 0:
        return order, ks, np.zeros(0, np.int64), np.zeros(0, np.int64)
    start = np.flatnonzero(np.concatenate([[True], ks[1:] != ks[:-1]]))
    counts = np.diff(np.concatenate([start, [len(ks)]]))
    return order, ks, start, counts


def edge_adjacent_face_pairs(faces, n_vertices: int, groups=None) -> tuple[np.ndarray, np.ndarray]:
    """For every edge shared by exactly two faces: the two faces (P, 2) and the edge's vertices (P, 2).

    ``groups``: :func:`edge_groups` of the same mesh, when computed already.
    """
    order, ks, start, counts = edge_groups(faces, n_vertices) if groups is None else groups
    face_of = np.tile(np.arange(len(faces)), 3)
    two = start[counts == 2]
    pairs = np.column_stack([face_of[order[two]], face_of[order[two + 1]]])
    k = ks[two]
    return pairs, np.column_stack([k // n_vertices, k % n_vertices])


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


def euler_characteristic(faces, n_vertices: int, n_edges: int | None = None) -> int:
    """χ = V − E + F (V counts every vertex, referenced or not); ``n_edges``: E, when counted already."""
    if n_edges is None:
        n_edges = len(edge_face_counts(faces, n_vertices)[0])
    return int(n_vertices - n_edges + len(faces))


def component_euler(faces, n_vertices: int, labels: np.ndarray, n: int, groups=None) -> tuple[np.ndarray, np.ndarray]:
    """Per component of the faces (``labels`` (F,) in [0, n)): its Euler characteristic V − E + F, each vertex and
    edge counted once per component that uses it, and how many of its edges it does not hold in exactly two of its
    faces (0: the component is a closed surface).  ``groups``: :func:`edge_groups` of the same faces, when
    computed already.

    Returns
    -------
    euler, open_edges : numpy.ndarray of int, shape (n,)
    """
    f = np.asarray(faces, np.int64)
    labels = np.asarray(labels, np.int64)
    order, _, start, counts = edge_groups(f, n_vertices) if groups is None else groups
    n_f = np.bincount(labels, minlength=n)
    # (edge, component) pairs of the sorted face edges: runs of one edge id, split by component
    edge_id = np.repeat(np.arange(len(start), dtype=np.int64), counts)
    pair, per_pair = np.unique(edge_id * n + labels[order % max(len(f), 1)], return_counts=True)
    owner = pair % n
    n_e = np.bincount(owner, minlength=n)
    n_open = np.bincount(owner, weights=per_pair != 2, minlength=n).astype(np.int64)
    used = unique_ints(np.repeat(labels, 3) * np.int64(n_vertices) + f.reshape(-1))
    n_v = np.bincount(used // n_vertices, minlength=n)
    return n_v - n_e + n_f, n_open


def genus(euler: int, n_components: int = 1) -> int:
    """Genus of a closed orientable surface from χ = Σ (2 − 2gᵢ): g = (2c − χ) / 2 (summed over components)."""
    return int((2 * n_components - euler) // 2)


def connected_components(faces, n_vertices: int | None = None, *, by: str = "vertex", edges=None,
                         face_pairs=None) -> tuple[int, np.ndarray]:
    """``(count, labels)`` of the connected components.

    ``by='vertex'``: vertices joined by face edges, labels (V,) over all ``n_vertices`` (an unreferenced
    vertex is a component of its own).  ``by='face'``: faces joined when they share an undirected edge,
    labels (F,); two surfaces touching at a single vertex are two components here, one by vertex.
    ``edges``: with ``by='vertex'``, :func:`edges_unique` of ``faces`` when computed already.  ``face_pairs``:
    with ``by='face'``, the (P, 2) pairs of faces to join instead (e.g. those of the edges in exactly two faces,
    :func:`edge_adjacent_face_pairs`: then faces meeting only at a non-manifold edge stay apart, as in trimesh).
    """
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components as _cc

    f = np.asarray(faces, np.int64)
    if by == "vertex":
        nv = int(f.max()) + 1 if n_vertices is None else int(n_vertices)
        e = edges_unique(f) if edges is None else edges
        g = coo_matrix((np.ones(len(e)), (e[:, 0], e[:, 1])), shape=(nv, nv))
    elif by == "face" and face_pairs is not None:
        p = np.asarray(face_pairs, np.int64).reshape(-1, 2)
        g = coo_matrix((np.ones(len(p)), (p[:, 0], p[:, 1])), shape=(len(f), len(f)))
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
