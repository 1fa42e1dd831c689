"""Self-intersections of a triangle mesh: every pair of non-adjacent faces whose closed triangles intersect.

:func:`self_intersection_pairs` returns every pair of *non-adjacent* faces (no shared vertex index) whose
closed triangles intersect.  Broad phase: faces are grouped by size class (bounding-sphere radius about the
centroid r ≤ r₀·2^(k/4), r₀ = the median radius — faster than the 10th percentile on marching-cubes meshes,
whose smallest tenth are slivers: a fifth less CPU at 100k faces, the same pairs), a ``scipy.spatial.cKDTree``
over the centroids of each class finds every pair whose bounding spheres can touch (``query_pairs`` within a class,
``sparse_distance_matrix`` between classes), then box overlap, "no shared vertex" and a separating-plane
test prune them.  Narrow phase (numpy, batched): two non-coplanar triangles intersect iff one of the six
edges meets the other triangle (the ends of the intersection segment lie on edges); each edge–triangle
test uses signed volumes (the Plücker test), with volumes below 1e-12 × extent³ taken as zero so rounding
noise cannot decide degenerate configurations.  Pairs within 1e-10 × extent of coplanar get a 2-D overlap
test instead (edge–edge crossings plus containment).  Touching counts as intersecting.
Cross-checked in the tests against MeshLab's ``compute_selection_by_self_intersections_per_face``
(which selects faces, not pairs, hence our own count).
Used by the metrics (``self_intersections``) and by methods that must keep their meshes intersection-free.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from . import broadphase
from .arrays import unique_ints
from .compiled import wanted

__all__ = ["self_intersection_pairs", "intersecting_faces", "crossing_pairs"]


def _dot(a, b):
    return np.einsum("ij,ij->i", a, b)


def _orient3d(a, b, c, d):
    """Signed volume det[b − a, c − a, d − a] (rows)."""
    return _dot(b - a, np.cross(c - a, d - a))


def _snap(x, tol):
    """Values within ``tol`` of zero become exactly zero (rounding noise of a degenerate configuration)."""
    return np.where(np.abs(x) <= tol, 0.0, x)


def _segment_hits_triangle(p, q, a, b, c, tol):
    """Closed segment pq meets closed triangle abc (pq not lying in the triangle's plane).

    Signed volumes within ``tol`` (per row) of zero count as zero, so a segment whose end lies in the
    plane, or whose line grazes an edge, is decided by geometry and not by the sign of rounding noise.
    """
    sp = _snap(_orient3d(a, b, c, p), tol)
    sq = _snap(_orient3d(a, b, c, q), tol)
    straddle = (((sp <= 0) & (sq >= 0)) | ((sp >= 0) & (sq <= 0))) & ~((sp == 0) & (sq == 0))
    e1 = _snap(_orient3d(p, q, a, b), tol)
    e2 = _snap(_orient3d(p, q, b, c), tol)
    e3 = _snap(_orient3d(p, q, c, a), tol)
    inside = ((e1 >= 0) & (e2 >= 0) & (e3 >= 0)) | ((e1 <= 0) & (e2 <= 0) & (e3 <= 0))
    return straddle & inside


def _orient2d(a, b, c):
    return (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0])


def _on_segment_2d(a, b, p):
    """p (collinear with ab) lies within the bounding box of ab."""
    return ((np.minimum(a[:, 0], b[:, 0]) <= p[:, 0]) & (p[:, 0] <= np.maximum(a[:, 0], b[:, 0]))
            & (np.minimum(a[:, 1], b[:, 1]) <= p[:, 1]) & (p[:, 1] <= np.maximum(a[:, 1], b[:, 1])))


def _segments_meet_2d(p, q, r, s):
    o1, o2 = _orient2d(p, q, r), _orient2d(p, q, s)
    o3, o4 = _orient2d(r, s, p), _orient2d(r, s, q)
    hit = (o1 * o2 < 0) & (o3 * o4 < 0)
    hit |= (o1 == 0) & _on_segment_2d(p, q, r)
    hit |= (o2 == 0) & _on_segment_2d(p, q, s)
    hit |= (o3 == 0) & _on_segment_2d(r, s, p)
    hit |= (o4 == 0) & _on_segment_2d(r, s, q)
    return hit


def _point_in_triangle_2d(p, a, b, c):
    d1, d2, d3 = _orient2d(a, b, p), _orient2d(b, c, p), _orient2d(c, a, p)
    return ((d1 >= 0) & (d2 >= 0) & (d3 >= 0)) | ((d1 <= 0) & (d2 <= 0) & (d3 <= 0))


def _coplanar_overlap(A, B, normal):
    """2-D overlap of coplanar triangles A, B (N, 3, 3), projected along the dominant normal axis."""
    drop = np.argmax(np.abs(normal), axis=1)
    keep = np.array([[1, 2], [0, 2], [0, 1]])[drop]                       # (N, 2)
    rows = np.arange(len(A))[:, None]
    a2 = np.stack([A[:, k][rows, keep] for k in range(3)], axis=1)       # (N, 3, 2)
    b2 = np.stack([B[:, k][rows, keep] for k in range(3)], axis=1)
    hit = np.zeros(len(A), bool)
    for i in range(3):
        for j in range(3):
            hit |= _segments_meet_2d(a2[:, i], a2[:, (i + 1) % 3], b2[:, j], b2[:, (j + 1) % 3])
    hit |= _point_in_triangle_2d(a2[:, 0], b2[:, 0], b2[:, 1], b2[:, 2])
    hit |= _point_in_triangle_2d(b2[:, 0], a2[:, 0], a2[:, 1], a2[:, 2])
    return hit


def _triangles_intersect(A: np.ndarray, B: np.ndarray, coplanar_tol: float = 1e-10,
                         volume_tol: float = 1e-12) -> np.ndarray:
    """Batched closed triangle–triangle intersection test, A and B of shape (N, 3, 3).

    A pair is coplanar when every vertex of one triangle is within ``coplanar_tol`` × (pair extent) of the
    other's plane; coplanar pairs get the 2-D test only (the 3-D signed volumes are pure rounding noise
    there), all others the six edge–triangle tests with signed volumes below ``volume_tol`` × extent³
    taken as zero.
    """
    hit = np.zeros(len(A), bool)
    scale = _pair_extent(A, B)
    nA = np.cross(A[:, 1] - A[:, 0], A[:, 2] - A[:, 0])
    nB = np.cross(B[:, 1] - B[:, 0], B[:, 2] - B[:, 0])
    lenA = np.linalg.norm(nA, axis=1)
    lenB = np.linalg.norm(nB, axis=1)
    copA = lenA > 0
    copB = lenB > 0
    for k in range(3):
        copA &= np.abs(_dot(B[:, k] - A[:, 0], nA)) <= coplanar_tol * lenA * scale
        copB &= np.abs(_dot(A[:, k] - B[:, 0], nB)) <= coplanar_tol * lenB * scale
    cop = copA | copB
    gen = ~cop
    if gen.any():
        Ag, Bg = A[gen], B[gen]
        tol = volume_tol * scale[gen] ** 3          # signed volumes scale with the cube of the extent
        hg = np.zeros(len(Ag), bool)
        for T, S in ((Ag, Bg), (Bg, Ag)):
            for k in range(3):
                hg |= _segment_hits_triangle(T[:, k], T[:, (k + 1) % 3], S[:, 0], S[:, 1], S[:, 2], tol)
        hit[gen] = hg
    if cop.any():
        normal = np.where((lenA >= lenB)[:, None], nA, nB)
        hit[cop] = _coplanar_overlap(A[cop], B[cop], normal[cop])
    return hit


def _candidate_pairs(tri: np.ndarray, ratio: float = 2.0 ** 0.25, q0: float = 50.0) -> np.ndarray:
    """Face pairs whose bounding spheres (centroid, max centroid–vertex distance) may touch, each once.

    Faces are binned by radius into classes rad ≤ r0·ratioᵏ (r0 = the ``q0`` percentile radius) so that
    small faces are searched with a small radius even when a few faces are huge.
    """
    c = tri.mean(axis=1)
    rad = np.linalg.norm(tri - c[:, None, :], axis=2).max(axis=1)
    pos = rad[rad > 0]
    r0 = float(np.percentile(pos, q0)) if len(pos) else 1.0
    cls = np.zeros(len(tri), dtype=np.int64)
    big = rad > r0
    cls[big] = np.ceil(np.log(rad[big] / r0) / np.log(ratio)).astype(np.int64)
    # guard against rounding in the log: make sure rad <= r0 * ratio**cls
    cls += rad > r0 * ratio ** cls
    levels = np.unique(cls)
    groups = [np.flatnonzero(cls == k) for k in levels]
    trees = [cKDTree(c[g]) for g in groups]
    bound = [r0 * ratio ** float(k) for k in levels]
    out = []
    for a, ga in enumerate(groups):
        pr = trees[a].query_pairs(2.0 * bound[a] * (1 + 1e-9), output_type="ndarray")
        if len(pr):
            out.append(ga[pr])
        for b in range(a + 1, len(groups)):
            sdm = trees[a].sparse_distance_matrix(trees[b], (bound[a] + bound[b]) * (1 + 1e-9),
                                                  output_type="ndarray")
            if len(sdm):
                out.append(np.column_stack([ga[sdm["i"]], groups[b][sdm["j"]]]))
    if not out:
        return np.zeros((0, 2), dtype=np.int64)
    return np.concatenate(out).astype(np.int64)


def _pair_extent(A: np.ndarray, B: np.ndarray) -> np.ndarray:
    """Largest coordinate offset of any vertex of the pair from A's first vertex, (N,)."""
    return np.max(np.abs(np.concatenate([A, B], axis=1) - A[:, :1]).reshape(len(A), -1), axis=1)


