"""Peer: Reach for the Arcs (Sellán, Ren, Batty & Stein, "Reach For the Arcs: Reconstructing Surfaces from SDFs
via Tangency Information", 2024) — the successor of Reach for the Spheres, ``gpytoolbox.reach_for_the_arcs``.

Each grid sample u with value φ(u) defines a sphere of radius |φ(u)| that the surface touches and does not
cross.  The method finds, for every sphere, a point on it that lies in no other sphere (a tangency point: a
rasterisation of the spheres gives points outside all of them, each sphere takes the nearest one's direction and
a local search makes it feasible), with the normal from the sphere's centre; it fine-tunes that oriented point
cloud against a screened-Poisson surface of it (points moved or added where the surface crosses or misses a
sphere), and returns the screened-Poisson surface (PSR, Kazhdan & Hoppe 2013) of the final cloud.  No start
mesh, no flow: any topology.

The adapter runs the library's own steps (``_sdf_to_point_cloud``, ``_fine_tune_point_cloud_iteration``,
``point_cloud_to_mesh``) in the library's order with the library's random seeds, so that the PSR depth, which
it does not expose, can be set: with ``clamp = 0, psr_depth = 10, rasterization = 0, fine_tune_iters = 3,
batch_size = 10000`` it returns exactly what ``gpytoolbox.reach_for_the_arcs(U, S, force_cpu=True)`` returns
on an SDF whose cloud stays inside the grid box (tests/test_methods_reach_for_the_arcs.py; the two corrections
below).

Cost, and the defaults.  Called as it is
on a sphere at N = 33 the library takes minutes and returns 111k vertices.  The time goes to

* the rasterisation, which marks, for every sphere, the cells of a res³ grid inside it: a
  sample far from the surface has a sphere as large as the shape, so the cost grows with Σ |φ|³ ≈ N⁶.  The
  library's answer for this is the clamped SDF: ``clamp`` (in h, default 3) caps every radius at clamp·h and
  passes the same value as the library's ``clamp_value``, so those spheres still keep the cloud out of their
  (capped) balls but are not asked for a tangency point.  The surface is fixed by the spheres near it: the
  points of the far spheres lie on the same surface, and a sphere of radius ≥ h around every sample still
  fills the space outside the band;
* screened Poisson at octree depth 10, fixed inside the library (4 solves: one per fine-tuning iteration and
  the last), i.e. about 1,000 cells across the shape, 30–70 per grid step, which is where the 111k vertices
  come from.  ``psr_depth`` (default auto: the smallest depth whose cell is at most h / 3 across the point
  cloud's bounding box, 6–7 at N = 32–64) matches the surface to the data it is drawn from;
* the rasterisation grid: the library's 64 · ceil(N / 16) cells across the grid box (≈ 4–6 per h) cost 3× the
  time of ``rasterization`` = 2 cells per h (the default) for the same surface;
* the fine-tuning iterations (``fine_tune_iters``), each a PSR solve, a distance query of every sample to the
  current surface and local searches on the spheres it crosses or misses — each about as costly as all the
  rest.  The default is 1, not the library's 3: on the bunny at N = 32 three are 3× the time and no more
  accurate, none is half the time and less accurate;
* the local searches, whose obstacles are ``batch_size`` spheres drawn at random: on a noisy volume most searches
  fail and run all ``local_search_iters``, and with the library's 10,000 obstacles ``check-method``'s noisy
  sphere took far longer than with 3,000, the default (on the clean bunny faster too, and nearly as close).

Radii (``redistance``).  The spheres need |φ| to be a distance; the adapter reads it and, when it is not one,
gives the library the distance to φ's zero set instead, exactly as ``reach_for_the_spheres`` does (its module
docstring; the same functions).  Without it a normalised implicit (``check-method``'s ellipsoid) came back as 109
components.

The grid box.  A sphere near the edge of the grid reaches past it, where no sample's sphere excludes a point:
there the first step finds "tangency" points off the surface, and PSR closes a second shell round them (the
``check-method`` torus, whose surface is 2 h from the grid's top and bottom).  The surface is inside the grid
(``check_volume``), so the cloud points more than h / 2 outside the grid box are dropped before every PSR solve
(``info["points_outside_box"]``).

The rasterisation runs on the CPU (``rasterizer = "cpu"``): the library's GPU path (WebGPU) is slower on a
machine without a GPU and prints errors; ``"auto"`` lets the library choose.

Reported in ``info``: ``cloud_points`` (after the first step) and ``fine_tuned_points``, ``psr_depth``,
``rasterization_resolution``, ``points_outside_box``, ``redistanced`` and the distance reading, the three phases'
times (``time_cloud_s``, ``time_fine_tune_s``, ``time_psr_s``) and the mesh's facts.  The method has no iterations
of its own to report beyond ``fine_tune_iters``.

Limits (the paper): the screened-Poisson surface interpolates the cloud, so the result is smooth but not on
φ = 0 between the points; the far spheres' clamping makes the first step blind beyond clamp·h; noise in φ puts
the tangency points off the surface by about the noise.
"""

