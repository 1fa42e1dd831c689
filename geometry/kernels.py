"""Compiled (numba) forms of the mesh operators, the curvature fit, the trilinear sampler and the Jacobi-CG.

Each kernel computes what a numpy function of the suite computes — that function stays the reference and
the tests compare both (``tests/test_geometry_kernels.py``):

* :func:`cg_csr` — :func:`geometry.operators.jacobi_cg` on a CSR matrix (copied to a padded row layout
  whose product vectorises): the sparse product, the dot products and the vector updates of one CG
  iteration in three passes over the vectors instead of a dozen numpy calls;
* :func:`ring_curvature` — :meth:`geometry.operators.MeshOperators.curvature` (the 1-ring gather and
  :func:`geometry.curvature.fit_ring`) vertex by vertex, nothing but the result written to memory;
* :func:`trilinear` — :func:`geometry.trilinear.trilinear_channels` point by point (:func:`trilinear_point`, the
  one compiled trilinear sum, also DistMesh's);
* :func:`face_geometry`, :func:`vertex_sums`, :func:`face_edges` — the face and vertex quantities of
  :class:`geometry.operators.MeshGeometry` (cross products, normals, areas, centroids; vertex normal and
  area sums) in one pass each, without the (3, 3, F) corner array;
* :func:`ring_mean3` — :meth:`geometry.operators.MeshOperators.ring_mean_t` (3 rows) without its
  (W, V) temporaries.

Why: at 100k vertices one iteration of the shape-gradient flow (their main user) is ~80 CG iterations whose numpy
form is bound by passes over memory, and a paraboloid fit whose numpy form streams dozens of (W, V) temporaries;
numpy alone stays above the 0.1 s target.  The callers run the kernels on arrays of at least
:data:`geometry.compiled.MIN_SIZE` elements (:func:`geometry.compiled.wanted`) and the numpy reference otherwise
(also when numba is missing).  Sums run in a different order than numpy's (results equal to rounding).
"""

from __future__ import annotations

import math

import numpy as np

from .compiled import jit

__all__ = ["cg_csr", "ring_curvature", "trilinear", "trilinear_point", "face_geometry", "vertex_sums", "face_edges",
           "ring_mean3"]


# ---------------------------------------------------------------------------------------------- CG
# The matrix is copied into a padded row-major layout (ELL: every row holds a multiple of 8 entries,
# padding = zero weight on the row's own index): the product's inner loop has a fixed trip count of 8
# that the compiler unrolls and vectorises — about twice as fast as the CSR loop on a mesh matrix
# (7 entries per row on a triangulated sphere), which more than pays for the copy.
# 'reassoc': sums may be taken in SIMD lanes (a single running sum is bound by the latency of one
# addition per entry).
_ELL_BLOCK = 8


@jit
def _csr_to_ell(data, indices, indptr, width):
    n = indptr.shape[0] - 1
    d = np.zeros((n, width))
    idx = np.empty((n, width), dtype=np.uint32)
    for i in range(n):
        k = 0
        for q in range(indptr[i], indptr[i + 1]):
            d[i, k] = data[q]
            idx[i, k] = indices[q]
            k += 1
        while k < width:
            idx[i, k] = i
            k += 1
    return d, idx


@jit(fastmath={"reassoc"})
def _ell_matvec_dot(d, idx, p, Ap):
    """Ap = A p and p·Ap."""
    pAp = 0.0
    W = d.shape[1]
    for i in range(p.shape[0]):
        s = 0.0
        for k0 in range(0, W, 8):
            for k in range(k0, k0 + 8):
                s += d[i, k] * p[idx[i, k]]
        Ap[i] = s
        pAp += p[i] * s
    return pAp


