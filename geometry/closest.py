"""The closest point on a triangle, and the exact unsigned distance from points to a triangle mesh.

The point–triangle kernel
    :func:`point_triangle` is Ericson's region test (*Real-Time Collision Detection*, 5.1.5) in double precision,
    compiled: the squared distance, the feature the closest point lies on (:data:`FACE`, a vertex :data:`VA` …,
    an edge :data:`EAB` …), its barycentric coordinates and the point.  A degenerate triangle — zero area, or one
    whose region test divides by zero — is its three edges.  It is the suite's one point–triangle test: the
    metrics' distance below, the mesh phantoms' search index (:func:`closest_on_faces`) and their grid signed
    distance (``phantoms.mesh.grid_kernels``) all call it.  :func:`closest_point_on_triangles` is its numpy
    reference, equal bit for bit (the tests hold them to it).

The distance to a mesh
    The metrics' truth → mesh and band → mesh distances query ~10⁵ points that all lie within a few grid steps
    of the mesh.  The triangles are bucketed into a uniform grid whose cell is :data:`CELL_SIZE` times the median
    triangle's box (each triangle in every cell its bounding box overlaps); a point's search visits the cells at
    Chebyshev distance 0, 1, 2, … from its own cell and stops as soon as the closest triangle found is no farther
    than the boundary of the visited block — every triangle outside the block is at least that far, so the answer
    is exact.  Inside the block a cell, and in an opened cell a triangle's box, farther from the point than the
    best distance so far is skipped: a closer triangle would have its closest point in a cell it is bucketed in,
    and inside its box.  "Farther" means by more than a tolerance far above rounding (:data:`PRUNE_TOL` of the
    coordinates' magnitude), so the search returns the smallest distance the point–triangle kernel gives over all
    the triangles, bit for bit the brute-force minimum.  A point far outside the mesh's box is searched the same
    way from the nearest cell.

Points far from the mesh (the SDF energy's grid points) go to :func:`geometry.bvh.point_mesh_distance_far`: a
bounding-volume hierarchy with the same kernel and tolerance, for the same numbers with fewer tests there.

Why not pymeshlab's ``compute_scalar_by_distance_from_another_mesh_per_vertex``: it returns float32 and is
slower on these queries; this search also releases the GIL, so the metrics run it beside numpy's work.  The
tests compare this search with a brute-force numpy distance and with pymeshlab.
"""

from __future__ import annotations

import math

import numba
import numpy as np

__all__ = ["point_mesh_distance", "point_triangle", "triangle_point", "closest_on_faces", "closest_point_on_triangles",
           "bucket_triangles", "box_distance2", "prune_tolerance", "triangle_boxes", "MAX_CELLS", "CELL_SIZE",
           "PRUNE_TOL", "FACE", "VA", "VB", "VC", "EAB", "EBC", "ECA"]

#: the feature of a triangle (a, b, c) its closest point lies on: the interior, a vertex, an edge
FACE, VA, VB, VC, EAB, EBC, ECA = range(7)

#: error_model="numpy": a division by zero gives inf/nan instead of raising (the point–triangle test then takes the
#: triangle's edges), and the compiler need not check every division
_jit = numba.njit(cache=True, nogil=True, error_model="numpy")

#: at most this many grid cells (memory: one int64 per cell plus one int32 per triangle-cell pair)
MAX_CELLS = 1 << 21

#: the grid cell of :func:`point_mesh_distance`, in median triangle boxes (fewest tests per near query: a smaller
#: cell holds fewer triangles, a larger one needs fewer neighbour cells)
CELL_SIZE = 1.5

#: the searches (this grid, :mod:`geometry.bvh`) skip a cell or box only when it is farther than the best distance
#: so far by this fraction of the largest coordinate magnitude: many orders of magnitude above the rounding of the
#: box and point–triangle distances, so no triangle the kernel puts at the minimum is ever skipped
PRUNE_TOL = 1e-9