from __future__ import annotations

import math
import time

import numpy as np
import trimesh

from geometry.mesh import mesh_facts
from phantoms import Volume

from .base import Method, check_volume
from .contract import Reconstruction, ReconstructionFailed
from .params import Param
from .isosurface import orient_outward
from .reach_for_the_spheres import distance_reading, zero_set_distance

__all__ = ["ReachForTheArcs", "auto_psr_depth", "clamped_samples", "inside_box"]

#: screened Poisson's octree depth range of the auto setting (the library's fixed depth is 10; PSR's cap 12)
PSR_DEPTHS = (5, 10)


def clamped_samples(volume: Volume, clamp: float, values: np.ndarray | None = None
                    ) -> tuple[np.ndarray, np.ndarray, float]:
    """Every grid sample's world position (K, 3) and value (K,) with |φ| capped at ``clamp`` · h (0 = no cap),
    and the cap itself in world units (inf when none): the library's clamped SDF.  ``values`` (K,) replace the
    volume's own, in the same (C) order."""
    idx = np.indices(volume.shape).reshape(3, -1).T
    U = volume.origin + idx * volume.spacing
    S = np.array(volume.values.reshape(-1) if values is None else values, dtype=np.float64)
    if clamp <= 0:
        return U, S, math.inf
    cap = clamp * volume.h
    np.clip(S, -cap, cap, out=S)
    return U, S, cap


def inside_box(P: np.ndarray, lo: np.ndarray, hi: np.ndarray, margin: float) -> np.ndarray:
    """Mask of the points (P, 3) within ``margin`` of the box [lo, hi]."""
    return ((P >= lo - margin) & (P <= hi + margin)).all(axis=1)


def auto_psr_depth(points: np.ndarray, h: float) -> int:
    """The smallest screened-Poisson octree depth whose cell is at most h / 3 over the bounding cube of
    ``points`` (PSR's cube: the points' box enlarged by 1.1), within :data:`PSR_DEPTHS`."""
    extent = 1.1 * float(np.ptp(points, axis=0).max())
    depth = math.ceil(math.log2(max(extent / (h / 3.0), 1.0)))
    return int(min(max(depth, PSR_DEPTHS[0]), PSR_DEPTHS[1]))


