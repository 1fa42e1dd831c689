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
  edge length; or the mesh grew past ``max_vertices``, the adapter's guard against a crumpling flow whose
  steps get ever slower; ``stop_message`` says which).

Units.  The library's defaults are absolute lengths tuned for shapes in [-1, 1]³ (tangency tolerance 0.01,
first target edge length 0.2).  The adapter maps the grid's box to [-1, 1]³ (centre at 0, one uniform
scale: half the longest side → 1; SDF values scaled by the same factor), runs there and maps the mesh back,
so the method behaves the same on a grid of any size.  ``edge_length`` is in grid spacings h (default 2 h,
which is the library's own default, twice the mean sample spacing).

Samples.  ``samples = "all"`` (default) gives every grid sample, the paper's setting: ≈ N³ spheres, of
which each step uses ``batch_size`` random ones plus every inside one (the library's batching).  ``"band"``
gives every inside sample (φ < 0) and the outside samples with φ < ``band`` · h: cheaper steps (bunny,
N = 48, loaded machine: 20 s instead of 45 s, Hausdorff 0.81 h either way), but fragile — without the far
outside spheres nothing stops the surface from crumpling outwards, and at N = 96 with band = 4 the bunny's
and the cortex's meshes grow without bound (75,000 vertices, 8 h on the cortex; band = 8 recovers the bunny).
A two-sided band |φ| < band·h is worse still (the bunny crumples at N = 48).  The initial icosphere is put
close around the shape: centred on the bounding box of the inside samples, radius half that box's diagonal
plus h.

Noise.  The library stops when every sphere is tangent within ``tol``, or after 100 steps without progress
at the finest edge length.  On a noisy volume the first never happens, so every noisy cell pays the 100
stalled steps: on the paper grid (N = 96, loaded 2-core machine) the clean cells take 2–23 s, the noisy
ones 13–87 s.  ``tol = 0.02`` would cut the noisy sphere from 66–124 s to 6 s, but stops the clean sphere
after 2 steps off the zero set (median |φ| 0.57 h at the vertices: invalid), so the grids keep 0.01.

Limits (the library's docstring and the paper): the result has the initial mesh's topology (genus 0); deep,
narrow concavities (cortical sulci) are reached slowly and may self-intersect.
"""

from __future__ import annotations

import time

import numpy as np
import trimesh

from phantoms import InputError, Volume

from .base import Method, Param, Reconstruction, ReconstructionFailed, check_volume
from .marching_cubes import mesh_facts, orient_outward

__all__ = ["ReachForTheSpheres", "grid_samples"]


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


class ReachForTheSpheres(Method):
    name = "reach_for_the_spheres"
    description = ("Reach for the Spheres (Sellán, Batty & Stein 2023, gpytoolbox): an icosphere flowed to "
                   "tangency with the samples' spheres, remeshed; genus 0")
    params = {
        "init_subdivisions": Param(2, "the initial mesh: an icosphere with this many subdivisions (2 = 162 "
                                      "vertices, the library's example)", type=int, min=0, max=6),
        "init_radius": Param(1.0, "the icosphere's radius as a multiple of the sphere around the inside "
                                  "samples' bounding box (centred on it; 1 = that circumscribed sphere plus one h)",
                             type=float, min=0.1, max=3.0),
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
        "max_vertices": Param(None, "stop (stop_reason 'diverged') when the mesh has more vertices than this; "
                                    "default: the number of grid samples with |φ| < h (≈ 2× a marching-cubes mesh, "
                                    "≈ 4× what 2 h edges need) — the flow crumples on some shapes (the cortex at "
                                    "N = 96 grows past 30,000 vertices in 85 steps, each slower)", type=int,
                            min=4, max=10**8),
        "batch_size": Param(20000, "samples drawn at random per step (plus every inside sample), the "
                                   "library's batching; 0 = all every step", type=int, min=0, max=10**8),
    }

    def reconstruct(self, volume: Volume) -> Reconstruction:
        import gpytoolbox as gpy

        check_volume(volume, self.name)
        cfg = self.config
        U, S = grid_samples(volume, cfg["samples"], cfg["band"])
        if len(U) < 10:
            raise InputError(f"method {self.name!r}: only {len(U)} grid samples in the band; widen 'band'")
        # map the grid box to [-1, 1]^3 (uniform scale) where the library's defaults are meant to work
        lo = volume.origin
        hi = volume.origin + (np.asarray(volume.shape) - 1) * volume.spacing
        centre, scale = 0.5 * (lo + hi), 0.5 * float((hi - lo).max())
        Un, Sn = (U - centre) / scale, S / scale
        V0, F0 = gpy.icosphere(cfg["init_subdivisions"])
        inside = np.argwhere(volume.values < 0)
        in_lo, in_hi = (volume.origin + inside.min(0) * volume.spacing, volume.origin + inside.max(0) * volume.spacing)
        radius = cfg["init_radius"] * (0.5 * float(np.linalg.norm(in_hi - in_lo)) + volume.h)
        V0 = (V0 * radius + 0.5 * (in_lo + in_hi) - centre) / scale
        min_h = cfg["edge_length"] * volume.h / scale
        state = gpy.ReachForTheSpheresState(V=V0, F=F0, U=Un, S=Sn, sdf=None, h=max(0.2, min_h), min_h=min_h)
        t0 = time.perf_counter()
        cap = cfg["max_vertices"] or max(int((np.abs(volume.values) < volume.h).sum()), 4 * len(V0))
        done = crumpled = False
        try:
            while not (done or crumpled):
                done = gpy.reach_for_the_spheres_iteration(
                    state, max_iter=cfg["max_iter"], tol=cfg["tol"], batch_size=cfg["batch_size"])
                crumpled = len(state.V) > cap
        except (ValueError, RuntimeError, np.linalg.LinAlgError) as exc:
            raise ReconstructionFailed(f"method {self.name!r}: the flow failed at iteration {state.its} ({exc})")
        wall = time.perf_counter() - t0
        its = int(state.its)
        if crumpled:
            stop, msg = "diverged", (f"the mesh grew past max_vertices = {cap} ({len(state.V)} vertices): the flow "
                                     "crumples; the current mesh is returned")
        elif its >= cfg["max_iter"]:
            stop, msg = "max_iter", f"the iteration cap {cfg['max_iter']} was reached"
        elif state.V.shape == state.V_last_converged.shape and np.array_equal(state.V, state.V_last_converged):
            stop, msg = "diverged", ("a flow singularity (NaN, zero-area face or non-manifold edge): the last "
                                     "mesh converged at a coarser edge length was returned")
        else:
            stop, msg = "converged", "every sphere tangent within tol, or no progress at the finest edge length"
        V = np.asarray(state.V, dtype=np.float64) * scale + centre
        mesh = trimesh.Trimesh(V, np.asarray(state.F, dtype=np.int64), process=False)
        orient_outward(mesh)
        info = {"iterations": its, "stop_reason": stop, "stop_message": msg, "samples_used": int(len(U)),
                "final_edge_target_h": float(state.h) * scale / volume.h, "wall_flow_s": wall}
        info.update({f"mesh_{k}": v for k, v in mesh_facts(mesh).items()})
        return Reconstruction(mesh, info)
