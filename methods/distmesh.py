"""Baseline: DistMesh on the zero level set — a vectorised port of Persson's ``distmeshsurface``.

Per-O. Persson's ``distmeshsurface.m`` (DistMesh 2012 release, MIT licensed) meshes the zero set of a
distance function with a uniform size function.  Here the distance function is the trilinear interpolant
of the volume (its gradient the interpolated central-difference gradient of the volume):

1. initial mesh: marching cubes of the volume resampled on a grid of spacing ``h0``;
2. each iteration
   a. if any node moved more than ``ttol·h0`` since the last retriangulation: an edge-flip sweep — an edge
      is flipped when the worse of its two triangles has quality q = 4√3·A/Σl² < 0.9, the flip raises the
      minimum quality by more than 0.025, the two new triangles' normals agree with each other and with the
      old pair's, and the new edge does not already exist (so the mesh stays a closed 2-manifold);
   b. repulsive bar forces: L0 = Fscale·√(ΣL²/#bars) (uniform size), F = max(L0 − L, 0), nodes move by
      Δt·ΣF·(bar direction);
   c. one Newton projection of every node back onto φ = 0: p ← p − φ·∇φ/|∇φ|²;
   d. stop when the largest node move of the iteration is below ``dptol·h0``.

The original is unstable on noisy level sets (the paper reports it): nodes crowd into the rough zero set,
the mesh folds, bars lengthen and the nodes eventually leave the surface.

What the original lacks and this port adds: an iteration cap (``max_iter``), zero-length bars get a fixed
direction instead of a division by zero, nodes where |∇φ| ≈ 0 are not projected (and counted), the Newton
step is capped at ``h0``, nodes are kept inside the volume box, a divergence guard stops the run when the
rms bar length grows past ``max_growth`` × its smallest value (a tangling mesh; a healthy run settles), and
``info`` says how it stopped (``converged``, ``stop_reason`` in {"converged", "max_iter", "diverged"}, a
human-readable ``status``, ``folded_faces`` = faces whose normal opposes ∇φ).  ``newton_steps`` > 1 (not
in the original) projects more completely each iteration.

The flip sweep is vectorised too: each round computes the flip test for every edge at once and applies a
set of improving flips no two of which share a triangle (the best flip around each triangle wins);
rounds repeat until no edge qualifies.
"""

from __future__ import annotations

import time

import numpy as np
import trimesh
from scipy import sparse

from geometry.levelset import newton_project
from geometry.mesh import mesh_facts
from geometry.topology import edges_unique

from phantoms import InputError, Volume

from . import distmesh_loop
from .base import Method, check_volume
from .contract import Reconstruction
from .params import Param
from .cost_model import PowerLaw
from .isosurface import marching_cubes_mesh, orient_outward

__all__ = ["DistMesh", "flip_edges", "triangle_quality"]

_SQRT3x4 = 4.0 * np.sqrt(3.0)


