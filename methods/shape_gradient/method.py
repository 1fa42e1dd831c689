"""The Method: parameters, presets, and ``reconstruct`` = prepare the flow, run it, pack the result."""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from geometry.operators import MeshOperators
from geometry.sphere import PAPER_SPHERE_RADIUS, PAPER_SPHERE_VERTICES
from phantoms import InputError, Volume

from ..base import Method, check_volume
from ..contract import Reconstruction, ReconstructionFailed
from ..params import Param
from .field import CLEAN_NOISE_VOXELS, estimate_noise, noise_after_smoothing, smoothed_field, start_smoothing
from .carved_start import carved_surface
from .choose import data_errors, lacks_a_part, pick, rms, start_candidates
from .flow import ShapeGradientFlow
from .settings import FlowSettings, edge_length_voxels
from .start import denoised_topology, initial_surface, parse_snapshots, target_topology, topology_gap

__all__ = ["ShapeGradient", "PRESETS"]

#: values a preset imposes on every parameter it names (parameters passed explicitly win)
PRESETS: dict[str, dict[str, Any]] = {
    "none": {},
    # the paper's algorithm as printed: no divergence term, plain (unpreconditioned) descent, the paper's
    # paraboloid fit, no relaxation, no pre-smoothing.  The step stays capped + backtracked: taken literally
    # (step='fixed', tau=0.1) the first step throws Γ0 past the target and the mesh tangles.
    # the paper runs a fixed number of iterations (100; 150 on the fused spheres) at α = 5, β = 1: no stop on
    # a tolerance, so its tables' rows 50 and 100 are reached unless the line search runs out of steps.
    "paper": {"gradient": "paper", "precondition": "none", "relax": 0.0, "presmooth": 0.0,
              "curvature": "paper", "polish": "off", "init": "sphere", "remesh_every": 0, "guard": False,
              "extend_tips": False, "beta": 1.0,
              "projection": "off", "max_iter": 100, "tol": 0.0, "move_tol": 0.0, "l2_fallback": False,
              "reach_samples": False},
    # the paper's experiment (the same Γ0, β, iteration count and fixed connectivity) run by the suite's
    # corrected flow: the full gradient, H¹ preconditioning, capped backtracking, relaxation, the guard and,
    # on clean volumes, the crease polish and final projection — as they were when its rows were measured: no
    # plain-gradient step past the line-search floor and no reach to the samples, which came later (its rows stay
    # comparable)
    "paper+fixes": {"init": "sphere", "remesh_every": 0, "beta": 1.0,
                    "max_iter": 100, "tol": 0.0, "move_tol": 0.0, "l2_fallback": False,
                    "reach_samples": False},
}

_AUTO_PRESMOOTH_SIGMA = 1.0   # presmooth='auto': σ (voxels) used on noisy volumes (field.CLEAN_NOISE_VOXELS)
_PINHOLE_FLOOR_VOXELS = 0.25  # close_pinholes: a pinhole's sample is below max(noise std of the start's values, this)


def _auto_or_number(key: str, value: Any, hi: float) -> "float | str":
    """'auto' or a number in [0, hi] (a parameter whose default depends on the volume)."""
    if isinstance(value, str) and value.strip().lower() == "auto":
        return "auto"
    try:
        v = float(value)
    except (TypeError, ValueError):
        v = -1.0
    if not (np.isfinite(v) and 0.0 <= v <= hi):
        raise InputError(f"method 'shape_gradient', parameter '{key}': expected 'auto' or a number in [0, {hi:g}]; "
                         f"got {value!r}")
    return v


