"""Peer: Reach for the Spheres (Sellán, Batty & Stein, "Reach For the Spheres: Tangency-Aware Surface
Reconstruction of SDFs", SIGGRAPH Asia 2023) — ``gpytoolbox.reach_for_the_spheres``.

Each grid sample u with value φ(u) defines a sphere of radius |φ(u)| that the surface must be tangent to (and
not cross).  An initial mesh (an icosphere around the inside samples) is flowed towards tangency with every
sphere, with Botsch–Kobbelt remeshing inside the loop; the target edge length is halved whenever progress
stalls, down to a minimum.  It is the direct peer of the suite's shape-gradient method: a flow of a genus-0
surface driven by the SDF samples.

The adapter runs gpytoolbox's own iteration (``reach_for_the_spheres_iteration``) so it can report

* ``iterations`` – flow steps taken;
* ``stop_reason`` – ``converged`` (every sphere tangent within the tolerance, or no progress at the
  finest edge length), ``max_iter`` (the cap was hit) or ``diverged`` (a flow singularity — NaN, a
  zero-area face or a non-manifold edge: the library returns the last mesh it had converged at a coarser
  edge length; ``stop_message`` says so);
* ``redistanced``, ``distance_ratio``, ``distance_spread`` – the radii test below.

Units.  The library's defaults are absolute lengths tuned for shapes in [-1, 1]³ (tangency tolerance 0.01,
first target edge length 0.2).  The adapter maps the grid's box to [-1, 1]³ (centre at 0, one uniform
scale: half the longest side → 1; SDF values scaled by the same factor), runs there and maps the mesh back,
so the method behaves the same on a grid of any size.  ``edge_length`` is in grid spacings h (default 2 h,
which is the library's own default, twice the mean sample spacing).

Radii (``redistance``).  The method needs |φ| to be the distance to the surface: a sphere smaller than the
distance cannot be made tangent, one larger crosses the surface.  The suite's volumes are level sets, not
always distances (the paper's polynomial variant: |φ| ≈ 2 × the distance near the sphere; a normalised implicit
of the ellipsoid (1, 0.7, 0.5), as in ``check-method``: 0.5–1 ×), and given such a field the flow crumples or
stops off the zero set.  So the adapter reads |φ| / d, d = the distance to φ's zero set (its marching-cubes
triangulation, exact point-to-triangle distance, gpytoolbox), over the samples 2–6 h from it: an exact SDF reads
about 1, c × an SDF reads c.  ``redistance = "auto"`` (default) keeps |φ| when the median ratio is within 15 % of
1 — the library then sees exactly the grid it is given — and otherwise gives it sign(φ) · d (the zero set
unchanged).  A field so noisy that marching cubes breaks its zero set into bubbles (the ratio's 90th/10th
percentiles more than 2× apart) is given as it is.  ``"yes"``/``"no"`` force either.

Start.  An icosphere (``init_subdivisions``) centred on the bounding box of the inside samples, through its
corners (radius ``init_radius`` × half its diagonal, + h), squeezed per axis to end one h inside the grid box:
in a grid too flat for it (the torus case) the sphere would stick out where no sample's sphere holds the
surface; in a cubic grid it fits as it is.

Divergence.  A flow that crumples grows its mesh and leaves the samples, each step slower.  The run fails with
``methods.ReconstructionFailed`` — never a crumpled mesh returned as a result — when the mesh has more than
``max_vertices`` vertices (default: the samples with |φ| < h, ≈ 4× what 2 h edges need) or a vertex is more than
2 h outside the grid box; the message gives the iteration, the reason and the target's topology read at grid
resolution (the suite's ``target_topology``): the flow keeps the start's genus 0, so a torus (χ = 0) cannot be
reached.  There is no automatic restart with "safer" settings because none was found: a coarser edge_length
converges on the N = 96 cortex, but no better.

Samples.  ``samples = "all"`` (default) gives every grid sample, the paper's setting: ≈ N³ spheres, of which
each step uses ``batch_size`` random ones plus every inside one (the library's batching).  ``"band"`` gives every
inside sample (φ < 0) and the outside samples with φ < ``band`` · h: cheaper steps, but fragile — without the far
outside spheres nothing stops the surface from crumpling outwards (a two-sided band |φ| < band·h is worse still).

Noise and patience.  The library stops when every sphere is tangent within ``tol``, or after 100 steps without
progress at the finest edge length.  On a noisy volume the first never happens, so every noisy cell pays the
100 stalled steps, over which the distances barely change.  ``patience`` stops sooner, at somewhat worse
distances on the hard shapes, so the grids keep the library's 100; they keep ``tol`` = 0.01 too (a looser one
stops the clean sphere off the zero set).

Limits (the library's docstring and the paper): the result has the initial mesh's topology (genus 0); deep,
narrow concavities (cortical sulci) are reached slowly and may self-intersect.
"""

