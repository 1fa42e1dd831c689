"""The flow: one iteration = gradient, H¹ preconditioner, capped backtracking line search, relaxation, stop
tests; the result packs the mesh and what the run did into a Reconstruction."""

from __future__ import annotations

import time

import numpy as np
import trimesh

from geometry.operators import MeshOperators, jacobi_cg
from phantoms import InputError

from ..base import Reconstruction
from .energy import evaluate_state, gradient_from_state, no_fold
from .polish import crease_polish

__all__ = ["ShapeGradientFlow", "STOP_REASONS"]

STOP_REASONS = ("converged", "max_iter", "line_search_floor", "diverged")

_CONVERGE_PATIENCE = 3     # consecutive iterations with relative energy change < tol
_FLOOR_MOVE_VOXELS = 1e-4  # the line search gives up when the largest trial move falls below this
_ARMIJO = 1e-4             # sufficient-decrease constant of the backtracking line search
_CG_RTOL = 1e-3            # relative residual of the H¹ solve (an inexact solve is still a descent direction)
_CG_MAXITER = 100
_FOLD_DEGREES = 60.0       # a trial step that turns any face normal by more than this is rejected


class ShapeGradientFlow:
    """One run of the flow, iteration by iteration (see the module docstring for what an iteration does).

    >>> flow = ShapeGradient().prepare(volume)
    >>> while flow.step(): ...                  # or flow.run()
    >>> rec = flow.result()                     # the Reconstruction (mesh + info)
    """

    def __init__(self, field, ops: MeshOperators, x: np.ndarray, cfg: dict, h: float, *,
                 setup_seconds: float = 0.0):
        self.field, self.ops, self.cfg, self.h = field, ops, cfg, float(h)
        self.t_start = time.perf_counter() - setup_seconds
        self.timings = dict.fromkeys(("setup", "interpolation", "curvature", "gradient", "preconditioner",
                                      "energy", "relax", "polish"), 0.0)
        self.timings["setup"] = setup_seconds
        self.alpha, self.beta = cfg["alpha"], cfg["beta"]
        self.kind, self.linear = cfg["gradient"], cfg["curvature"] == "tilted"
        self.max_move = cfg["max_move"] * self.h
        self.floor_move = _FLOOR_MOVE_VOXELS * self.h
        self.snap_set = set(cfg["snapshots"])
        self.init_flipped = False
        self.noise = float("nan")
        self.state = evaluate_state(field, ops, np.asarray(x, float), self.alpha, self.beta, self.timings)
        if not np.isfinite(self.state.E):
            raise InputError("method 'shape_gradient': the energy of the initial surface is not finite")
        self.history = [self.state.E]
        self.snapshots = {0: self.state.x.copy()}
        self.iteration = 0
        self.stop: str | None = None
        self.message = ""
        self._calm = self._still = 0
        self.n_backtracks = 0
        self.n_rejected_folds = 0
        self.curvature_fallbacks = 0
        self._V_prev = None
        self._move_prev = self.max_move
        self._grow = True
        self.cg_iterations: list[int] = []
        self.moves: list[float] = []
        self._polished = None

    # ------------------------------------------------------------------ one iteration
    def _end(self, reason: str, message: str) -> bool:
        self.stop, self.message = reason, message
        return False

    def step(self) -> bool:
        """Do one iteration; False when the run has ended (``stop``/``message`` say why)."""
        if self.stop is not None:
            return False
        if self.iteration >= self.cfg["max_iter"]:
            return self._end("max_iter", f"reached max_iter = {self.cfg['max_iter']}")
        cfg, ops, field, timings = self.cfg, self.ops, self.field, self.timings
        alpha, beta, h = self.alpha, self.beta, self.h
        it = self.iteration + 1
        state = self.state
        G, _ = gradient_from_state(field, state, ops, alpha, beta, kind=self.kind, linear=self.linear,
                                   timings=timings)
        self.curvature_fallbacks += state.curvature_fallbacks
        if not np.isfinite(G).all():
            bad = int((~np.isfinite(G)).sum())
            return self._end("diverged", f"iteration {it}: the shape gradient is not finite at {bad} vertices "
                                         "(degenerate mesh or curvature fit)")
        t0 = time.perf_counter()
        geo = state.geo
        M = geo.vertex_areas
        b = M * G
        Vel = G
        if cfg["precondition"] == "h1" and cfg["s"] > 0:
            K = ops.stiffness(geo)
            s = cfg["s"]
            diag = M + s * ops.stiffness_diagonal(K)
            sol, ncg, _ = jacobi_cg(lambda p: M * p + s * (K @ p), b, diag, x0=self._V_prev, rtol=_CG_RTOL,
                                    maxiter=_CG_MAXITER)
            self.cg_iterations.append(ncg)
            if np.isfinite(sol).all() and float(b @ sol) > 0:
                Vel = sol
        self._V_prev = Vel
        timings["preconditioner"] += time.perf_counter() - t0
        direction = -Vel[:, None] * geo.vertex_normals
        vmax = float(np.abs(Vel).max())
        slope = float(b @ Vel)                           # −dE/dτ at τ = 0 (> 0)
        if vmax == 0.0:
            return self._end("converged", f"iteration {it}: the shape gradient vanishes")
        shift = None
        if cfg["relax"] > 0:
            t0 = time.perf_counter()
            nt = geo.vertex_normals_t
            d = ops.ring_mean_t(geo.vertices_t) - geo.vertices_t
            d -= (d[0] * nt[0] + d[1] * nt[1] + d[2] * nt[2]) * nt
            shift = cfg["relax"] * d.T
            timings["relax"] += time.perf_counter() - t0
        if cfg["step"] == "fixed":
            tau = cfg["tau"]
            x_new = state.x + tau * direction + (0.0 if shift is None else shift)
            if not np.isfinite(x_new).all():
                return self._end("diverged", f"iteration {it}: non-finite vertex positions")
            new = evaluate_state(field, ops, x_new, alpha, beta, timings)
            if not np.isfinite(new.E):
                return self._end("diverged", f"iteration {it}: the mesh left the volume box" if new.X is None
                                 else f"iteration {it}: non-finite energy")
            move = tau * vmax
        else:
            new = None
            # first trial: twice the last accepted move after a first-try success, else the same move again
            first = min(self.max_move, (2.0 if self._grow else 1.0) * self._move_prev)
            for with_shift in ((True, False) if shift is not None else (False,)):
                move = first
                while True:
                    tau = move / vmax
                    x_new = state.x + tau * direction
                    if with_shift:
                        x_new += shift
                    cand = evaluate_state(field, ops, x_new, alpha, beta, timings)
                    if np.isfinite(cand.E) and cand.E <= state.E - _ARMIJO * tau * slope \
                            and no_fold(geo, cand.geo):
                        new = cand
                        break
                    self.n_rejected_folds += np.isfinite(cand.E) and cand.E <= state.E - _ARMIJO * tau * slope
                    self.n_backtracks += 1
                    move *= 0.5
                    if move < self.floor_move:
                        break
                if new is not None:
                    break
            if new is None:
                return self._end("line_search_floor",
                                 f"iteration {it}: no decrease of E for moves down to "
                                 f"{self.floor_move / h:.1g} voxels (the gradient no longer predicts a "
                                 "decrease of the discrete energy)")
            self._grow = move == first
            self._move_prev = move
        self.moves.append(move)
        prev = state.E
        self.state = new
        self.iteration = it
        self.history.append(new.E)
        if it in self.snap_set:
            self.snapshots[it] = new.x.copy()
        rel = abs(prev - new.E) / max(abs(prev), 1e-300)
        self._calm = self._calm + 1 if rel < cfg["tol"] else 0
        self._still = self._still + 1 if move < cfg["move_tol"] * h else 0
        if self._calm >= _CONVERGE_PATIENCE:
            return self._end("converged", f"iteration {it}: relative energy change below tol = {cfg['tol']:g} "
                                          f"for {_CONVERGE_PATIENCE} iterations")
        if self._still >= _CONVERGE_PATIENCE:
            return self._end("converged", f"iteration {it}: largest normal move below move_tol = "
                                          f"{cfg['move_tol']:g} voxels for {_CONVERGE_PATIENCE} iterations")
        return True

    def run(self) -> "ShapeGradientFlow":
        while self.step():
            pass
        return self

    # ------------------------------------------------------------------ the result
    def _polish(self):
        """(geometry of the final mesh, info['polish']): the last iterate, crease-polished if asked."""
        info = {"used": bool(self.cfg.get("polish_used", False))}
        if not info["used"]:
            return self.state.geo, info
        t0 = time.perf_counter()
        x, stats = crease_polish(self.field, self.ops, self.state.x, self.h, angle=self.cfg["polish_angle"],
                                 weight=self.cfg["polish_weight"])
        geo = self.ops.geometry(x)
        info.update(stats)
        info["energy"] = float(evaluate_state(self.field, self.ops, x, self.alpha, self.beta).E) \
            if stats["zone_vertices"] else float(self.state.E)
        self.timings["polish"] += time.perf_counter() - t0
        return geo, info

    def result(self) -> Reconstruction:
        """The mesh (closed, outward, the initial connectivity) and the info dict."""
        cfg, h = self.cfg, self.h
        t0 = time.perf_counter()
        if self._polished is None:
            self._polished = self._polish()
        final_geo, polish_info = self._polished
        H_final, K_final = self.ops.curvature(final_geo, linear=self.linear)
        self.timings["curvature"] += time.perf_counter() - t0
        self.timings["total"] = time.perf_counter() - self.t_start
        mesh = trimesh.Trimesh(final_geo.vertices.copy(), self.ops.faces.copy(), process=False)
        params_used = {k: (v.tolist() if isinstance(v, np.ndarray) else v) for k, v in cfg.items()}
        params_used["init_mesh"] = None if cfg["init_mesh"] is None else "user mesh"
        params_used["snapshots"] = list(cfg["snapshots"])
        info = {
            "iterations": int(self.iteration),
            "stop_reason": self.stop or "max_iter",
            "stop_message": self.message,
            "energy_history": [float(e) for e in self.history],
            "energy_final": float(self.history[-1]),
            "snapshots": dict(self.snapshots),
            "H": H_final,
            "K": K_final,
            "parameters": params_used,
            "timings": dict(self.timings),
            "n_backtracks": int(self.n_backtracks),
            "n_rejected_folds": int(self.n_rejected_folds),
            "curvature_fallbacks": int(self.curvature_fallbacks),
            "cg_iterations": list(self.cg_iterations),
            "move_history_voxels": [float(m / h) for m in self.moves],
            "init_flipped": bool(self.init_flipped),
            "noise_estimate": float(self.noise),
            "noise_estimate_voxels": float(self.noise / h),
            "presmooth_used": float(cfg.get("presmooth_used", 0.0)),
            "grid_spacing": float(h),
            "polish": polish_info,
        }
        return Reconstruction(mesh, info)
