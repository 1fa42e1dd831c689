"""Compiled (numba) kernels of the grid signed distance (:mod:`phantoms.mesh.grid_sdf`).

* :func:`tri_eval` — the point–triangle distance and closest feature, one pair at a time: the suite's one kernel,
  :func:`geometry.closest.triangle_point` (numba's cache does not notice a change to a jitted function in another
  file: after editing that kernel, delete this module's cache, ``phantoms/mesh/__pycache__/grid_kernels.*.nb[ic]``;
  tests/test_phantoms_mesh_grid_kernels.py compares the two bit for bit);
* :func:`closest_faces` — the certified exact closest triangle of each point, from the triangles binned into a
  uniform grid of cubic cells (:func:`geometry.closest.bucket_triangles`): cells are visited in Chebyshev
  rings around the point's cell, skipping cells farther than the best distance so far; after ring ``k``
  every triangle with a point within ``k · c − (offset of the point in its cell)`` has been evaluated, so
  the search stops once the best distance is below that (``c`` the cell size).  Exact (to rounding) for
  every point, cost growing with the distance;
* :func:`mark_band` — grid points within a radius of a mesh vertex (the narrow band), vertex by vertex;
* :func:`propagate` — closest-triangle propagation from the band into the far region (breadth first over the
  26 neighbours, then Gauss–Seidel passes; see :mod:`phantoms.mesh.grid_sdf`).

Everything is written into arrays the caller allocates: nothing of size N³ is created here.  Compiled on
first use and cached on disk (``cache=True``).
"""

from __future__ import annotations

import math

import numba
import numpy as np

from geometry.closest import VA, VC, triangle_point

#: the 26 neighbours of a grid point as index offsets (di, dj, dk), in the order of three nested loops over
#: −1, 0, 1 with the centre left out: the propagation visits them in this order (the first of equally near faces
#: wins)
NEIGHBOURS = np.array([(di, dj, dk) for di in (-1, 0, 1) for dj in (-1, 0, 1) for dk in (-1, 0, 1)
                       if (di, dj, dk) != (0, 0, 0)], np.int64)


def _jit(fn):
    return numba.njit(cache=True, nogil=True)(fn)


@_jit
def tri_eval(px, py, pz, tri, f):
    """(distance, feature) from point p to triangle ``tri[f]``: :func:`geometry.closest.triangle_point`."""
    d2, feat, _, _, _, _, _, _ = triangle_point(px, py, pz, tri, f)
    return math.sqrt(d2), feat


@_jit
def _box_d2(fx, fy, fz, i, j, k):
    """Squared distance (in cells²) from the point at fractional cell coordinates f to cell (i, j, k)."""
    d2 = 0.0
    for val, ce in ((fx, i), (fy, j), (fz, k)):
        if val < ce:
            d2 += (ce - val) ** 2
        elif val > ce + 1:
            d2 += (val - ce - 1) ** 2
    return d2 * (1.0 - 1e-9)


@_jit
def _closest_one(px, py, pz, tri, start, cfaces, lo, c, dims):
    nx, ny, nz = dims[0], dims[1], dims[2]
    # the point's cell (may lie outside the cell grid: clamp, and account for the gap in the stop test)
    fx, fy, fz = (px - lo[0]) / c, (py - lo[1]) / c, (pz - lo[2]) / c
    ci = min(max(int(math.floor(fx)), 0), nx - 1)
    cj = min(max(int(math.floor(fy)), 0), ny - 1)
    ck = min(max(int(math.floor(fz)), 0), nz - 1)
    # distance from p to the boundary of the block of rings 0..k is at least k·c − slack
    slack = 0.0
    for val, ce in ((fx, ci), (fy, cj), (fz, ck)):
        below = val - ce                 # offset of p inside its (clamped) cell, in cells
        slack = max(slack, below, 1.0 - below)
    best = np.inf
    bestf = -1
    kmax = max(nx, ny, nz)
    for ring in range(kmax + 1):
        for i in range(ci - ring, ci + ring + 1):
            if i < 0 or i >= nx:
                continue
            for j in range(cj - ring, cj + ring + 1):
                if j < 0 or j >= ny:
                    continue
                edge_ij = i == ci - ring or i == ci + ring or j == cj - ring or j == cj + ring
                k = ck - ring
                while k <= ck + ring:
                    if 0 <= k < nz and start[(i * ny + j) * nz + k + 1] > start[(i * ny + j) * nz + k] \
                            and _box_d2(fx, fy, fz, i, j, k) * (c * c) <= best * best:
                        q = (i * ny + j) * nz + k
                        for s in range(start[q], start[q + 1]):
                            f = cfaces[s]
                            d, _ = tri_eval(px, py, pz, tri, f)
                            if d < best or (d == best and f < bestf):
                                best = d
                                bestf = f
                    if edge_ij or k == ck + ring:
                        k += 1
                    else:
                        k = ck + ring            # interior of the block: only its two k faces are new
        # every triangle with a point within (ring + 1 − slack)·c of p lies in rings 0..ring
        if best <= (ring + 1.0 - slack) * c:
            break
    return bestf