def triangle_quality(p: np.ndarray, a: np.ndarray, b: np.ndarray, c: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Quality q = 4√3·A/(l₁² + l₂² + l₃²) (1 for equilateral, 0 degenerate) and the un-normalised normal
    (b − a) × (c − a) of triangles (a, b, c)."""
    pa, pb, pc = p[a], p[b], p[c]
    cr = np.cross(pb - pa, pc - pa)
    area = 0.5 * np.linalg.norm(cr, axis=1)
    l2 = ((pb - pa) ** 2).sum(1) + ((pc - pb) ** 2).sum(1) + ((pa - pc) ** 2).sum(1)
    q = _SQRT3x4 * area / np.where(l2 > 0, l2, 1.0)
    return np.where(l2 > 0, q, 0.0), cr


def _flip_candidates(p, a, b, c, d, qmax: float, gain: float) -> tuple[np.ndarray, np.ndarray]:
    """(flip wanted, quality gain) per edge (a, b) with opposite corners c, d (numpy; the reference of
    :func:`methods.distmesh_loop.flip_candidates`)."""
    q1, n1 = triangle_quality(p, a, b, c)
    q2, n2 = triangle_quality(p, b, a, d)
    qold = np.minimum(q1, q2)
    r1, m1 = triangle_quality(p, a, d, c)
    r2, m2 = triangle_quality(p, d, b, c)
    qnew = np.minimum(r1, r2)
    nold = n1 + n2
    cand = ((qold < qmax) & (qnew > qold + gain)
            & (np.einsum("ij,ij->i", m1, m2) > 0)
            & (np.einsum("ij,ij->i", m1, nold) > 0)
            & (np.einsum("ij,ij->i", m2, nold) > 0))
    return cand, np.where(qold < qmax, qnew - qold, 0.0)


def flip_edges(p: np.ndarray, t: np.ndarray, *, qmax: float = 0.9, gain: float = 0.025,
               max_rounds: int = 200, compiled: bool = True) -> tuple[np.ndarray, int, int]:
    """Edge-flip sweep on a closed, consistently oriented triangle mesh.

    Returns ``(faces, flips, rounds)``; the input faces are not modified.  Only edges shared by exactly two
    consistently oriented triangles are considered, so a non-manifold input is left alone where it is.
    """
    t = np.array(t, dtype=np.int64, copy=True)
    n = len(p)
    total = 0
    rounds = 0
    for rounds in range(1, max_rounds + 1):
        nf = len(t)
        frm = t.ravel()
        to = t[:, [1, 2, 0]].ravel()
        opp = t[:, [2, 0, 1]].ravel()
        face = np.repeat(np.arange(nf), 3)
        key = np.minimum(frm, to) * n + np.maximum(frm, to)
        order = np.argsort(key, kind="stable")
        ks = key[order]
        # edges seen exactly twice (manifold interior edges of a closed mesh)
        start = np.flatnonzero(np.r_[True, ks[1:] != ks[:-1]])
        count = np.diff(np.r_[start, len(ks)])
        two = start[count == 2]
        h1, h2 = order[two], order[two + 1]
        ok = (frm[h2] == to[h1]) & (to[h2] == frm[h1])  # consistent orientation
        h1, h2 = h1[ok], h2[ok]
        a, b, c, d = frm[h1], to[h1], opp[h1], opp[h2]
        f1, f2 = face[h1], face[h2]
        keep = c != d
        a, b, c, d, f1, f2 = a[keep], b[keep], c[keep], d[keep], f1[keep], f2[keep]
        if not len(a):
            break
        if compiled and distmesh_loop.AVAILABLE:
            cand, improve = distmesh_loop.flip_candidates(p, a, b, c, d, qmax, gain)
        else:
            cand, improve = _flip_candidates(p, a, b, c, d, qmax, gain)
        if cand.any():
            # the new edge must not exist already (else the mesh would become non-manifold); ks is sorted
            newkey = np.minimum(c, d) * n + np.maximum(c, d)
            pos = np.minimum(np.searchsorted(ks, newkey), len(ks) - 1)
            cand &= ks[pos] != newkey
        if not cand.any():
            break
        idx = np.flatnonzero(cand)
        improve = improve[idx]
        a, b, c, d, f1, f2 = (x[idx] for x in (a, b, c, d, f1, f2))
        # independent set: a flip wins when it has the largest improvement around both of its triangles
        rank = np.empty(len(idx), dtype=np.int64)
        rank[np.argsort(improve, kind="stable")] = np.arange(1, len(idx) + 1)
        best = np.zeros(nf, dtype=np.int64)
        np.maximum.at(best, f1, rank)
        np.maximum.at(best, f2, rank)
        win = (best[f1] == rank) & (best[f2] == rank)
        a, b, c, d, f1, f2 = (x[win] for x in (a, b, c, d, f1, f2))
        # two winning flips may create the same new edge: keep one
        newkey = np.minimum(c, d) * n + np.maximum(c, d)
        _, first = np.unique(newkey, return_index=True)
        a, b, c, d, f1, f2 = (x[first] for x in (a, b, c, d, f1, f2))
        t[f1] = np.column_stack([a, d, c])
        t[f2] = np.column_stack([d, b, c])
        total += len(a)
    return t, total, rounds


def _bar_system(t: np.ndarray, n: int, rng: np.random.Generator, incidence: bool = True):
    """The bars (unique edges) of faces ``t``, the signed node-bar incidence (n, bars) — the force sum is
    then one sparse product per iteration — and a fixed random unit direction per bar (for zero-length
    bars)."""
    bars = edges_unique(t)
    nb = len(bars)
    if incidence:                   # (the compiled iterations sum the forces bar by bar: no matrix)
        rows = np.r_[bars[:, 0], bars[:, 1]]
        cols = np.r_[np.arange(nb), np.arange(nb)]
        signs = np.r_[np.ones(nb), -np.ones(nb)]
        incidence = sparse.csr_matrix((signs, (rows, cols)), shape=(n, nb))
    fallback = rng.standard_normal((nb, 3))
    fallback /= np.linalg.norm(fallback, axis=1, keepdims=True)
    return bars, incidence, fallback


class DistMesh(Method):
    name = "distmesh"
    relative_cost = 4.0
    description = ("Persson's distmeshsurface (2012) on the trilinear volume: MC start on an h0 grid, edge "
                   "flips, repulsive bar forces, Newton projection")
    params = {
        "h0": Param(None, "target edge length in world units (default: 2 × the grid spacing)", type=float,
                    min=1e-12),
        "max_iter": Param(2000, "iteration cap (the original has none)", type=int, min=1, max=1_000_000),
        "dptol": Param(1e-4, "stop when every node moves less than dptol·h0 in an iteration", type=float,
                       min=0.0, max=1.0),
        "ttol": Param(0.1, "flip sweep when a node moved more than ttol·h0 since the last sweep", type=float,
                      min=0.0, max=10.0),
        "fscale": Param(1.2, "Fscale: L0 = Fscale·rms(L); > 1 makes all bars repulsive", type=float,
                        min=1.0, max=3.0),
        "deltat": Param(0.2, "Δt of the force step", type=float, min=1e-6, max=1.0),
        "max_growth": Param(1.25, "divergence guard: stop when the rms bar length exceeds this multiple of "
                                  "its smallest value so far", type=float, min=1.01, max=100.0),
        "newton_steps": Param(1, "Newton projection steps per iteration (the original: 1; near a crease 2–3 "
                                 "stop the nodes from oscillating there)", type=int, min=1, max=20),
        "history": Param(True, "record the max move of every iteration in info['max_move_history']",
                         type=bool),
        "compiled": Param(True, "run the iterations compiled (methods/distmesh_loop.py, numba; faster); "
                                "False: the numpy form, the reference (the same steps; nodes equal to rounding)",
                          type=bool),
    }

    #: the cost model: CPU seconds, fitted to the clean sphere and bunny at
    #: N = 24–128 (the nodes grow with the surface: q = 1 is assumed, not fitted)
    COST = PowerLaw(a=0.465, p=2.51, q=1.0)

    def estimate_seconds(self, shape, n_crossing_cells: int | None = None) -> float | None:
        """The fit of the default settings (h0 = 2 h, compiled), × 40 for the numpy form; None with an h0 of
        one's own, which sets the number of nodes and was not measured."""
        if self.config["h0"] is not None:
            return None
        return self.COST.seconds(shape, n_crossing_cells) * (1.0 if self.config["compiled"] else 40.0)

    # ------------------------------------------------------------------
    def _h0(self, volume: Volume) -> float:
        h0 = self.config["h0"]
        if h0 is None:
            return 2.0 * volume.h
        box = float((volume.upper - volume.lower).min())
        if h0 < 0.5 * volume.h:
            raise InputError(f"method {self.name!r}, parameter 'h0': {h0!r} is below half the grid spacing "
                             f"({0.5 * volume.h:.6g}); the volume cannot resolve edges that short")
        if h0 > 0.25 * box:
            raise InputError(f"method {self.name!r}, parameter 'h0': {h0!r} is more than a quarter of the "
                             f"volume box ({box:.6g}); no surface would be resolved")
        return float(h0)

    def _initial_mesh(self, volume: Volume, h0: float) -> trimesh.Trimesh:
        """Marching cubes of the trilinear volume resampled on a grid of spacing h0 (padded positive)."""
        lo, hi = volume.lower, volume.upper
        axes = [lo[k] + h0 * np.arange(int(np.floor((hi[k] - lo[k]) / h0 + 1e-9)) + 2) for k in range(3)]
        grid = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1)
        vals = volume.sample(grid.reshape(-1, 3), clamp=True).phi.reshape(grid.shape[:3])
        pad_value = max(float(np.abs(volume.values).max()), 1.0)
        vals = np.pad(vals, 1, constant_values=pad_value)
        coarse = Volume(vals, origin=lo - h0, spacing=h0)
        if not coarse.has_zero_crossing():
            raise InputError(f"method {self.name!r}, parameter 'h0': a grid of spacing {h0:.6g} misses the "
                             "surface entirely; use a smaller h0")
        # (grid points past the upper corner were sampled clamped onto the box: φ > 0 there for a closed
        # level set, so they only shift initial vertices, which the projection corrects)
        return marching_cubes_mesh(coarse, name=self.name)

    def reconstruct(self, volume: Volume) -> Reconstruction:
        check_volume(volume, self.name)
        cfg = self.config
        h0 = self._h0(volume)
        t_start = time.perf_counter()
        mesh0 = self._initial_mesh(volume, h0)
        p = np.array(mesh0.vertices, dtype=np.float64)
        t = np.array(mesh0.faces, dtype=np.int64)
        sampler = volume.sampler(1)
        # |∇φ|² below this counts as "no gradient": such nodes are not projected (guard against ∇φ ≈ 0)
        g2_floor = 1e-12 * max(float(np.median((sampler.flat[:, 1:] ** 2).sum(1))), 1e-300)
        iterate = self._iterate_compiled if cfg["compiled"] and distmesh_loop.AVAILABLE else self._iterate_numpy
        p, t, run = iterate(volume, p, t, sampler, h0, g2_floor)
        return self._finish(volume, mesh0, p, t, sampler, h0, t_start, run)

    def _iterate_compiled(self, volume: Volume, p, t, sampler, h0: float, g2_floor: float):
        """The iterations in :mod:`methods.distmesh_loop`; back here only for each retriangulation."""
        cfg = self.config
        rng = np.random.default_rng(12345)         # deterministic fallback directions for zero-length bars
        prm = (h0, cfg["ttol"], cfg["dptol"], cfg["fscale"], cfg["deltat"], cfg["max_growth"], g2_floor, 1e-9 * h0)
        state = np.array([np.nan, np.inf, np.inf])  # lrms, lrms_min, max_move
        history = np.zeros(cfg["max_iter"])
        counts = np.zeros(2, np.int64)              # flat-gradient nodes, capped Newton steps
        n_retri = n_flips = 0
        it, code = 1, distmesh_loop.RETRIANGULATE
        while code == distmesh_loop.RETRIANGULATE:
            pold = p.copy()
            t, flips, _ = flip_edges(p, t)
            n_flips += flips
            n_retri += 1
            bars, _, fallback = _bar_system(t, len(p), rng, incidence=False)
            code, it = distmesh_loop.relax(p, pold, bars, fallback, sampler, (volume.lower, volume.upper), prm,
                                           cfg["newton_steps"], it, cfg["max_iter"], state, history, counts)
        done = it if code != distmesh_loop.DIVERGED else it - 1   # iterations whose max move was recorded
        run = dict(it=it, converged=code == distmesh_loop.CONVERGED, diverged=code == distmesh_loop.DIVERGED,
                   max_move=float(state[2]), lrms=float(state[0]), lrms_min=float(state[1]),
                   history=history[:done].tolist() if cfg["history"] else [], retriangulations=n_retri,
                   flips=n_flips, flat=int(counts[0]), capped=int(counts[1]))
        return p, t, run

    def _iterate_numpy(self, volume: Volume, p, t, sampler, h0: float, g2_floor: float):
        """The iterations in numpy (the reference of the compiled form)."""
        cfg = self.config
        dptol, ttol, fscale, deltat = cfg["dptol"], cfg["ttol"], cfg["fscale"], cfg["deltat"]
        n = len(p)
        lo, hi = volume.lower, volume.upper
        newton_steps = cfg["newton_steps"]

        def phi_grad(points):
            s = sampler(points)
            return s.phi, s.grad

        rng = np.random.default_rng(12345)         # deterministic fallback directions for zero-length bars
        tiny = 1e-9 * h0
        pold = np.full_like(p, np.inf)
        bars = None
        history: list[float] = []
        n_retri = n_flips = n_flat = n_capped = 0
        converged = diverged = False
        lrms_min = np.inf
        lrms = np.nan
        it = 0
        max_move = np.inf
        for it in range(1, cfg["max_iter"] + 1):
            p0 = p.copy()
            # 3. retriangulation by edge flips when anything moved by more than ttol·h0
            dp = p - pold
            if bars is None or np.einsum("ij,ij->i", dp, dp).max() > (ttol * h0) ** 2:
                pold = p.copy()
                t, flips, _ = flip_edges(p, t, compiled=False)
                n_flips += flips
                n_retri += 1
                bars, incidence, fallback = _bar_system(t, n, rng)
            # 6. repulsive bar forces
            barvec = p[bars[:, 0]] - p[bars[:, 1]]
            L2 = np.einsum("ij,ij->i", barvec, barvec)
            L = np.sqrt(L2)
            lrms = float(np.sqrt(L2.sum() / len(L)))
            L0 = fscale * lrms
            # divergence guard: on a fixed surface the rms bar length settles; when it keeps growing the
            # mesh is tangling/leaving the surface (the original's instability on noisy input) — stop
            lrms_min = min(lrms_min, lrms)
            if lrms > cfg["max_growth"] * lrms_min:
                diverged = True
                break
            F = np.maximum(L0 - L, 0.0)
            short = L < tiny
            if short.any():  # zero-length bar: push along a fixed direction instead of dividing by 0
                unit = np.where(short[:, None], fallback, barvec / np.where(short, 1.0, L)[:, None])
                fvec = F[:, None] * unit
            else:
                fvec = (F / L)[:, None] * barvec
            p = p + deltat * (incidence @ fvec)
            np.clip(p, lo, hi, out=p)
            # 7. Newton projection back onto φ = 0 (flat-gradient nodes stay, steps capped at h0, kept in the box)
            p, counts = newton_project(phi_grad, p, newton_steps, max_step=h0, flat_g2=g2_floor, box=(lo, hi))
            n_flat += counts["flat"]
            n_capped += counts["capped"]
            # 8. termination: every node moved less than dptol·h0
            dp = p - p0
            max_move = float(np.sqrt(np.einsum("ij,ij->i", dp, dp).max())) / h0
            if cfg["history"]:
                history.append(max_move)
            if max_move < dptol:
                converged = True
                break
        run = dict(it=it, converged=converged, diverged=diverged, max_move=max_move, lrms=lrms, lrms_min=lrms_min,
                   history=history, retriangulations=n_retri, flips=n_flips, flat=n_flat, capped=n_capped)
        return p, t, run

    def _finish(self, volume: Volume, mesh0, p: np.ndarray, t: np.ndarray, sampler, h0: float, t_start: float,
                run: dict) -> Reconstruction:
        """A last flip sweep, the outward mesh and the info dict (how the run ``run`` stopped, quality)."""
        cfg = self.config
        dptol, max_iter = cfg["dptol"], cfg["max_iter"]
        it, converged, diverged, max_move = run["it"], run["converged"], run["diverged"], run["max_move"]
        lrms, lrms_min, n_flips = run["lrms"], run["lrms_min"], run["flips"]
        # a last sweep so the output has the quality the final positions allow
        t, flips, _ = flip_edges(p, t, compiled=cfg["compiled"])
        n_flips += flips
        mesh = trimesh.Trimesh(p, t, process=False)
        mesh.remove_unreferenced_vertices()
        orient_outward(mesh)
        wall = time.perf_counter() - t_start
        pv, fv = np.asarray(mesh.vertices), np.asarray(mesh.faces)
        q, nrm = triangle_quality(pv, fv[:, 0], fv[:, 1], fv[:, 2])
        # faces whose normal opposes ∇φ at their centroid: folds of a tangled mesh (0 when healthy)
        gc = sampler(pv[fv].mean(axis=1)).grad
        folded = int((np.einsum("ij,ij->i", nrm, gc) < 0).sum())
        if converged:
            status = f"converged after {it} iterations (max move {max_move:.3g}·h0 < dptol = {dptol:g})"
        elif diverged:
            status = (f"diverged at iteration {it}: the rms bar length grew to {lrms / lrms_min:.3g}× its "
                      f"minimum (> max_growth = {cfg['max_growth']:g}); the mesh is tangling or leaving the "
                      f"surface ({folded} folded faces); output is the mesh at that iteration")
        else:
            status = (f"stopped without converging at the iteration cap max_iter = {max_iter} "
                      f"(last max move {max_move:.3g}·h0, dptol = {dptol:g})")
        phi_end = sampler(pv).phi
        info = {
            "iterations": it,
            "converged": converged,
            "stop_reason": "converged" if converged else ("diverged" if diverged else "max_iter"),
            "folded_faces": folded,
            "status": status,
            "h0": h0,
            "final_max_move_h0": max_move,
            "max_move_history": run["history"],
            "retriangulations": run["retriangulations"],
            "flips": n_flips,
            "flat_gradient_nodes": run["flat"],
            "capped_newton_steps": run["capped"],
            "initial_vertices": int(len(mesh0.vertices)),
            "min_quality": float(q.min()) if len(q) else 0.0,
            "mean_quality": float(q.mean()) if len(q) else 0.0,
            "max_abs_phi_over_h": float(np.abs(phi_end).max() / volume.h) if len(phi_end) else 0.0,
            "wall_s": wall,
        }
        info.update({f"mesh_{k}": v for k, v in mesh_facts(mesh).items()})
        return Reconstruction(mesh, info)
