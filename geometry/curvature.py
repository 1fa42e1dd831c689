"""Mean and Gaussian curvature by a local paraboloid fit (docs/METHOD.md, "Mean Curvature Estimation").

For every vertex at once: translate the vertex to the origin, express its neighbours in an orthonormal
frame whose third axis is the vertex normal, least-squares fit z = A/2 x² + B xy + C/2 y², and read off
the Weingarten map W = [[−A, −B], [−B, −C]]: H = −(A + C)/2, K = AC − B².

The paper rotates the neighbourhood with Rodrigues' formula so that the normal becomes +z; any rotation
taking the normal to +z differs from it only by a rotation about z, under which A + C and AC − B² are
invariant, so the result is the same.  The frame used here is built without the singularity Rodrigues has
at n = −z.  With the outward normal, H > 0 on a sphere (H = 1/R, K = 1/R²).
"""

from __future__ import annotations

import numpy as np


def tangent_frames_t(n) -> tuple[tuple, tuple]:
    """Orthonormal tangent frames of unit normals stored by coordinate ``n`` (3, V): (t1, t2), each a
    tuple of three (V,) arrays.  Branch-free (Duff et al. 2017), valid for every unit n (no singularity
    at n = −z as Rodrigues' formula has)."""
    nx, ny, nz = n[0], n[1], n[2]
    sg = np.where(nz >= 0, 1.0, -1.0)
    a = -1.0 / (sg + nz)
    bb = nx * ny * a
    return (1.0 + sg * nx * nx * a, sg * bb, -sg * nx), (bb, sg + ny * ny * a, -ny)