from __future__ import annotations

import time

import numpy as np
import trimesh

from geometry.mesh import mesh_facts
from phantoms import InputError, Volume

from .base import Method, check_volume
from .contract import Reconstruction, ReconstructionFailed
from .params import Param
from .cost_model import PowerLaw
from .isosurface import marching_cubes_mesh, orient_outward

__all__ = ["ReachForTheSpheres", "grid_samples", "distance_reading", "zero_set_distance", "initial_ellipsoid"]

#: the distance test: |φ| is read as a distance when the median of |φ| / (distance to the zero set) over the
#: samples 2–6 h from the surface is within 15 % of 1 ...
DISTANCE_TOL = 0.15
#: ... and a field whose ratio spreads more than this (90th / 10th percentile) is too noisy to judge
DISTANCE_SPREAD = 2.0


def grid_samples(volume: Volume, samples: str, band: float) -> tuple[np.ndarray, np.ndarray]:
    """World positions (K, 3) and values (K,) of the grid samples the method gets: 'all', or 'band' (every
    inside sample and the outside ones with φ < band·h)."""
    v = volume.values
    if samples == "all":
        mask = np.ones(v.shape, dtype=bool)
    else:
        mask = v < band * volume.h
    idx = np.argwhere(mask)
    return volume.origin + idx * volume.spacing, v[mask]


def zero_set_distance(volume: Volume, points: np.ndarray, name: str = "reach_for_the_spheres") -> np.ndarray:
    """Unsigned distance from ``points`` (world, (K, 3)) to φ's zero set, triangulated by marching cubes
    (the zero set of the trilinear interpolant along the grid edges; within O(h²) of a smooth surface)."""
    import gpytoolbox as gpy

    mc = marching_cubes_mesh(volume, name=name)
    d2 = gpy.squared_distance(np.asarray(points, float), np.asarray(mc.vertices, float),
                              np.asarray(mc.faces, np.int64), use_cpp=True, use_aabb=True)[0]
    return np.sqrt(d2)


def distance_reading(volume: Volume) -> dict:
    """Is |φ| a distance?  ``{"ratio": median, "spread": p90 / p10, "is_distance": bool}`` of |φ| / d over the
    grid samples 2–6 h from the zero set, d = :func:`zero_set_distance`.  An exact signed distance reads
    0.99–1.0 (bunny and cortex 0.96–0.99), one with paper-SNR noise 1.02–1.03; the paper's polynomial sphere
    2.1, an ellipsoid's normalised implicit 0.74.  A field too noisy for marching cubes to give a surface
    (spread > 2, e.g. SNR 20 dB: 1.3–10) counts as a distance: it is given to the method as it is."""
    a = np.abs(volume.values)
    band = (a > 2 * volume.h) & (a < 6 * volume.h)
    if band.sum() < 10:
        return {"ratio": float("nan"), "spread": float("nan"), "is_distance": True}
    pts = volume.origin + np.argwhere(band) * volume.spacing
    r = a[band] / np.maximum(zero_set_distance(volume, pts), 1e-12 * volume.h)
    p10, p50, p90 = np.percentile(r, [10, 50, 90])
    spread = float(p90 / max(p10, 1e-12))
    ok = abs(p50 - 1.0) <= DISTANCE_TOL or spread > DISTANCE_SPREAD
    return {"ratio": float(p50), "spread": spread, "is_distance": bool(ok)}


def initial_ellipsoid(volume: Volume, subdivisions: int, size: float) -> tuple[np.ndarray, np.ndarray]:
    """The start: an icosphere through the corners of the inside samples' bounding box (radius ``size`` × half
    its diagonal, plus h), centred on that box — then squeezed, per axis, to end one grid step inside the grid
    box, where the samples' spheres can still push it (an ellipsoid only in grids too flat for the sphere)."""
    import gpytoolbox as gpy

    V0, F0 = gpy.icosphere(subdivisions)
    inside = np.argwhere(volume.values < 0)
    lo, hi = volume.origin, volume.origin + (np.asarray(volume.shape) - 1) * volume.spacing
    in_lo, in_hi = volume.origin + inside.min(0) * volume.spacing, volume.origin + inside.max(0) * volume.spacing
    centre = 0.5 * (in_lo + in_hi)
    radius = size * 0.5 * float(np.linalg.norm(in_hi - in_lo)) + volume.h
    room = np.minimum(hi - centre, centre - lo) - volume.spacing
    semi = np.maximum(np.minimum(radius, room), volume.spacing)
    return V0 * semi + centre, F0


