"""The exact Euclidean distance of every voxel centre to the nearest inside voxel centre of a binary mask, with the
passes restricted to the inside voxels' bounding box (a compiled kernel of :func:`phantoms.masks.mask_distances`).

The transform is the separable one of Felzenszwalb & Huttenlocher (2012, "Distance transforms of sampled
functions"): a 1-D distance along the first axis, then two lower envelopes of parabolas along the others.  A mask's
inside voxels fill a box that is often a fraction of the grid, and every line outside that box has no inside voxel,
so the first pass runs only on the lines through the box (the other two axes inside it), the second only on the
slabs of the last axis inside the box, and each envelope is built from the box's sites only; only the last pass
visits every voxel.  The axes are taken in the order that makes the restricted passes smallest.  The numpy/scipy
reference the tests compare against is :func:`scipy.ndimage.distance_transform_edt` (``reference=True`` of
:func:`phantoms.masks.mask_distances`).
"""

from __future__ import annotations

import numba
import numpy as np

__all__ = ["outside_distance", "true_box"]

_jit = numba.njit(cache=True, nogil=True)


def outside_distance(m: np.ndarray, spacing, box: tuple[np.ndarray, np.ndarray] | None = None) -> np.ndarray:
    """Distance (float64, world units, C order) of each voxel centre of the boolean 3-D ``m`` to the nearest true
    voxel centre, 0 on the true voxels; ``spacing`` the per-axis voxel size; ``box`` :func:`true_box` of ``m`` when
    the caller has it.  ``m`` must have a true voxel."""
    spacing = np.broadcast_to(np.asarray(spacing, dtype=np.float64), (3,))
    lo, hi = true_box(m) if box is None else box
    frac = (hi - lo) / np.asarray(m.shape, dtype=float)
    order = [int(a) for a in np.argsort(-frac, kind="stable")]     # largest extent first, smallest last
    out = np.empty(m.shape, np.float64)
    _transform(np.transpose(m, order), np.transpose(out, order), spacing[order].copy(), lo[order].copy(),
               hi[order].copy())
    return out


def true_box(m: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The bounding box [lo, hi) of the true voxels, per axis."""
    lo, hi = [], []
    for axis in range(3):
        hit = np.flatnonzero(m.any(axis=tuple(a for a in range(3) if a != axis)))
        lo.append(int(hit[0]))
        hi.append(int(hit[-1]) + 1)
    return np.asarray(lo, np.int64), np.asarray(hi, np.int64)


@_jit
def _cross(f, p, s, first, w2):
    """Where the parabolas w2·(q − first − t)² + f[t] of the sites t = p < s cross."""
    qp = first + p
    qs = first + s
    return ((f[s] + w2 * qs * qs) - (f[p] + w2 * qp * qp)) / (2.0 * w2 * (qs - qp))


@_jit
def _envelope(f, n_sites, first, w2, n_out, v, z, out_line):
    """Lower envelope of the parabolas w2·(q − first − t)² + f[t] over the finite f[t], t < n_sites, evaluated at
    q = 0 … n_out − 1 into ``out_line`` (squared distances; inf where no site is finite)."""
    k = -1
    for s in range(n_sites):
        if f[s] == np.inf:
            continue
        if k < 0:
            k = 0
            v[0] = s
            z[0] = -np.inf
            z[1] = np.inf
            continue
        x = _cross(f, v[k], s, first, w2)
        while x <= z[k]:                         # z[0] = −inf: k stays ≥ 0
            k -= 1
            x = _cross(f, v[k], s, first, w2)
        k += 1
        v[k] = s
        z[k] = x
        z[k + 1] = np.inf
    if k < 0:
        for q in range(n_out):
            out_line[q] = np.inf
        return
    j = 0
    for q in range(n_out):
        while z[j + 1] < q:
            j += 1
        d = q - (first + v[j])
        out_line[q] = w2 * d * d + f[v[j]]


@_jit
def _transform(m, out, w, lo, hi):
    """The three passes, in place in ``out``: pass 1 writes the lines through the box, pass 2 reads each line's
    box sites into a buffer before it writes the line, pass 3 the same along the last axis."""
    na, nb, nc = m.shape
    bb, bc = hi[1] - lo[1], hi[2] - lo[2]
    wa2, wb2, wc2 = w[0] * w[0], w[1] * w[1], w[2] * w[2]
    # pass 1 along a on the lines (b, c) through the box, plane by plane: d(i) = 0 on a true voxel, else
    # min(d_before(i), d(i + 1) + 1) with d_before(i) = d_before(i − 1) + 1 (index units; inf before any)
    for i in range(na):
        for j in range(lo[1], hi[1]):
            for k in range(lo[2], hi[2]):
                if m[i, j, k]:
                    out[i, j, k] = 0.0
                else:
                    out[i, j, k] = np.inf if i == 0 else out[i - 1, j, k] + 1.0
    after = np.full((bb, bc), np.inf)            # d(i + 1), index units
    for i in range(na - 1, -1, -1):
        for j in range(bb):
            for k in range(bc):
                d = min(out[i, lo[1] + j, lo[2] + k], after[j, k] + 1.0)
                after[j, k] = d
                out[i, lo[1] + j, lo[2] + k] = wa2 * d * d
    n_max = max(na, max(nb, nc))
    f = np.empty(n_max)
    v = np.empty(n_max, np.int64)
    z = np.empty(n_max + 1)
    line = np.empty(n_max)
    for i in range(na):                          # pass 2 along b, lines (a, c) with c inside the box
        for k in range(lo[2], hi[2]):
            for j in range(bb):
                f[j] = out[i, lo[1] + j, k]
            _envelope(f, bb, lo[1], wb2, nb, v, z, line)
            for j in range(nb):
                out[i, j, k] = line[j]
    for i in range(na):                          # pass 3 along c, every line (a, b)
        for j in range(nb):
            for k in range(bc):
                f[k] = out[i, j, lo[2] + k]
            _envelope(f, bc, lo[2], wc2, nc, v, z, line)
            for k in range(nc):
                out[i, j, k] = np.sqrt(line[k])