def _edge_length_voxels(cfg: dict, x: np.ndarray, faces: np.ndarray, h: float, facts: dict) -> float:
    """The remeshing's edge length (voxels): ``edge_length``, or longer where the surface is so large that
    triangles of that size would exceed ``max_faces`` — the mesh's size follows the surface's area, not the
    grid's (a label map at its native resolution: millions of faces for a smooth organ).  The start's area
    is read before it is remeshed (a staircase overestimates it a little: the cap errs on the coarse side)."""
    edge = float(cfg["edge_length"])
    cap = cfg["max_faces"]
    if cap <= 0 or cfg["remesh_every"] <= 0:
        return edge
    tri = x[faces]
    area = 0.5 * float(np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1).sum())
    # an equilateral triangle of edge e has area √3/4 e²
    needed = float(np.sqrt(4.0 * area / (np.sqrt(3.0) * cap))) / h
    if needed > edge:
        facts["edge_length_voxels_for_max_faces"] = round(needed, 4)
        return needed
    return edge


def _refuse_far_topology(topology: dict, max_gap: int) -> None:
    """Raise when the (denoised) region φ < 0 is farther than ``max_gap`` from one genus-0 solid."""
    gap = topology_gap(topology)
    if gap > max_gap:
        best = min(topology["readings"], key=lambda r: r["components"] - 1 + abs(r["euler_solid"] - 1))
        raise InputError(
            f"method 'shape_gradient': the region φ < 0 is far from one genus-0 surface (at its most favourable "
            f"reading, level {best['level_voxels']:+g} voxel, {best['components']} component(s) with Euler "
            f"characteristic {best['euler_solid']}: a gap of {gap} > max_topology_gap = {max_gap}); the method "
            "evolves one genus-0 surface — use a method that follows the level set (marching_cubes, flying_edges) "
            "or raise max_topology_gap")


