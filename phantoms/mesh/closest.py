"""Point–triangle kernels of the mesh phantoms: closest points, point–segment distance, winding number.

Closest point
    :func:`closest_point_on_triangles` is Ericson's region test (*Real-Time Collision Detection*,
    §5.1.5), vectorised over (point, triangle) pairs; :func:`closest_bary` is the same test with the
    per-triangle dot products precomputed (the search index packs them once per mesh).  It returns the
    barycentric coordinates of the closest point and the *feature* it lies on (face interior, one of the
    vertices, one of the edges): the sign test of :mod:`phantoms.mesh.index` needs the feature.

Winding number
    The generalised winding number (exact solid-angle sum, :func:`winding_number`) signs the far field of the
    grid volume (:mod:`phantoms.mesh.grid_sdf`) and cross-checks the pseudonormal sign in the tests.
"""

from __future__ import annotations

import numpy as np

from ..base import as_points

__all__ = ["closest_point_on_triangles", "closest_bary", "point_segment_distance", "winding_number",
           "segments_min", "FACE", "VA", "VB", "VC", "EAB", "EBC", "ECA"]

# feature codes returned by closest_point_on_triangles
FACE, VA, VB, VC, EAB, EBC, ECA = range(7)


def closest_point_on_triangles(p, a, b, c):
    """Closest points on triangles (a, b, c) to points p, all arrays (m, 3), row by row.

    Returns ``(bary, feature)``: barycentric coordinates (m, 3) of the closest point
    ``x = bary[:, 0] a + bary[:, 1] b + bary[:, 2] c`` and the feature it lies on (0 face interior,
    1/2/3 vertex a/b/c, 4/5/6 edge ab/bc/ca).  Ericson, Real-Time Collision Detection §5.1.5, vectorised.
    """
    ab, ac = b - a, c - a
    return closest_bary(p - a, ab, ac, np.einsum("ij,ij->i", ab, ab), np.einsum("ij,ij->i", ab, ac),
                        np.einsum("ij,ij->i", ac, ac))


def closest_bary(ap, ab, ac, abab, abac, acac):
    """Ericson's region tests with the per-triangle dot products precomputed (ap = p − a).

    With d1 = ab·ap and d2 = ac·ap the other four products follow: ab·bp = d1 − ab·ab,
    ac·bp = d2 − ab·ac, ab·cp = d1 − ab·ac, ac·cp = d2 − ac·ac.
    """
    d1 = np.einsum("ij,ij->i", ab, ap)
    d2 = np.einsum("ij,ij->i", ac, ap)
    d3 = d1 - abab
    d4 = d2 - abac
    d5 = d1 - abac
    d6 = d2 - acac
    va = d3 * d6 - d5 * d4
    vb = d5 * d2 - d1 * d6
    vc = d1 * d4 - d3 * d2
    conds = [
        (d1 <= 0) & (d2 <= 0),                                  # vertex a
        (d3 >= 0) & (d4 <= d3),                                 # vertex b
        (vc <= 0) & (d1 >= 0) & (d3 <= 0),                      # edge ab
        (d6 >= 0) & (d5 <= d6),                                 # vertex c
        (vb <= 0) & (d2 >= 0) & (d6 <= 0),                      # edge ca
        (va <= 0) & (d4 - d3 >= 0) & (d5 - d6 >= 0),            # edge bc
    ]
    feature = np.select(conds, [VA, VB, EAB, VC, ECA, EBC], default=FACE).astype(np.int8)
    m = len(ap)
    bary = np.zeros((m, 3))
    with np.errstate(invalid="ignore", divide="ignore"):
        sel = feature == VA
        bary[sel, 0] = 1.0
        sel = feature == VB
        bary[sel, 1] = 1.0
        sel = feature == VC
        bary[sel, 2] = 1.0
        sel = feature == EAB
        t = d1[sel] / (d1[sel] - d3[sel])
        bary[sel, 0], bary[sel, 1] = 1.0 - t, t
        sel = feature == ECA
        t = d2[sel] / (d2[sel] - d6[sel])
        bary[sel, 0], bary[sel, 2] = 1.0 - t, t
        sel = feature == EBC
        t = (d4[sel] - d3[sel]) / ((d4[sel] - d3[sel]) + (d5[sel] - d6[sel]))
        bary[sel, 1], bary[sel, 2] = 1.0 - t, t
        sel = feature == FACE
        den = va[sel] + vb[sel] + vc[sel]
        v = vb[sel] / den
        w = vc[sel] / den
        bary[sel, 0], bary[sel, 1], bary[sel, 2] = 1.0 - v - w, v, w
    bad = ~np.isfinite(bary).all(axis=1)
    if bad.any():  # degenerate (zero-area) triangle reached the face branch: take its nearest vertex
        q = ap[bad]
        cand = np.stack([np.zeros_like(q), ab[bad], ac[bad]], axis=1)
        k = np.argmin(((cand - q[:, None]) ** 2).sum(-1), axis=1)
        bary[bad] = 0.0
        bary[np.flatnonzero(bad), k] = 1.0
        feature[bad] = (VA + k).astype(np.int8)
    return bary, feature


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
