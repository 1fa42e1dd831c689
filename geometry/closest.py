"""Exact unsigned distance from points to a triangle mesh: a uniform grid of triangle boxes, searched in shells.

The metrics' truth → mesh and band → mesh distances query ~10⁵ points that all lie within a few grid steps of
the mesh.  The triangles are bucketed into a uniform grid whose cell is about twice the mean triangle size
(each triangle in every cell its bounding box overlaps); a point's search visits the cells at Chebyshev
distance 0, 1, 2, … from its own cell and stops as soon as the closest triangle found is no farther than the
boundary of the visited block — every triangle outside the block is at least that far, so the answer is exact
(the closest point on a triangle by Ericson's region test, in double precision).  Inside the block a cell
farther from the point than the best distance so far is not opened: a closer triangle would have its closest
point in a cell it is bucketed in, and that cell would be closer.  A point far outside the
mesh's box is searched the same way from the nearest cell.

Why not pymeshlab's ``compute_scalar_by_distance_from_another_mesh_per_vertex``: it returns float32 and is
slower on these queries; this search also releases the GIL, so the metrics run it beside numpy's work (timings
and the command that measures them: docs/NOTES.md, "The exact distance query").  The tests compare this
search with a brute-force numpy distance and with pymeshlab.
"""

from __future__ import annotations

import numpy as np

import numba

__all__ = ["point_mesh_distance", "MAX_CELLS"]

#: error_model="numpy": a division by zero gives inf/nan instead of raising (none happens: degenerate triangles
#: are handled first), and the compiler need not check every division
_jit = numba.njit(cache=True, nogil=True, error_model="numpy")

#: at most this many grid cells (memory: one int64 per cell plus one int32 per triangle-cell pair)
MAX_CELLS = 1 << 21


@_jit
def _bucket(lo, cell, dims, tmin, tmax):
    """CSR (start, items) of the triangles whose box overlaps each cell."""
    nx, ny, nz = dims[0], dims[1], dims[2]
    nt = tmin.shape[0]
    count = np.zeros(nx * ny * nz + 1, np.int64)
    rng = np.empty((nt, 6), np.int64)
    for t in range(nt):
        for a in range(3):
            d = dims[a]
            i0 = int((tmin[t, a] - lo[a]) / cell)
            i1 = int((tmax[t, a] - lo[a]) / cell)
            rng[t, a] = min(max(i0, 0), d - 1)
            rng[t, 3 + a] = min(max(i1, 0), d - 1)
        for i in range(rng[t, 0], rng[t, 3] + 1):
            for j in range(rng[t, 1], rng[t, 4] + 1):
                for k in range(rng[t, 2], rng[t, 5] + 1):
                    count[(i * ny + j) * nz + k + 1] += 1
    for c in range(nx * ny * nz):
        count[c + 1] += count[c]
    fill = count[:-1].copy()
    items = np.empty(count[-1], np.int32)
    for t in range(nt):
        for i in range(rng[t, 0], rng[t, 3] + 1):
            for j in range(rng[t, 1], rng[t, 4] + 1):
                for k in range(rng[t, 2], rng[t, 5] + 1):
                    c = (i * ny + j) * nz + k
                    items[fill[c]] = t
                    fill[c] += 1
    return count, items


@_jit
def _seg_dist2(px, py, pz, a0, a1, a2, b0, b1, b2):
    ex, ey, ez = b0 - a0, b1 - a1, b2 - a2
    ee = ex * ex + ey * ey + ez * ez
    s = 0.0
    if ee > 0.0:
        s = min(max(((px - a0) * ex + (py - a1) * ey + (pz - a2) * ez) / ee, 0.0), 1.0)
    return (px - a0 - s * ex) ** 2 + (py - a1 - s * ey) ** 2 + (pz - a2 - s * ez) ** 2