@_jit
def closest_faces(P, tri, start, cfaces, lo, c, dims, out):
    """Certified exact closest triangle of each point of P (M, 3), written into ``out`` (M,)."""
    for m in range(P.shape[0]):
        out[m] = _closest_one(P[m, 0], P[m, 1], P[m, 2], tri, start, cfaces, lo, c, dims)


@_jit
def mark_band(V, axis, radius, state, band_value):
    """``state[i, j, k] = band_value`` for every grid point within ``radius`` of a vertex of V."""
    n = axis.shape[0]
    h = axis[1] - axis[0]
    r2 = radius * radius
    for v in range(V.shape[0]):
        lo_i = np.empty(3, np.int64)
        hi_i = np.empty(3, np.int64)
        for a in range(3):
            lo_i[a] = max(int(math.floor((V[v, a] - radius - axis[0]) / h)) - 1, 0)
            hi_i[a] = min(int(math.ceil((V[v, a] + radius - axis[0]) / h)) + 1, n - 1)
        for i in range(lo_i[0], hi_i[0] + 1):
            dx = axis[i] - V[v, 0]
            for j in range(lo_i[1], hi_i[1] + 1):
                dy = axis[j] - V[v, 1]
                for k in range(lo_i[2], hi_i[2] + 1):
                    dz = axis[k] - V[v, 2]
                    if dx * dx + dy * dy + dz * dz <= r2:
                        state[i, j, k] = band_value


@_jit
def _descend(px, py, pz, d, f, feat, tri, faces, face_adj, vfaces, steps):
    """Local descent from face f: the faces across its edges and the fan of its closest vertex."""
    evals = 0
    for _ in range(steps):
        bd = d
        bf = f
        bfeat = feat
        for e in range(3):
            g = face_adj[f, e]
            if g < 0:
                continue
            dd, ft = tri_eval(px, py, pz, tri, g)
            evals += 1
            if dd < bd:
                bd, bf, bfeat = dd, g, ft
        if VA <= feat <= VC:
            vert = faces[f, feat - VA]
            for s in range(vfaces.shape[1]):
                g = vfaces[vert, s]
                if g < 0:
                    break
                dd, ft = tri_eval(px, py, pz, tri, g)
                evals += 1
                if dd < bd:
                    bd, bf, bfeat = dd, g, ft
        if bf == f:
            break
        d, f, feat = bd, bf, bfeat
    return d, f, feat, evals


@_jit
def neighbour_offsets(n):
    """The flat-index offsets of :data:`NEIGHBOURS` in a C-ordered (n, n, n) grid (int64 (26,))."""
    off = np.empty(26, np.int64)
    for m in range(26):
        off[m] = (NEIGHBOURS[m, 0] * n + NEIGHBOURS[m, 1]) * n + NEIGHBOURS[m, 2]
    return off


