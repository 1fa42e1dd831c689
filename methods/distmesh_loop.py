"""DistMesh's iterations between two retriangulations, compiled (numba): bar forces, the force step, Newton
projection onto φ = 0 and the stopping tests, point by point.

The numpy form of one iteration (:meth:`methods.distmesh.DistMesh` with ``compiled=False``) is about fifteen array
operations on ~2,000 nodes, bound by numpy's per-call overhead, and a run takes 1,000–2,000 iterations.  Here an
iteration is one pass over the bars and one over the nodes (no per-call overhead).  Every step is the numpy
form's, in the same order per node and per bar; sums run in another order, so the nodes agree to rounding (the
tests compare both forms).
"""

from __future__ import annotations

import math

import numpy as np

from geometry.compiled import AVAILABLE, jit
from geometry.kernels import trilinear_point

__all__ = ["AVAILABLE", "RETRIANGULATE", "CONVERGED", "DIVERGED", "MAX_ITER", "relax"]

RETRIANGULATE, CONVERGED, DIVERGED, MAX_ITER = 0, 1, 2, 3


@jit
def _sample(flat, n0, n1, n2, origin, spacing, x, y, z, out):
    """φ, ∂φ/∂x, ∂φ/∂y, ∂φ/∂z (trilinear, clamped onto the grid) at one point into ``out``."""
    fx = min(max((x - origin[0]) / spacing[0], 0.0), n0 - 1.0)
    fy = min(max((y - origin[1]) / spacing[1], 0.0), n1 - 1.0)
    fz = min(max((z - origin[2]) / spacing[2], 0.0), n2 - 1.0)
    trilinear_point(flat, n0, n1, n2, fx, fy, fz, out.reshape(4, 1), 0)


@jit
def _project(p, flat, dims, origin, spacing, lo, hi, steps, max_step, flat_g2, counts):
    """``steps`` capped Newton steps x ← x − φ∇φ/|∇φ|² of every node, clamped into the box (in place)."""
    s = np.empty(4)
    for i in range(p.shape[0]):
        for _ in range(steps):
            _sample(flat, dims[0], dims[1], dims[2], origin, spacing, p[i, 0], p[i, 1], p[i, 2], s)
            g2 = s[1] * s[1] + s[2] * s[2] + s[3] * s[3]
            if g2 < flat_g2:
                counts[0] += 1
                continue
            coef = s[0] / g2
            st0, st1, st2 = coef * s[1], coef * s[2], coef * s[3]
            slen2 = st0 * st0 + st1 * st1 + st2 * st2
            if slen2 > max_step * max_step:
                counts[1] += 1
                shrink = max_step / math.sqrt(slen2)
                st0, st1, st2 = st0 * shrink, st1 * shrink, st2 * shrink
            p[i, 0] = min(max(p[i, 0] - st0, lo[0]), hi[0])
            p[i, 1] = min(max(p[i, 1] - st1, lo[1]), hi[1])
            p[i, 2] = min(max(p[i, 2] - st2, lo[2]), hi[2])


@jit
def _relax(p, pold, bars, fallback, flat, dims, origin, spacing, lo, hi, prm, steps, it, max_iter, state,
           history, counts):
    """Iterations ``it``, ``it + 1``, … (in place on ``p``) until a retriangulation is due or the run stops.

    ``prm`` = (h0, ttol, dptol, fscale, deltat, max_growth, flat_g2, tiny); ``state`` = [lrms, lrms_min,
    max_move] (read and updated); ``history[k - 1]`` = the max move of iteration k.  Returns (code, it): the
    iteration at which the retriangulation is due (not yet run) or at which the run stopped."""
    h0, ttol, dptol, fscale, deltat, max_growth, flat_g2, tiny = (prm[0], prm[1], prm[2], prm[3], prm[4],
                                                                  prm[5], prm[6], prm[7])
    n, nb = p.shape[0], bars.shape[0]
    p0 = np.empty_like(p)
    disp = np.empty_like(p)
    L = np.empty(nb)
    while it <= max_iter:
        moved = 0.0
        for i in range(n):
            d0, d1, d2 = p[i, 0] - pold[i, 0], p[i, 1] - pold[i, 1], p[i, 2] - pold[i, 2]
            moved = max(moved, d0 * d0 + d1 * d1 + d2 * d2)
        if moved > (ttol * h0) ** 2:
            return RETRIANGULATE, it
        p0[:] = p
        total = 0.0
        for b in range(nb):
            d0 = p[bars[b, 0], 0] - p[bars[b, 1], 0]
            d1 = p[bars[b, 0], 1] - p[bars[b, 1], 1]
            d2 = p[bars[b, 0], 2] - p[bars[b, 1], 2]
            l2 = d0 * d0 + d1 * d1 + d2 * d2
            total += l2
            L[b] = math.sqrt(l2)
        lrms = math.sqrt(total / nb)
        state[0] = lrms
        state[1] = min(state[1], lrms)
        if lrms > max_growth * state[1]:
            return DIVERGED, it
        L0 = fscale * lrms
        disp[:] = 0.0
        for b in range(nb):
            F = max(L0 - L[b], 0.0)
            a, c = bars[b, 0], bars[b, 1]
            for k in range(3):
                u = fallback[b, k] if L[b] < tiny else (p[a, k] - p[c, k]) / L[b]
                disp[a, k] += F * u
                disp[c, k] -= F * u
        for i in range(n):
            for k in range(3):
                p[i, k] = min(max(p[i, k] + deltat * disp[i, k], lo[k]), hi[k])
        _project(p, flat, dims, origin, spacing, lo, hi, steps, h0, flat_g2, counts)
        m2 = 0.0
        for i in range(n):
            d0, d1, d2 = p[i, 0] - p0[i, 0], p[i, 1] - p0[i, 1], p[i, 2] - p0[i, 2]
            m2 = max(m2, d0 * d0 + d1 * d1 + d2 * d2)
        state[2] = math.sqrt(m2) / h0
        history[it - 1] = state[2]
        if state[2] < dptol:
            return CONVERGED, it
        it += 1
    return MAX_ITER, max_iter


