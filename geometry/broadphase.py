"""Compiled broad phase of the self-intersection test: face pairs whose bounding boxes overlap and that share
no vertex index, each once.

:func:`geometry.intersections.self_intersection_pairs` needs exactly these pairs before its exact tests; its
numpy reference (size-classed ``cKDTree`` queries over face centroids, then box overlap and the shared-vertex
filter) spends 70 % of its time there on a 67k-face mesh, nearly all on neighbouring faces that share a
vertex.  This kernel puts every face into the cells of a uniform grid (twice the median box wide) that its box
touches, tests the pairs within each cell — closed boxes overlap (touching counts), no vertex index shared —
and reports a pair only in the cell holding the lower corner of the two boxes' intersection, so each once:
the same set, the whole test four times faster.  The tests compare both (``tests/test_geometry_broadphase.py``).
"""

from __future__ import annotations

import numpy as np

from .compiled import jit

__all__ = ["box_pairs"]


@jit
def _cell_entries(c_lo, c_hi, dims):
    """(cell key, face) of every cell each face's box touches, in face order."""
    F = c_lo.shape[0]
    total = 0
    for i in range(F):
        total += (c_hi[i, 0] - c_lo[i, 0] + 1) * (c_hi[i, 1] - c_lo[i, 1] + 1) * (c_hi[i, 2] - c_lo[i, 2] + 1)
    keys = np.empty(total, dtype=np.int64)
    owner = np.empty(total, dtype=np.int64)
    n = 0
    for i in range(F):
        for x0 in range(c_lo[i, 0], c_hi[i, 0] + 1):
            for x1 in range(c_lo[i, 1], c_hi[i, 1] + 1):
                for x2 in range(c_lo[i, 2], c_hi[i, 2] + 1):
                    keys[n] = (x0 * dims[1] + x1) * dims[2] + x2
                    owner[n] = i
                    n += 1
    return keys, owner


@jit
def _pairs_in_cells(lo, hi, faces, keys, owner, origin, cell, dims):
    """Within each cell: pairs with overlapping boxes and no shared vertex, reported only in the cell that
    holds the lower corner of the two boxes' intersection (so each pair once)."""
    m = keys.shape[0]
    cap = 4 * lo.shape[0] + 16
    out = np.empty((cap, 2), dtype=np.int64)
    n = 0
    s = 0
    while s < m:
        e = s + 1
        while e < m and keys[e] == keys[s]:
            e += 1
        key = keys[s]
        for p in range(s, e):
            i = owner[p]
            a0, a1, a2 = faces[i, 0], faces[i, 1], faces[i, 2]
            for q in range(p + 1, e):
                j = owner[q]
                if (lo[i, 0] > hi[j, 0] or lo[j, 0] > hi[i, 0] or lo[i, 1] > hi[j, 1]
                        or lo[j, 1] > hi[i, 1] or lo[i, 2] > hi[j, 2] or lo[j, 2] > hi[i, 2]):
                    continue
                b0, b1, b2 = faces[j, 0], faces[j, 1], faces[j, 2]
                if (a0 == b0 or a0 == b1 or a0 == b2 or a1 == b0 or a1 == b1 or a1 == b2
                        or a2 == b0 or a2 == b1 or a2 == b2):
                    continue
                k0 = min(int((max(lo[i, 0], lo[j, 0]) - origin[0]) / cell), dims[0] - 1)
                k1 = min(int((max(lo[i, 1], lo[j, 1]) - origin[1]) / cell), dims[1] - 1)
                k2 = min(int((max(lo[i, 2], lo[j, 2]) - origin[2]) / cell), dims[2] - 1)
                if (k0 * dims[1] + k1) * dims[2] + k2 != key:
                    continue
                if n == cap:
                    grown = np.empty((2 * cap, 2), dtype=np.int64)
                    grown[:n] = out[:n]
                    out = grown
                    cap *= 2
                out[n, 0] = min(i, j)
                out[n, 1] = max(i, j)
                n += 1
        s = e
    return out[:n]


def box_pairs(lo: np.ndarray, hi: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Pairs (i < j) of faces whose closed boxes [lo, hi] overlap and that share no vertex index, (P, 2)."""
    lo = np.ascontiguousarray(lo, dtype=np.float64)
    hi = np.ascontiguousarray(hi, dtype=np.float64)
    faces = np.ascontiguousarray(faces, dtype=np.int64)
    if len(faces) < 2:
        return np.zeros((0, 2), dtype=np.int64)
    origin = lo.min(axis=0)
    span = float(np.max(hi.max(axis=0) - origin))
    ext = np.max(hi - lo, axis=1)
    # cells twice the median box: a typical box touches 1–8 of them; at most ~256 a side
    cell = max(2.0 * float(np.median(ext)), span / 256.0, 1e-300)
    c_lo = np.floor((lo - origin) / cell).astype(np.int64)
    c_hi = np.floor((hi - origin) / cell).astype(np.int64)
    dims = c_hi.max(axis=0) + 1
    np.minimum(c_lo, dims - 1, out=c_lo)
    keys, owner = _cell_entries(c_lo, c_hi, dims)
    order = np.argsort(keys, kind="stable")
    return _pairs_in_cells(lo, hi, faces, keys[order], owner[order], origin, cell, dims)