@_jit
def _neighbour(r, m, n, off):
    """Flat index of neighbour m of grid point r, or −1 when it lies off the grid."""
    nn = n * n
    i = r // nn + NEIGHBOURS[m, 0]
    j = (r // n) % n + NEIGHBOURS[m, 1]
    k = r % n + NEIGHBOURS[m, 2]
    if 0 <= i < n and 0 <= j < n and 0 <= k < n:
        return r + off[m]
    return -1


@_jit
def _interior(r, n):
    """Whether grid point r has all 26 neighbours on the grid."""
    nn = n * n
    i = r // nn
    j = (r // n) % n
    k = r % n
    return 0 < i < n - 1 and 0 < j < n - 1 and 0 < k < n - 1


@_jit
def _pull(r, n, off, axis, dist, face, state, tri, faces, face_adj, vfaces, steps, done, seen):
    """Best of the distinct closest faces of r's 26 neighbours whose state is ≥ ``done``, then descent.
    Returns (distance, face, evaluations); face −1 when no neighbour is done.  ``dist``, ``face``, ``state``:
    the grids flattened; ``off``: :func:`neighbour_offsets`; ``seen``: int32 (26,) work space."""
    px, py, pz = axis[r // (n * n)], axis[(r // n) % n], axis[r % n]
    inner = _interior(r, n)
    ns = 0
    best = dist[r]
    bf = face[r]
    bfeat = -1
    evals = 0
    for m in range(26):
        q = r + off[m] if inner else _neighbour(r, m, n, off)
        if q < 0 or state[q] < done:
            continue
        g = face[q]
        if g < 0:
            continue
        dup = False
        for s in range(ns):
            if seen[s] == g:
                dup = True
                break
        if dup:
            continue
        seen[ns] = g
        ns += 1
        dd, ft = tri_eval(px, py, pz, tri, g)
        evals += 1
        if dd < best:
            best, bf, bfeat = dd, g, ft
    if bf >= 0 and best < dist[r]:    # descend from a better face (from the current one it was done)
        best, bf, bfeat, e2 = _descend(px, py, pz, best, bf, bfeat, tri, faces, face_adj, vfaces, steps)
        evals += e2
    return best, bf, evals


@_jit
def _enqueue(r, n, off, state, sign, queue, tail):
    """Queue the unreached (state 0) neighbours of grid point r with its sign (flat grids); returns the new
    queue length."""
    inner = _interior(r, n)
    for m in range(26):
        q = r + off[m] if inner else _neighbour(r, m, n, off)
        if q < 0 or state[q] != 0:
            continue
        state[q] = 1
        sign[q] = sign[r]
        queue[tail] = q
        tail += 1
    return tail


@_jit
def _worth_a_pull(r, p, n, off, face, state):
    """Whether Gauss–Seidel pass p visits grid point r (flat grids): the first pass where a neighbour holds a face
    (≥ 0) other than r's own, later ones at or next to a change of this pass or the previous one (state ≥ 4)."""
    if p > 0 and state[r] >= 4:
        return True
    inner = _interior(r, n)
    for m in range(26):
        q = r + off[m] if inner else _neighbour(r, m, n, off)
        if q >= 0 and ((face[q] != face[r] and face[q] >= 0) if p == 0 else state[q] >= 4):
            return True
    return False


@_jit
def _passes(nfar, n, off, axis, dist, face, state, queue, tri, faces, face_adj, vfaces, steps, passes, seen):
    """The Gauss–Seidel passes of :func:`propagate` (flat grids); returns (evaluations, passes done)."""
    evals = 0
    # state 4 = changed in the current pass, 5 = changed in the previous pass; a point is visited when it or a
    # neighbour changed in either
    done = 0
    for p in range(passes):
        changed = 0
        for t in range(nfar):
            r = queue[t] if p % 2 == 0 else queue[nfar - 1 - t]
            if not _worth_a_pull(r, p, n, off, face, state):
                continue
            d, f, e = _pull(r, n, off, axis, dist, face, state, tri, faces, face_adj, vfaces, steps, 2, seen)
            evals += e
            if d < dist[r]:
                dist[r] = d
                face[r] = f
                state[r] = 4
                changed += 1
        # age the marks: previous pass's 5 -> 3, this pass's 4 -> 5
        for t in range(nfar):
            r = queue[t]
            if state[r] == 5:
                state[r] = 3
            elif state[r] == 4:
                state[r] = 5
        done = p + 1
        if changed == 0:
            break
    for t in range(nfar):
        state[queue[t]] = 3
    return evals, done


@_jit
def propagate(n, axis, dist, face, state, sign, queue, tri, faces, face_adj, vfaces, steps, passes):
    """Closest-triangle propagation from the band (state 2) into the far region (state 0).

    1. Breadth first over the 26 neighbours (:data:`NEIGHBOURS`), starting from the band points in index order:
       a far point takes the best of the closest faces of its finished neighbours (band or far, state ≥ 2 / 3),
       then descends on the mesh; it inherits the sign of the neighbour that reached it.
    2. Up to ``passes`` Gauss–Seidel passes over the far points (alternately in and against the breadth-first
       order): each pulls again from all 26 neighbours (and descends when that found a better face); the
       first pass visits only points with a neighbour of another face, later ones only points next to a
       change.  Returns (far points, evaluations, passes done).

    ``state``: 0 far, not reached; 1 queued; 2 band; 3 far, finished (uint8, (n, n, n)); ``queue`` int32 (n³,).
    The grids are C-contiguous and read through flat indices.
    """
    size = n * n * n
    dist_f, face_f, state_f, sign_f = dist.reshape(size), face.reshape(size), state.reshape(size), sign.reshape(size)
    off = neighbour_offsets(n)
    tail = 0
    evals = 0
    seen = np.empty(26, np.int32)
    for r in range(size):                  # seed: the far neighbours of every band point
        if state_f[r] == 2:
            tail = _enqueue(r, n, off, state_f, sign_f, queue, tail)
    head = 0
    while head < tail:
        r = queue[head]
        head += 1
        d, f, e = _pull(r, n, off, axis, dist_f, face_f, state_f, tri, faces, face_adj, vfaces, steps, 2, seen)
        evals += e
        dist_f[r] = d
        face_f[r] = f
        state_f[r] = 3
        tail = _enqueue(r, n, off, state_f, sign_f, queue, tail)
    nfar = tail
    e, done = _passes(nfar, n, off, axis, dist_f, face_f, state_f, queue, tri, faces, face_adj, vfaces, steps,
                      passes, seen)
    return nfar, evals + e, done
