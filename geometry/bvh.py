"""The exact unsigned distance from points far from a triangle mesh: a bounding-volume hierarchy.

The SDF energy (``bench/metrics/sdf_energy.py``) queries grid points all over the volume's box, most of them far
from the surface.  Seen from far, the part of the surface within a grid cell's reach of the closest point holds
hundreds of triangles, and :func:`geometry.closest.point_mesh_distance`'s Chebyshev shells open all of them.
:func:`point_mesh_distance_far` searches a hierarchy of boxes instead (:func:`build_bvh`: at most
:data:`BVH_LEAF` triangles per leaf, split at the median box centre along the axis where the centres spread most),
nearest box first, and opens a box — or, in a leaf, a triangle's own box — only when it may hold a triangle no
farther than the best distance so far plus :func:`geometry.closest.prune_tolerance`, far above rounding.  So it
finds the smallest distance the point–triangle kernel (:func:`geometry.closest.point_triangle`) gives over all the
triangles: bit for bit the brute-force minimum, and the grid search's numbers.  Near the surface the grid is the
faster of the two.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from .closest import box_distance2, prune_tolerance, query_inputs, triangle_point

__all__ = ["point_mesh_distance_far", "build_bvh", "BVH_LEAF"]

#: triangles per leaf box of :func:`build_bvh` (the fastest far queries on the metrics' meshes; within a leaf a
#: triangle whose own box is out of reach is skipped)
BVH_LEAF = 8

#: as :mod:`geometry.closest`'s kernels: cached, without the GIL (the metrics run the query in a worker thread)
_jit = numba.njit(cache=True, nogil=True, error_model="numpy")


@_jit
def _select(order, keys, s, e, k):
    """Reorder ``order[s:e]`` so that ``order[k]`` is the element of rank k − s by ``keys[order]``, smaller or
    equal keys before it and larger or equal after (Hoare's quickselect; compiled)."""
    lo, hi = s, e - 1
    while lo < hi:
        pivot = keys[order[(lo + hi) // 2]]
        i, j = lo, hi
        while i <= j:
            while keys[order[i]] < pivot:
                i += 1
            while keys[order[j]] > pivot:
                j -= 1
            if i <= j:
                order[i], order[j] = order[j], order[i]
                i += 1
                j -= 1
        if k <= j:
            hi = j
        elif k >= i:
            lo = i
        else:
            break


@_jit
def build_bvh(tmin, tmax, leaf_size):
    """A bounding-volume hierarchy of triangles given by their boxes (compiled).

    Each node's triangles are split at the median of their box centres along the axis where those centres
    spread most, until a node holds at most ``leaf_size``.

    Parameters
    ----------
    tmin, tmax : (T, 3) float arrays (T ≥ 1), the triangles' bounding boxes.
    leaf_size : int ≥ 1.

    Returns
    -------
    bmin, bmax (N, 3) the nodes' boxes; child (N,) int64, the first of a node's two children (the second is
    child + 1), −1 for a leaf; span (N, 2) int64, the node's triangles ``order[span[n, 0]:span[n, 1]]``; order
    (T,) int64.  Node 0 is the root.
    """
    nt = tmin.shape[0]
    leaf_size = max(leaf_size, 1)
    # a split node holds > leaf_size triangles, so every leaf at least (leaf_size + 1) // 2 (or the root alone)
    cap = 2 * (nt // max((leaf_size + 1) // 2, 1)) + 1
    bmin = np.empty((cap, 3))
    bmax = np.empty((cap, 3))
    child = np.full(cap, -1, np.int64)
    span = np.empty((cap, 2), np.int64)
    order = np.arange(nt)
    keys = np.empty(nt)
    todo = np.empty(cap, np.int64)
    span[0, 0], span[0, 1] = 0, nt
    nodes, top = 1, 1
    todo[0] = 0
    while top > 0:
        top -= 1
        n = todo[top]
        s, e = span[n, 0], span[n, 1]
        axis, spread = 0, -1.0
        for a in range(3):
            lo, hi, clo, chi = np.inf, -np.inf, np.inf, -np.inf
            for m in range(s, e):
                t = order[m]
                lo = min(lo, tmin[t, a])
                hi = max(hi, tmax[t, a])
                c = 0.5 * (tmin[t, a] + tmax[t, a])
                clo = min(clo, c)
                chi = max(chi, c)
            bmin[n, a], bmax[n, a] = lo, hi
            if chi - clo > spread:
                axis, spread = a, chi - clo
        if e - s <= leaf_size:
            continue
        for m in range(s, e):
            t = order[m]
            keys[t] = 0.5 * (tmin[t, axis] + tmax[t, axis])
        mid = (s + e) // 2
        _select(order, keys, s, e, mid)
        child[n] = nodes
        span[nodes, 0], span[nodes, 1] = s, mid
        span[nodes + 1, 0], span[nodes + 1, 1] = mid, e
        todo[top], todo[top + 1] = nodes, nodes + 1
        nodes += 2
        top += 2
    return bmin[:nodes].copy(), bmax[:nodes].copy(), child[:nodes].copy(), span[:nodes].copy(), order


@_jit
def _bvh_query(points, tri, tmin, tmax, bmin, bmax, child, span, tol):
    """The smallest kernel distance from each point to the triangles ``tri`` (in the hierarchy's leaf order, their
    boxes ``tmin``, ``tmax`` too): depth first, the nearer child first, a box skipped when farther than the best
    distance + ``tol``."""
    n = points.shape[0]
    out = np.empty(n)
    todo = np.empty(128, np.int64)          # a visit pops one entry and pushes ≤ 2: ≤ 1 + depth ≤ 64 held
    for q in range(n):
        px, py, pz = points[q, 0], points[q, 1], points[q, 2]
        best = np.inf
        reach = np.inf                      # (√best + tol)²: a box farther than this holds nothing closer
        top = 1
        todo[0] = 0
        while top > 0:
            top -= 1
            node = todo[top]
            if box_distance2(px, py, pz, bmin, bmax, node) > reach:
                continue
            a = child[node]
            if a < 0:
                for t in range(span[node, 0], span[node, 1]):
                    if box_distance2(px, py, pz, tmin, tmax, t) > reach:
                        continue
                    d = triangle_point(px, py, pz, tri, t)[0]
                    if d < best:
                        best = d
                        r = math.sqrt(d) + tol
                        reach = r * r
                continue
            b = a + 1
            da = box_distance2(px, py, pz, bmin, bmax, a)
            db = box_distance2(px, py, pz, bmin, bmax, b)
            if da > db:
                a, b, da, db = b, a, db, da
            if db <= reach:
                todo[top] = b
                top += 1
            if da <= reach:
                todo[top] = a
                top += 1
        out[q] = math.sqrt(best)
    return out


def point_mesh_distance_far(points, vertices, faces) -> np.ndarray:
    """Exact unsigned distance (float64) from each point, near the mesh or far from it, to the triangle mesh:
    the same numbers as :func:`point_mesh_distance` (the kernel's minimum over all triangles), by a
    bounding-volume hierarchy (:func:`build_bvh`), faster than the grid for points far from the surface.

    Parameters
    ----------
    points : (P, 3) float array.
    vertices : (V, 3) float array.
    faces : (F, 3) int array (at least one face).

    Returns
    -------
    (P,) float array.
    """
    p, boxes = query_inputs(points, vertices, faces, "point_mesh_distance_far")
    if boxes is None:
        return np.zeros(0)
    tri, tmin, tmax = boxes
    bmin, bmax, child, span, order = build_bvh(tmin, tmax, BVH_LEAF)
    tri = np.ascontiguousarray(tri[order])                            # a leaf's triangles side by side in memory
    return _bvh_query(p, tri, tmin[order], tmax[order], bmin, bmax, child, span, prune_tolerance(tri, p))