@_jit
def bucket_triangles(lo, cell, dims, tmin, tmax):
    """The triangles whose bounding box overlaps each cell of a uniform grid, in CSR form (compiled).

    Parameters
    ----------
    lo : (3,) float array, the grid's lower corner.
    cell : float, the cells' side.
    dims : (3,) int array, the cells along each axis (cell (i, j, k) is number (i · ny + j) · nz + k).
    tmin, tmax : (T, 3) float arrays, the triangles' bounding boxes; a box reaching past the grid is clamped to it.

    Returns
    -------
    start (C + 1,) int64 and items int32: the triangles of cell c, in increasing order, are
    ``items[start[c]:start[c + 1]]``.
    """
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
def _segment(px, py, pz, a0, a1, a2, b0, b1, b2):
    """(squared distance, s) from p to the segment a + s (b − a), s ∈ [0, 1] (s = 0 when a = b)."""
    ex, ey, ez = b0 - a0, b1 - a1, b2 - a2
    ee = ex * ex + ey * ey + ez * ez
    s = 0.0
    if ee > 0.0:
        s = min(max(((px - a0) * ex + (py - a1) * ey + (pz - a2) * ez) / ee, 0.0), 1.0)
    return (px - a0 - s * ex) ** 2 + (py - a1 - s * ey) ** 2 + (pz - a2 - s * ez) ** 2, s


@_jit
def _on_edges(px, py, pz, ax, ay, az, bx, by, bz, cx, cy, cz):
    """:func:`point_triangle` for a degenerate triangle: the closest point of its three edges (ab, bc, ca; the
    first of equally near ones)."""
    d, s = _segment(px, py, pz, ax, ay, az, bx, by, bz)
    e = 0
    d1, s1 = _segment(px, py, pz, bx, by, bz, cx, cy, cz)
    if d1 < d:
        d, s, e = d1, s1, 1
    d2, s2 = _segment(px, py, pz, cx, cy, cz, ax, ay, az)
    if d2 < d:
        d, s, e = d2, s2, 2
    if e == 0:
        feature = VA if s == 0.0 else (VB if s == 1.0 else EAB)
        return d, feature, 1.0 - s, s, 0.0, ax + s * (bx - ax), ay + s * (by - ay), az + s * (bz - az)
    if e == 1:
        feature = VB if s == 0.0 else (VC if s == 1.0 else EBC)
        return d, feature, 0.0, 1.0 - s, s, bx + s * (cx - bx), by + s * (cy - by), bz + s * (cz - bz)
    feature = VC if s == 0.0 else (VA if s == 1.0 else ECA)
    return d, feature, s, 0.0, 1.0 - s, cx + s * (ax - cx), cy + s * (ay - cy), cz + s * (az - cz)