class ReachForTheArcs(Method):
    name = "reach_for_the_arcs"
    imports = ("gpytoolbox", "gpytoolbox.point_cloud_to_mesh", "gpytoolbox.reach_for_the_arcs")
    description = ("Reach for the Arcs (Sellán, Ren, Batty & Stein 2024, gpytoolbox): tangency points of the "
                   "samples' spheres, fine-tuned, screened Poisson; any topology")
    params = {
        "clamp": Param(3.0, "cap on the sphere radii |φ|, in grid spacings h (the library's clamped SDF): "
                            "spheres at the cap exclude but get no tangency point; 0 = none (the library's "
                            "default; its cost grows as N⁶)", type=float, min=0.0, max=1000.0),
        "redistance": Param("auto", "the sphere radii: 'auto' = |φ| when it reads as a distance, else the "
                                    "distance to φ's zero set (as reach_for_the_spheres, see its module "
                                    "docstring); 'yes' / 'no' force either", type=str, choices=("auto", "yes", "no")),
        "psr_depth": Param(None, "screened Poisson's octree depth; default: the smallest with cells ≤ h/3 "
                                 "across the point cloud (6–7 at N = 32–64; the library fixes 10)", type=int,
                           min=2, max=12),
        "rasterization": Param(2.0, "the rasterisation grid, in cells per grid spacing h; 0 = the library's "
                                    "64 · ceil(N/16) cells across the grid box (≈ 4 per h, 3× the time for the "
                                    "same surface)", type=float, min=0.0, max=16.0),
        "fine_tune_iters": Param(1, "fine-tuning iterations, each one screened-Poisson solve and a local search "
                                    "on every sphere the surface crosses or misses (the library's default is 3: "
                                    "more time for little gain)", type=int, min=0, max=50),
        "batch_size": Param(3000, "spheres drawn at random as the obstacles of each local search and "
                                  "fine-tuning step (the library's batching; its default 10000 is 2-10× the time, "
                                  "most on noisy volumes; 0 = all)", type=int, min=0, max=10**8),
        "max_points_per_sphere": Param(3, "points a crossed sphere may hold after fine-tuning (the library's "
                                          "default; 1 = never add)", type=int, min=1, max=20),
        "local_search_iters": Param(20, "iterations of each local search for a feasible point (the library's "
                                        "default)", type=int, min=0, max=1000),
        "local_search_t": Param(0.01, "step along the arc of a fine-tuning move, in units of the grid box's "
                                      "longest side (the library's 0.01 in its [0, 1]³)", type=float,
                                min=1e-5, max=1.0),
        "screening_weight": Param(10.0, "screened Poisson's screening weight (the library's default)",
                                  type=float, min=0.0, max=1e4),
        "tol": Param(1e-4, "inside-a-sphere tolerance, in units of the grid box's longest side (the library's "
                           "default)", type=float, min=0.0, max=0.1),
        "rng_seed": Param(3452, "the library's random seed (batches, search order)", type=int, min=0,
                          max=2**31 - 1),
        "rasterizer": Param("cpu", "where the spheres are rasterised: 'cpu', or 'auto' (the library's choice: "
                                   "WebGPU when it finds an adapter)", type=str, choices=("cpu", "auto")),
        "parallel": Param(False, "the library's own threads (the suite runs one process per cell)", type=bool),
    }

    def _cloud(self, U, S, cap, res, nls, seed):
        """The library's first step, for the outside (φ ≥ 0) and the inside spheres separately."""
        from gpytoolbox.reach_for_the_arcs import _sdf_to_point_cloud

        cfg = self.config
        parts = []
        for ids in (np.flatnonzero(S >= 0), np.flatnonzero(S < 0)):
            if not len(ids):
                continue
            P, N, f = _sdf_to_point_cloud(U[ids], S[ids], rng_seed=seed(), rasterization_resolution=res,
                                          n_local_searches=nls, local_search_iters=cfg["local_search_iters"],
                                          batch_size=cfg["batch_size"], num_rasterization_spheres=0,
                                          tol=cfg["tol"], clamp_value=cap, force_cpu=cfg["rasterizer"] == "cpu",
                                          parallel=cfg["parallel"], verbose=False)
            if P.size:
                parts.append((P, N, ids[f]))
        if not parts:
            return np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0, np.int64)
        return tuple(np.concatenate([p[i] for p in parts]) for i in range(3))

    def _psr(self, P, N, depth):
        from gpytoolbox.point_cloud_to_mesh import point_cloud_to_mesh

        return point_cloud_to_mesh(P, N, psr_screening_weight=self.config["screening_weight"], psr_depth=depth,
                                   psr_outer_boundary_type="Neumann", verbose=False)

    def _fine_tune(self, U, S, cap, P, N, f, nls, seed, depth_of, keep):
        """The library's fine-tuning loop (``_fine_tune_point_cloud``) with the adapter's PSR depth; ``keep``
        drops the points outside the grid box before each solve.  Returns (P, N, f, points dropped)."""
        from gpytoolbox.reach_for_the_arcs import _fine_tune_point_cloud_iteration

        cfg = self.config
        rng = np.random.default_rng(seed=seed())
        n_sdf, dropped = len(U), 0
        for _ in range(cfg["fine_tune_iters"]):
            bs = cfg["batch_size"]
            if 0 < bs < n_sdf:
                batch = rng.choice(n_sdf, bs)
            else:
                batch = np.arange(n_sdf)
                rng.shuffle(batch)
            P, N, f, k = keep(P, N, f)
            dropped += k
            if len(P) < 2:
                break
            V, F = self._psr(P, N, depth_of(P))
            if V.size == 0:
                break
            P, N, f = _fine_tune_point_cloud_iteration(
                U, S, V, F, P, N, f, batch, cfg["max_points_per_sphere"], rng.integers(0, np.iinfo(np.int32).max),
                nls, cfg["local_search_iters"], cfg["local_search_t"], cfg["tol"], cap, cfg["parallel"], False)
        P, N, f, k = keep(P, N, f)
        return P, N, f, dropped + k

    def _radii(self, volume: Volume) -> tuple[np.ndarray | None, dict]:
        """The sphere radii's source (``redistance``): None = φ itself, else sign(φ) · the distance to φ's
        zero set, in the samples' C order; and the reading for ``info``."""
        mode = self.config["redistance"]
        reading = distance_reading(volume) if mode == "auto" else {}
        info = {f"distance_{k}": v for k, v in reading.items()}
        if mode == "yes" or (mode == "auto" and not reading["is_distance"]):
            U = volume.origin + np.indices(volume.shape).reshape(3, -1).T * volume.spacing
            d = zero_set_distance(volume, U, self.name)
            return np.sign(volume.values.reshape(-1)) * d, {"redistanced": True, **info}
        return None, {"redistanced": False, **info}

    def reconstruct(self, volume: Volume) -> Reconstruction:
        check_volume(volume, self.name)
        cfg = self.config
        values, radii_info = self._radii(volume)
        U, S, cap = clamped_samples(volume, cfg["clamp"], values)
        # the library's own normalisation: the samples' box to [0, 1]³ (its steps assert it), one scale
        trans = U.min(0)
        U = U - trans
        scale = float(U.max())
        U, S, cap = U / scale, S / scale, cap / scale
        n_sdf = len(U)
        if not cfg["rasterization"]:
            res = 64 * math.ceil(n_sdf ** (1 / 3) / 16)
        else:
            res = max(2, math.ceil(cfg["rasterization"] * scale / volume.h))
        res += res % 2                                        # the library makes it even itself
        nls = math.ceil(2 * n_sdf ** (1 / 3))                 # the library's n_local_searches
        h01 = volume.h / scale
        hi01 = U.max(0)

        def keep(P, N, f):
            # a point outside the grid box is no tangency point of the surface (which is inside: check_volume);
            # it comes from a sphere reaching past the samples, where none excludes it
            m = inside_box(P, 0.0, hi01, 0.5 * h01)
            return (P, N, f, 0) if m.all() else (P[m], N[m], f[m], int((~m).sum()))

        depth_of = (lambda P: cfg["psr_depth"]) if cfg["psr_depth"] else (lambda P: auto_psr_depth(P, h01))
        rng = np.random.default_rng(seed=cfg["rng_seed"])
        seed = lambda: rng.integers(0, np.iinfo(np.int32).max)        # noqa: E731  (the library's seed chain)
        times = {}
        try:
            t0 = time.perf_counter()
            P, N, f = self._cloud(U, S, cap, res, nls, seed)
            times["time_cloud_s"], n_cloud, t1 = time.perf_counter() - t0, len(P), time.perf_counter()
            if len(P) == 0:
                raise ReconstructionFailed(f"method {self.name!r}: no sphere got a tangency point "
                                           f"(rasterization = {res} cells across the grid box)")
            P, N, f, dropped = self._fine_tune(U, S, cap, P, N, f, nls, seed, depth_of, keep)
            times["time_fine_tune_s"], t2 = time.perf_counter() - t1, time.perf_counter()
            if len(P) < 2:
                raise ReconstructionFailed(f"method {self.name!r}: fine-tuning left {len(P)} points")
            depth = depth_of(P)
            V, F = self._psr(P, N, depth)
            times["time_psr_s"] = time.perf_counter() - t2
        except (AssertionError, ValueError, RuntimeError, MemoryError) as exc:
            raise ReconstructionFailed(f"method {self.name!r}: the library failed ({type(exc).__name__}: "
                                       f"{exc})") from None
        if V.size == 0 or F.size == 0:
            raise ReconstructionFailed(f"method {self.name!r}: screened Poisson returned no surface from "
                                       f"{len(P)} points")
        mesh = trimesh.Trimesh(np.asarray(V, np.float64) * scale + trans, np.asarray(F, np.int64), process=False)
        orient_outward(mesh)
        facts = mesh_facts(mesh)
        if not facts["watertight"]:
            raise ReconstructionFailed(f"method {self.name!r}: screened Poisson returned an open surface "
                                       f"({facts['faces']} faces, psr_depth = {depth})")
        info = {"iterations": int(cfg["fine_tune_iters"]), "stop_reason": "converged",
                "stop_message": f"{cfg['fine_tune_iters']} fine-tuning iterations (a fixed count)",
                "cloud_points": int(n_cloud), "fine_tuned_points": int(len(P)), "psr_depth": int(depth),
                "rasterization_resolution": int(res), "clamp_h": float(cfg["clamp"]),
                "points_outside_box": int(dropped), **radii_info, **times}
        info.update({f"mesh_{k}": v for k, v in facts.items()})
        return Reconstruction(mesh, info)
