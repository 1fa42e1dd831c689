"""Linear finite-element (P1) operators on a triangle mesh (docs/METHOD.md, "Discretisation").

Conventions (λ_i is the hat function of vertex i, a_f the area of face f):

* per-face gradient of a P1 function u:   (∇u)_f = Σ_{k∈f} u_k ∇λ_k|_f        — :func:`face_gradient`
* cotangent stiffness:                    K_ij = Σ_f a_f ∇λ_i·∇λ_j            — :func:`cotangent_stiffness`
  (positive semi-definite, rows sum to 0, K_ij = −(cot α_ij + cot β_ij)/2 off the diagonal)
* lumped mass:                            M_ii = one third of the incident face areas
* surface divergence of a per-face tangent field X, the negative transpose of the gradient weighted by
  face area, divided by the lumped area:  (div_Γ X)_i = −(1/M_ii) Σ_f a_f X_f·∇λ_i|_f  — :func:`divergence`
  (so Σ_i M_ii u_i (div X)_i = −Σ_f a_f X_f·(∇u)_f: the discrete Green formula, and div ∇ = −M⁻¹K).

:class:`MeshOperators` precomputes everything that depends only on the connectivity (the CSR pattern of
K, the 1-ring) so that an iterative method rebuilds the geometric quantities with a handful of
vectorised calls per iteration.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from . import compiled, kernels
from .arrays import unique_ints
from .curvature import fit_ring, tangent_frames_t
from .mesh import lumped_vertex_areas, padded_from_pairs
from .topology import edges_unique

__all__ = [
    "face_gradient_basis", "face_gradient", "gradient_operator", "divergence", "cotangent_stiffness",
    "lumped_mass", "MeshOperators", "MeshGeometry", "jacobi_cg", "dot",
]


def _face_frame(vertices: np.ndarray, faces: np.ndarray):
    p = [vertices[faces[:, k]] for k in range(3)]
    cross = np.cross(p[1] - p[0], p[2] - p[0])
    dblarea = np.linalg.norm(cross, axis=1)
    return p, cross, dblarea


def _basis_from(p, cross, dblarea) -> np.ndarray:
    # ∇λ_k = n × e_k / (2a) with e_k the edge opposite corner k (counter-clockwise) and n = cross / 2a,
    # i.e. ∇λ_k = cross × e_k / (2a)²
    e = np.stack([p[2] - p[1], p[0] - p[2], p[1] - p[0]], axis=1)          # (F, 3, 3)
    denom = np.where(dblarea > 0, dblarea, np.inf) ** 2
    return np.cross(cross[:, None, :], e) / denom[:, None, None]


def face_gradient_basis(vertices, faces) -> np.ndarray:
    """∇λ_k on every face, shape (F, 3 corners, 3 coordinates); zero on degenerate faces."""
    vertices = np.asarray(vertices, float)
    faces = np.asarray(faces)
    p, cross, dblarea = _face_frame(vertices, faces)
    return _basis_from(p, cross, dblarea)


def face_gradient(vertices, faces, u, basis: np.ndarray | None = None) -> np.ndarray:
    """Per-face gradient of the P1 interpolant of vertex values ``u`` (V,) or (V, C): (F, 3) or (F, C, 3)."""
    faces = np.asarray(faces)
    if basis is None:
        basis = face_gradient_basis(vertices, faces)
    u = np.asarray(u, float)
    uf = u[faces]                                                          # (F, 3) or (F, 3, C)
    if uf.ndim == 2:
        return np.einsum("fk,fkd->fd", uf, basis)
    return np.einsum("fkc,fkd->fcd", uf, basis)


def gradient_operator(vertices, faces) -> sp.csr_matrix:
    """Sparse (3F, V) matrix D with (D u)[3f + d] = (∇u)_f[d]."""
    vertices = np.asarray(vertices, float)
    faces = np.asarray(faces)
    basis = face_gradient_basis(vertices, faces)                           # (F, 3, 3)
    F = len(faces)
    rows = (3 * np.arange(F)[:, None, None] + np.arange(3)[None, None, :]).repeat(3, axis=1)
    cols = np.broadcast_to(faces[:, :, None], (F, 3, 3))
    return sp.csr_matrix((basis.ravel(), (rows.ravel(), cols.ravel())), shape=(3 * F, len(vertices)))


def divergence(vertices, faces, X, *, vertex_areas: np.ndarray | None = None,
               basis: np.ndarray | None = None, weak: bool = False) -> np.ndarray:
    """Surface divergence at the vertices of a per-face vector field ``X`` (F, 3).

    ``weak=True`` returns −Σ_f a_f X_f·∇λ_i (the integral of div over the vertex's lumped area) instead
    of dividing by the lumped area.  Components of X normal to a face do not contribute.
    """
    vertices = np.asarray(vertices, float)
    faces = np.asarray(faces)
    p, cross, dblarea = _face_frame(vertices, faces)
    if basis is None:
        basis = _basis_from(p, cross, dblarea)
    contrib = -0.5 * dblarea[:, None] * np.einsum("fkd,fd->fk", basis, np.asarray(X, float))
    w = np.bincount(faces.ravel(), weights=contrib.ravel(), minlength=len(vertices))
    if weak:
        return w
    if vertex_areas is None:
        vertex_areas = lumped_vertex_areas(vertices, faces)
    return w / np.where(vertex_areas > 0, vertex_areas, np.inf)


def _local_stiffness(basis: np.ndarray, dblarea: np.ndarray) -> np.ndarray:
    return 0.5 * dblarea[:, None, None] * np.einsum("fid,fjd->fij", basis, basis)


def cotangent_stiffness(vertices, faces) -> sp.csr_matrix:
    """Cotangent stiffness matrix K (V, V), symmetric positive semi-definite, K·1 = 0."""
    vertices = np.asarray(vertices, float)
    faces = np.asarray(faces)
    p, cross, dblarea = _face_frame(vertices, faces)
    local = _local_stiffness(_basis_from(p, cross, dblarea), dblarea)
    rows = np.repeat(faces, 3, axis=1).ravel()
    cols = np.tile(faces, (1, 3)).ravel()
    K = sp.csr_matrix((local.ravel(), (rows, cols)), shape=(len(vertices), len(vertices)))
    K.sum_duplicates()
    return K


def lumped_mass(vertices, faces) -> sp.dia_matrix:
    """Lumped (barycentric) mass matrix: diag of one third of the incident face areas."""
    return sp.diags(lumped_vertex_areas(vertices, faces))


_DOT_BLOCK = 8192   # OpenBLAS runs a dot product of more than 10,000 entries on all its threads


def dot(a: np.ndarray, b: np.ndarray) -> float:
    """a·b of two 1-D float arrays on one thread.

    ``a @ b`` hands long vectors to the multi-threaded BLAS: on a loaded machine each call may wait for
    a descheduled BLAS thread (milliseconds for a 100k-vector dot, more than the sparse product of the
    same CG iteration), and CPU time doubles.  Blocks of ``_DOT_BLOCK`` entries stay on the calling
    thread (``np.vecdot`` of the rows, then their sum).  Same value up to rounding.
    """
    n = len(a)
    if n <= _DOT_BLOCK:
        return float(a @ b)
    m = n - n % _DOT_BLOCK
    out = float(np.vecdot(a[:m].reshape(-1, _DOT_BLOCK), b[:m].reshape(-1, _DOT_BLOCK)).sum())
    return out + float(a[m:] @ b[m:]) if m < n else out


def jacobi_cg(matvec, b: np.ndarray, diag: np.ndarray, x0: np.ndarray | None = None, *,
              rtol: float = 1e-4, maxiter: int = 200) -> tuple[np.ndarray, int, float]:
    """Jacobi-preconditioned conjugate gradients for an SPD system; returns (x, iterations, rel. residual).

    ``matvec(x)`` applies the matrix — or ``matvec`` is the matrix itself (anything with ``@``, e.g. the
    CSR matrix of :meth:`MeshOperators.h1_matrix`, one sparse product per iteration; from
    :data:`geometry.compiled.MIN_SIZE` unknowns on, a CSR matrix runs the compiled
    :func:`geometry.kernels.cg_csr`, the same iteration); ``diag`` is its diagonal.  Stops when
    ‖r‖ ≤ rtol‖b‖ or after ``maxiter`` iterations (the loop is over CG iterations, each a few vectorised
    operations, updates in place, dot products on one thread: :func:`dot`).
    """
    if not callable(matvec):
        A = matvec
        if compiled.wanted(len(b)) and sp.issparse(A) and A.format == "csr":
            return kernels.cg_csr(A, b, diag, x0, rtol, maxiter)
        matvec = A.__matmul__
    bnorm = float(np.sqrt(dot(b, b)))
    if bnorm == 0.0 or not np.isfinite(bnorm):
        return np.zeros_like(b), 0, 0.0 if bnorm == 0.0 else np.nan
    inv = 1.0 / diag
    if x0 is None:
        x = np.zeros_like(b)
        r = b.copy()
    else:
        x = x0.copy()
        r = b - matvec(x)
    z = inv * r
    p = z.copy()
    tmp = np.empty_like(b)
    rz = dot(r, z)
    tol2 = (rtol * bnorm) ** 2
    rr = dot(r, r)
    it = 0
    while rr > tol2 and it < maxiter:
        Ap = matvec(p)
        pAp = dot(p, Ap)
        if not pAp > 0:
            break
        a = rz / pAp
        x += np.multiply(a, p, out=tmp)
        r -= np.multiply(a, Ap, out=tmp)
        rr = dot(r, r)
        np.multiply(inv, r, out=z)
        rz_new = dot(r, z)
        p *= rz_new / rz
        p += z
        rz = rz_new
        it += 1
    return x, it, float(np.sqrt(rr) / bnorm)


_CURVATURE_BLOCK = 4096   # vertices per block of MeshOperators.curvature
_PAIRS = ((0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2))   # the distinct (i, j) corner pairs of a face


def _cross_t(a, b) -> np.ndarray:
    """Cross product of vectors stored by coordinate, (3, N) × (3, N) → (3, N)."""
    return np.stack([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]])


def _dot_t(a, b) -> np.ndarray:
    """Dot product of vectors stored by coordinate, (3, ...) · (3, ...) → (...)."""
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


class MeshGeometry:
    """Geometric quantities of one vertex configuration (see :meth:`MeshOperators.geometry`).

    Stored by coordinate (``*_t`` arrays have shape (3, N)): numpy is several times faster on (3, N)
    arrays than on (N, 3) ones for the short per-row sums a mesh needs.  The usual (N, 3) views are
    properties.  Face quantities are computed at once, vertex quantities and edges on first use — with
    numba by the compiled passes of :func:`geometry.kernels.face_geometry` and
    :func:`geometry.kernels.vertex_sums` (the same arithmetic; ``reference=True`` keeps numpy).
    """

    def __init__(self, ops: "MeshOperators", vertices: np.ndarray, *, reference: bool = False):
        self._ops = ops
        self.vertices = vertices                                            # (V, 3)
        self.vertices_t = xt = np.ascontiguousarray(vertices.T)             # (3, V)
        self._vertex_areas = self._vertex_normals_t = self._edges_t = None
        self._kernels = compiled.wanted(len(vertices)) and not reference and vertices.dtype == np.float64
        if self._kernels:                            # one compiled pass over the faces (same numbers)
            self._corners_t = None
            self.cross_t, self.normals_t, self.face_areas, self.centroids_t = \
                kernels.face_geometry(vertices, ops.faces)
            return
        self._corners_t = P = np.take(xt, ops.faces_t, axis=1)              # (3 coords, 3 corners, F)
        self.cross_t = c = _cross_t(P[:, 1] - P[:, 0], P[:, 2] - P[:, 0])   # 2 a_f n_f
        dbl = np.sqrt(_dot_t(c, c))
        self.face_areas = 0.5 * dbl
        self.normals_t = c / np.where(dbl > 0, dbl, 1.0)
        self.centroids_t = P.sum(axis=1) / 3.0                              # (3, F)

    @property
    def corners_t(self) -> np.ndarray:
        """The face corners (3 coords, 3 corners, F) (gathered on first use with the kernels)."""
        if self._corners_t is None:
            self._corners_t = np.take(self.vertices_t, self._ops.faces_t, axis=1)
        return self._corners_t

    # ---- (N, 3) views
    @property
    def face_cross(self) -> np.ndarray:
        return self.cross_t.T

    @property
    def face_normals(self) -> np.ndarray:
        return self.normals_t.T

    @property
    def centroids(self) -> np.ndarray:
        return self.centroids_t.T

    @property
    def vertex_normals(self) -> np.ndarray:
        """Area-weighted vertex normals (V, 3), unit length."""
        return self.vertex_normals_t.T

    # ---- lazily computed
    @property
    def vertex_areas(self) -> np.ndarray:
        """Lumped vertex areas (V,): one third of the incident face areas."""
        if self._vertex_areas is None:
            if self._kernels:
                self._vertex_sums()
            else:
                self._vertex_areas = self._ops.incidence @ (self.face_areas / 3.0)
        return self._vertex_areas

    def _vertex_sums(self):
        vn, self._vertex_areas = kernels.vertex_sums(self._ops.faces, self.cross_t, self.face_areas,
                                                     self._ops.n_vertices)
        vn /= np.maximum(np.sqrt(_dot_t(vn, vn)), 1e-300)
        self._vertex_normals_t = vn

    @property
    def vertex_normals_t(self) -> np.ndarray:
        """Area-weighted vertex normals (3, V), unit length."""
        if self._vertex_normals_t is None and self._kernels:
            self._vertex_sums()
        if self._vertex_normals_t is None:
            vn = np.ascontiguousarray((self._ops.incidence @ self.cross_t.T).T)
            vn /= np.maximum(np.sqrt(_dot_t(vn, vn)), 1e-300)
            self._vertex_normals_t = vn
        return self._vertex_normals_t

    @property
    def edges_t(self) -> np.ndarray:
        """Edge opposite each corner, counter-clockwise: (3 coords, 3 corners, F)."""
        if self._edges_t is None and self._kernels and self._corners_t is None:
            self._edges_t = kernels.face_edges(self.vertices, self._ops.faces)
        if self._edges_t is None:
            P = self.corners_t
            self._edges_t = np.stack([P[:, 2] - P[:, 1], P[:, 0] - P[:, 2], P[:, 1] - P[:, 0]], axis=1)
        return self._edges_t

    @property
    def basis(self) -> np.ndarray:
        """∇λ_k on every face (F, 3 corners, 3) = n × e_k / (2a); zero on degenerate faces."""
        E = self.edges_t
        n = self.normals_t
        dbl = 2.0 * self.face_areas
        inv = 1.0 / np.where(dbl > 0, dbl, np.inf)
        b = np.stack([n[1] * E[2] - n[2] * E[1], n[2] * E[0] - n[0] * E[2], n[0] * E[1] - n[1] * E[0]])
        return np.ascontiguousarray((b * inv).transpose(2, 1, 0))


class MeshOperators:
    """Connectivity-dependent precomputation for a mesh whose vertices move but whose faces do not.

    >>> ops = MeshOperators(faces, n_vertices)
    >>> geo = ops.geometry(vertices)            # areas, normals, edges, lumped areas
    >>> K = ops.stiffness(geo)                  # CSR, same pattern every call
    >>> H, K_gauss = ops.curvature(geo)         # batched paraboloid fit over the 1-ring
    """

    def __init__(self, faces, n_vertices: int):
        faces = np.ascontiguousarray(faces, dtype=np.int64)
        if faces.ndim != 2 or faces.shape[1] != 3:
            raise ValueError(f"faces must have shape (F, 3); got {faces.shape}")
        self.faces = faces
        self.faces_t = np.ascontiguousarray(faces.T)
        self.n_vertices = V = int(n_vertices)
        F = len(faces)
        # the pattern of K: the diagonal and both directions of every edge, keys row·V + col in CSR order
        e = edges_unique(faces).astype(np.int64, copy=False)
        self._edges = e
        upper = e[:, 0] * V + e[:, 1]                        # sorted (edges_unique is lexicographic)
        uniq = unique_ints(np.concatenate([np.arange(V, dtype=np.int64) * (V + 1), upper, e[:, 1] * V + e[:, 0]]))
        self._nnz = len(uniq)
        r, c = uniq // V, uniq % V
        self._indices = c.astype(np.int32)
        self._indptr = np.concatenate([[0], np.cumsum(np.bincount(r, minlength=V))]).astype(np.int32)
        self._diag_slot = np.flatnonzero(r == c)
        upper_slot = np.searchsorted(uniq, upper)
        # K is symmetric: assemble the 6 distinct corner products of each face (rows of _PAIRS, faces
        # along the row) onto the slot of the upper-triangle entry (min, max), then copy it to (max, min)
        self._slot6 = np.concatenate(
            [self._diag_slot[faces[:, i]] if i == j else
             upper_slot[np.searchsorted(upper, np.minimum(faces[:, i], faces[:, j]) * V
                                        + np.maximum(faces[:, i], faces[:, j]))] for i, j in _PAIRS])
        mirror = np.empty(self._nnz, dtype=np.int64)         # each entry's upper-triangle twin
        mirror[self._diag_slot] = self._diag_slot
        mirror[upper_slot] = upper_slot
        mirror[np.searchsorted(uniq, e[:, 1] * V + e[:, 0])] = upper_slot
        self._mirror = mirror
        #: (V, F) vertex-face incidence (ones): sums face quantities onto vertices
        self.incidence = sp.csr_matrix((np.ones(3 * F), (faces.ravel(), np.repeat(np.arange(F), 3))),
                                       shape=(V, F))
        #: (V, 3F) scatter of per-corner values stored corner-major (k·F + f) onto the vertices
        self.corner_scatter = sp.csr_matrix((np.ones(3 * F), (self.faces_t.ravel(), np.arange(3 * F))),
                                            shape=(V, 3 * F))
        self.ring = padded_from_pairs(np.concatenate([e[:, 0], e[:, 1]]), np.concatenate([e[:, 1], e[:, 0]]), V)
        #                                                  the 1-ring (V, W) padded with −1 (geometry.mesh.one_ring)
        self.ring_valid = self.ring >= 0
        self.ring_weight = self.ring_valid.astype(float)
        self.ring_count = self.ring_valid.sum(1)
        self._ring_safe = np.where(self.ring_valid, self.ring, 0)
        # padded slots point at the vertex itself, so its offset to itself (0) needs no mask
        self._ring_self_t = np.ascontiguousarray(
            np.where(self.ring_valid, self.ring, np.arange(V)[:, None]).T)   # (W, V)
        self._ring_t = np.ascontiguousarray(self._ring_safe.T)              # (W, V)
        self.ring_weight_t = np.ascontiguousarray(self.ring_weight.T)

    @property
    def edges(self) -> np.ndarray:
        """Unique undirected edges (E, 2), ``e[:, 0] < e[:, 1]``, in lexicographic order."""
        return self._edges

    # ---------------------------------------------------------------- per-configuration geometry
    def geometry(self, vertices: np.ndarray, *, reference: bool = False) -> MeshGeometry:
        """The geometry of ``vertices`` (V, 3); ``reference=True``: computed by numpy, not the kernels."""
        return MeshGeometry(self, np.asarray(vertices, dtype=np.float64), reference=reference)

    # ---------------------------------------------------------------- operators
    def stiffness(self, geo: MeshGeometry) -> sp.csr_matrix:
        """Cotangent stiffness K of ``geo`` (CSR with a pattern fixed by the connectivity).

        On a face, a_f ∇λ_i·∇λ_j = e_i·e_j / (4 a_f) with e_k the edge opposite corner k.  The 6
        distinct products per face are laid out by pair (contiguous rows) and summed onto the upper
        triangle by one ``bincount`` over a precomputed slot array, then mirrored: an off-diagonal entry
        is the same two-term sum as a full 9-entries-per-face assembly (bit-identical), a diagonal entry
        the same terms in another order.
        """
        E = geo.edges_t
        inv = 1.0 / np.where(geo.face_areas > 0, 4.0 * geo.face_areas, np.inf)
        w = np.empty((len(_PAIRS), len(inv)))
        for k, (i, j) in enumerate(_PAIRS):
            np.multiply(_dot_t(E[:, i], E[:, j]), inv, out=w[k])
        data = np.bincount(self._slot6, weights=w.ravel(), minlength=self._nnz)[self._mirror]
        return sp.csr_matrix((data, self._indices, self._indptr), shape=(self.n_vertices,) * 2)

    def h1_matrix(self, geo: MeshGeometry, s: float, K: sp.csr_matrix | None = None):
        """(A, diag): the H¹ preconditioner matrix A = M + sK (M the lumped mass, K :meth:`stiffness`) as
        one CSR matrix with K's pattern, and its diagonal.

        ``jacobi_cg(A, b, diag)`` solves (M + sK)V = b with one sparse product per CG iteration, where
        ``jacobi_cg(lambda p: M * p + s * (K @ p), b, M + s * stiffness_diagonal(K))`` needs the product
        and three vector passes (same solution up to rounding; the diagonal is the same numbers).
        """
        K = self.stiffness(geo) if K is None else K
        data = s * K.data
        data[self._diag_slot] += geo.vertex_areas
        A = sp.csr_matrix((data, self._indices, self._indptr), shape=(self.n_vertices,) * 2)
        return A, data[self._diag_slot]

    def stiffness_diagonal(self, K: sp.csr_matrix) -> np.ndarray:
        return K.data[self._diag_slot]

    def face_gradient(self, geo: MeshGeometry, u: np.ndarray) -> np.ndarray:
        return face_gradient(geo.vertices, self.faces, u, basis=geo.basis)

    def divergence(self, geo: MeshGeometry, X: np.ndarray, weak: bool = False, *,
                   transposed: bool = False) -> np.ndarray:
        """div_Γ of the per-face field X (F, 3) — or (3, F) with ``transposed`` — at the vertices.

        −a_f X·∇λ_k = −½ X·(n × e_k) = −½ e_k·(X × n)  (see :func:`divergence`).
        """
        Xt = X if transposed else X.T
        Y = _cross_t(Xt, geo.normals_t)                                     # (3, F)
        E = geo.edges_t
        contrib = -0.5 * (E[0] * Y[0] + E[1] * Y[1] + E[2] * Y[2])          # (3 corners, F)
        w = self.corner_scatter @ contrib.ravel()
        if weak:
            return w
        return w / np.where(geo.vertex_areas > 0, geo.vertex_areas, np.inf)

    def ring_mean_t(self, xt: np.ndarray, *, reference: bool = False) -> np.ndarray:
        """Mean of the 1-ring neighbours of per-vertex vectors stored by coordinate (C, V) → (C, V)
        (3 rows with numba: :func:`geometry.kernels.ring_mean3`, unless ``reference``)."""
        if compiled.wanted(xt.shape[1]) and not reference and len(xt) == 3:
            return kernels.ring_mean3(xt, self.ring)
        w = self.ring_weight_t
        cnt = np.maximum(self.ring_count, 1)
        return np.stack([(np.take(row, self._ring_t) * w).sum(0) / cnt for row in xt])

    def ring_mean(self, x: np.ndarray) -> np.ndarray:
        """Mean of the 1-ring neighbours' rows of ``x`` (V, C) — the uniform-Laplacian centroid."""
        return self.ring_mean_t(np.ascontiguousarray(np.asarray(x, float).T)).T

    def curvature(self, geo: MeshGeometry, *, linear: bool = True, normals: np.ndarray | None = None,
                  reference: bool = False):
        """Per-vertex (H, K) by the batched paraboloid fit over the 1-ring.

        :func:`geometry.curvature.paraboloid_curvature` restricted to the precomputed 1-ring, for an inner
        loop: the ring offsets are gathered in (W, V) layout and handed to the same closed-form solver,
        :func:`geometry.curvature.fit_ring`.  NaN where the fit is not determined.  Runs the compiled
        :func:`geometry.kernels.ring_curvature` (the same arithmetic vertex by vertex) unless numba is
        missing or ``reference`` asks for the numpy form.
        """
        n = geo.vertex_normals_t if normals is None else np.asarray(normals, float).T
        if compiled.wanted(self.n_vertices) and not reference:
            return kernels.ring_curvature(geo.vertices, n, self.ring, self.ring_count, linear)
        t1, t2 = tangent_frames_t(n)
        xt = geo.vertices_t
        V = self.n_vertices
        H, K = np.empty(V), np.empty(V)
        # blocks of vertices: the dozens of (W, block) temporaries of the fit stay in the cache instead
        # of being (W, V) arrays allocated (page faults) and streamed through memory one by one; every
        # vertex's fit is independent, so the result is the same
        for s in range(0, V, _CURVATURE_BLOCK):
            b = slice(s, min(V, s + _CURVATURE_BLOCK))
            ring = self._ring_self_t[:, b]
            # ring offsets in (W, block) layout, so that sums over the ring run over the short leading axis
            dx = np.take(xt[0], ring) - xt[0, b]                              # padded slots → 0
            dy = np.take(xt[1], ring) - xt[1, b]
            dz = np.take(xt[2], ring) - xt[2, b]
            u = dx * t1[0][b] + dy * t1[1][b] + dz * t1[2][b]
            v = dx * t2[0][b] + dy * t2[1][b] + dz * t2[2][b]
            z = dx * n[0, b] + dy * n[1, b] + dz * n[2, b]
            H[b], K[b] = fit_ring(u, v, z, self.ring_count[b], linear=linear)[:2]
        return H, K
