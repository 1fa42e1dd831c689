"""The flow: one iteration = the paper's four steps (interpolate, gradient, precondition, step) and the named
additions it calls (the carve limit, the L² fallback, the stages, the sign guard, the intersection guard); the
result packs the mesh and what the run did into a Reconstruction."""

from __future__ import annotations

import time
from dataclasses import dataclass, field as dataclass_field

import numpy as np
import trimesh

from geometry.mesh import signed_volume
from geometry.operators import MeshOperators, dot
from phantoms import InputError

from ..contract import Reconstruction, ReconstructionFailed
from .carve import CarvedHull, remesh_keep
from .convergence import ConvergenceTest, Stages
from .energy import evaluate_state, gradient_from_state
from .guard import count_intersections, repair_intersections
from .linesearch import LineSearch, l2_fallback_direction
from .post import post_steps, reach_step
from .remesh import drift, remesh, touch_up
from .settings import FlowSettings
from .signs import SignGuard
from .sobolev import FLOW_SOLVER, SobolevSolver

__all__ = ["ShapeGradientFlow", "FlowStats", "STOP_REASONS"]

#: ``fixed_iterations``: the run had no convergence test (``tol`` and ``move_tol`` both 0, as the paper's presets)
#: and ran its full ``max_iter`` count by design; ``max_iter``: a run with a test hit the cap before it held
STOP_REASONS = ("converged", "fixed_iterations", "max_iter", "line_search_floor", "diverged", "sign_guard")

_FLOOR_MOVE_VOXELS = 1e-4  # the line search gives up when the largest trial move falls below this
_OFF_SURFACE_VOXELS = 0.5      # a result whose median |φ| at the vertices exceeds this (voxels) has failed ...
_OFF_SURFACE_NOISE = 1.0       # ... added in quadrature to this many noise stds (on the true surface of a noisy
#                                volume the median |φ| is already 0.67 std)
#: split/collapse/flip/relax rounds of the start's remesh (marching cubes' slivers); a later remesh, of a mesh already
#: near isotropic, runs one
START_REMESH_ROUNDS = 3