@jit(fastmath={"reassoc"})
def _cg_ell(d, idx, b, diag, x, use_x0, rtol, maxiter):
    n = b.shape[0]
    inv = np.empty(n)
    r = np.empty(n)
    z = np.empty(n)
    p = np.empty(n)
    Ap = np.empty(n)
    bb = 0.0
    for i in range(n):
        bb += b[i] * b[i]
    bnorm = math.sqrt(bb)
    if bnorm == 0.0 or not math.isfinite(bnorm):
        return 0, bnorm, 0.0
    if use_x0:
        _ell_matvec_dot(d, idx, x, Ap)
    rz = 0.0
    rr = 0.0
    for i in range(n):
        inv[i] = 1.0 / diag[i]
        ri = b[i] - Ap[i] if use_x0 else b[i]
        r[i] = ri
        zi = inv[i] * ri
        z[i] = zi
        p[i] = zi
        rz += ri * zi
        rr += ri * ri
    tol2 = (rtol * bnorm) ** 2
    it = 0
    while rr > tol2 and it < maxiter:
        pAp = _ell_matvec_dot(d, idx, p, Ap)
        if not pAp > 0:
            break
        a = rz / pAp
        rr = 0.0
        rz_new = 0.0
        for i in range(n):
            x[i] += a * p[i]
            ri = r[i] - a * Ap[i]
            r[i] = ri
            rr += ri * ri
            zi = inv[i] * ri
            z[i] = zi
            rz_new += ri * zi
        beta = rz_new / rz
        for i in range(n):
            p[i] = p[i] * beta + z[i]
        rz = rz_new
        it += 1
    return it, bnorm, math.sqrt(rr) / bnorm


