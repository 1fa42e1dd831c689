"""The H¹ (Sobolev) velocity of the flow: V = (M + sK)⁻¹ M G, the shape gradient G smoothed along the surface
(M lumped areas, K cotangent stiffness), by one of three solvers, with the state that makes it cheap between
iterations — a factor of a nearby geometry, the last velocity as a warm start, the solver chosen once per mesh."""

from __future__ import annotations

import numpy as np
from scipy.sparse.linalg import cg, splu

from geometry.operators import MeshOperators, dot, jacobi_cg

__all__ = ["SobolevSolver", "FLOW_SOLVER"]

_CG_RTOL = 1e-3            # relative residual of the H¹ solve (an inexact solve is still a descent direction)
_CG_MAXITER = 100
_DIRECT_MAX_VERTICES = 40_000  # solver='auto': the LU up to this many vertices, multigrid above ...
_CG_MAX_S_EDGES = 2.0          # ... or CG while s is at most this many squared edge lengths
_FACTOR_REFRESH = 5            # the direct and multigrid H¹ solvers rebuild their factor every this many iterations
_AMG_SMOOTH = ("jacobi", {"weighting": "local"})  # row-wise weights: no spectral-radius estimate


#: the flow's H¹ solver: 'auto' picks CG, the LU or multigrid per mesh (:meth:`SobolevSolver._auto`)
FLOW_SOLVER = "auto"


class SobolevSolver:
    """The H¹ solve of one flow (``solver``: 'auto', 'direct', 'amg' or 'cg'); :meth:`reset` when the mesh changes.

    ``solver='direct'``: a sparse LU of M + sK (SuperLU), refreshed every ``_FACTOR_REFRESH`` iterations and at
    every remesh — between refreshes the factor of a nearby geometry is used, which is still a symmetric
    positive-definite smoothing, so V stays a descent direction.  ``'amg'``: CG preconditioned by a
    smoothed-aggregation multigrid (pyamg) of a nearby geometry, refreshed likewise (the LU's fill-in grows too
    fast past ~50k vertices).  ``'auto'``: :meth:`_auto`.  ``'cg'``: Jacobi-preconditioned CG on the current
    matrix, warm-started (the exact operator every iteration; slow when s is many squared edge lengths).
    """

    def __init__(self, solver: str):
        self.solver = solver
        self.reset()

    def reset(self) -> None:
        """Forget the factor, the warm start and the solver choice (they belong to the old mesh)."""
        self._factor = None                      # the LU factor or multigrid preconditioner
        self._factor_age = 0
        self._choice: str | None = None
        self._V_prev = None

    def velocity(self, ops: MeshOperators, geo, G: np.ndarray, b: np.ndarray, s: float,
                 cg_iterations: list) -> np.ndarray:
        """V for the gradient ``G`` (``b`` = M G) with smoothing weight ``s`` (world units²); G itself when the
        solve gives no descent direction.  The 'cg' solver appends its iteration count to ``cg_iterations``."""
        solver = self._auto(ops, geo, s) if self.solver == "auto" else self.solver
        if solver == "direct":
            if self._factor is None or self._factor_age >= _FACTOR_REFRESH:
                # M + sK is symmetric: a symmetric ordering (minimum degree on A + Aᵀ, diagonal pivots) fills
                # less than COLAMD, so the factorisation and each solve are faster
                self._factor = splu(ops.h1_matrix(geo, s)[0].tocsc(), permc_spec="MMD_AT_PLUS_A",
                                    diag_pivot_thresh=0.0, options={"SymmetricMode": True})
                self._factor_age = 0
            sol = self._factor.solve(b)
            self._factor_age += 1
        elif solver == "amg":
            import pyamg

            A = ops.h1_matrix(geo, s)[0]
            if self._factor is None or self._factor_age >= _FACTOR_REFRESH:
                self._factor = pyamg.smoothed_aggregation_solver(A, symmetry="symmetric", smooth=_AMG_SMOOTH
                                                                 ).aspreconditioner(cycle="V")
                self._factor_age = 0
            sol, _ = cg(A, b, x0=self._V_prev, rtol=_CG_RTOL, maxiter=_CG_MAXITER, M=self._factor)
            self._factor_age += 1
        else:
            A, diag = ops.h1_matrix(geo, s)
            sol, ncg, _ = jacobi_cg(A, b, diag, x0=self._V_prev, rtol=_CG_RTOL, maxiter=_CG_MAXITER)
            cg_iterations.append(ncg)
        Vel = sol if np.isfinite(sol).all() and dot(b, sol) > 0 else G
        self._V_prev = Vel
        return Vel

    def _auto(self, ops: MeshOperators, geo, s: float) -> str:
        """solver='auto': warm-started CG while s is at most ``_CG_MAX_S_EDGES`` squared edge lengths (the system
        is then well conditioned: a few iterations), else the LU up to ``_DIRECT_MAX_VERTICES`` vertices, else
        multigrid.  Decided once per mesh."""
        if self._choice is None:
            e = ops.edges
            d = geo.vertices[e[:, 0]] - geo.vertices[e[:, 1]]
            ell2 = float(np.mean(np.einsum("ij,ij->i", d, d)))
            if s <= _CG_MAX_S_EDGES * ell2:
                self._choice = "cg"
            else:
                self._choice = "direct" if len(geo.vertices) <= _DIRECT_MAX_VERTICES else "amg"
        return self._choice
