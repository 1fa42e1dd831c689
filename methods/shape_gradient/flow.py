"""The flow: one iteration = gradient, H¹ preconditioner, capped backtracking line search, relaxation, stop
tests; the result packs the mesh and what the run did into a Reconstruction."""

from __future__ import annotations

import time

import numpy as np
import trimesh

from geometry.mesh import signed_volume
from geometry.operators import MeshOperators, dot
from phantoms import InputError

from ..contract import Reconstruction, ReconstructionFailed
from .carve import CarvedHull, remesh_keep
from .energy import evaluate_state, gradient_from_state, no_fold
from .guard import count_intersections, repair_intersections
from .post import post_steps, reach_step
from .remesh import remesh
from .settings import FlowSettings, Stage
from .signs import SignGuard
from .sobolev import SobolevSolver

__all__ = ["ShapeGradientFlow", "STOP_REASONS"]

#: ``fixed_iterations``: the run had no convergence test (``tol`` and ``move_tol`` both 0, as the paper's presets)
#: and ran its full ``max_iter`` count by design; ``max_iter``: a run with a test hit the cap before it held
STOP_REASONS = ("converged", "fixed_iterations", "max_iter", "line_search_floor", "diverged", "sign_guard")

_CONVERGE_PATIENCE = 3     # consecutive iterations with relative energy change < tol
_FLOOR_MOVE_VOXELS = 1e-4  # the line search gives up when the largest trial move falls below this
_ARMIJO = 1e-4             # sufficient-decrease constant of the backtracking line search
_OFF_SURFACE_VOXELS = 0.5      # a result whose median |φ| at the vertices exceeds this (voxels) has failed ...
_OFF_SURFACE_NOISE = 1.0       # ... added in quadrature to this many noise stds (on the true surface of a noisy
#                                volume the median |φ| is already 0.67 std)
_FOLD_DEGREES = 60.0       # a trial step that turns any face normal by more than this is rejected