@dataclass
class FlowStats:
    """What one run did, counted as it goes (reported in the result's info under the same names)."""

    n_backtracks: int = 0              # halvings of the line search
    n_rejected_folds: int = 0          # trials that decreased E but folded a face
    n_l2_fallbacks: int = 0            # line searches along the plain gradient after the H¹ one failed
    curvature_fallbacks: int = 0       # vertex-iterations whose paraboloid fit was undetermined (cotangent H used)
    cg_iterations: list = dataclass_field(default_factory=list)    # CG iterations of each H¹ solve that ran CG
    moves: list = dataclass_field(default_factory=list)            # the accepted trial moves (world units)
    remeshes: list = dataclass_field(default_factory=list)         # (iteration, vertices after the remesh)
    remesh_refused: int = 0            # remeshes given up (the remesher's result or its intersections refused)
    remesh_skipped: int = 0            # remesh points where the triangles were still the remesher's (none done)
    touch_ups: int = 0                 # remesh points where only patches around a few small angles were remeshed
    intersections: list = dataclass_field(default_factory=list)    # (iteration, intersecting faces found there)
    repairs: int = 0                   # intersections repaired
    rollbacks: int = 0                 # intersections undone by going back to the last safe mesh


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
        self.init_flipped, self.noise = bool(init_flipped), float(noise)
        self.topology: dict = dict(topology or {})
        self.init_facts: dict = dict(init_facts or {})
        self.stats = FlowStats()
        self.stages = Stages(settings.stages, self.h)
        self.line = LineSearch(settings.max_move * self.h, _FLOOR_MOVE_VOXELS * self.h)
        self.convergence = ConvergenceTest(settings.tol, settings.move_tol * self.h, settings.move_tol)
        self.sobolev = SobolevSolver(FLOW_SOLVER)        # the H¹ solve (its factor, warm start, solver choice)
        self.state = self._evaluate(np.asarray(x, float))
        if not np.isfinite(self.state.E):
            raise InputError("method 'shape_gradient': the energy of the initial surface is not finite")
        self.history = [self.state.E]
        self.snapshots = {0: self._snapshot()}
        self._safe = None                               # (x, ops, state) of the last intersection-free check
        self.stop: str | None = None
        self.message = ""
        self._final = None                              # the result's geometry and post-step facts (_finish)
        self.signs = None                               # the sign guard (signs.py), on clean volumes
        self.carve = CarvedHull.of(field, settings, self.state, self.h)   # the carve limit (carve.py), or None
        if settings.remesh_every and settings.remesh_start:
            self._remesh_and_guard(0)                   # a start with marching cubes' slivers: isotropic first
        elif settings.guard:
            self._guard(0)                              # the start: the first safe state (or repaired)
        if settings.sign_guard and getattr(field, "volume", None) is not None:
            self.signs = SignGuard(field.volume, self.h, self.state.x, self.ops.faces, self.ops)

    @property
    def iteration(self) -> int:
        """The iterations accepted so far (one energy per iteration after the start's)."""
        return len(self.history) - 1

    @property
    def density(self) -> float:
        """−α(2/3)³σ̂² on a noisy volume (unbias): the area term a noisy φ² adds to E (energy.evaluate_state)."""
        return -float(self.settings.alpha) * self.settings.noise_variance

    @property
    def before_reach(self) -> np.ndarray | None:
        """The final vertices before the reach to the samples (set by :meth:`result`; what the start choice
        scores)."""
        return None if self._final is None else self._final[-1]

    def _evaluate(self, x: np.ndarray, ops: MeshOperators | None = None, timed: bool = True):
        """The state (geometry, energy) at ``x`` on ``ops`` (default: the current mesh's) with the current β."""
        return evaluate_state(self.field, self.ops if ops is None else ops, x, self.settings.alpha, self.stages.beta,
                              self.timings if timed else None, density=self.density)

    # ------------------------------------------------------------------ one iteration
    def step(self) -> bool:
        """Do one iteration — the paper's four steps — and accept its state; False when the run has ended
        (``stop``/``message`` say why)."""
        if self.stop is not None:
            return False
        if self.iteration >= self.settings.max_iter:
            return self._end(*self._iteration_limit())
        it, state = self.iteration + 1, self.state
        self._interpolate(state)                                         # 1. φ, ∇φ, D²φ at the vertices
        G = self._gradient(state)                                        # 2. the shape gradient
        if not np.isfinite(G).all():
            return self._end("diverged", f"iteration {it}: the shape gradient is not finite at "
                                         f"{int((~np.isfinite(G)).sum())} vertices (degenerate mesh or curvature fit)")
        V, limit = self._precondition(state.geo, G)                      # 3. the velocity, carve-limited
        if float(np.abs(V).max()) == 0.0:
            return self._end("converged", f"iteration {it}: the shape gradient vanishes")
        new, move, moved = self._step(state, G, V, limit)                # 4. the step (line search)
        if new is None:
            return self._settle("line_search_floor", f"iteration {it}: no decrease of E for moves down to "
                                f"{_FLOOR_MOVE_VOXELS:.1g} voxels (the gradient no longer predicts a decrease "
                                "of the discrete energy)")
        return self._accept(it, new, move, moved)

    def _interpolate(self, state) -> None:
        """Step 1: φ, ∇φ and D²φ at every vertex of ``state``, one trilinear gather of the derivative grids."""
        if state.channels is None:
            t0 = time.perf_counter()
            state.channels = self.field.sample_t(state.geo.vertices_t, 2)
            self.timings["interpolation"] += time.perf_counter() - t0

    def _gradient(self, state) -> np.ndarray:
        """Step 2: the shape gradient G at every vertex (energy.gradient_from_state)."""
        st = self.settings
        G, _ = gradient_from_state(self.field, state, self.ops, st.alpha, self.stages.beta, kind=st.gradient,
                                   linear=st.curvature == "tilted", timings=self.timings, density=self.density)
        self.stats.curvature_fallbacks += state.curvature_fallbacks
        return G

    def _precondition(self, geo, G: np.ndarray) -> tuple[np.ndarray, np.ndarray | None]:
        """Step 3: the normal velocity V — the H¹ (Sobolev) gradient (M + sK)⁻¹ M G (sobolev.py) or G itself —
        and, with the carve limit, each vertex's largest inward move (V held at 0 where that is 0)."""
        st, V = self.settings, G
        if st.precondition == "h1" and st.s_world > 0:
            t0 = time.perf_counter()
            V = self.sobolev.velocity(self.ops, geo, G, geo.vertex_areas * G, st.s_world, self.stats.cg_iterations)
            self.timings["preconditioner"] += time.perf_counter() - t0
        return (V, None) if self.carve is None else self.carve.hold(self.state.x, V)[::-1]

    def _step(self, state, G: np.ndarray, V: np.ndarray, limit: np.ndarray | None):
        """Step 4: (new state, trial move, normal move) of the capped line search along −V n with the tangential
        relaxation (held by the carve limit); where it finds no decrease, the L² fallback along −G n."""
        geo = state.geo
        shift = self._relax_shift(geo)
        if limit is not None:
            shift = self.carve.still(state.x, shift, limit)
        direction, vmax, slope = -V[:, None] * geo.vertex_normals, float(np.abs(V).max()), dot(geo.vertex_areas * G, V)
        found = self.line.search(self._evaluate, state, direction, shift, vmax, slope, limit, self.stats)
        fallback = None
        if found[0] is None and self.settings.l2_fallback and V is not G:
            fallback = l2_fallback_direction(geo, G, limit)
        if fallback is not None:
            self.stats.n_l2_fallbacks += 1
            found = self.line.search(self._evaluate, state, fallback[0], None, fallback[1], fallback[2], limit,
                                     self.stats)
        return found

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

    def _accept(self, it: int, new, move: float, moved: float) -> bool:
        """Take ``new`` as iteration ``it``'s state (remesh and snapshot when due), then the stop tests
        (``moved``: the step's largest normal move)."""
        self.stats.moves.append(move)
        prev = self.state.E
        self.state = new
        self.history.append(new.E)
        if self._remesh_due(it) and not self._remesh_point(it):
            return self._end("sign_guard", self.signs.message)
        if it in self.settings.snapshots:
            if self.settings.guard and (not self.stats.intersections or self.stats.intersections[-1][0] != it):
                self._guard(it)                      # a snapshot is a result too: intersection-free
            self.snapshots[it] = self._snapshot()
        reason = self.convergence.observe(abs(prev - new.E) / max(abs(prev), 1e-300), moved)
        return True if reason is None else self._settle("converged", f"iteration {it}: {reason}")

    def _iteration_limit(self) -> tuple[str, str]:
        """The stop at ``max_iter``: by design without a convergence test, else a cap hit."""
        st = self.settings
        if st.tol <= 0 and st.move_tol <= 0:
            return "fixed_iterations", (f"ran its fixed count of {st.max_iter} iterations (no convergence test: "
                                        "tol = move_tol = 0)")
        return "max_iter", f"reached max_iter = {st.max_iter}"

    def _end(self, reason: str, message: str) -> bool:
        self.stop, self.message = reason, message
        return False

    def _settle(self, reason: str, message: str) -> bool:
        """The flow has settled at this stage: go on with the next stage's settings, or end the run."""
        if not self.stages.more():
            return self._end(reason, message)
        self.stages.enter(self.iteration)
        self.convergence.reset()
        self.line.restart()
        if self.settings.remesh_every:
            self._remesh_and_guard(self.iteration)
        self.state = self._evaluate(self.state.x)
        self._safe = None
        return True

    # ------------------------------------------------------------------ remeshing and the intersection guard
    def _remesh_due(self, it: int) -> bool:
        """The remesh cadence: whether the flow remeshes after accepting iteration ``it``."""
        return bool(self.settings.remesh_every) and it % self.settings.remesh_every == 0

    def _snapshot(self):
        """The current vertices, with the faces too once the connectivity can change (remeshing)."""
        x = self.state.x.copy()
        return (x, self.ops.faces.copy()) if self.settings.remesh_every else x

    def _set_mesh(self, x: np.ndarray, ops: MeshOperators, state=None) -> None:
        self.ops = ops
        self.state = state if state is not None else self._evaluate(x, ops)
        self.sobolev.reset()         # the warm start and the factor of the H¹ solve belong to the old mesh

    def _remesh_point(self, it: int) -> bool:
        """Remesh and check; False when the sign guard rolled the mesh back (the flow must stop).  The sign
        guard looks before the remesh (a flow that already cut a part is not worth remeshing) and after it
        (the remesher's collapses can cut a voxel-thin tip too).  Where the triangles are still near the
        remesher's (:func:`.remesh.drift`: a surface that moved a fraction of a voxel keeps them), the remesh is
        skipped and the mesh only checked; where only a few angles got small, patches around them are remeshed
        (:func:`.remesh.touch_up`)."""
        how = drift(self.state.x, self.ops.faces, self.stages.edge_length) if self.settings.remesh_when_drifted \
            else "always"
        if how is None or (how == "angles" and self._touch_up()):
            self.stats.remesh_skipped += how is None
            self._guard(it)
            back = self.signs.check(it, self.state.x, self.ops) if self.signs is not None else None
        else:
            back = self.signs.check(it, self.state.x, self.ops, keep=False) if self.signs is not None else None
            if back is None:
                self._remesh_and_guard(it)
                back = self.signs.check(it, self.state.x, self.ops) if self.signs is not None else None
        if back is not None:
            self._set_mesh(*back)
            return False
        return True

    def _touch_up(self) -> bool:
        """Remesh patches around the few small angles (held tips kept); False when the whole mesh needs it."""
        t0 = time.perf_counter()
        keep = remesh_keep(self.ops, self.state.geo, self.h, self.carve)
        out = touch_up(self.state.x, self.ops.faces, self.stages.edge_length, keep)
        if out is not None:
            self._set_mesh(out[0], MeshOperators(out[1], len(out[0])))
            self.stats.touch_ups += 1
        self.timings["remesh"] += time.perf_counter() - t0
        return out is not None

    def _remesh_and_guard(self, it: int) -> None:
        """Remesh toward the target edge length, then make sure no faces intersect (repair or roll back)."""
        t0 = time.perf_counter()
        # the flow's meshes are closed (checked at every remesh); the start is checked here once more, and gets
        # all the rounds (marching cubes' slivers); a later mesh is near isotropic: one round
        rounds = START_REMESH_ROUNDS if it == 0 else 1
        before = (self.state.x, self.ops, self.state)
        # the carve limit: held tips stay (the start, marching cubes' slivers, is remeshed freely)
        keep = {"keep": remesh_keep(self.ops, self.state.geo, self.h, self.carve)} if it > 0 else {}
        out = remesh(self.state.x, self.ops.faces, self.stages.edge_length, rounds, closed=it > 0, **keep)
        if out is None:
            self.stats.remesh_refused += 1
        else:
            x, f = out
            self._set_mesh(x, MeshOperators(f, len(x)))
            self.stats.remeshes.append((it, len(x)))
            # a new mesh: the line search starts again from the step cap, the stop tests count afresh
            self.line.restart()
            self.convergence.reset(held=False)
        self.timings["remesh"] += time.perf_counter() - t0
        if not self._guard(it) and self._safe is None and out is not None:   # an unrepairable remeshed start:
            self.stats.remesh_refused += 1                                     # the start as grown is safe
            self._set_mesh(*before)
            self.convergence.reset(held=self._guard(it))

    def _checked(self) -> bool:
        """True when the current mesh is the last one the intersection guard passed (nothing moved since)."""
        return (self._safe is not None and self._safe[1] is self.ops
                and np.array_equal(self._safe[0], self.state.x))

    def _guard(self, it: int) -> bool:
        """Check for self-intersections; repair or roll back.  True when the mesh is now intersection-free."""
        t0 = time.perf_counter()
        n, bad = count_intersections(self.state.x, self.ops.faces)
        self.stats.intersections.append((it, n))
        clean = n == 0
        if not clean:
            fixed = repair_intersections(self.ops, self.state.x, bad)
            if fixed is not None:
                self.stats.repairs += 1
                self._set_mesh(fixed, self.ops)
                clean = True
            elif self._safe is not None:
                self.stats.rollbacks += 1
                self._set_mesh(*self._safe)
                self.line.halve_cap()
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
        """(final geometry, info['polish'], info['projection'], info['tips'], info['reach'], the vertices before
        the reach): the last iterate after the post-steps (post.py); the vertices before the reach to the samples
        are what the start choice scores (:attr:`before_reach`: the reach mends single spots, the start decides
        the rest)."""
        st, h = self.settings, self.h
        guard = st.guard
        if guard and not self._checked():
            self._guard(self.iteration)
        energy = (lambda xe: self._evaluate(xe, timed=False).E)
        x, polish, projection, tips = post_steps(self.field, self.ops, self.state.x, h, st, guard=guard,
                                                 energy=energy, timings=self.timings)
        if polish.get("used") and polish["energy"] is None:           # nothing polished: the flow's last energy
            polish["energy"] = float(self.state.E)
        before_reach = x
        x, reach = reach_step(self.field, self.ops, x, h, st, guard=guard, timings=self.timings, noise=self.noise)
        return self.ops.geometry(x), polish, projection, tips, reach, before_reach

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
        st, h, stats = self.settings, self.h, self.stats
        if self._final is None:
            self._final = self._finish()
        t0 = time.perf_counter()
        final_geo, polish_info, projection_info, tips_info, reach_info, _ = self._final
        checks = self._check_result(final_geo)
        H_final, K_final = self.ops.curvature(final_geo, linear=st.curvature == "tilted")
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
            "n_backtracks": int(stats.n_backtracks),
            "n_rejected_folds": int(stats.n_rejected_folds),
            "n_l2_fallbacks": int(stats.n_l2_fallbacks),
            "curvature_fallbacks": int(stats.curvature_fallbacks),
            "cg_iterations": list(stats.cg_iterations),
            "move_history_voxels": [float(m / h) for m in stats.moves],
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
            "remeshes": [list(r) for r in stats.remeshes],
            "stages": [dict(r) for r in self.stages.starts],
            "remesh_refused": int(stats.remesh_refused),
            "remesh_skipped": int(stats.remesh_skipped),
            "remesh_touched_up": int(stats.touch_ups),
            "intersections": [list(r) for r in stats.intersections],
            "intersection_repairs": int(stats.repairs),
            "intersection_rollbacks": int(stats.rollbacks),
            **checks,
        }
        return Reconstruction(mesh, info)