class ReachForTheSpheres(Method):
    name = "reach_for_the_spheres"
    imports = ("gpytoolbox",)
    description = ("Reach for the Spheres (Sellán, Batty & Stein 2023, gpytoolbox): an icosphere flowed to "
                   "tangency with the samples' spheres, remeshed; genus 0")
    params = {
        "init_subdivisions": Param(2, "the initial mesh: an icosphere with this many subdivisions (2 = 162 "
                                      "vertices, the library's example)", type=int, min=0, max=6),
        "init_radius": Param(1.0, "the icosphere's radius as a multiple of the sphere around the inside "
                                  "samples' bounding box (centred on it; 1 = that circumscribed sphere plus one h), "
                                  "squeezed per axis to one h inside the grid box", type=float, min=0.1, max=3.0),
        "edge_length": Param(2.0, "the finest target edge length, in grid spacings h (the library's default "
                                  "is twice the mean sample spacing, i.e. 2 h)", type=float, min=0.25, max=20.0),
        "max_iter": Param(2000, "iteration cap (the library's default is 20000)", type=int, min=1,
                          max=100000),
        "tol": Param(0.01, "tangency tolerance, in units of the grid box's half-size (the library's 0.01 for "
                           "shapes in [-1, 1]³)", type=float, min=1e-5, max=0.5),
        "samples": Param("all", "which grid samples it gets: 'all' (the paper; cost grows with N³) or "
                                 "'band' (every inside sample and the outside ones with φ < band·h)", type=str,
                         choices=("all", "band")),
        "band": Param(4.0, "outside width of the band in grid spacings h (with samples = 'band')", type=float,
                      min=1.0, max=100.0),
        "redistance": Param("auto", "the sphere radii: 'auto' = |φ| when it reads as a distance (see the module "
                                    "docstring), else the distance to φ's zero set; 'yes' = always that distance; "
                                    "'no' = always |φ|", type=str, choices=("auto", "yes", "no")),
        "max_vertices": Param(None, "the divergence guard: the run fails (ReconstructionFailed) when the mesh has "
                                    "more vertices than this; default: the number of grid samples with |φ| < h "
                                    "(≈ 2× a marching-cubes mesh, ≈ 4× what 2 h edges need)", type=int,
                              min=4, max=10**8),
        "batch_size": Param(20000, "samples drawn at random per step (plus every inside sample), the "
                                   "library's batching; 0 = all every step", type=int, min=0, max=10**8),
        "patience": Param(100, "stop after this many steps without progress at the finest edge length (the "
                               "library's fixed rule is 100; fewer stops noisy volumes sooner, see the module "
                               "docstring)", type=int, min=1, max=100),
    }

    #: the cost model: CPU seconds per flow step, fitted to the runs of the clean
    #: sphere and bunny at N = 32–64 and the noisy sphere at N = 64–192; the flow takes ≈ patience + 30 steps
    COST = PowerLaw(a=0.099, p=3.5, q=0.0, floor=0.0933)
    STEPS_OVER_PATIENCE = 30

    def estimate_seconds(self, shape, n_crossing_cells: int | None = None) -> float | None:
        """Steps × seconds per step, the steps those of a surface that is not tangent to every sphere (a noisy
        volume, a real shape: the flow stops about :attr:`STEPS_OVER_PATIENCE` steps after ``patience`` stalled
        ones) — the clean sphere and ellipsoid converge by tangency in ≈ 15 steps, several times sooner.  None
        with ``samples = 'band'`` or a ``batch_size`` other than its default, which were not measured."""
        if self.config["samples"] != "all" or self.config["batch_size"] != self.params["batch_size"].default:
            return None
        steps = self.config["patience"] + self.STEPS_OVER_PATIENCE
        return steps * self.COST.seconds(shape, n_crossing_cells)

    def _radii(self, volume: Volume, S: np.ndarray, U: np.ndarray) -> tuple[np.ndarray, dict]:
        mode = self.config["redistance"]
        reading = distance_reading(volume) if mode == "auto" else {}
        if mode == "yes" or (mode == "auto" and not reading["is_distance"]):
            S = np.sign(S) * zero_set_distance(volume, U, self.name)
            return S, {"redistanced": True, **{f"distance_{k}": v for k, v in reading.items()}}
        return S, {"redistanced": False, **{f"distance_{k}": v for k, v in reading.items()}}

    def _diverged(self, volume: Volume, its: int, why: str, radii: dict) -> ReconstructionFailed:
        from .shape_gradient.start import target_topology

        topo = target_topology(volume)
        note = topo["message"] if not topo["compatible"] else "the region φ < 0 reads as one genus-0 solid"
        ratio = radii.get("distance_ratio")
        read = f"|φ| reads as {ratio:.2f} × the distance to its zero set" if ratio is not None else "not read"
        radii_text = "the distance to φ's zero set" if radii["redistanced"] else "|φ|"
        return ReconstructionFailed(f"method {self.name!r}: the flow diverged at iteration {its}: {why}; {note}; "
                                    f"sphere radii: {radii_text} ({read})")

    def reconstruct(self, volume: Volume) -> Reconstruction:
        import gpytoolbox as gpy

        check_volume(volume, self.name)
        cfg = self.config
        U, S = grid_samples(volume, cfg["samples"], cfg["band"])
        if len(U) < 10:
            raise InputError(f"method {self.name!r}: only {len(U)} grid samples in the band; widen 'band'")
        S, radii_info = self._radii(volume, S, U)
        # map the grid box to [-1, 1]^3 (uniform scale) where the library's defaults are meant to work
        lo = volume.origin
        hi = volume.origin + (np.asarray(volume.shape) - 1) * volume.spacing
        centre, scale = 0.5 * (lo + hi), 0.5 * float((hi - lo).max())
        V0, F0 = initial_ellipsoid(volume, cfg["init_subdivisions"], cfg["init_radius"])
        V0 = (V0 - centre) / scale
        min_h = cfg["edge_length"] * volume.h / scale
        state = gpy.ReachForTheSpheresState(V=V0, F=F0, U=(U - centre) / scale, S=S / scale, sdf=None,
                                            h=max(0.2, min_h), min_h=min_h)
        cap = cfg["max_vertices"] or max(int((np.abs(volume.values) < volume.h).sum()), 4 * len(V0))
        box_lo, box_hi = (lo - centre - 2 * volume.h) / scale, (hi - centre + 2 * volume.h) / scale
        t0, done, stalled = time.perf_counter(), False, False
        try:
            while not done:
                done = gpy.reach_for_the_spheres_iteration(
                    state, max_iter=cfg["max_iter"], tol=cfg["tol"], batch_size=cfg["batch_size"])
                stalled = state.h <= state.min_h and state.convergence_counter > cfg["patience"]
                done = done or stalled
                if len(state.V) > cap:
                    raise self._diverged(volume, state.its, f"the mesh grew past max_vertices = {cap} "
                                         f"({len(state.V)} vertices): it crumples", radii_info)
                out = ((state.V < box_lo) | (state.V > box_hi)).any(1).sum()
                if out:
                    raise self._diverged(volume, state.its, f"{out} vertex(es) left the grid box by "
                                         "more than 2 h, where no sample's sphere holds them", radii_info)
        except (ValueError, RuntimeError, np.linalg.LinAlgError) as exc:
            if isinstance(exc, ReconstructionFailed):
                raise
            raise ReconstructionFailed(f"method {self.name!r}: the flow failed at iteration {state.its} ({exc})")
        wall = time.perf_counter() - t0
        its = int(state.its)
        if stalled and its < cfg["max_iter"]:
            stop, msg = "converged", f"no progress for {cfg['patience']} steps at the finest edge length"
        elif its >= cfg["max_iter"]:
            stop, msg = "max_iter", f"the iteration cap {cfg['max_iter']} was reached"
        elif state.V.shape == state.V_last_converged.shape and np.array_equal(state.V, state.V_last_converged):
            stop, msg = "diverged", ("a flow singularity (NaN, zero-area face or non-manifold edge): the last "
                                     "mesh converged at a coarser edge length was returned")
        else:
            stop, msg = "converged", "every sphere tangent within tol"
        V = np.asarray(state.V, dtype=np.float64) * scale + centre
        mesh = trimesh.Trimesh(V, np.asarray(state.F, dtype=np.int64), process=False)
        orient_outward(mesh)
        info = {"iterations": its, "stop_reason": stop, "stop_message": msg, "samples_used": int(len(U)),
                "final_edge_target_h": float(state.h) * scale / volume.h, "wall_flow_s": wall, **radii_info}
        info.update({f"mesh_{k}": v for k, v in mesh_facts(mesh).items()})
        return Reconstruction(mesh, info)