class ShapeGradient(Method):
    name = "shape_gradient"
    imports = ("scipy.ndimage", "skimage.measure", "skimage.segmentation", "pymeshlab", "gpytoolbox", "pyamg")
    description = ("the paper's shape-gradient descent of E = ∫ αφ² + β|∇_Γφ|² from a genus-0 surface grown "
                   "from the volume (full gradient, H¹ preconditioning, capped backtracking)")
    params = {
        "alpha": Param(5.0, "weight α of the data term φ² (pulls Γ onto φ = 0)", float, min=0.0),
        "beta": Param("auto", "weight β of the alignment term |∇_Γφ|² (wants n ∥ ∇φ); 0 = the paper's ablation; "
                      "'auto' = 1 on clean volumes, 0.01 on noisy ones (estimated noise ≥ 0.05 voxel), where ∇φ is "
                      "read from the pre-smoothed volume: in it voxel-thin parts (the bunny's ears) have merged, and "
                      "β = 1 pulls them off", object),
        "gradient": Param("full", "'full': the true shape gradient of E (docs/METHOD.md, with the divergence term); "
                          "'paper': the paper's eq. (dJ_finel) without it", str, choices=("full", "paper")),
        "step": Param("capped", "'capped': largest move capped at max_move voxels, then halved until E "
                      "decreases (Armijo); 'fixed': x ← x − τVn with τ = tau, unguarded (the paper's loop)",
                      str, choices=("capped", "fixed")),
        "max_move": Param(1.0, "step cap: the largest vertex move per iteration, in voxels (step='capped')",
                          float, min=1e-3, max=10.0),
        "tau": Param(0.1, "the constant step τ of step='fixed' (world units per unit of G)", float, min=0.0),
        "precondition": Param("h1", "'h1': Sobolev velocity V = (M + sK)⁻¹MG (M lumped areas, K cotangent "
                              "stiffness; Jacobi-preconditioned CG); 'none': V = G", str, choices=("h1", "none")),
        "s": Param(18.0, "H¹ smoothing weight s in voxels² (s·h² world units²; precondition='h1'); 18 is "
                   "0.05 world units² at the paper's N = 96", float, min=0.0),
        "solver": Param("auto", "how the H¹ system is solved: 'direct' = sparse LU of M + sK refreshed every 5 "
                        "iterations and at every remesh; 'amg' = CG preconditioned by a multigrid hierarchy "
                        "(pyamg) refreshed likewise; 'cg' = Jacobi-preconditioned CG every iteration (the "
                        "slowest for large s); 'auto' = cg while s ≤ 2 squared edge lengths (coarse meshes), "
                        "else direct up to 40,000 vertices, amg above", str,
                        choices=("auto", "direct", "amg", "cg")),
        "relax": Param(0.5, "tangential relaxation weight per iteration (move toward the 1-ring centroid "
                       "within the tangent plane); 0 = off", float, min=0.0, max=1.0),
        "presmooth": Param("auto", "Gaussian pre-smoothing of the volume the derivative grids ∇φ, D²φ are "
                           "computed from, σ in voxels (0 = off); 'auto': σ = 1 voxel when the estimated noise "
                           "(robust std of 4th differences) is at least 0.05 voxel, else off", object),
        "start_smooth": Param("auto", "Gaussian σ in voxels of the values the genus-0 start is grown from (0 = the "
                              "data's own values); 'auto' = the presmooth σ", object),
        "unbias": Param(True, "on noisy volumes, subtract the estimated noise variance from φ² in the data term: "
                        "trilinear φ of noise with std σ has E[φ²] = φ_true² + (2/3)³σ² on average, so ∫αφ² carries "
                        "(2/3)³ασ² × area, a mean-curvature flow that shrinks thin parts and tips",
                        bool),
        "polish": Param("auto", "crease polish of the final mesh (crease_polish): vertices next to sharp creases "
                        "of the level set are Newton-projected onto φ = 0 and one endpoint of every edge "
                        "crossing a crease is put on the crease; smooth regions are not touched. 'auto': on "
                        "for clean volumes (estimated noise below 0.05 voxel, i.e. no pre-smoothing), off on "
                        "noisy ones (projection onto the noisy level set would roughen the mesh)", str,
                        choices=("auto", "on", "off")),
        "polish_angle": Param(45.0, "crease polish: an edge crosses a crease when ∇φ at its two (projected) "
                              "endpoints differs by more than this many degrees", float, min=1.0, max=179.0),
        "polish_weight": Param(0.1, "crease polish: weight w of |y − p_i|² in the crease-point quadric "
                               "(relative to one plane; smaller = sharper but less stable)", float, min=1e-6),
        "curvature": Param("tilted", "paraboloid fit for H: 'tilted' adds linear terms (robust to a tilted "
                           "vertex normal), 'paper' is z = A/2x² + Bxy + C/2y² as printed", str,
                           choices=("tilted", "paper")),
        "max_iter": Param(300, "maximum number of iterations (paper: 100; 150 for the fused spheres)", int,
                          min=0, max=100000),
        "tol": Param(1e-4, "stop ('converged') when the relative energy change stays below tol for 3 "
                     "iterations (0 = off)", float, min=0.0),
        "move_tol": Param(0.01, "stop ('converged') when the largest normal move per iteration stays below "
                          "move_tol voxels for 3 iterations (0 = off): the surface has stopped and the energy "
                          "only changes by the tangential relaxation", float, min=0.0),
        "init": Param("genus0", "initial surface: 'genus0' = a genus-0 surface of the volume itself: the region "
                      "φ < 0 (pre-smoothed on noisy volumes) grown from its deepest sample keeping only simple points "
                      "(one component, no handle, no cavity: where sulcal banks or thin parts merge at grid "
                      "resolution the growth stops at the thinnest place), then marching cubes with its ambiguous "
                      "cells resolved to that topology (falls back to 'auto' if that fails); 'auto' = a sphere "
                      "enclosing the region φ < 0 (its bounding sphere plus 2 voxels) meshed at edge_length; "
                      "'sphere' = the Fibonacci sphere of init_radius / init_vertices / init_center (the paper's "
                      "Γ0); init_mesh overrides all", str, choices=("genus0", "auto", "sphere")),
        "join_below": Param(0.5, "init='genus0': where the region φ < 0 falls apart into pieces at grid resolution, "
                            "join the pieces whose lowest saddle of φ is below this many voxels (a part thinner than "
                            "a voxel: a neck 0.6 voxel thick has its saddle at 0.41 voxel at worst; two objects d "
                            "voxels apart at d/2) through a path of samples at that saddle, so the start grows into "
                            "all of them; farther pieces: the largest is kept, with the topology warning. Under "
                            "noise the threshold is lowered by the noise std σ̂ (a saddle read through noise is about "
                            "σ̂ lower; 30 dB speckles are never joined). 0 = never join", float, min=0.0, max=10.0),
        "close_pinholes": Param(True, "init='genus0' on a noisy volume: where noise lifted one sample of a thin sheet "
                                "(an ear, a wing) above 0, the growth would stop at the pinhole and the start lose "
                                "the tip beyond it; close such holes — one sample below max(noise std, 1/4 voxel), "
                                "next to the samples left out (methods.shape_gradient.pinholes). "
                                "Wider gaps (sulcal banks touching) stay open", bool),
        "sign_guard": Param(True, "with the genus-0 start on a clean volume: at every remesh, count the grid samples "
                            "that are clearly inside or outside (|φ| > h/4, within 3 h of φ = 0) but on the wrong side "
                            "of the surface (inside samples it covered and no longer covers, outside samples it "
                            "covers; inside samples the start missed may be grown into); when the flow puts more "
                            "there than its start did (+2), it is cutting a part of the object (a voxel-thin ear "
                            "on a coarse grid), so the mesh goes back to the accepted checkpoint with "
                            "the fewest samples on the wrong side (the latest of equals) and the run stops "
                            "(stop_reason 'sign_guard'); info['sign_guard'] lists (iteration, count)", bool),
        "edge_length": Param("auto", "target edge length of the initial sphere (init='auto') and of the "
                             "remeshing, in voxels (0.1–20); 'auto' = 1 on a binary mask (it resolves nothing finer: "
                             "as close and faster), else 0.5, which "
                             "keeps parts a voxel thin (the bunny's ear tips are lost at 1)", object),
        "remesh_iterations": Param(3, "split/collapse/flip/relax rounds of the start's remesh (marching cubes' "
                                   "slivers); the later remeshes, of a mesh already near isotropic, run one", int,
                                   min=1, max=20),
        "remesh_every": Param(5, "isotropic remeshing (Botsch–Kobbelt, gpytoolbox) toward edge_length every this "
                              "many iterations; 0 = fixed connectivity (the paper)", int, min=0, max=100000),
        "guard": Param(True, "keep the surface free of self-intersections: check at every remesh and at the end, "
                       "repair by local smoothing or roll back (and halve the step cap); a collapsed or "
                       "off-surface result is an error", bool),
        "projection": Param("auto", "final Newton projection of the vertices onto φ = 0 (3 steps of at most 0.5 "
                            "voxel; kept only if it makes no faces intersect). 'auto': on for clean volumes, off "
                            "on noisy ones (like polish)", str, choices=("auto", "on", "off")),
        "extend_tips": Param(True, "tip extension of the final mesh (tips.py): vertices of sharply convex parts "
                             "(mean curvature above tip_curvature per voxel) move outwards along their normal, up "
                             "to a voxel, until they touch the empty ball |x − q| < φ(q)/|∇φ(q)| of an outside "
                             "sample q; halved, then kept back, where faces would meet", bool),
        "reach_samples": Param(True, "last post-step on a signed distance (reach.py): where a sample q in the band "
                               "|φ| < 1.5 voxels is farther from the mesh than |φ(q)| by more than half a voxel plus "
                               "three noise stds (a crevice, a limb's stump, a tip the zero set rounds off), the "
                               "mesh vertex nearest q's foot point q − φ∇φ/|∇φ| moves there; 3 rounds, kept "
                               "back where faces would meet; on a noisy volume only samples with a flagged neighbour "
                               "pull. The start choice scores each flow before it", bool),
        "hold_carved": Param(False, "the flow moves a vertex inwards only as far as it stays within carve_margin "
                             "voxels of the union of the outside samples' empty balls |x − q| < φ(q)/|∇φ| (carve.py): "
                             "a part thinner than a voxel, which φ shows only as a dip, is not cut where no ball "
                             "covers it", bool),
        "start_level": Param(0.0, "the genus-0 start is grown from φ < start_level voxels (with hold_carved: a part "
                             "thinner than a voxel that φ shows as a dip below that level enters the start, and the "
                             "flow keeps what no empty ball covers)", float, min=0.0, max=2.0),
        "carved_start": Param(False, "the genus-0 start is grown from the carved hull — the region, read on a grid "
                              "twice as fine, that no outside sample's empty ball reaches (carved_start.py) — so a "
                              "part thinner than a voxel that every sample misses is in the start (with hold_carved "
                              "the flow keeps it)", bool),
        "l2_fallback": Param(True, "where the line search along the H¹ direction finds no decrease of E (under "
                             "noise: the direction is the pre-smoothed field's), search along the plain (L²) shape "
                             "gradient before stopping on the line-search floor", bool),
        "start_choice": Param("auto", "'auto': on a signed distance whose refined grid fits (N ≤ 128), the flow runs "
                              "from φ < 0 and, where its result lacks a part of the data (a sample lies outside it "
                              "by more than ½ voxel + 3 noise stds past its distance), also from two more genus-0 "
                              "starts — the carved hull (carved_start, hold_carved, "
                              "carve_margin = 0.1) and the carved hull read at φ < ¼ voxel (start_level = 0.25) — "
                              "and keeps the result whose signed distance agrees best with the samples (rms of "
                              "d_Γ − φ over |φ| < 1.5 voxels; choose.py; info['start_choice']); 'off', or any of "
                              "those four parameters set: one flow as configured", str, choices=("auto", "off")),
        "carve_margin": Param(0.25, "hold_carved: how far, in voxels, the surface may retreat past the union of the "
                              "empty balls", float, min=0.0, max=10.0),
        "tip_curvature": Param(0.3, "tip extension: the least mean curvature, per voxel, of a vertex that may move",
                               float, min=0.0),
        "strict_topology": Param(False, "refuse (error) when the region φ < 0 is not compatible with one genus-0 "
                                 "surface (several components, handles, cavities); otherwise info['topology'] "
                                 "and a warning say so", bool),
        "max_faces": Param(1_000_000, "the remeshing keeps about this many faces at most: where the surface's area "
                           "needs more triangles of edge_length, the edge length grows (info['init']); 0 = no cap",
                           int, min=0),
        "max_topology_gap": Param(5, "refuse (error, before any iteration) a volume whose region φ < 0, read after "
                                  "smoothing (σ ≥ 1 voxel; noise below 0.1 voxel), is farther than this from one "
                                  "genus-0 solid: (components − 1) + |χ − 1| at its most favourable level and "
                                  "connectivity — about "
                                  "the number of handles (a torus 1; a skull with openings many); one genus-0 "
                                  "surface cannot follow such data (the development and held-out shapes read 0–2 "
                                  "at 20–40 dB)", int, min=0),
        "init_radius": Param(PAPER_SPHERE_RADIUS, "radius of the initial Fibonacci sphere (world units)",
                             float, min=1e-9),
        "init_vertices": Param(PAPER_SPHERE_VERTICES, "vertices of the initial sphere (1,896 → 3,788 "
                               "triangles, the paper's Γ0)", int, min=12, max=5_000_000),
        "init_center": Param(None, "centre of the initial sphere, 3 numbers (default: centre of the grid box)",
                             object),
        "init_mesh": Param(None, "any closed genus-0 mesh to start from instead of the sphere (trimesh.Trimesh, "
                           "(vertices, faces) or a file path)", object),
        "snapshots": Param("1,50,100", "iterations whose vertices are kept in info['snapshots'] (0, the "
                           "initial surface, is always kept)", object),
        "preset": Param("none", "'paper': the paper's algorithm as printed (gradient='paper', "
                        "precondition='none', curvature='paper', relax=0, presmooth=0, the radius-2 sphere of "
                        "1,896 vertices, fixed connectivity, β = 1, 100 iterations with no tolerance stop); "
                        "'paper+fixes': the same experiment (Γ0, β, iterations, fixed connectivity) with the "
                        "suite's flow (full gradient, H¹, capped backtracking, guard); explicitly passed "
                        "parameters still win", str, choices=tuple(PRESETS)),
    }

    def __init__(self, **params: Any) -> None:
        super().__init__(**params)
        self.explicit = set(params)
        preset = PRESETS[self.config["preset"]]
        for key, value in preset.items():
            if key not in params:
                self.config[key] = value
        self.config["snapshots"] = parse_snapshots(self.config["snapshots"])
        for key, hi in (("presmooth", 10.0), ("start_smooth", 10.0), ("beta", 1e6), ("edge_length", 20.0)):
            self.config[key] = _auto_or_number(key, self.config[key], hi)
        if self.config["edge_length"] != "auto" and self.config["edge_length"] < 0.1:
            raise InputError("method 'shape_gradient', parameter 'edge_length': expected 'auto' or a number in "
                             f"[0.1, 20]; got {self.config['edge_length']!r}")
        c = self.config["init_center"]
        if c is not None:
            try:
                c = np.asarray(
                    [float(t) for t in c.replace(",", " ").split()] if isinstance(c, str) else c, dtype=float)
            except (TypeError, ValueError):
                c = None
            if c is None or c.shape != (3,) or not np.isfinite(c).all():
                raise InputError("method 'shape_gradient', parameter 'init_center': expected 3 finite numbers")
            self.config["init_center"] = c

    @property
    def relative_cost(self) -> float:
        """The paper's fixed-connectivity sphere (1,896 vertices) costs about a marching-cubes cell; the default's
        remeshed ½-voxel surface (≈ 35k vertices at N = 96) ten times that."""
        return 2.0 if self.config["remesh_every"] == 0 and self.config["init"] == "sphere" else 12.0

    def prepare(self, volume: Volume, *, ops: MeshOperators | None = None,
                overrides: dict | None = None) -> "ShapeGradientFlow":
        """Check the input, build the initial surface, the (pre-smoothed) field and the operators, and
        return the flow before its first iteration (``reconstruct`` = ``prepare(volume).run()`` + packing).

        ``ops`` reuses a :class:`MeshOperators` built for the same initial connectivity (benchmarks);
        ``overrides`` replaces parameters for this flow only (a start of the start choice).
        """
        check_volume(volume, self.name)
        config = {**self.config, **(overrides or {})}
        cfg = {**config, "edge_length": edge_length_voxels(config["edge_length"], volume.kind)}
        t_start = time.perf_counter()
        topology = target_topology(volume)
        if not topology["compatible"] and cfg["strict_topology"]:
            raise InputError(f"method 'shape_gradient' (strict_topology): {topology['message']}")
        noise = estimate_noise(volume)
        clean = noise < CLEAN_NOISE_VOXELS * volume.h
        # a clean volume's raw reading is reliable; under noise one reading can look compatible by chance
        if (not topology["compatible"] or not clean) and cfg["init_mesh"] is None:
            _refuse_far_topology(denoised_topology(volume, noise), cfg["max_topology_gap"])
        sigma = cfg["presmooth"]
        if sigma == "auto":
            sigma = 0.0 if clean else _AUTO_PRESMOOTH_SIGMA
        s0 = start_smoothing(noise / volume.h) if cfg["start_smooth"] == "auto" else cfg["start_smooth"]
        values = None
        if s0 > 0 and cfg["init"] == "genus0" and cfg["init_mesh"] is None:
            from scipy.ndimage import gaussian_filter
            values = gaussian_filter(volume.values, float(s0), mode="nearest")
        if cfg["start_level"] and cfg["init"] == "genus0" and cfg["init_mesh"] is None:
            values = (volume.values if values is None else values) - float(cfg["start_level"]) * volume.h
        # under noise a saddle is lower by about a noise std (the lowest of many paths' highest samples): the
        # threshold is lowered by σ̂, so the speckles of 30 dB noise (σ̂ ≈ 0.6 voxel) are never joined
        join_below = float(cfg["join_below"]) if clean else max(float(cfg["join_below"]) - noise / volume.h, 0.0)
        pinhole_below = 0.0
        if cfg["close_pinholes"] and not clean:
            pinhole_below = max(noise_after_smoothing(noise / volume.h, s0), _PINHOLE_FLOOR_VOXELS)
        x, faces, flipped, init_facts = initial_surface(
            volume, init=cfg["init"], init_mesh=cfg["init_mesh"], edge_length=cfg["edge_length"],
            join_below=join_below, init_vertices=cfg["init_vertices"], init_radius=cfg["init_radius"],
            init_center=cfg["init_center"], values=values, pinhole_below=pinhole_below)
        if init_facts["kind"] == "genus0":
            init_facts["pinhole_below_voxels"] = round(pinhole_below, 4)
            if cfg["carved_start"]:
                x, faces, init_facts["carved"] = carved_surface(
                    volume, volume.values if values is None else values, x, faces, pinhole_below,
                    0.0 if clean else noise)
        edge = _edge_length_voxels(cfg, x, faces, volume.h, init_facts)
        cfg["edge_length"] = edge
        settings = FlowSettings.resolve(cfg, h=volume.h, clean=clean, noise=noise, presmooth=sigma, start_smooth=s0,
                                        join_below=join_below, remesh_start=init_facts["kind"] == "genus0")
        field = smoothed_field(volume, sigma)
        if ops is None or ops.n_vertices != len(x) or not np.array_equal(ops.faces, faces):
            ops = MeshOperators(faces, len(x))
        field.sample_t(np.ascontiguousarray(x[:1].T), 2)     # build the cached derivative grids now (setup)
        return ShapeGradientFlow(field, ops, x, settings, volume.h, setup_seconds=time.perf_counter() - t_start,
                                 init_flipped=flipped, noise=noise, topology=topology, init_facts=init_facts)

    def reconstruct(self, volume: Volume) -> Reconstruction:
        candidates = start_candidates(self.config, self.explicit, volume)
        if not candidates:
            flow = self.prepare(volume)
            flow.run()
            return flow.result()
        return self._choose(volume, candidates)

    def _choose(self, volume: Volume, candidates) -> Reconstruction:
        """Flow from every start of ``candidates`` and keep the result :func:`.choose.pick` picks by the data
        residual (choose.py); where the first's (the usual start's) result lacks no part of the data (no sample lies
        outside it farther than its distance allows), the others are not tried.  A candidate whose flow fails is
        left out — the usual one's failure is the method's only when every candidate fails; an error about the
        input (InputError) from the usual start is raised at once."""
        results, residuals, facts, first_error = {}, {}, {}, None
        for k, (name, overrides) in enumerate(candidates):
            t0 = time.perf_counter()
            try:
                flow = self.prepare(volume, overrides=overrides)
                flow.run()
                rec = flow.result()
            except (InputError, ReconstructionFailed) as exc:
                if k == 0 and isinstance(exc, InputError):
                    raise
                first_error = exc if k == 0 else first_error
                facts[name] = {"error": str(exc), "seconds": round(time.perf_counter() - t0, 3)}
                continue
            errors = data_errors(volume, flow.before_reach, np.asarray(rec.mesh.faces))      # the flow's own result
            residual = rms(errors)
            facts[name] = {"residual_voxels": round(residual, 5), "stop_reason": rec.info["stop_reason"],
                           "iterations": rec.info["iterations"], "seconds": round(time.perf_counter() - t0, 3)}
            results[name], residuals[name] = rec, residual
            if k == 0:
                facts[name]["largest_error_voxels"] = round(float(np.abs(errors).max()), 4) if len(errors) else None
                facts[name]["largest_outside_error_voxels"] = round(float(errors.max()), 4) if len(errors) else None
                if not lacks_a_part(errors, float(rec.info["noise_estimate_voxels"])):
                    break
        if not results:
            raise first_error if first_error is not None else ReconstructionFailed(
                "method 'shape_gradient': no start gave a surface")
        name = pick(residuals)
        rec = results[name]
        rec.info["start_choice"] = {"chosen": name, "candidates": facts}
        return rec