class ShapeGradientFlow:
    """One run of the flow, iteration by iteration (see the module docstring for what an iteration does).

    >>> flow = ShapeGradient().prepare(volume)
    >>> while flow.step(): ...                  # or flow.run()
    >>> rec = flow.result()                     # the Reconstruction (mesh + info)

    ``init_flipped``, ``noise``, ``topology`` and ``init_facts`` are what the preparation found (the start was
    reoriented, the noise estimate, the topology check, the start's facts); the flow reports them in its result.
    """

    def __init__(self, field, ops: MeshOperators, x: np.ndarray, settings: FlowSettings, h: float, *,
                 setup_seconds: float = 0.0, init_flipped: bool = False, noise: float = float("nan"),
                 topology: dict | None = None, init_facts: dict | None = None):
        self.field, self.ops, self.settings, self.h = field, ops, settings, float(h)
        self.t_start = time.perf_counter() - setup_seconds
        self.timings = dict.fromkeys(("setup", "interpolation", "curvature", "gradient", "preconditioner",
                                      "energy", "relax", "polish", "remesh", "guard", "projection", "tips"), 0.0)
        self.timings["setup"] = setup_seconds
        self.alpha, self.beta = settings.alpha, settings.beta
        # −α(2/3)³σ̂² on a noisy volume (unbias): the area term a noisy φ² adds to E (energy.evaluate_state)
        self.density = -float(settings.alpha) * settings.noise_variance
        self.kind, self.linear = settings.gradient, settings.curvature == "tilted"
        self.max_move = settings.max_move * self.h
        self.floor_move = _FLOOR_MOVE_VOXELS * self.h
        self.snap_set = set(settings.snapshots)
        self.init_flipped = bool(init_flipped)
        self.noise = float(noise)
        self.topology: dict = dict(topology or {})
        self.init_facts: dict = dict(init_facts or {})
        self.iteration = 0
        self.remesh_every = settings.remesh_every
        self.stages = list(settings.stages)             # the stages still to come, first first
        self.stage_starts: list[dict] = []
        self._enter_stage(self.stages.pop(0))
        self.state = evaluate_state(field, ops, np.asarray(x, float), self.alpha, self.beta, self.timings,
                                    density=self.density)
        if not np.isfinite(self.state.E):
            raise InputError("method 'shape_gradient': the energy of the initial surface is not finite")
        self.history = [self.state.E]
        self.snapshots = {0: self._snapshot()}
        self.remeshes: list[tuple[int, int]] = []       # (iteration, vertices after the remesh)
        self.remesh_refused = 0
        self.intersections: list[tuple[int, int]] = []  # (iteration, intersecting faces found there)
        self.repairs = self.rollbacks = 0
        self._safe = None                               # (x, ops, state) of the last intersection-free check
        self.stop: str | None = None
        self.message = ""
        # the stop tests' counters: consecutive iterations whose relative energy change is below tol, and whose
        # largest normal move is below move_tol voxels
        self._flat_energy_iterations = self._small_move_iterations = 0
        self._hold_stop = False                         # no stop test until a remesh (see _remesh_and_guard)
        self.n_backtracks = 0
        self.n_rejected_folds = 0
        self.n_l2_fallbacks = 0
        self.curvature_fallbacks = 0
        self.sobolev = SobolevSolver(settings.solver)    # the H¹ solve (its factor, warm start, solver choice)
        self._move_prev = self.max_move
        self._grow = True
        self.cg_iterations: list[int] = []
        self.moves: list[float] = []
        self._normal_move: float | None = None          # the accepted step's largest normal move after the limits
        self._polished = None
        self.before_reach = None      # the final vertices before the reach to the samples (set by result())
        self.guard = settings.guard
        self.signs = None                            # the sign guard (signs.py), on clean volumes
        self.carve = CarvedHull.of(field, settings, self.state, self.h)   # hold_carved (carve.py), or None
        if self.remesh_every and settings.remesh_start:
            self._remesh_and_guard(0)                # a start with marching cubes' slivers: isotropic first
        elif self.guard:
            self._guard(0)                           # the start: the first safe state (or repaired)
        if settings.sign_guard:
            if getattr(field, "volume", None) is not None:
                self.signs = SignGuard(field.volume, self.h, self.state.x, self.ops.faces, self.ops)

    # ------------------------------------------------------------------ one iteration
    def _end(self, reason: str, message: str) -> bool:
        self.stop, self.message = reason, message
        return False

    def _enter_stage(self, stage: Stage) -> None:
        self.beta = stage.beta
        self.edge_length = stage.edge_length * self.h
        self.stage_starts.append({"iteration": self.iteration, "beta": self.beta,
                                  "edge_length_voxels": self.edge_length / self.h})

    def _settle(self, reason: str, message: str) -> bool:
        """The flow has settled at this stage: go on with the next stage's settings, or end the run."""
        if not self.stages:
            return self._end(reason, message)
        self._enter_stage(self.stages.pop(0))
        self._flat_energy_iterations = self._small_move_iterations = 0
        self._move_prev, self._grow = self.max_move, False
        if self.remesh_every:
            self._remesh_and_guard(self.iteration)
        self.state = evaluate_state(self.field, self.ops, self.state.x, self.alpha, self.beta, self.timings,
                                    density=self.density)
        self._safe = None
        return True

    def step(self) -> bool:
        """Do one iteration; False when the run has ended (``stop``/``message`` say why).

        The stages: the gradient and the descent direction, the tangential relaxation shift, the step (fixed
        or an Armijo line search), then accepting the new state (remesh, snapshot) and the convergence tests."""
        if self.stop is not None:
            return False
        if self.iteration >= self.settings.max_iter:
            if self.settings.tol <= 0 and self.settings.move_tol <= 0:
                return self._end("fixed_iterations", f"ran its fixed count of {self.settings.max_iter} iterations "
                                                      "(no convergence test: tol = move_tol = 0)")
            return self._end("max_iter", f"reached max_iter = {self.settings.max_iter}")
        it = self.iteration + 1
        state = self.state
        G, _ = gradient_from_state(self.field, state, self.ops, self.alpha, self.beta, kind=self.kind,
                                   linear=self.linear, timings=self.timings, density=self.density)
        self.curvature_fallbacks += state.curvature_fallbacks
        if not np.isfinite(G).all():
            bad = int((~np.isfinite(G)).sum())
            return self._end("diverged", f"iteration {it}: the shape gradient is not finite at {bad} vertices "
                                         "(degenerate mesh or curvature fit)")
        geo = state.geo
        b = geo.vertex_areas * G
        Vel = self._velocity(geo, G, b)
        limit, Vel = (None, Vel) if self.carve is None else self.carve.hold(state.x, Vel)   # hold_carved
        direction = -Vel[:, None] * geo.vertex_normals
        vmax = float(np.abs(Vel).max())
        slope = dot(b, Vel)                           # −dE/dτ at τ = 0 (> 0)
        if vmax == 0.0:
            return self._end("converged", f"iteration {it}: the shape gradient vanishes")
        shift = self._relax_shift(geo) if limit is None else self.carve.still(state.x, self._relax_shift(geo), limit)
        if self.settings.step == "fixed":
            tau = self.settings.tau
            x_new = state.x + tau * direction + (0.0 if shift is None else shift)
            if not np.isfinite(x_new).all():
                return self._end("diverged", f"iteration {it}: non-finite vertex positions")
            new = evaluate_state(self.field, self.ops, x_new, self.alpha, self.beta, self.timings,
                                 density=self.density)
            if not np.isfinite(new.E):
                return self._end("diverged", f"iteration {it}: the mesh left the volume box" if new.X is None
                                 else f"iteration {it}: non-finite energy")
            move = tau * vmax
        else:
            new, move = self._line_search(geo, direction, shift, vmax, slope, limit)
            if new is None and self.settings.l2_fallback and Vel is not G:
                Vel2 = G if limit is None else CarvedHull.stopped(G, limit)     # the same limits: same x
                vmax2, slope2 = float(np.abs(Vel2).max()), dot(b, Vel2)
                if vmax2 > 0 and slope2 > 0:
                    self.n_l2_fallbacks += 1
                    new, move = self._line_search(geo, -Vel2[:, None] * geo.vertex_normals, None, vmax2, slope2,
                                                  limit)
            if new is None:
                return self._settle("line_search_floor",
                                    f"iteration {it}: no decrease of E for moves down to "
                                    f"{self.floor_move / self.h:.1g} voxels (the gradient no longer predicts a "
                                    "decrease of the discrete energy)")
        return self._accept(it, new, move)

    def _relax_shift(self, geo) -> np.ndarray | None:
        """The tangential relaxation of the vertices (``relax`` × the tangential part of the one-ring mean's
        offset), or None without relaxation."""
        if self.settings.relax <= 0:
            return None
        t0 = time.perf_counter()
        nt = geo.vertex_normals_t
        d = self.ops.ring_mean_t(geo.vertices_t) - geo.vertices_t
        d -= (d[0] * nt[0] + d[1] * nt[1] + d[2] * nt[2]) * nt
        self.timings["relax"] += time.perf_counter() - t0
        return self.settings.relax * d.T

    def _line_search(self, geo, direction, shift, vmax: float, slope: float, limit=None):
        """(new state, move) of the Armijo backtracking search along ``direction`` (first with the relaxation
        shift, then without it), or ``(None, move)`` when no move down to ``floor_move`` decreases E; ``limit``:
        each vertex's largest inward move (hold_carved)."""
        state = self.state
        new = None
        # first trial: twice the last accepted move after a first-try success, else the same move again
        first = min(self.max_move, (2.0 if self._grow else 1.0) * self._move_prev)
        for with_shift in ((True, False) if shift is not None else (False,)):
            move = first
            while True:
                tau = move / vmax
                x_new = state.x + (tau * direction if limit is None
                                   else CarvedHull.clamp(tau * direction, geo.vertex_normals, limit))
                if with_shift:
                    x_new += shift
                cand = evaluate_state(self.field, self.ops, x_new, self.alpha, self.beta, self.timings,
                                      density=self.density)
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
        if new is not None:
            self._grow = move == first
            self._move_prev = move
            self._normal_move = move if limit is None else self._clamped_move(geo, direction, move / vmax, limit)
        return new, move

    @staticmethod
    def _clamped_move(geo, direction: np.ndarray, tau: float, limit: np.ndarray) -> float:
        """The largest normal move the step ``tau`` · ``direction`` makes once each vertex's inward part is cut to
        its ``limit`` (hold_carved): the move the stop test reads.  The uncut trial move stays large while a held
        vertex pushes against its limit, so a flow whose surface has stopped on the carved hull would never read
        as still."""
        outward = tau * np.einsum("vd,vd->v", direction, geo.vertex_normals)       # < 0: inward
        moved = np.where(outward >= 0.0, outward, np.minimum(-outward, limit))
        return float(moved.max()) if len(moved) else 0.0

    def _accept(self, it: int, new, move: float) -> bool:
        """Take ``new`` as iteration ``it``'s state (remesh and snapshot when due), then the convergence tests."""
        st, h = self.settings, self.h
        self.moves.append(move)
        prev = self.state.E
        self.state = new
        self.iteration = it
        self.history.append(new.E)
        if self.remesh_every and it % self.remesh_every == 0 and not self._remesh_point(it):
            return self._end("sign_guard", self.signs.message)
        if it in self.snap_set:
            if self.guard and (not self.intersections or self.intersections[-1][0] != it):
                self._guard(it)                      # a snapshot is a result too: intersection-free
            self.snapshots[it] = self._snapshot()
        rel = abs(prev - new.E) / max(abs(prev), 1e-300)
        held = self._hold_stop        # the start kept unremeshed: marching cubes' slivers move slowly until a remesh
        moved = self._normal_move if self._normal_move is not None else move
        self._normal_move = None
        if held:
            self._flat_energy_iterations = self._small_move_iterations = 0
        else:
            self._flat_energy_iterations = self._flat_energy_iterations + 1 if rel < st.tol else 0
            self._small_move_iterations = self._small_move_iterations + 1 if moved < st.move_tol * h else 0
        if self._flat_energy_iterations >= _CONVERGE_PATIENCE:
            return self._settle("converged", f"iteration {it}: relative energy change below tol = {st.tol:g} "
                                          f"for {_CONVERGE_PATIENCE} iterations")
        if self._small_move_iterations >= _CONVERGE_PATIENCE:
            return self._settle("converged", f"iteration {it}: largest normal move below move_tol = "
                                          f"{st.move_tol:g} voxels for {_CONVERGE_PATIENCE} iterations")
        return True

    def _velocity(self, geo, G: np.ndarray, b: np.ndarray) -> np.ndarray:
        """The normal velocity: the H¹ (Sobolev) gradient V = (M + sK)⁻¹ M G (sobolev.py), or G itself."""
        st = self.settings
        if st.precondition != "h1" or st.s_world <= 0:
            return G
        t0 = time.perf_counter()
        Vel = self.sobolev.velocity(self.ops, geo, G, b, st.s_world, self.cg_iterations)
        self.timings["preconditioner"] += time.perf_counter() - t0
        return Vel

    # ------------------------------------------------------------------ remeshing and the intersection guard
    def _snapshot(self):
        """The current vertices, with the faces too once the connectivity can change (remeshing)."""
        x = self.state.x.copy()
        return (x, self.ops.faces.copy()) if self.remesh_every else x

    def _set_mesh(self, x: np.ndarray, ops: MeshOperators, state=None) -> None:
        self.ops = ops
        self.state = state if state is not None else evaluate_state(self.field, ops, x, self.alpha, self.beta,
                                                                    self.timings, density=self.density)
        self.sobolev.reset()         # the warm start and the factor of the H¹ solve belong to the old mesh

    def _remesh_point(self, it: int) -> bool:
        """Remesh and check; False when the sign guard rolled the mesh back (the flow must stop).  The sign
        guard looks before the remesh (a flow that already cut a part is not worth remeshing) and after it
        (the remesher's collapses can cut a voxel-thin tip too)."""
        back = self.signs.check(it, self.state.x, self.ops, keep=False) if self.signs is not None else None
        if back is None:
            self._remesh_and_guard(it)
            back = self.signs.check(it, self.state.x, self.ops) if self.signs is not None else None
        if back is not None:
            self._set_mesh(*back)
            return False
        return True

    def _remesh_and_guard(self, it: int) -> None:
        """Remesh toward the target edge length, then make sure no faces intersect (repair or roll back)."""
        t0 = time.perf_counter()
        # the flow's meshes are closed (checked at every remesh); the start is checked here once more, and gets
        # all the rounds (marching cubes' slivers); a later mesh is near isotropic: one round
        rounds = self.settings.remesh_iterations if it == 0 else 1
        before = (self.state.x, self.ops, self.state)
        # hold_carved: held tips stay (the start, marching cubes' slivers, is remeshed freely)
        keep = {"keep": remesh_keep(self.ops, self.state.geo, self.h, self.settings, self.carve)} if it > 0 else {}
        out = remesh(self.state.x, self.ops.faces, self.edge_length, rounds, closed=it > 0, **keep)
        if out is None:
            self.remesh_refused += 1
        else:
            x, f = out
            self._set_mesh(x, MeshOperators(f, len(x)))
            self.remeshes.append((it, len(x)))
            # a new mesh: the line search starts again from the step cap, the stop tests count afresh
            self._move_prev, self._grow, self._hold_stop = self.max_move, False, False
            self._flat_energy_iterations = self._small_move_iterations = 0
        self.timings["remesh"] += time.perf_counter() - t0
        if not self._guard(it) and self._safe is None and out is not None:   # an unrepairable remeshed start:
            self.remesh_refused += 1                                           # the start as grown is safe
            self._set_mesh(*before)
            self._hold_stop = self._guard(it)

    def _checked(self) -> bool:
        """True when the current mesh is the last one the intersection guard passed (nothing moved since)."""
        return (self._safe is not None and self._safe[1] is self.ops
                and np.array_equal(self._safe[0], self.state.x))

    def _guard(self, it: int) -> bool:
        """Check for self-intersections; repair or roll back.  True when the mesh is now intersection-free."""
        t0 = time.perf_counter()
        n, bad = count_intersections(self.state.x, self.ops.faces)
        self.intersections.append((it, n))
        clean = n == 0
        if not clean:
            fixed = repair_intersections(self.ops, self.state.x, bad)
            if fixed is not None:
                self.repairs += 1
                self._set_mesh(fixed, self.ops)
                clean = True
            elif self._safe is not None:
                self.rollbacks += 1
                self._set_mesh(*self._safe)
                self.max_move = max(0.5 * self.max_move, 4.0 * self.floor_move)
                self._move_prev = min(self._move_prev, self.max_move)
                clean = True
        if clean:
            self._safe = (self.state.x.copy(), self.ops, self.state)
        self.timings["guard"] += time.perf_counter() - t0
        return clean

    def run(self) -> "ShapeGradientFlow":
        while self.step():
            pass
        return self

    # ------------------------------------------------------------------ the result
    def _finish(self):
        """(final geometry, info['polish'], info['projection'], info['tips'], info['reach']): the last iterate
        after the post-steps (post.py); :attr:`before_reach` keeps the vertices before the reach to the samples
        (what the start choice scores: the reach mends single spots, the start decides the rest)."""
        st, h = self.settings, self.h
        guard = st.guard
        if guard and not self._checked():
            self._guard(self.iteration)
        energy = (lambda xe: evaluate_state(self.field, self.ops, xe, self.alpha, self.beta, density=self.density).E)
        x, polish, projection, tips = post_steps(self.field, self.ops, self.state.x, h, st, guard=guard,
                                                 energy=energy, timings=self.timings)
        if polish.get("used") and polish["energy"] is None:           # nothing polished: the flow's last energy
            polish["energy"] = float(self.state.E)
        self.before_reach = x
        x, reach = reach_step(self.field, self.ops, x, h, st, guard=guard, timings=self.timings, noise=self.noise)
        return self.ops.geometry(x), polish, projection, tips, reach

    def _check_result(self, geo) -> dict:
        """Volume and distance of the final mesh to φ = 0; a collapsed or off-surface result is a failure."""
        vol = signed_volume(geo.vertices, self.ops.faces)
        phi = self.field.sample_t(geo.vertices_t, 0)[0]
        med = float(np.median(np.abs(phi)))
        noise = float(self.noise) if np.isfinite(self.noise) else 0.0
        limit = float(np.hypot(_OFF_SURFACE_VOXELS * self.h, _OFF_SURFACE_NOISE * noise))
        facts = {"signed_volume": vol, "median_abs_phi_voxels": med / self.h,
                 "off_surface_limit_voxels": limit / self.h}
        if self.stop != "diverged" and self.settings.guard:
            if vol <= self.h ** 3:
                raise ReconstructionFailed(
                    f"method 'shape_gradient': the surface collapsed (enclosed volume {vol:.3g}, less than one "
                    f"voxel) after {self.iteration} iterations ({self.stop or 'max_iter'})")
            if med > limit:
                raise ReconstructionFailed(
                    f"method 'shape_gradient': the surface did not reach φ = 0 (median |φ| at the vertices "
                    f"{med / self.h:.2f} voxels, more than {limit / self.h:.2f} for this volume's noise, after "
                    f"{self.iteration} iterations, {self.stop or 'max_iter'}); "
                    "raise max_iter or check the volume")
        return facts

    def result(self) -> Reconstruction:
        """The mesh (closed, outward) and the info dict; ReconstructionFailed for a collapsed or off-surface result."""
        st, h = self.settings, self.h
        if self._polished is None:
            self._polished = self._finish()
        t0 = time.perf_counter()
        final_geo, polish_info, projection_info, tips_info, reach_info = self._polished
        checks = self._check_result(final_geo)
        H_final, K_final = self.ops.curvature(final_geo, linear=self.linear)
        self.timings["curvature"] += time.perf_counter() - t0
        self.timings["total"] = time.perf_counter() - self.t_start
        mesh = trimesh.Trimesh(final_geo.vertices.copy(), self.ops.faces.copy(), process=False)
        info = {
            "iterations": int(self.iteration), "stop_reason": self.stop or "max_iter", "stop_message": self.message,
            "energy_history": [float(e) for e in self.history], "energy_final": float(self.history[-1]),
            "snapshots": dict(self.snapshots),
            "H": H_final, "K": K_final,
            "parameters": st.reported_parameters(),
            "timings": dict(self.timings),
            "n_backtracks": int(self.n_backtracks),
            "n_rejected_folds": int(self.n_rejected_folds),
            "n_l2_fallbacks": int(self.n_l2_fallbacks),
            "curvature_fallbacks": int(self.curvature_fallbacks),
            "cg_iterations": list(self.cg_iterations),
            "move_history_voxels": [float(m / h) for m in self.moves],
            "init_flipped": bool(self.init_flipped),
            "init": dict(self.init_facts),
            "sign_guard": [list(t) for t in self.signs.log] if self.signs is not None else [],
            "topology": dict(self.topology),
            "warnings": [] if self.topology.get("compatible", True) else [self.topology["message"]],
            "noise_estimate": float(self.noise),
            "noise_estimate_voxels": float(self.noise / h),
            "presmooth_used": float(st.presmooth),
            "start_smooth_used": float(st.start_smooth),
            "beta_used": float(st.beta),
            "grid_spacing": float(h),
            "polish": polish_info,
            "projection": projection_info,
            "tips": tips_info,
            "reach": reach_info,
            "carved_held": None if self.carve is None else int(self.carve.held),
            "remeshes": [list(r) for r in self.remeshes],
            "stages": [dict(r) for r in self.stage_starts],
            "remesh_refused": int(self.remesh_refused),
            "intersections": [list(r) for r in self.intersections],
            "intersection_repairs": int(self.repairs),
            "intersection_rollbacks": int(self.rollbacks),
            **checks,
        }
        return Reconstruction(mesh, info)