def cg_csr(A, b: np.ndarray, diag: np.ndarray, x0: np.ndarray | None, rtol: float, maxiter: int):
    """(x, iterations, relative residual) of Jacobi-preconditioned CG on the CSR matrix ``A``, as
    :func:`geometry.operators.jacobi_cg` (the same iteration; one pass over the vectors per phase)."""
    b = np.ascontiguousarray(b, dtype=np.float64)
    x = np.zeros_like(b) if x0 is None else np.array(x0, dtype=np.float64)
    width = max(int(np.diff(A.indptr).max(initial=0)), 1)
    width = -(-width // _ELL_BLOCK) * _ELL_BLOCK
    d, idx = _csr_to_ell(np.ascontiguousarray(A.data, dtype=np.float64), A.indices, A.indptr, width)
    it, bnorm, rel = _cg_ell(d, idx, b, np.ascontiguousarray(diag, dtype=np.float64), x, x0 is not None,
                             float(rtol), int(maxiter))
    if bnorm == 0.0 or not np.isfinite(bnorm):
        return np.zeros_like(b), 0, 0.0 if bnorm == 0.0 else np.nan
    return x, int(it), float(rel)


# ------------------------------------------------------------------------------------ curvature
@jit
def _solve_fit(m, cnt, linear):
    """(H, K) from the ring moments ``m`` of one vertex: fit_ring's closed form, scalar by scalar."""
    q11, q12, q13 = 0.25 * m[0], 0.5 * m[1], 0.25 * m[2]
    q22, q23, q33 = m[3], 0.5 * m[4], 0.25 * m[5]
    r1, r2, r3 = 0.5 * m[6], m[7], 0.5 * m[8]
    trace = q11 + q22 + q33
    scale = trace if trace > 0 else 1.0
    ridge = 1e-12 * scale
    det_q = q11 * (q22 * q33 - q23 * q23) - q12 * (q12 * q33 - q23 * q13) + q13 * (q12 * q23 - q22 * q13)
    q11r, q22r, q33r = q11 + ridge, q22 + ridge, q33 + ridge
    if linear:
        c14, c15, c24, c25, c34, c35 = 0.5 * m[9], 0.5 * m[10], m[11], m[12], 0.5 * m[13], 0.5 * m[14]
        l44, l45, l55 = m[15] + ridge, m[16], m[17] + ridge
        r4, r5 = m[18], m[19]
        if cnt < 5:
            c14 = c15 = c24 = c25 = c34 = c35 = l45 = r4 = r5 = 0.0
            l44 = l55 = 1.0 + ridge
        det_l = l44 * l55 - l45 * l45
        if det_l == 0:
            det_l = np.inf
        inv_l = 1.0 / det_l
        i44, i45, i55 = l55 * inv_l, -l45 * inv_l, l44 * inv_l
        e10, e11 = c14 * i44 + c15 * i45, c14 * i45 + c15 * i55
        e20, e21 = c24 * i44 + c25 * i45, c24 * i45 + c25 * i55
        e30, e31 = c34 * i44 + c35 * i45, c34 * i45 + c35 * i55
        s11 = q11r - (e10 * c14 + e11 * c15)
        s12 = q12 - (e10 * c24 + e11 * c25)
        s13 = q13 - (e10 * c34 + e11 * c35)
        s22 = q22r - (e20 * c24 + e21 * c25)
        s23 = q23 - (e20 * c34 + e21 * c35)
        s33 = q33r - (e30 * c34 + e31 * c35)
        b1 = r1 - (e10 * r4 + e11 * r5)
        b2 = r2 - (e20 * r4 + e21 * r5)
        b3 = r3 - (e30 * r4 + e31 * r5)
    else:
        s11, s12, s13, s22, s23, s33 = q11r, q12, q13, q22r, q23, q33r
        b1, b2, b3 = r1, r2, r3
    m11 = s22 * s33 - s23 * s23
    m12 = s13 * s23 - s12 * s33
    m13 = s12 * s23 - s13 * s22
    m22 = s11 * s33 - s13 * s13
    m23 = s12 * s13 - s11 * s23
    m33 = s11 * s22 - s12 * s12
    det = s11 * m11 + s12 * m12 + s13 * m13
    inv = 1.0 / det if det != 0 else 0.0
    A = (m11 * b1 + m12 * b2 + m13 * b3) * inv
    B = (m12 * b1 + m22 * b2 + m23 * b3) * inv
    C = (m13 * b1 + m23 * b2 + m33 * b3) * inv
    if cnt < 3 or not (abs(det_q) > 1e-10 * scale ** 3) or not (det > 0):
        return np.nan, np.nan
    if linear:
        fx = i44 * (r4 - c14 * A - c24 * B - c34 * C) + i45 * (r5 - c15 * A - c25 * B - c35 * C)
        fy = i45 * (r4 - c14 * A - c24 * B - c34 * C) + i55 * (r5 - c15 * A - c25 * B - c35 * C)
        g = 1.0 + fx * fx + fy * fy
        return -((1 + fy * fy) * A - 2 * fx * fy * B + (1 + fx * fx) * C) / (2.0 * g * math.sqrt(g)), \
            (A * C - B * B) / (g * g)
    return -0.5 * (A + C), A * C - B * B


@jit
def _ring_curvature(x, n, ring, count, linear, H, K, start):
    for r in range(ring.shape[0]):
        i = start + r                                    # row r holds the neighbours of vertex start + r
        x0, x1, x2 = x[i, 0], x[i, 1], x[i, 2]
        nx, ny, nz = n[0, i], n[1, i], n[2, i]
        sg = 1.0 if nz >= 0 else -1.0                    # tangent_frames_t
        a = -1.0 / (sg + nz)
        bb = nx * ny * a
        t10, t11, t12 = 1.0 + sg * nx * nx * a, sg * bb, -sg * nx
        t20, t21, t22 = bb, sg + ny * ny * a, -ny
        # the 20 ring moments of fit_ring, in registers
        m0 = m1 = m2 = m3 = m4 = m5 = m6 = m7 = m8 = m9 = 0.0
        m10 = m11 = m12 = m13 = m14 = m15 = m16 = m17 = m18 = m19 = 0.0
        for w in range(ring.shape[1]):
            j = ring[r, w]
            if j < 0:
                break
            dx, dy, dz = x[j, 0] - x0, x[j, 1] - x1, x[j, 2] - x2
            u = dx * t10 + dy * t11 + dz * t12
            v = dx * t20 + dy * t21 + dz * t22
            z = dx * nx + dy * ny + dz * nz
            uu, uv, vv = u * u, u * v, v * v
            m0 += uu * uu
            m1 += uu * uv
            m2 += uu * vv
            m3 += uv * uv
            m4 += uv * vv
            m5 += vv * vv
            m6 += uu * z
            m7 += uv * z
            m8 += vv * z
            m9 += uu * u
            m10 += uu * v
            m11 += uv * u
            m12 += uv * v
            m13 += vv * u
            m14 += vv * v
            m15 += uu
            m16 += uv
            m17 += vv
            m18 += u * z
            m19 += v * z
        H[r], K[r] = _solve_fit((m0, m1, m2, m3, m4, m5, m6, m7, m8, m9, m10, m11, m12, m13, m14, m15, m16,
                                 m17, m18, m19), count[r], linear)


def ring_curvature(x: np.ndarray, n: np.ndarray, ring: np.ndarray, count: np.ndarray, linear: bool,
                   start: int = 0):
    """(H, K) of the paraboloid fit over the 1-ring ``ring`` (V, W) padded with −1 (trailing), vertices
    ``x`` (V, 3) and unit normals ``n`` stored by coordinate (3, V):
    :meth:`geometry.operators.MeshOperators.curvature`.  With ``start``, ``ring`` (R, W) holds the
    neighbourhoods of vertices start..start+R−1 only (a block of :func:`geometry.radius_curvature`) and the
    results are (R,)."""
    R = ring.shape[0]
    H, K = np.empty(R), np.empty(R)
    _ring_curvature(np.ascontiguousarray(x, dtype=np.float64), np.ascontiguousarray(n, dtype=np.float64),
                    np.ascontiguousarray(ring), np.ascontiguousarray(count, dtype=np.int64), bool(linear), H, K,
                    int(start))
    return H, K


# ------------------------------------------------------------------------------------ trilinear
@jit(inline="always")      # inlined by numba: a compiled call per point is slower than the sum itself
def trilinear_point(flat, n0, n1, n2, fx, fy, fz, out, p):
    """The first ``out.shape[0]`` channels of the stacked grids ``flat`` (N, C) at one fractional index (fx,
    fy, fz), inside [0, n − 1] per axis, into column ``p`` of ``out``: the one trilinear sum of the compiled
    code (the grids' samplers here, DistMesh's loop), equal to :func:`geometry.trilinear.trilinear_channels`."""
    sx = n1 * n2
    i0, i1, i2 = min(int(fx), n0 - 2), min(int(fy), n1 - 2), min(int(fz), n2 - 2)   # idx >= 0: floor
    tx, ty, tz = fx - i0, fy - i1, fz - i2
    ux, uy, uz = 1.0 - tx, 1.0 - ty, 1.0 - tz
    a00, a01, a10, a11 = ux * uy, ux * ty, tx * uy, tx * ty
    w0, w1, w2, w3 = a00 * uz, a00 * tz, a01 * uz, a01 * tz
    w4, w5, w6, w7 = a10 * uz, a10 * tz, a11 * uz, a11 * tz
    b = i0 * sx + i1 * n2 + i2
    for c in range(out.shape[0]):
        out[c, p] = (w0 * flat[b, c] + w1 * flat[b + 1, c] + w2 * flat[b + n2, c]
                     + w3 * flat[b + n2 + 1, c] + w4 * flat[b + sx, c] + w5 * flat[b + sx + 1, c]
                     + w6 * flat[b + sx + n2, c] + w7 * flat[b + sx + n2 + 1, c])


@jit
def _trilinear(flat, n0, n1, n2, idx_t, out):
    for p in range(idx_t.shape[1]):
        fx, fy, fz = idx_t[0, p], idx_t[1, p], idx_t[2, p]
        if not (0.0 <= fx <= n0 - 1 and 0.0 <= fy <= n1 - 1 and 0.0 <= fz <= n2 - 1):   # NaN too
            raise IndexError("trilinear: fractional indices outside the grid (or not finite)")
        trilinear_point(flat, n0, n1, n2, fx, fy, fz, out, p)


def trilinear(flat: np.ndarray, shape, idx_t: np.ndarray, channels: int | None = None) -> np.ndarray:
    """:func:`geometry.trilinear.trilinear_channels` point by point: (C, P) from the stacked grids ``flat``
    (N, C) at the fractional indices ``idx_t`` (3, P), finite and inside [0, N − 1] per axis; ``channels``:
    only the first this many grids (C = ``channels``)."""
    n = flat.shape[1] if channels is None else int(channels)
    if not 0 < n <= flat.shape[1]:
        raise ValueError(f"trilinear: channels = {channels} of a stack of {flat.shape[1]}")
    out = np.empty((n, idx_t.shape[1]))
    _trilinear(flat, int(shape[0]), int(shape[1]), int(shape[2]),
               np.ascontiguousarray(idx_t, dtype=np.float64), out)
    return out


# ------------------------------------------------------------------------------------- geometry
@jit
def _face_geometry(x, faces, cross_t, normals_t, areas, centroids_t):
    for f in range(faces.shape[0]):
        a, b, c = faces[f, 0], faces[f, 1], faces[f, 2]
        p0, p1, p2 = x[a, 0], x[a, 1], x[a, 2]
        q0, q1, q2 = x[b, 0], x[b, 1], x[b, 2]
        r0, r1, r2 = x[c, 0], x[c, 1], x[c, 2]
        e0, e1, e2 = q0 - p0, q1 - p1, q2 - p2
        g0, g1, g2 = r0 - p0, r1 - p1, r2 - p2
        c0, c1, c2 = e1 * g2 - e2 * g1, e2 * g0 - e0 * g2, e0 * g1 - e1 * g0
        dbl = math.sqrt(c0 * c0 + c1 * c1 + c2 * c2)
        cross_t[0, f], cross_t[1, f], cross_t[2, f] = c0, c1, c2
        areas[f] = 0.5 * dbl
        s = dbl if dbl > 0 else 1.0
        normals_t[0, f], normals_t[1, f], normals_t[2, f] = c0 / s, c1 / s, c2 / s
        centroids_t[0, f] = (p0 + q0 + r0) / 3.0
        centroids_t[1, f] = (p1 + q1 + r1) / 3.0
        centroids_t[2, f] = (p2 + q2 + r2) / 3.0


def face_geometry(x: np.ndarray, faces: np.ndarray):
    """(cross_t, normals_t, areas, centroids_t) of every face in one pass: the face cross products
    2 a_f n_f (3, F), unit normals (3, F) (zero on degenerate faces), areas (F,) and centroids (3, F),
    with the arithmetic of :class:`geometry.operators.MeshGeometry`'s numpy form (same numbers)."""
    F = len(faces)
    cross_t, normals_t, centroids_t = np.empty((3, F)), np.empty((3, F)), np.empty((3, F))
    areas = np.empty(F)
    _face_geometry(np.ascontiguousarray(x, dtype=np.float64), faces, cross_t, normals_t, areas, centroids_t)
    return cross_t, normals_t, areas, centroids_t


@jit
def _vertex_sums(faces, cross_t, areas, vn, va):
    for f in range(faces.shape[0]):
        a3 = areas[f] / 3.0
        for k in range(3):
            v = faces[f, k]
            vn[0, v] += cross_t[0, f]
            vn[1, v] += cross_t[1, f]
            vn[2, v] += cross_t[2, f]
            va[v] += a3


def vertex_sums(faces: np.ndarray, cross_t: np.ndarray, areas: np.ndarray, n_vertices: int):
    """(Σ cross_t, Σ area/3) over the faces around each vertex — the un-normalised area-weighted vertex
    normals (3, V) and the lumped vertex areas (V,) — summed in face order as the (V, F) incidence
    product of :class:`geometry.operators.MeshGeometry` does."""
    vn, va = np.zeros((3, n_vertices)), np.zeros(n_vertices)
    _vertex_sums(faces, cross_t, areas, vn, va)
    return vn, va


# ------------------------------------------------------------------------------------ ring mean
@jit
def _ring_mean(xt, ring, out):
    for i in range(xt.shape[1]):
        cnt = 0
        s0 = s1 = s2 = 0.0
        for w in range(ring.shape[1]):
            j = ring[i, w]
            if j < 0:
                break
            s0 += xt[0, j]
            s1 += xt[1, j]
            s2 += xt[2, j]
            cnt += 1
        c = max(cnt, 1)
        out[0, i], out[1, i], out[2, i] = s0 / c, s1 / c, s2 / c


def ring_mean3(xt: np.ndarray, ring: np.ndarray) -> np.ndarray:
    """Mean of the 1-ring neighbours (``ring`` (V, W), trailing −1) of 3-vectors stored by coordinate
    (3, V): :meth:`geometry.operators.MeshOperators.ring_mean_t`."""
    out = np.empty((3, xt.shape[1]))
    _ring_mean(np.ascontiguousarray(xt, dtype=np.float64), ring, out)
    return out


@jit
def _face_edges(x, faces, E):
    for f in range(faces.shape[0]):
        for k in range(3):
            a, b = faces[f, (k + 1) % 3], faces[f, (k + 2) % 3]       # e_k = P[k+2] − P[k+1]
            E[0, k, f] = x[b, 0] - x[a, 0]
            E[1, k, f] = x[b, 1] - x[a, 1]
            E[2, k, f] = x[b, 2] - x[a, 2]


def face_edges(x: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """The edge opposite each corner, counter-clockwise, (3 coords, 3 corners, F):
    :attr:`geometry.operators.MeshGeometry.edges_t` without the corner array."""
    E = np.empty((3, 3, len(faces)))
    _face_edges(np.ascontiguousarray(x, dtype=np.float64), faces, E)
    return E
