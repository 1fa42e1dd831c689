"""Mesh topology, triangle quality and self-intersections (docs/METRICS.md).

All functions take plain arrays (vertices (V, 3) float, faces (F, 3) int) and are vectorised.

Self-intersections are counted by :func:`geometry.intersections.self_intersection_pairs`.
"""

from __future__ import annotations

import numpy as np

from geometry.arrays import unique_ints
from geometry.intersections import self_intersection_pairs
from geometry.topology import edge_face_counts, face_edge_keys

__all__ = [
    "drop_degenerate_index_faces", "compact", "edge_face_counts", "topology_metrics", "sif_pct",
    "triangle_angles", "quality_metrics", "self_intersection_pairs",
]


# --------------------------------------------------------------------------- cleaning

def drop_degenerate_index_faces(faces: np.ndarray) -> np.ndarray:
    """Faces with three distinct vertex indices (a face like (a, a, b) has no area and no real edges)."""
    f = np.asarray(faces, dtype=np.int64)
    ok = (f[:, 0] != f[:, 1]) & (f[:, 1] != f[:, 2]) & (f[:, 2] != f[:, 0])
    return f[ok]


def compact(vertices: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Drop unreferenced vertices; returns (vertices, faces, old_index_of_each_kept_vertex)."""
    used = unique_ints(faces)
    remap = np.full(len(vertices), -1, dtype=np.int64)
    remap[used] = np.arange(len(used))
    return np.asarray(vertices, float)[used], remap[faces], used


# --------------------------------------------------------------------------- topology

def edge_adjacent_face_pairs(faces: np.ndarray, n_vertices: int) -> tuple[np.ndarray, np.ndarray]:
    """For every edge shared by exactly two faces: the two faces (P, 2) and the edge's vertices (P, 2)."""
    key = face_edge_keys(faces, n_vertices)
    face_of = np.tile(np.arange(len(faces)), 3)
    order = np.argsort(key, kind="stable")
    ks = key[order]
    start = np.flatnonzero(np.concatenate([[True], ks[1:] != ks[:-1]]))
    counts = np.diff(np.concatenate([start, [len(ks)]]))
    two = start[counts == 2]
    pairs = np.column_stack([face_of[order[two]], face_of[order[two + 1]]])
    k = ks[two]
    return pairs, np.column_stack([k // n_vertices, k % n_vertices])


def topology_metrics(vertices: np.ndarray, faces: np.ndarray) -> dict:
    """``watertight`` (every edge in exactly two faces), ``boundary_edges`` (edges in one face),
    ``nonmanifold_edges`` (edges in three or more), ``euler`` (V − E + F), ``components``.

    Expects a compacted mesh (every vertex referenced) without index-degenerate faces; components are
    connected through shared vertices.  One sort of the edge keys serves every count.
    """
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components as _cc

    nv = len(vertices)
    if nv == 0 or len(faces) == 0:
        return {"watertight": False, "boundary_edges": 0, "nonmanifold_edges": 0, "euler": 0, "components": 0}
    key = np.sort(face_edge_keys(faces, nv))
    first = np.concatenate([[True], key[1:] != key[:-1]])
    uniq = key[first]
    counts = np.diff(np.append(np.flatnonzero(first), len(key)))
    g = coo_matrix((np.ones(len(uniq)), (uniq // nv, uniq % nv)), shape=(nv, nv))
    n_comp, _ = _cc(g, directed=False)
    return {"watertight": bool(np.all(counts == 2)), "boundary_edges": int((counts == 1).sum()),
            "nonmanifold_edges": int((counts > 2).sum()), "euler": int(nv - len(uniq) + len(faces)),
            "components": int(n_comp)}


def sif_pct(pairs: np.ndarray, n_faces: int) -> float:
    """SIF %: share of the faces that intersect at least one non-adjacent face (``pairs`` from
    :func:`self_intersection_pairs`), in percent."""
    return float(100.0 * len(unique_ints(pairs)) / n_faces) if n_faces else float("nan")


# --------------------------------------------------------------------------- quality

def triangle_angles(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """The interior angles of every triangle, in degrees.

    Parameters
    ----------
    vertices : numpy.ndarray, shape (V, 3)
    faces : numpy.ndarray of int, shape (F, 3)
        The mesh.

    Returns
    -------
    numpy.ndarray, shape (F, 3)
        The angle at each face's corners; a face with a zero-length edge gets 0° at the affected corners.
    """
    t = np.asarray(vertices, float)[faces]
    out = np.empty((len(faces), 3))
    for k in range(3):
        a = t[:, (k + 1) % 3] - t[:, k]
        b = t[:, (k + 2) % 3] - t[:, k]
        na = np.linalg.norm(a, axis=1)
        nb = np.linalg.norm(b, axis=1)
        # atan2(|a×b|, a·b) is accurate for tiny and near-180° angles, unlike arccos
        ang = np.degrees(np.arctan2(np.linalg.norm(np.cross(a, b), axis=1), np.einsum("ij,ij->i", a, b)))
        out[:, k] = np.where((na > 0) & (nb > 0), ang, 0.0)
    return out


def quality_metrics(vertices: np.ndarray, faces: np.ndarray) -> dict:
    """``min_angle_deg`` (smallest angle of any triangle) and ``pct_angle_lt_10`` (% of triangles with an
    angle below 10°)."""
    if len(faces) == 0:
        return {"min_angle_deg": float("nan"), "pct_angle_lt_10": float("nan")}
    ang = triangle_angles(vertices, faces)
    mn = ang.min(axis=1)
    return {"min_angle_deg": float(mn.min()), "pct_angle_lt_10": float(100.0 * np.mean(mn < 10.0))}
