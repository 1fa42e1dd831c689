"""φ, ∇φ and the symmetrised Hessian of a grid in one compiled pass per order: the interpolation grids.

:func:`derivative_stack` computes what :func:`numpy.gradient` (``edge_order=2``, uniform spacing per axis)
gives for ∇φ and for ∂ⱼ(∂ᵢφ), symmetrised ½(∂ⱼ∂ᵢφ + ∂ᵢ∂ⱼφ), with the same formulas in the same
floating-point order — the numpy form (:func:`phantoms.volume._derivative_channels`) is the reference and
the two are equal bit for bit in float64 (``tests/test_geometry_grid_derivatives.py``).  It writes each
grid point's C channels together, once, into the (nx, ny, nz, C) array, with no temporary grid: numpy's form
writes every channel with a stride of C values and keeps up to four N³ temporaries (at N = 256 about ten
times the time, and C + 4 grids instead of C).

Values are computed in float64; ``dtype=np.float32`` stores them rounded (half the memory).
"""

from __future__ import annotations

import numpy as np

import numba

__all__ = ["derivative_stack"]

_jit = numba.njit(cache=True, nogil=True)


@_jit
def _d(f, i, j, k, axis, n, dx):
    """numpy.gradient's value along ``axis`` at (i, j, k): central inside, second-order one-sided at the ends."""
    di = 1 if axis == 0 else 0
    dj = 1 if axis == 1 else 0
    dk = 1 if axis == 2 else 0
    p = i if axis == 0 else (j if axis == 1 else k)
    if 0 < p < n - 1:
        return (f[i + di, j + dj, k + dk] - f[i - di, j - dj, k - dk]) / (2.0 * dx)
    if p == 0:
        return ((-1.5 / dx) * f[i, j, k] + (2.0 / dx) * f[i + di, j + dj, k + dk]
                + (-0.5 / dx) * f[i + 2 * di, j + 2 * dj, k + 2 * dk])
    return ((0.5 / dx) * f[i - 2 * di, j - 2 * dj, k - 2 * dk] + (-2.0 / dx) * f[i - di, j - dj, k - dk]
            + (1.5 / dx) * f[i, j, k])


@_jit
def _dd(f, i, j, k, a, b, shape, spacing):
    """∂_b (∂_a φ) at (i, j, k): numpy.gradient along b of numpy.gradient along a, ∂_a φ taken at the
    neighbours the outer difference reads."""
    di = 1 if b == 0 else 0
    dj = 1 if b == 1 else 0
    dk = 1 if b == 2 else 0
    p = i if b == 0 else (j if b == 1 else k)
    n, dx = shape[b], spacing[b]
    na, da = shape[a], spacing[a]
    if 0 < p < n - 1:
        return (_d(f, i + di, j + dj, k + dk, a, na, da) - _d(f, i - di, j - dj, k - dk, a, na, da)) / (2.0 * dx)
    if p == 0:
        return ((-1.5 / dx) * _d(f, i, j, k, a, na, da) + (2.0 / dx) * _d(f, i + di, j + dj, k + dk, a, na, da)
                + (-0.5 / dx) * _d(f, i + 2 * di, j + 2 * dj, k + 2 * dk, a, na, da))
    return ((0.5 / dx) * _d(f, i - 2 * di, j - 2 * dj, k - 2 * dk, a, na, da)
            + (-2.0 / dx) * _d(f, i - di, j - dj, k - dk, a, na, da) + (1.5 / dx) * _d(f, i, j, k, a, na, da))