@_jit
def point_triangle(px, py, pz, ax, ay, az, bx, by, bz, cx, cy, cz):
    """The closest point of triangle (a, b, c) to p: Ericson, *Real-Time Collision Detection*, 5.1.5.

    Returns ``(d2, feature, ba, bb, bc, qx, qy, qz)``: the squared distance |p − q|², the feature q lies on
    (:data:`FACE`, :data:`VA` … :data:`ECA`), its barycentric coordinates (q = ba a + bb b + bc c) and q.
    A degenerate triangle — zero area (|ab × ac|² = 0), or one whose region test divides by zero — is its
    three edges (:func:`_on_edges`): the one rule for every caller.  Scalars in and out: an array view per
    call costs more than the test itself.  :func:`closest_point_on_triangles` is the numpy reference, equal
    bit for bit.
    """
    abx, aby, abz = bx - ax, by - ay, bz - az
    acx, acy, acz = cx - ax, cy - ay, cz - az
    nx, ny, nz = aby * acz - abz * acy, abz * acx - abx * acz, abx * acy - aby * acx
    if nx * nx + ny * ny + nz * nz == 0.0:
        return _on_edges(px, py, pz, ax, ay, az, bx, by, bz, cx, cy, cz)
    apx, apy, apz = px - ax, py - ay, pz - az
    d1 = abx * apx + aby * apy + abz * apz
    d2 = acx * apx + acy * apy + acz * apz
    bpx, bpy, bpz = px - bx, py - by, pz - bz
    d3 = abx * bpx + aby * bpy + abz * bpz
    d4 = acx * bpx + acy * bpy + acz * bpz
    cpx, cpy, cpz = px - cx, py - cy, pz - cz
    d5 = abx * cpx + aby * cpy + abz * cpz
    d6 = acx * cpx + acy * cpy + acz * cpz
    vc = d1 * d4 - d3 * d2
    vb = d5 * d2 - d1 * d6
    va = d3 * d6 - d5 * d4
    if d1 <= 0.0 and d2 <= 0.0:
        feature, ba, bb, bc, qx, qy, qz = VA, 1.0, 0.0, 0.0, ax, ay, az
    elif d3 >= 0.0 and d4 <= d3:
        feature, ba, bb, bc, qx, qy, qz = VB, 0.0, 1.0, 0.0, bx, by, bz
    elif vc <= 0.0 and d1 >= 0.0 and d3 <= 0.0:
        v = d1 / (d1 - d3)
        feature, ba, bb, bc, qx, qy, qz = EAB, 1.0 - v, v, 0.0, ax + v * abx, ay + v * aby, az + v * abz
    elif d6 >= 0.0 and d5 <= d6:
        feature, ba, bb, bc, qx, qy, qz = VC, 0.0, 0.0, 1.0, cx, cy, cz
    elif vb <= 0.0 and d2 >= 0.0 and d6 <= 0.0:
        w = d2 / (d2 - d6)
        feature, ba, bb, bc, qx, qy, qz = ECA, 1.0 - w, 0.0, w, ax + w * acx, ay + w * acy, az + w * acz
    elif va <= 0.0 and (d4 - d3) >= 0.0 and (d5 - d6) >= 0.0:
        w = (d4 - d3) / ((d4 - d3) + (d5 - d6))
        feature, ba, bb, bc = EBC, 0.0, 1.0 - w, w
        qx, qy, qz = bx + w * (cx - bx), by + w * (cy - by), bz + w * (cz - bz)
    else:
        den = va + vb + vc                          # = |ab × ac|² > 0 but for rounding
        v = vb / den
        w = vc / den
        feature, ba, bb, bc = FACE, 1.0 - v - w, v, w
        qx, qy, qz = ax + abx * v + acx * w, ay + aby * v + acy * w, az + abz * v + acz * w
    if not (math.isfinite(qx) and math.isfinite(qy) and math.isfinite(qz)):
        return _on_edges(px, py, pz, ax, ay, az, bx, by, bz, cx, cy, cz)
    return (px - qx) ** 2 + (py - qy) ** 2 + (pz - qz) ** 2, feature, ba, bb, bc, qx, qy, qz


@_jit
def triangle_point(px, py, pz, tri, t):
    """:func:`point_triangle` for triangle ``tri[t]`` of a (F, 3, 3) array."""
    return point_triangle(px, py, pz, tri[t, 0, 0], tri[t, 0, 1], tri[t, 0, 2], tri[t, 1, 0], tri[t, 1, 1],
                          tri[t, 1, 2], tri[t, 2, 0], tri[t, 2, 1], tri[t, 2, 2])


@_jit
def _closest_pairs(points, tri, face, d, x, bary, feature):
    for m in range(points.shape[0]):
        d2, f, ba, bb, bc, qx, qy, qz = triangle_point(points[m, 0], points[m, 1], points[m, 2], tri, face[m])
        d[m] = math.sqrt(d2)
        feature[m] = f
        bary[m, 0], bary[m, 1], bary[m, 2] = ba, bb, bc
        x[m, 0], x[m, 1], x[m, 2] = qx, qy, qz


def closest_on_faces(points, tri, face):
    """The closest point of triangle ``tri[face[m]]`` to ``points[m]``, for every m (compiled).

    Parameters
    ----------
    points : (M, 3) float array.
    tri : (F, 3, 3) float array, C-contiguous: the corners of each triangle.
    face : (M,) int array of indices into ``tri``.

    Returns
    -------
    distance (M,), closest point (M, 3), barycentric coordinates (M, 3), feature (M,) int8 (:data:`FACE` …).
    """
    p = np.ascontiguousarray(points, np.float64).reshape(-1, 3)
    m = len(p)
    d, x, bary, feature = np.empty(m), np.empty((m, 3)), np.empty((m, 3)), np.empty(m, np.int8)
    _closest_pairs(p, np.ascontiguousarray(tri, np.float64), np.asarray(face, np.int64), d, x, bary, feature)
    return d, x, bary, feature