def tangent_frames(normals: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit tangent vectors (V, 3) each, orthonormal to ``normals`` (V, 3) and to each other."""
    t1, t2 = tangent_frames_t(np.asarray(normals, float).T)
    return np.stack(t1, axis=1), np.stack(t2, axis=1)


def fit_ring(u, v, z, count, *, linear: bool = True):
    """(H, K, A, B, C) of the least-squares paraboloid fit of every vertex at once, in closed form.

    ``u``, ``v``, ``z`` (W, V): the neighbours' coordinates in the vertex's frame (tangent, tangent,
    normal), vertex at the origin, laid out neighbour-slot first so that the sums over a neighbourhood
    run over the short leading axis; padded slots must be exactly 0 (they then add nothing).  ``count``
    (V,): the number of real neighbours.

    The 5×5 (``linear``) or 3×3 normal equations of all vertices are solved at once: the 2×2 block of
    the linear terms is eliminated by its Schur complement and the remaining symmetric 3×3 system is
    solved by its adjugate — several times faster than a batched ``np.linalg.solve`` on small systems.
    A tiny relative ridge (1e-12 of the trace) keeps exactly-singular systems solvable; such fits are
    flagged: NaN where ``count`` < 3 or the quadratic block is (almost) rank-deficient.  Vertices with
    fewer than 5 neighbours fit the linear terms as zero (the paper's fit).
    """
    uu, uv, vv = u * u, u * v, v * v
    S = lambda p: p.sum(0)  # noqa: E731 - sum over the neighbourhood
    D = lambda p, q: np.einsum("wv,wv->v", p, q)  # noqa: E731 - S(p * q) without the (W, V) product
    # moments of the design columns a = (u²/2, uv, v²/2, u, v)
    q11, q12, q13 = 0.25 * D(uu, uu), 0.5 * D(uu, uv), 0.25 * D(uu, vv)
    q22, q23, q33 = D(uv, uv), 0.5 * D(uv, vv), 0.25 * D(vv, vv)
    r1, r2, r3 = 0.5 * D(uu, z), D(uv, z), 0.5 * D(vv, z)
    trace = q11 + q22 + q33
    scale = np.where(trace > 0, trace, 1.0)
    ridge = 1e-12 * scale
    cnt = np.asarray(count)
    # determinant of the unregularised quadratic block: the degeneracy test
    det_q = q11 * (q22 * q33 - q23 * q23) - q12 * (q12 * q33 - q23 * q13) + q13 * (q12 * q23 - q22 * q13)
    q11r, q22r, q33r = q11 + ridge, q22 + ridge, q33 + ridge
    if linear:
        c14, c15 = 0.5 * D(uu, u), 0.5 * D(uu, v)
        c24, c25 = D(uv, u), D(uv, v)
        c34, c35 = 0.5 * D(vv, u), 0.5 * D(vv, v)
        l44, l45, l55 = S(uu) + ridge, S(uv), S(vv) + ridge
        r4, r5 = D(u, z), D(v, z)
        few = cnt < 5                      # too few neighbours for the linear terms: fit them as zero
        if few.any():
            for arr in (c14, c15, c24, c25, c34, c35, l45, r4, r5):
                arr[few] = 0.0
            l44[few] = l55[few] = 1.0 + ridge[few]
        det_l = l44 * l55 - l45 * l45
        det_l = np.where(det_l != 0, det_l, np.inf)
        i44, i45, i55 = l55 / det_l, -l45 / det_l, l44 / det_l
        # C L⁻¹ (rows 1..3)
        e1 = (c14 * i44 + c15 * i45, c14 * i45 + c15 * i55)
        e2 = (c24 * i44 + c25 * i45, c24 * i45 + c25 * i55)
        e3 = (c34 * i44 + c35 * i45, c34 * i45 + c35 * i55)
        s11 = q11r - (e1[0] * c14 + e1[1] * c15)
        s12 = q12 - (e1[0] * c24 + e1[1] * c25)
        s13 = q13 - (e1[0] * c34 + e1[1] * c35)
        s22 = q22r - (e2[0] * c24 + e2[1] * c25)
        s23 = q23 - (e2[0] * c34 + e2[1] * c35)
        s33 = q33r - (e3[0] * c34 + e3[1] * c35)
        b1 = r1 - (e1[0] * r4 + e1[1] * r5)
        b2 = r2 - (e2[0] * r4 + e2[1] * r5)
        b3 = r3 - (e3[0] * r4 + e3[1] * r5)
    else:
        s11, s12, s13, s22, s23, s33 = q11r, q12, q13, q22r, q23, q33r
        b1, b2, b3 = r1, r2, r3
    # adjugate solve of the symmetric 3×3 system
    m11 = s22 * s33 - s23 * s23
    m12 = s13 * s23 - s12 * s33
    m13 = s12 * s23 - s13 * s22
    m22 = s11 * s33 - s13 * s13
    m23 = s12 * s13 - s11 * s23
    m33 = s11 * s22 - s12 * s12
    det = s11 * m11 + s12 * m12 + s13 * m13
    safe = np.where(det != 0, det, np.inf)
    A = (m11 * b1 + m12 * b2 + m13 * b3) / safe
    B = (m12 * b1 + m22 * b2 + m23 * b3) / safe
    C = (m13 * b1 + m23 * b2 + m33 * b3) / safe
    if linear:
        fx = i44 * (r4 - c14 * A - c24 * B - c34 * C) + i45 * (r5 - c15 * A - c25 * B - c35 * C)
        fy = i45 * (r4 - c14 * A - c24 * B - c34 * C) + i55 * (r5 - c15 * A - c25 * B - c35 * C)
        g = 1.0 + fx * fx + fy * fy
        H = -((1 + fy * fy) * A - 2 * fx * fy * B + (1 + fx * fx) * C) / (2.0 * g ** 1.5)
        K = (A * C - B * B) / (g * g)
    else:
        H = -0.5 * (A + C)
        K = A * C - B * B
    bad = (cnt < 3) | ~(np.abs(det_q) > 1e-10 * scale ** 3) | ~(det > 0)
    if bad.any():
        H[bad] = np.nan
        K[bad] = np.nan
    return H, K, A, B, C


def paraboloid_curvature(vertices, normals, neighbors, *, linear: bool = True, return_coeffs: bool = False,
                         rows=None):
    """Batched paraboloid-fit curvature over arbitrary (padded) neighbourhoods.

    Parameters
    ----------
    vertices : (V, 3) float
    normals : (V, 3) unit outward normals at the vertices
    neighbors : (V, W) int, padded with −1 (e.g. :func:`geometry.mesh.one_ring`); with ``rows`` (R, W), the
        neighbours of the vertices ``rows``
    linear : bool
        True (default): fit z = D x + E y + A/2 x² + B xy + C/2 y² and evaluate H, K of that graph at
        the vertex, which removes the bias a slightly tilted vertex normal causes (on a level-5
        icosphere the area-weighted normals are off by up to 0.17°, which biases the paper's fit by 2 %).
        Needs 5 neighbours; vertices with fewer fall back to the paper's fit.
        False: the paper's fit z = A/2 x² + B xy + C/2 y² exactly as printed.

    rows : slice or (R,) int array, optional
        Fit only these vertices (a block of a large mesh: :func:`radius_curvature`); default all.

    Returns
    -------
    H, K : (V,) arrays — (R,) with ``rows`` — (NaN where a vertex has fewer than 3 neighbours or a degenerate
    fit); with ``return_coeffs`` also the (V, 3) array of (A, B, C).

    The fit itself is :func:`fit_ring`, the one implementation the shape-gradient flow's in-loop
    curvature (:meth:`geometry.operators.MeshOperators.curvature`) also calls.
    """
    xt = np.asarray(vertices, float).T                         # (3, V)
    n = np.asarray(normals, float).T
    nb = np.asarray(neighbors).T                               # (W, V) or (W, R)
    centers = np.arange(xt.shape[1])
    if rows is not None:
        centers = centers[rows]
        xc, n = xt[:, centers], n[:, centers]
    else:
        xc = xt
    valid = nb >= 0
    idx = np.where(valid, nb, centers)                         # padded slots → the vertex itself: offset 0
    d = [np.take(xt[c], idx) - xc[c] for c in range(3)]        # (W, V) each
    t1, t2 = tangent_frames_t(n)
    u = d[0] * t1[0] + d[1] * t1[1] + d[2] * t1[2]
    v = d[0] * t2[0] + d[1] * t2[1] + d[2] * t2[2]
    z = d[0] * n[0] + d[1] * n[1] + d[2] * n[2]
    H, K, A, B, C = fit_ring(u, v, z, valid.sum(0), linear=linear)
    if return_coeffs:
        return H, K, np.stack([A, B, C], axis=1)
    return H, K


def radius_curvature(vertices, faces, radius: float, normals=None, *, linear: bool = True,
                     max_width: int | None = None, block: int | None = None, compiled: bool | None = None,
                     edges=None) -> tuple[np.ndarray, np.ndarray]:
    """(H, K) per vertex by :func:`paraboloid_curvature` over :func:`geometry.mesh.radius_neighbors` (the 1-ring
    and the nearest others within ``radius``, at most ``max_width`` = :data:`geometry.mesh.MAX_NEIGHBORS` = 96),
    fitted block by block (:data:`geometry.mesh.NEIGHBOR_BLOCK` vertices): O(V · max_width) time and
    O(block · max_width) memory beyond the (V,) results, whatever the mesh density — the neighbour array of
    the whole mesh and the fit's (W, V) temporaries are never built.  The same numbers as the one-shot fit
    over the whole neighbour array (each vertex's fit reads only its own row).

    ``normals``: unit outward vertex normals (default :func:`geometry.mesh.vertex_normals`).
    ``compiled``: fit with :func:`geometry.kernels.ring_curvature` (the same arithmetic vertex by vertex, sums
    in another order: equal to rounding) instead of :func:`paraboloid_curvature`; None: from
    :data:`geometry.compiled.MIN_SIZE` vertices on.  ``edges``: :func:`geometry.topology.edges_unique` of
    ``faces``, when computed already (a :class:`geometry.mesh.ScoredMesh` keeps them).
    """
    from . import kernels
    from .compiled import wanted
    from .mesh import MAX_NEIGHBORS, NEIGHBOR_BLOCK, radius_neighbor_blocks, vertex_normals

    vertices = np.asarray(vertices, float)
    normals = vertex_normals(vertices, faces) if normals is None else np.asarray(normals, float)
    compiled = wanted(len(vertices)) if compiled is None else compiled
    n_t = np.ascontiguousarray(normals.T) if compiled else None
    H = np.full(len(vertices), np.nan)
    K = np.full(len(vertices), np.nan)
    for s, t, nb in radius_neighbor_blocks(vertices, faces, radius,
                                           MAX_NEIGHBORS if max_width is None else max_width,
                                           NEIGHBOR_BLOCK if block is None else block, edges):
        if compiled:                              # rows are left-justified: the kernel stops at the first −1
            H[s:t], K[s:t] = kernels.ring_curvature(vertices, n_t, nb, (nb >= 0).sum(axis=1), linear, start=s)
        else:
            H[s:t], K[s:t] = paraboloid_curvature(vertices, normals, nb, linear=linear, rows=slice(s, t))
    return H, K
