"""Mesh topology, triangle quality and self-intersections (docs/METRICS.md).

The metric functions take a :class:`geometry.mesh.ScoredMesh` (``faces`` None), whose edges and counts they
read, or plain arrays (vertices (V, 3) float, faces (F, 3) int); all are vectorised.

Self-intersections are counted by :func:`geometry.intersections.self_intersection_pairs`.
"""

from __future__ import annotations

import numpy as np

from geometry.arrays import unique_ints
from geometry.intersections import self_intersection_pairs
from geometry.mesh import corner_angles, scored_mesh
from geometry.topology import edge_adjacent_face_pairs, edge_face_counts

__all__ = [
    "drop_degenerate_index_faces", "compact", "edge_face_counts", "edge_adjacent_face_pairs", "topology_metrics",
    "sif_pct",
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

def topology_metrics(vertices, faces: np.ndarray | None = None) -> dict:
    """``watertight`` (every edge in exactly two faces), ``boundary_edges`` (edges in one face),
    ``nonmanifold_edges`` (edges in three or more), ``euler`` (V − E + F), ``components``.

    Parameters
    ----------
    vertices : geometry.mesh.ScoredMesh or numpy.ndarray, shape (V, 3)
        The mesh (its cached edge counts are used), or its vertices.
    faces : numpy.ndarray of int, shape (F, 3), optional
        The triangles, with a vertex array.  The mesh is expected compacted (every vertex referenced) and
        without index-degenerate faces; components are connected through shared vertices.

    Returns
    -------
    dict
    """
    m = scored_mesh(vertices, faces)
    if len(m.vertices) == 0 or len(m.faces) == 0:
        return {"watertight": False, "boundary_edges": 0, "nonmanifold_edges": 0, "euler": 0, "components": 0}
    counts = m.edge_face_counts
    return {"watertight": m.watertight, "boundary_edges": int((counts == 1).sum()),
            "nonmanifold_edges": int((counts > 2).sum()), "euler": m.euler, "components": int(m.n_components)}


def sif_pct(pairs: np.ndarray, n_faces: int) -> float:
    """SIF %: share of the faces that intersect at least one non-adjacent face (``pairs`` from
    :func:`self_intersection_pairs`), in percent."""
    return float(100.0 * len(unique_ints(pairs)) / n_faces) if n_faces else float("nan")


# --------------------------------------------------------------------------- quality

def triangle_angles(vertices, faces: np.ndarray | None = None) -> np.ndarray:
    """The interior angles of every triangle, in degrees.

    Parameters
    ----------
    vertices : geometry.mesh.ScoredMesh or numpy.ndarray, shape (V, 3)
        The mesh, or its vertices.
    faces : numpy.ndarray of int, shape (F, 3), optional
        The triangles, with a vertex array.

    Returns
    -------
    numpy.ndarray, shape (F, 3)
        The angle at each face's corners; a face with a zero-length edge gets 0° at the affected corners.
    """
    m = scored_mesh(vertices, faces)
    return corner_angles(m.vertices, m.faces)


def quality_metrics(vertices, faces: np.ndarray | None = None) -> dict:
    """``min_angle_deg`` (smallest angle of any triangle) and ``pct_angle_lt_10`` (% of triangles with an
    angle below 10°) of a :class:`geometry.mesh.ScoredMesh` or of (vertices, faces)."""
    m = scored_mesh(vertices, faces)
    if len(m.faces) == 0:
        return {"min_angle_deg": float("nan"), "pct_angle_lt_10": float("nan")}
    ang = triangle_angles(m)
    mn = ang.min(axis=1)
    return {"min_angle_deg": float(mn.min()), "pct_angle_lt_10": float(100.0 * np.mean(mn < 10.0))}