@_jit
def box_distance2(px, py, pz, bmin, bmax, n):
    """Squared distance from p to box n of the (N, 3) corner arrays (0 inside; compiled)."""
    dx = max(bmin[n, 0] - px, px - bmax[n, 0], 0.0)
    dy = max(bmin[n, 1] - py, py - bmax[n, 1], 0.0)
    dz = max(bmin[n, 2] - pz, pz - bmax[n, 2], 0.0)
    return dx * dx + dy * dy + dz * dz


@_jit
def _query(points, tri, tmin, tmax, lo, cell, dims, start, items, tol):
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
        reach = np.inf                                    # (√best + tol)²: anything farther holds nothing closer
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
                    if dxy > reach:
                        continue                          # the whole column of cells is no closer
                    for k in range(k0, k1 + 1):
                        if not shell_ij and abs(k - ck) != r:
                            continue                      # inside the block already searched
                        dz = max(lo[2] + k * cell - pz, pz - (lo[2] + (k + 1) * cell), 0.0)
                        if dxy + dz * dz > reach:
                            continue                      # every point of this cell is farther than the best
                        c = (i * ny + j) * nz + k
                        for s in range(start[c], start[c + 1]):
                            t = items[s]
                            if stamp[t] == q:
                                continue
                            stamp[t] = q
                            if box_distance2(px, py, pz, tmin, tmax, t) > reach:
                                continue                  # the triangle's box is farther than the best
                            d = triangle_point(px, py, pz, tri, t)[0]
                            if d < best:
                                best = d
                                rr = math.sqrt(d) + tol
                                reach = rr * rr
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
            if bound == np.inf or (bound > 0.0 and reach <= bound * bound):
                break
        out[q] = np.sqrt(best)
    return out


@_jit
def _max_abs(a):
    m = 0.0
    for x in a.ravel():
        m = max(m, abs(x))
    return m


def prune_tolerance(tri, points) -> float:
    """The pruning tolerance: :data:`PRUNE_TOL` of the largest coordinate magnitude of triangles and points."""
    return PRUNE_TOL * max(_max_abs(np.ascontiguousarray(tri)), _max_abs(np.ascontiguousarray(points)), 1e-300)


@_jit
def _gather_boxes(v, f):
    nt = f.shape[0]
    tri = np.empty((nt, 3, 3))
    tmin = np.empty((nt, 3))
    tmax = np.empty((nt, 3))
    for t in range(nt):
        for k in range(3):
            for a in range(3):
                tri[t, k, a] = v[f[t, k], a]
        for a in range(3):
            tmin[t, a] = min(tri[t, 0, a], min(tri[t, 1, a], tri[t, 2, a]))
            tmax[t, a] = max(tri[t, 0, a], max(tri[t, 1, a], tri[t, 2, a]))
    return tri, tmin, tmax


def query_inputs(points, vertices, faces, name: str):
    """``(points (P, 3), triangle_boxes(...) or None without points)`` of a distance query (ValueError: no faces)."""
    p, f = np.ascontiguousarray(points, np.float64).reshape(-1, 3), np.asarray(faces, np.int64)
    if len(p) and not len(f):
        raise ValueError(f"{name}: the mesh has no faces")
    return p, (triangle_boxes(np.asarray(vertices, np.float64), f) if len(p) else None)


def triangle_boxes(vertices, faces):
    """``(tri (F, 3, 3), tmin (F, 3), tmax (F, 3))``: each face's corners and bounding box, C-contiguous float64
    (compiled, one pass: ``vertices[faces]`` and its min and max over the corners).  ValueError for a face that
    indexes a missing vertex."""
    v = np.ascontiguousarray(vertices, np.float64)
    f = np.ascontiguousarray(faces, np.int64)
    if len(f) and (f.min() < 0 or f.max() >= len(v)):
        raise ValueError("faces index vertices that do not exist")
    return _gather_boxes(v, f)