def _plane_sides(A: np.ndarray, B: np.ndarray, scale: np.ndarray, tol: float = 1e-10) -> np.ndarray:
    """Signed (scaled) distances (N, 3) of B's vertices from A's plane; values within ``tol`` × extent of
    the plane (rounding noise of coplanar pairs) are set to zero."""
    nA = np.cross(A[:, 1] - A[:, 0], A[:, 2] - A[:, 0])
    s = np.stack([_dot(B[:, k] - A[:, 0], nA) for k in range(3)], axis=1)
    return _snap(s, (tol * np.linalg.norm(nA, axis=1) * scale)[:, None])


def _straddles(s: np.ndarray) -> np.ndarray:
    """Not all three values strictly on one side (a zero counts as touching)."""
    return ~((s > 0).all(axis=1) | (s < 0).all(axis=1))


def self_intersection_pairs(vertices: np.ndarray, faces: np.ndarray, chunk: int = 500_000,
                            compiled: bool | None = None) -> np.ndarray:
    """All intersecting pairs of faces that share no vertex index.

    Parameters
    ----------
    vertices : numpy.ndarray, shape (V, 3)
    faces : numpy.ndarray of int, shape (F, 3)
        The mesh.
    chunk : int
        Candidate pairs tested per block (bounds the memory of the exact test).
    compiled : bool, optional
        True: the broad phase of :mod:`geometry.broadphase` (numba) instead of the numpy/cKDTree one; None:
        compiled from :data:`geometry.compiled.MIN_SIZE` faces on.  The same pairs either way.

    Returns
    -------
    numpy.ndarray of int, shape (P, 2)
        Face index pairs (i, j), i < j, each pair once.
    """
    v = np.asarray(vertices, float)
    f = np.asarray(faces, dtype=np.int64)
    if len(f) < 2:
        return np.zeros((0, 2), dtype=np.int64)
    tri = v[f]
    lo, hi = tri.min(axis=1), tri.max(axis=1)
    compiled = wanted(len(f)) if compiled is None else compiled
    cand = broadphase.box_pairs(lo, hi, f) if compiled else _candidate_pairs(tri)
    found = []
    for s in range(0, len(cand), chunk):
        i, j = cand[s:s + chunk, 0], cand[s:s + chunk, 1]
        if not compiled:        # the compiled broad phase has applied these two filters already
            keep = np.ones(len(i), bool)
            for k in range(3):      # boxes overlap
                keep &= (lo[i, k] <= hi[j, k]) & (lo[j, k] <= hi[i, k])
            i, j = i[keep], j[keep]
            fi, fj = f[i], f[j]
            share = np.zeros(len(i), bool)
            for a in range(3):      # no shared vertex index
                for b in range(3):
                    share |= fi[:, a] == fj[:, b]
            i, j = i[~share], j[~share]
        if not len(i):
            continue
        A, B = tri[i], tri[j]
        # separating planes: all of B strictly on one side of A's plane, or vice versa
        scale = _pair_extent(A, B)
        sB = _plane_sides(A, B, scale)
        sA = _plane_sides(B, A, scale)
        maybe = _straddles(sB) & _straddles(sA)
        i, j = i[maybe], j[maybe]
        if len(i):
            hit = _triangles_intersect(tri[i], tri[j])
            found.append(np.column_stack([i[hit], j[hit]]))
    if not found:
        return np.zeros((0, 2), dtype=np.int64)
    p = np.concatenate(found)
    p.sort(axis=1)
    return p


def intersecting_faces(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Sorted indices of the faces that intersect some non-adjacent face (see :func:`self_intersection_pairs`)."""
    return unique_ints(self_intersection_pairs(vertices, faces))


def crossing_pairs(vertices: np.ndarray, faces: np.ndarray, shrink: float = 1e-3) -> np.ndarray:
    """The pairs of :func:`self_intersection_pairs` that still intersect when each triangle is shrunk towards its
    centroid by the relative amount ``shrink``: parts that cross, not faces that only touch (at an edge, a vertex,
    or by rounding — a mesh written in single precision can make non-adjacent faces meet).  What a closed mesh
    needs to bound one solid: a touch encloses no region on the wrong side, a crossing does."""
    v = np.asarray(vertices, float)
    f = np.asarray(faces, dtype=np.int64)
    pairs = self_intersection_pairs(v, f)
    if not len(pairs):
        return pairs
    tri = v[f]
    centre = tri.mean(axis=1, keepdims=True)
    small = centre + (1.0 - shrink) * (tri - centre)
    return pairs[_triangles_intersect(small[pairs[:, 0]], small[pairs[:, 1]])]