@_jit
def _tri_dist2(px, py, pz, tri, t):
    """Squared distance from p to triangle ``tri[t]`` = (a, b, c): Ericson, Real-Time Collision Detection,
    5.1.5.  (Scalars only: an array view per call costs more than the test itself.)"""
    a = (tri[t, 0, 0], tri[t, 0, 1], tri[t, 0, 2])
    b = (tri[t, 1, 0], tri[t, 1, 1], tri[t, 1, 2])
    c = (tri[t, 2, 0], tri[t, 2, 1], tri[t, 2, 2])
    ux, uy, uz = b[0] - a[0], b[1] - a[1], b[2] - a[2]
    wx, wy, wz = c[0] - a[0], c[1] - a[1], c[2] - a[2]
    nx, ny, nz = uy * wz - uz * wy, uz * wx - ux * wz, ux * wy - uy * wx
    if nx * nx + ny * ny + nz * nz == 0.0:     # a degenerate (zero-area) triangle: its edges decide
        return min(_seg_dist2(px, py, pz, a[0], a[1], a[2], b[0], b[1], b[2]),
                   min(_seg_dist2(px, py, pz, b[0], b[1], b[2], c[0], c[1], c[2]),
                       _seg_dist2(px, py, pz, c[0], c[1], c[2], a[0], a[1], a[2])))
    abx, aby, abz = b[0] - a[0], b[1] - a[1], b[2] - a[2]
    acx, acy, acz = c[0] - a[0], c[1] - a[1], c[2] - a[2]
    apx, apy, apz = px - a[0], py - a[1], pz - a[2]
    d1 = abx * apx + aby * apy + abz * apz
    d2 = acx * apx + acy * apy + acz * apz
    if d1 <= 0.0 and d2 <= 0.0:
        qx, qy, qz = a[0], a[1], a[2]
    else:
        bpx, bpy, bpz = px - b[0], py - b[1], pz - b[2]
        d3 = abx * bpx + aby * bpy + abz * bpz
        d4 = acx * bpx + acy * bpy + acz * bpz
        if d3 >= 0.0 and d4 <= d3:
            qx, qy, qz = b[0], b[1], b[2]
        else:
            vc = d1 * d4 - d3 * d2
            if vc <= 0.0 and d1 >= 0.0 and d3 <= 0.0:
                v = d1 / (d1 - d3)
                qx, qy, qz = a[0] + v * abx, a[1] + v * aby, a[2] + v * abz
            else:
                cpx, cpy, cpz = px - c[0], py - c[1], pz - c[2]
                d5 = abx * cpx + aby * cpy + abz * cpz
                d6 = acx * cpx + acy * cpy + acz * cpz
                if d6 >= 0.0 and d5 <= d6:
                    qx, qy, qz = c[0], c[1], c[2]
                else:
                    vb = d5 * d2 - d1 * d6
                    if vb <= 0.0 and d2 >= 0.0 and d6 <= 0.0:
                        w = d2 / (d2 - d6)
                        qx, qy, qz = a[0] + w * acx, a[1] + w * acy, a[2] + w * acz
                    else:
                        va = d3 * d6 - d5 * d4
                        if va <= 0.0 and (d4 - d3) >= 0.0 and (d5 - d6) >= 0.0:
                            w = (d4 - d3) / ((d4 - d3) + (d5 - d6))
                            qx = b[0] + w * (c[0] - b[0])
                            qy = b[1] + w * (c[1] - b[1])
                            qz = b[2] + w * (c[2] - b[2])
                        else:
                            den = va + vb + vc             # = |ab × ac|² > 0
                            v = vb / den
                            w = vc / den
                            qx = a[0] + abx * v + acx * w
                            qy = a[1] + aby * v + acy * w
                            qz = a[2] + abz * v + acz * w
    return (px - qx) ** 2 + (py - qy) ** 2 + (pz - qz) ** 2


