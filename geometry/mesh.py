"""Basic per-face and per-vertex quantities and vertex neighbourhoods of a triangle mesh."""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from .topology import edges_unique  # noqa: F401  (geometry.mesh.edges_unique: its old home)


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
    v = np.asarray(vertices, float)
    f = np.asarray(faces)
    if len(f) == 0:
        return 0.0
    v0, v1, v2 = (v[f[:, k]] for k in range(3))
    return float(np.einsum("ij,ij->i", v0, np.cross(v1, v2)).sum()) / 6.0


def face_areas(vertices, faces) -> np.ndarray:
    """Area of every face, shape (F,)."""
    return 0.5 * np.linalg.norm(_face_cross(np.asarray(vertices, float), np.asarray(faces)), axis=1)


def face_normals(vertices, faces) -> np.ndarray:
    """Unit normal of every face (right-hand rule on the vertex order), shape (F, 3)."""
    c = _face_cross(np.asarray(vertices, float), np.asarray(faces))
    n = np.linalg.norm(c, axis=1, keepdims=True)
    return c / np.where(n > 0, n, 1.0)


def vertex_normals(vertices, faces) -> np.ndarray:
    """Area-weighted average of the incident face normals, normalised, shape (V, 3).

    (The un-normalised face cross product is area × normal × 2, so summing it is the area weighting.)
    """
    vertices = np.asarray(vertices, float)
    faces = np.asarray(faces)
    c = _face_cross(vertices, faces)
    acc = np.zeros_like(vertices)
    for k in range(3):
        np.add.at(acc, faces[:, k], c)
    n = np.linalg.norm(acc, axis=1, keepdims=True)
    return acc / np.where(n > 0, n, 1.0)


def lumped_vertex_areas(vertices, faces) -> np.ndarray:
    """One third of the area of the incident faces per vertex (barycentric lumped mass), shape (V,)."""
    a = face_areas(vertices, faces) / 3.0
    faces = np.asarray(faces)
    return np.bincount(faces.ravel(), weights=np.repeat(a, 3), minlength=len(vertices))


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


def radius_neighbors(vertices, faces, radius: float, max_width: int = 96) -> np.ndarray:
    """Padded array of every vertex within ``radius`` of each vertex, always including its 1-ring.

    Rows are capped at ``max_width`` entries (the 1-ring first, then the nearest others).
    """
    vertices = np.asarray(vertices, float)
    e = edges_unique(faces)
    ring_i = np.concatenate([e[:, 0], e[:, 1]])
    ring_j = np.concatenate([e[:, 1], e[:, 0]])
    pairs = cKDTree(vertices).query_pairs(float(radius), output_type="ndarray")
    if len(pairs) and len(e):
        # drop radius pairs that are ring edges (the ring entry comes first anyway): both pair lists are
        # unique with a < b and the edge keys are sorted, so a searchsorted replaces a global unique
        nv = np.int64(len(vertices))
        ekey = e[:, 0].astype(np.int64) * nv + e[:, 1]
        pkey = pairs[:, 0].astype(np.int64) * nv + pairs[:, 1]
        pos = np.minimum(np.searchsorted(ekey, pkey), len(ekey) - 1)
        pairs = pairs[ekey[pos] != pkey]
    if len(pairs):
        pi = np.concatenate([pairs[:, 0], pairs[:, 1]])
        pj = np.concatenate([pairs[:, 1], pairs[:, 0]])
        # order the radius pairs by distance so a cap keeps the nearest ones
        d = np.linalg.norm(vertices[pi] - vertices[pj], axis=1)
        o = np.argsort(d, kind="stable")
        pi, pj = pi[o], pj[o]
    else:
        pi = pj = np.zeros(0, dtype=np.int64)
    i = np.concatenate([ring_i, pi])
    j = np.concatenate([ring_j, pj])
    return padded_from_pairs(i, j, len(vertices), max_width=max_width)
