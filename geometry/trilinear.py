"""Trilinear interpolation of stacked grids at fractional grid indices: the one gather of the suite.

:func:`trilinear_channels` is the numpy reference; with numba, the compiled :func:`geometry.kernels.trilinear`
(the same 8-term sum, point by point) runs in its place on large batches.  :class:`phantoms.volume.Volume`
samples φ, ∇φ and the Hessian with it, and so does the shape-gradient flow's field.  DistMesh's compiled
iterations inline the same per-point sum (:func:`geometry.kernels.trilinear_point`) into their jitted loop;
numba's disk cache watches the caller's file only, so after editing that sum delete the callers' caches
(``methods/__pycache__/distmesh_loop.*.nb[ic]``); ``tests/test_methods_distmesh_loop.py`` compares DistMesh's
samples with this reference.
"""

from __future__ import annotations

import numpy as np

from . import compiled, kernels

__all__ = ["trilinear_channels"]


_CHUNK = 4096   # points per block of trilinear_channels: the block's 8 corner rows stay in the L2 cache


def trilinear_channels(flat: np.ndarray, shape, idx_t: np.ndarray, *, channels: int | None = None,
                       reference: bool = False) -> np.ndarray:
    """Trilinear interpolation of stacked grids at fractional grid indices: the one gather.

    ``flat`` (N0·N1·N2, C): C grids of ``shape`` (N0, N1, N2), raveled in C order, all channels of a
    grid point adjacent in memory.  ``idx_t`` (3, P): fractional indices, already inside
    [0, N − 1] per axis (callers check or clamp).  Returns (C, P).  One ``np.take`` fetches the 8
    corner rows of every point (much faster than fancy indexing with numpy 2.x); the weights are 8
    products of coordinate arrays.  Shared by :meth:`phantoms.volume.Volume.sample` and the shape-gradient flow's
    inner loop.

    The gather and the weighted sum run over blocks of ``_CHUNK`` points into one reused buffer: the
    (8, P, C) corner array of all points at once (64 MB for 100k points and 10 channels) would be a
    fresh allocation per call, paid in page faults, and read back from main memory by the sum.  Each
    output value is the same 8-term sum either way (bit-identical results).

    ``channels``: interpolate only the first this many of the C grids (e.g. φ and ∇φ of a stack that also
    holds the Hessian: one stack serves every order, no copy of its first columns).

    With numba, the compiled :func:`geometry.kernels.trilinear` (the same sum, point by point) runs
    instead; ``reference=True`` keeps this numpy form.
    """
    if (compiled.wanted(idx_t.shape[1]) and not reference and flat.dtype in (np.float64, np.float32)
            and flat.flags.c_contiguous):
        return kernels.trilinear(flat, shape, idx_t, channels)
    if channels is not None:
        flat = flat[:, :channels]
    idx_t = np.asarray(idx_t, dtype=np.float64)
    if idx_t.shape[1] and not ((idx_t.min(axis=1) >= 0).all()                # NaN fails both tests
                               and (idx_t.max(axis=1) <= np.asarray(shape) - 1).all()):
        raise IndexError("trilinear_channels: fractional indices outside the grid (or not finite)")
    n1, n2 = int(shape[1]), int(shape[2])
    sx = n1 * n2
    ijk, frac = [], []
    for c in range(3):
        i0 = np.minimum(idx_t[c].astype(np.intp), int(shape[c]) - 2)   # idx >= 0: truncation is floor
        ijk.append(i0)
        frac.append(idx_t[c] - i0)
    base = ijk[0] * sx + ijk[1] * n2 + ijk[2]
    offsets = np.array([0, 1, n2, n2 + 1, sx, sx + 1, sx + n2, sx + n2 + 1], dtype=np.intp)[:, None]
    P, C = len(base), flat.shape[1]
    tx, ty, tz = frac
    ux, uy, uz = 1.0 - tx, 1.0 - ty, 1.0 - tz
    a00, a01, a10, a11 = ux * uy, ux * ty, tx * uy, tx * ty
    w = np.stack([a00 * uz, a00 * tz, a01 * uz, a01 * tz, a10 * uz, a10 * tz, a11 * uz, a11 * tz])
    out = np.empty((C, P))
    buf = np.empty((8, min(P, _CHUNK), C), dtype=flat.dtype)
    for s in range(0, P, _CHUNK):
        e = min(P, s + _CHUNK)
        corners = buf[:, :e - s]
        # indices are checked above, so 'clip' only skips numpy's own bounds buffering
        np.take(flat, base[s:e] + offsets, axis=0, out=corners, mode="clip")   # (8, n, C)
        np.einsum("kpc,kp->cp", corners, w[:, s:e], out=out[:, s:e])
    return out