@_jit
def _query(points, tri, lo, cell, dims, start, items):
    n = points.shape[0]
    nx, ny, nz = dims[0], dims[1], dims[2]
    out = np.empty(n)
    stamp = np.full(tri.shape[0], -1, np.int64)
    rmax = max(nx, max(ny, nz))
    for q in range(n):
        px, py, pz = points[q, 0], points[q, 1], points[q, 2]
        ci = min(max(int(np.floor((px - lo[0]) / cell)), 0), nx - 1)
        cj = min(max(int(np.floor((py - lo[1]) / cell)), 0), ny - 1)
        ck = min(max(int(np.floor((pz - lo[2]) / cell)), 0), nz - 1)
        best = np.inf
        for r in range(rmax + 1):
            i0, i1 = max(ci - r, 0), min(ci + r, nx - 1)
            j0, j1 = max(cj - r, 0), min(cj + r, ny - 1)
            k0, k1 = max(ck - r, 0), min(ck + r, nz - 1)
            for i in range(i0, i1 + 1):
                dx = max(lo[0] + i * cell - px, px - (lo[0] + (i + 1) * cell), 0.0)
                for j in range(j0, j1 + 1):
                    shell_ij = abs(i - ci) == r or abs(j - cj) == r
                    dy = max(lo[1] + j * cell - py, py - (lo[1] + (j + 1) * cell), 0.0)
                    dxy = dx * dx + dy * dy
                    if dxy >= best:
                        continue                          # the whole column of cells is no closer
                    for k in range(k0, k1 + 1):
                        if not shell_ij and abs(k - ck) != r:
                            continue                      # inside the block already searched
                        dz = max(lo[2] + k * cell - pz, pz - (lo[2] + (k + 1) * cell), 0.0)
                        if dxy + dz * dz >= best:
                            continue                      # every point of this cell is farther than the best
                        c = (i * ny + j) * nz + k
                        for s in range(start[c], start[c + 1]):
                            t = items[s]
                            if stamp[t] == q:
                                continue
                            stamp[t] = q
                            d = _tri_dist2(px, py, pz, tri, t)
                            if d < best:
                                best = d
            # every triangle not yet seen lies outside the block [i0, i1 + 1) × … of cells: at least as far
            # as the block's nearest face that is not the grid's own boundary (no triangle lies beyond those)
            bound = np.inf
            if i0 > 0:
                bound = min(bound, px - (lo[0] + i0 * cell))
            if i1 < nx - 1:
                bound = min(bound, lo[0] + (i1 + 1) * cell - px)
            if j0 > 0:
                bound = min(bound, py - (lo[1] + j0 * cell))
            if j1 < ny - 1:
                bound = min(bound, lo[1] + (j1 + 1) * cell - py)
            if k0 > 0:
                bound = min(bound, pz - (lo[2] + k0 * cell))
            if k1 < nz - 1:
                bound = min(bound, lo[2] + (k1 + 1) * cell - pz)
            if bound == np.inf or (bound > 0.0 and best <= bound * bound):
                break
        out[q] = np.sqrt(best)
    return out


def point_mesh_distance(points, vertices, faces, cells_per_axis: int | None = None) -> np.ndarray:
    """Exact unsigned distance (float64) from each point to the closest point of the triangle mesh.

    Parameters
    ----------
    points : (P, 3) float array.
    vertices : (V, 3) float array.
    faces : (F, 3) int array (at least one face).
    cells_per_axis : int, optional
        At most this many grid cells along the mesh box's longest side.  Default: cells of about twice a
        triangle, right for points near the surface.  Points far from it (a grid's points all over its box)
        search shells of cells out to their distance, so a coarse grid (e.g. 16) is much cheaper for them:
        the answer is exact either way.

    Returns
    -------
    (P,) float array.
    """
    p = np.ascontiguousarray(points, np.float64).reshape(-1, 3)
    v = np.asarray(vertices, np.float64)
    f = np.asarray(faces, np.int64)
    if len(p) == 0:
        return np.zeros(0)
    if len(f) == 0:
        raise ValueError("point_mesh_distance: the mesh has no faces")
    tri = np.ascontiguousarray(v[f])                                  # (F, 3, 3)
    tmin, tmax = tri.min(1), tri.max(1)
    lo, hi = tmin.min(0), tmax.max(0)
    extent = np.maximum(hi - lo, 1e-12)
    size = float(np.median((tmax - tmin).max(1)))                     # a typical triangle's box
    cell = max(2.0 * size, float(extent.max()) / 512.0, 1e-12)
    if cells_per_axis is not None:
        cell = max(cell, float(extent.max()) / max(int(cells_per_axis), 1))
    while np.prod(np.floor(extent / cell) + 1) > MAX_CELLS:
        cell *= 1.25
    dims = (np.floor(extent / cell) + 1).astype(np.int64)
    start, items = _bucket(lo, cell, dims, np.ascontiguousarray(tmin), np.ascontiguousarray(tmax))
    # queries in cell order: neighbouring queries read the same cells and triangles (from cache, not memory)
    ijk = np.clip(np.floor((p - lo) / cell).astype(np.int64), 0, dims - 1)
    order = np.argsort((ijk[:, 0] * dims[1] + ijk[:, 1]) * dims[2] + ijk[:, 2], kind="stable")
    out = np.empty(len(p))
    out[order] = _query(np.ascontiguousarray(p[order]), tri, lo, cell, dims, start, items)
    return out