@_jit
def _cell_order(points, lo, cell, dims):
    """The points' indices sorted by the number of the grid cell they fall in (clamped to the grid): a counting
    sort, so that neighbouring queries read the same cells and triangles (from cache, not memory)."""
    n = points.shape[0]
    nx, ny, nz = dims[0], dims[1], dims[2]
    key = np.empty(n, np.int64)
    count = np.zeros(nx * ny * nz + 1, np.int64)
    for q in range(n):
        i = int(min(max(np.floor((points[q, 0] - lo[0]) / cell), 0.0), nx - 1.0))
        j = int(min(max(np.floor((points[q, 1] - lo[1]) / cell), 0.0), ny - 1.0))
        k = int(min(max(np.floor((points[q, 2] - lo[2]) / cell), 0.0), nz - 1.0))
        key[q] = (i * ny + j) * nz + k
        count[key[q] + 1] += 1
    for c in range(nx * ny * nz):
        count[c + 1] += count[c]
    order = np.empty(n, np.int64)
    for q in range(n):
        order[count[key[q]]] = q
        count[key[q]] += 1
    return order


def point_mesh_distance(points, vertices, faces, cells_per_axis: int | None = None) -> np.ndarray:
    """Exact unsigned distance (float64) from each point to the closest point of the triangle mesh.

    Parameters
    ----------
    points, vertices, faces : (P, 3) float, (V, 3) float and (F, 3) int arrays (at least one face).
    cells_per_axis : int, optional
        At most this many grid cells along the mesh box's longest side.  Default: cells of :data:`CELL_SIZE`
        triangles, right for points near the surface.  Points far from it (a grid's points all over its box)
        search shells of cells out to their distance, so a coarse grid (e.g. 16) is cheaper for them
        (:func:`geometry.bvh.point_mesh_distance_far` cheaper still): the answer is exact either way.

    Returns
    -------
    (P,) float array.
    """
    p, boxes = query_inputs(points, vertices, faces, "point_mesh_distance")
    if boxes is None:
        return np.zeros(0)
    tri, tmin, tmax = boxes
    lo, hi = tmin.min(0), tmax.max(0)
    extent = np.maximum(hi - lo, 1e-12)
    size = float(np.median((tmax - tmin).max(1)))                     # a typical triangle's box
    cell = max(CELL_SIZE * size, float(extent.max()) / 512.0, 1e-12)
    if cells_per_axis is not None:
        cell = max(cell, float(extent.max()) / max(int(cells_per_axis), 1))
    while np.prod(np.floor(extent / cell) + 1) > MAX_CELLS:
        cell *= 1.25
    dims = (np.floor(extent / cell) + 1).astype(np.int64)
    start, items = bucket_triangles(lo, cell, dims, tmin, tmax)
    order = _cell_order(p, lo, cell, dims)
    out = np.empty(len(p))
    out[order] = _query(p[order], tri, tmin, tmax, lo, cell, dims, start, items, prune_tolerance(tri, p))
    return out


def _segments_np(p, a, b):
    """:func:`_segment` row by row (the numpy reference): (squared distance, s)."""
    ex, ey, ez = b[:, 0] - a[:, 0], b[:, 1] - a[:, 1], b[:, 2] - a[:, 2]
    ee = ex * ex + ey * ey + ez * ez
    with np.errstate(invalid="ignore", divide="ignore"):
        t = ((p[:, 0] - a[:, 0]) * ex + (p[:, 1] - a[:, 1]) * ey + (p[:, 2] - a[:, 2]) * ez) / ee
    s = np.where(ee > 0.0, np.minimum(np.maximum(t, 0.0), 1.0), 0.0)
    d = (p[:, 0] - a[:, 0] - s * ex) ** 2 + (p[:, 1] - a[:, 1] - s * ey) ** 2 + (p[:, 2] - a[:, 2] - s * ez) ** 2
    return d, s


def _on_edges_np(p, a, b, c):
    """:func:`_on_edges` row by row: (d2, feature, bary, q)."""
    corners = (a, b, c)
    best, s = _segments_np(p, a, b)
    edge = np.zeros(len(p), np.int64)
    for e in (1, 2):
        d, se = _segments_np(p, corners[e], corners[(e + 1) % 3])
        closer = d < best
        best, s, edge = np.where(closer, d, best), np.where(closer, se, s), np.where(closer, e, edge)
    bary = np.zeros((len(p), 3))
    q = np.empty((len(p), 3))
    feature = np.empty(len(p), np.int8)
    for e, (on_edge, at_start, at_end) in enumerate(((EAB, VA, VB), (EBC, VB, VC), (ECA, VC, VA))):
        k = edge == e
        start, end, se = corners[e][k], corners[(e + 1) % 3][k], s[k]
        q[k] = start + se[:, None] * (end - start)
        bary[k, e], bary[k, (e + 1) % 3] = 1.0 - se, se
        feature[k] = np.where(se == 0.0, at_start, np.where(se == 1.0, at_end, on_edge))
    return best, feature, bary, q


