"""Kernels of the mesh phantoms beside the closest point on a triangle (whose one home is
:mod:`geometry.closest`): the point–segment distance, the per-key argmin of the candidate search, the winding number.

Winding number
    The generalised winding number (exact solid-angle sum, :func:`winding_number`) signs the far field of the
    grid volume (:mod:`phantoms.mesh.grid_sdf`) and cross-checks the pseudonormal sign in the tests.
"""

from __future__ import annotations

import numpy as np

from ..base import as_points

__all__ = ["point_segment_distance", "winding_number", "segments_min"]

def point_segment_distance(p, a, b):
    """Distance from points p to segments ab, all arrays (m, 3), row by row."""
    ab = b - a
    L2 = np.einsum("ij,ij->i", ab, ab)
    with np.errstate(invalid="ignore", divide="ignore"):
        t = np.einsum("ij,ij->i", p - a, ab) / L2
    t = np.clip(np.where(L2 > 0, t, 0.0), 0.0, 1.0)
    return np.linalg.norm(p - (a + t[:, None] * ab), axis=1)


def winding_number(vertices, faces, points, chunk_pairs: int = 4_000_000) -> np.ndarray:
    """Exact generalised winding number of a triangle mesh at points (solid-angle sum / 4π).

    1 inside and 0 outside a closed, outward-oriented surface.  Brute force over all faces (van
    Oosterom–Strackee solid angle), chunked; costs P × F, so meant for checks and a few points.
    """
    V = np.asarray(vertices, float)
    F = np.asarray(faces, np.int64)
    P = as_points(points)
    A, B, C = V[F[:, 0]], V[F[:, 1]], V[F[:, 2]]
    out = np.empty(len(P))
    step = max(1, chunk_pairs // max(len(F), 1))
    for s in range(0, len(P), step):
        q = P[s:s + step, None, :]
        a, b, c = A[None] - q, B[None] - q, C[None] - q
        la, lb, lc = (np.linalg.norm(x, axis=-1) for x in (a, b, c))
        det = np.einsum("pfi,pfi->pf", a, np.cross(b, c))
        den = (la * lb * lc + np.einsum("pfi,pfi->pf", a, b) * lc + np.einsum("pfi,pfi->pf", b, c) * la
               + np.einsum("pfi,pfi->pf", c, a) * lb)
        out[s:s + step] = 2.0 * np.arctan2(det, den).sum(1) / (4.0 * np.pi)
    return out


def segments_min(keys: np.ndarray, values: np.ndarray, n: int):
    """For each key in 0..n-1: index (into values) of its smallest value; −1 where the key is absent."""
    best = np.full(n, -1, np.int64)
    if not len(keys):
        return best
    if (keys[1:] >= keys[:-1]).all():
        order = None
        ks, vs = keys, values
    else:
        order = np.argsort(keys, kind="stable")
        ks, vs = keys[order], values[order]
    starts = np.flatnonzero(np.concatenate([[True], ks[1:] != ks[:-1]]))
    mins = np.minimum.reduceat(vs, starts)
    grp = np.repeat(np.arange(len(starts)), np.diff(np.append(starts, len(ks))))
    hit = np.flatnonzero(vs <= mins[grp])
    gh = grp[hit]
    sel = hit[np.concatenate([[True], gh[1:] != gh[:-1]])]
    best[ks[sel]] = sel if order is None else order[sel]
    return best