def relax(p, pold, bars, fallback, sampler, box, prm, steps, it, max_iter, state, history, counts):
    """:func:`_relax` with the volume sampler's grids (φ and ∇φ channels) and the box ``(lo, hi)``."""
    dims = np.asarray(sampler.shape, np.int64)
    return _relax(p, pold, np.ascontiguousarray(bars, np.int64), fallback, sampler.flat, dims,
                  np.asarray(sampler.origin, float), np.asarray(sampler.spacing, float),
                  np.asarray(box[0], float), np.asarray(box[1], float), np.asarray(prm, float), int(steps),
                  int(it), int(max_iter), state, history, counts)


@jit
def _quality(p, i, j, k):
    """(q, normal) of triangle (i, j, k): :func:`methods.distmesh.triangle_quality` of one triangle."""
    e0, e1, e2 = p[j, 0] - p[i, 0], p[j, 1] - p[i, 1], p[j, 2] - p[i, 2]
    f0, f1, f2 = p[k, 0] - p[i, 0], p[k, 1] - p[i, 1], p[k, 2] - p[i, 2]
    n0, n1, n2 = e1 * f2 - e2 * f1, e2 * f0 - e0 * f2, e0 * f1 - e1 * f0
    area = 0.5 * math.sqrt(n0 * n0 + n1 * n1 + n2 * n2)
    g0, g1, g2 = p[k, 0] - p[j, 0], p[k, 1] - p[j, 1], p[k, 2] - p[j, 2]
    h0, h1, h2 = p[i, 0] - p[k, 0], p[i, 1] - p[k, 1], p[i, 2] - p[k, 2]
    l2 = (e0 * e0 + e1 * e1 + e2 * e2) + (g0 * g0 + g1 * g1 + g2 * g2) + (h0 * h0 + h1 * h1 + h2 * h2)
    q = 4.0 * math.sqrt(3.0) * area / l2 if l2 > 0 else 0.0
    return q, n0, n1, n2


@jit
def flip_candidates(p, a, b, c, d, qmax, gain):
    """The flip test of :func:`methods.distmesh.flip_edges` for every edge (a, b) with opposite corners c, d:
    (flip wanted, quality gain) — the worse old triangle below ``qmax``, the new pair's minimum quality higher by
    more than ``gain``, the new normals agreeing with each other and with the old pair's."""
    m = a.shape[0]
    cand = np.zeros(m, np.bool_)
    improve = np.zeros(m)
    for e in range(m):
        q1, x0, x1, x2 = _quality(p, a[e], b[e], c[e])
        q2, y0, y1, y2 = _quality(p, b[e], a[e], d[e])
        qold = min(q1, q2)
        if not qold < qmax:
            continue
        r1, u0, u1, u2 = _quality(p, a[e], d[e], c[e])
        r2, v0, v1, v2 = _quality(p, d[e], b[e], c[e])
        qnew = min(r1, r2)
        o0, o1, o2 = x0 + y0, x1 + y1, x2 + y2
        cand[e] = (qnew > qold + gain and u0 * v0 + u1 * v1 + u2 * v2 > 0
                   and u0 * o0 + u1 * o1 + u2 * o2 > 0 and v0 * o0 + v1 * o1 + v2 * o2 > 0)
        improve[e] = qnew - qold
    return cand, improve