def closest_point_on_triangles(p, a, b, c):
    """:func:`point_triangle` row by row in numpy: the reference the compiled kernel equals bit for bit.

    Parameters
    ----------
    p, a, b, c : (M, 3) float arrays: the points and the corners of their triangles.

    Returns
    -------
    d2 (M,) squared distances, feature (M,) int8, bary (M, 3) barycentric coordinates, q (M, 3) closest points.
    """
    p, a, b, c = (np.asarray(x, np.float64).reshape(-1, 3) for x in (p, a, b, c))
    ab, ac = b - a, c - a
    n = np.stack([ab[:, 1] * ac[:, 2] - ab[:, 2] * ac[:, 1], ab[:, 2] * ac[:, 0] - ab[:, 0] * ac[:, 2],
                  ab[:, 0] * ac[:, 1] - ab[:, 1] * ac[:, 0]], axis=1)

    def dot(u, w):
        return u[:, 0] * w[:, 0] + u[:, 1] * w[:, 1] + u[:, 2] * w[:, 2]

    degenerate = dot(n, n) == 0.0
    ap, bp, cp = p - a, p - b, p - c
    d1, d2, d3, d4, d5, d6 = dot(ab, ap), dot(ac, ap), dot(ab, bp), dot(ac, bp), dot(ab, cp), dot(ac, cp)
    vc, vb, va = d1 * d4 - d3 * d2, d5 * d2 - d1 * d6, d3 * d6 - d5 * d4
    feature = np.select([(d1 <= 0.0) & (d2 <= 0.0), (d3 >= 0.0) & (d4 <= d3), (vc <= 0.0) & (d1 >= 0.0) & (d3 <= 0.0),
                         (d6 >= 0.0) & (d5 <= d6), (vb <= 0.0) & (d2 >= 0.0) & (d6 <= 0.0),
                         (va <= 0.0) & ((d4 - d3) >= 0.0) & ((d5 - d6) >= 0.0)],
                        [VA, VB, EAB, VC, ECA, EBC], default=FACE).astype(np.int8)
    bary = np.zeros((len(p), 3))
    q = np.empty((len(p), 3))
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        for code, corner in ((VA, a), (VB, b), (VC, c)):
            k = feature == code
            bary[k, code - VA] = 1.0
            q[k] = corner[k]
        k = feature == EAB
        v = d1[k] / (d1[k] - d3[k])
        bary[k, 0], bary[k, 1], q[k] = 1.0 - v, v, a[k] + v[:, None] * ab[k]
        k = feature == ECA
        w = d2[k] / (d2[k] - d6[k])
        bary[k, 0], bary[k, 2], q[k] = 1.0 - w, w, a[k] + w[:, None] * ac[k]
        k = feature == EBC
        w = (d4[k] - d3[k]) / ((d4[k] - d3[k]) + (d5[k] - d6[k]))
        bary[k, 1], bary[k, 2], q[k] = 1.0 - w, w, b[k] + w[:, None] * (c[k] - b[k])
        k = feature == FACE
        den = va[k] + vb[k] + vc[k]
        v, w = vb[k] / den, vc[k] / den
        bary[k, 0], bary[k, 1], bary[k, 2] = 1.0 - v - w, v, w
        q[k] = a[k] + ab[k] * v[:, None] + ac[k] * w[:, None]
    d = (p[:, 0] - q[:, 0]) ** 2 + (p[:, 1] - q[:, 1]) ** 2 + (p[:, 2] - q[:, 2]) ** 2
    bad = degenerate | ~np.isfinite(q).all(axis=1)
    if bad.any():
        d[bad], feature[bad], bary[bad], q[bad] = _on_edges_np(p[bad], a[bad], b[bad], c[bad])
    return d, feature, bary, q