@_jit
def _interior(f, spacing, order, out):
    """Points at least two samples from every border: central differences only, in straight-line code (the
    same operations as :func:`_d` / :func:`_dd` there)."""
    n0, n1, n2 = f.shape
    t0, t1, t2 = 2.0 * spacing[0], 2.0 * spacing[1], 2.0 * spacing[2]
    for i in range(2, n0 - 2):
        for j in range(2, n1 - 2):
            for k in range(2, n2 - 2):
                c = f[i, j, k]
                out[i, j, k, 0] = c
                out[i, j, k, 1] = (f[i + 1, j, k] - f[i - 1, j, k]) / t0
                out[i, j, k, 2] = (f[i, j + 1, k] - f[i, j - 1, k]) / t1
                out[i, j, k, 3] = (f[i, j, k + 1] - f[i, j, k - 1]) / t2
                if order < 2:
                    continue
                out[i, j, k, 4] = ((f[i + 2, j, k] - c) / t0 - (c - f[i - 2, j, k]) / t0) / t0
                out[i, j, k, 7] = ((f[i, j + 2, k] - c) / t1 - (c - f[i, j - 2, k]) / t1) / t1
                out[i, j, k, 9] = ((f[i, j, k + 2] - c) / t2 - (c - f[i, j, k - 2]) / t2) / t2
                # ∂y(∂x φ) and ∂x(∂y φ)
                yx = ((f[i + 1, j + 1, k] - f[i - 1, j + 1, k]) / t0
                      - (f[i + 1, j - 1, k] - f[i - 1, j - 1, k]) / t0) / t1
                xy = ((f[i + 1, j + 1, k] - f[i + 1, j - 1, k]) / t1
                      - (f[i - 1, j + 1, k] - f[i - 1, j - 1, k]) / t1) / t0
                out[i, j, k, 5] = 0.5 * (yx + xy)
                zx = ((f[i + 1, j, k + 1] - f[i - 1, j, k + 1]) / t0
                      - (f[i + 1, j, k - 1] - f[i - 1, j, k - 1]) / t0) / t2
                xz = ((f[i + 1, j, k + 1] - f[i + 1, j, k - 1]) / t2
                      - (f[i - 1, j, k + 1] - f[i - 1, j, k - 1]) / t2) / t0
                out[i, j, k, 6] = 0.5 * (zx + xz)
                zy = ((f[i, j + 1, k + 1] - f[i, j - 1, k + 1]) / t1
                      - (f[i, j + 1, k - 1] - f[i, j - 1, k - 1]) / t1) / t2
                yz = ((f[i, j + 1, k + 1] - f[i, j + 1, k - 1]) / t2
                      - (f[i, j - 1, k + 1] - f[i, j - 1, k - 1]) / t2) / t1
                out[i, j, k, 8] = 0.5 * (zy + yz)


@_jit
def _stack(f, spacing, order, out):
    n0, n1, n2 = f.shape
    shape = (n0, n1, n2)
    if order >= 1:
        _interior(f, spacing, order, out)
    for i in range(n0):
        inner_i = 2 <= i < n0 - 2
        for j in range(n1):
            inner = inner_i and 2 <= j < n1 - 2
            for k in range(n2):
                if order >= 1 and inner and 2 <= k < n2 - 2:
                    continue                                    # done by _interior
                out[i, j, k, 0] = f[i, j, k]
                if order >= 1:
                    for a in range(3):
                        out[i, j, k, 1 + a] = _d(f, i, j, k, a, shape[a], spacing[a])
                if order >= 2:
                    s = 4
                    for a in range(3):
                        for b in range(a, 3):
                            if a == b:
                                out[i, j, k, s] = _dd(f, i, j, k, a, a, shape, spacing)
                            else:
                                out[i, j, k, s] = 0.5 * (_dd(f, i, j, k, a, b, shape, spacing)
                                                         + _dd(f, i, j, k, b, a, shape, spacing))
                            s += 1


def derivative_stack(values: np.ndarray, spacing, order: int, dtype=np.float64) -> np.ndarray:
    """The (nx, ny, nz, C) interpolation grids of ``values``: C = 1 (φ), 4 (φ, ∇φ) or 10 (and the Hessian
    entries xx, xy, xz, yy, yz, zz), ``order`` 0, 1 or 2.

    Parameters
    ----------
    values : (nx, ny, nz) float array, every side ≥ 3 when ``order`` ≥ 1 (numpy.gradient's requirement).
    spacing : three positive grid steps.
    order : 0, 1 or 2.
    dtype : numpy.float64 (default) or numpy.float32 (values computed in float64, stored rounded).
    """
    f = np.ascontiguousarray(values, dtype=np.float64)
    if f.ndim != 3:
        raise ValueError(f"derivative_stack: values must be a 3-D grid, got shape {f.shape}")
    if order not in (0, 1, 2):
        raise ValueError("derivative_stack: order must be 0, 1 or 2")
    if order >= 1 and min(f.shape) < 3:
        raise ValueError(f"derivative_stack: every side must be at least 3 samples, got {f.shape}")
    out = np.empty(f.shape + ({0: 1, 1: 4}.get(order, 10),), dtype=dtype)
    _stack(f, np.asarray(spacing, dtype=np.float64).reshape(3), order, out)
    return out
