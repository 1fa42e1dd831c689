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
from .choose import data_errors, lacks_a_part, pick, rms, start_candidates, start_settings
from .flow import ShapeGradientFlow
from .settings import FlowSettings, edge_length_voxels
from .start import denoised_topology, initial_surface, parse_snapshots, target_topology, topology_gap

__all__ = ["ShapeGradient", "PRESETS"]

#: values a preset imposes on every parameter it names (parameters passed explicitly win)
PRESETS: dict[str, dict[str, Any]] = {
    "none": {},
    # the paper's algorithm as printed: no divergence term, plain (unpreconditioned) descent, the paper's
    # paraboloid fit, no relaxation, no pre-smoothing.  The step stays capped + backtracked: the printed fixed
    # step τ = 0.1 throws Γ0 past the target at once and the mesh tangles (docs/METHOD.md).
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


def _edge_length_voxels(flow_params: dict, x: np.ndarray, faces: np.ndarray, h: float, facts: dict) -> float:
    """The remeshing's edge length (voxels): ``edge_length``, or longer where the surface is so large that
    triangles of that size would exceed ``max_faces`` — the mesh's size follows the surface's area, not the
    grid's (a label map at its native resolution: millions of faces for a smooth organ).  The start's area
    is read before it is remeshed (a staircase overestimates it a little: the cap errs on the coarse side)."""
    edge = float(flow_params["edge_length"])
    cap = flow_params["max_faces"]
    if cap <= 0 or flow_params["remesh_every"] <= 0:
        return edge
    tri = x[faces]
    area = 0.5 * float(np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1).sum())
    # an equilateral triangle of edge e has area √3/4 e²
    needed = float(np.sqrt(4.0 * area / (np.sqrt(3.0) * cap))) / h
    if needed > edge:
        facts["edge_length_voxels_for_max_faces"] = round(needed, 4)
        return needed
    return edge


def _start_values(volume: Volume, flow_params: dict, sigma: float) -> "np.ndarray | None":
    """The samples the genus-0 start is grown from: the volume's smoothed by ``sigma`` voxels and lowered by the
    start's ``start_level`` voxels; None (the volume's own) when neither applies or the start is not genus-0."""
    if flow_params["init"] != "genus0" or flow_params["init_mesh"] is not None:
        return None
    values = None
    if sigma > 0:
        from scipy.ndimage import gaussian_filter
        values = gaussian_filter(volume.values, float(sigma), mode="nearest")
    if flow_params["start_level"]:
        values = (volume.values if values is None else values) - float(flow_params["start_level"]) * volume.h
    return values


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
        "beta": Param("auto", "weight β of the alignment term |∇_Γφ|² (n ∥ ∇φ); 'auto' = 1 on clean volumes, "
                      "0.01 on noisy ones; 0 = the paper's ablation", object),
        "gradient": Param("full", "'full': the shape gradient of E with the divergence term; 'paper': the paper's "
                          "eq. (dJ_finel) without it", str, choices=("full", "paper")),
        "max_move": Param(1.0, "step cap: the largest vertex move per iteration, in voxels", float, min=1e-3,
                          max=10.0),
        "precondition": Param("h1", "'h1': the Sobolev velocity V = (M + sK)⁻¹MG; 'none': V = G", str,
                              choices=("h1", "none")),
        "s": Param(18.0, "H¹ smoothing weight s, in voxels² (s·h² world units²)", float, min=0.0),
        "relax": Param(0.5, "tangential relaxation weight per iteration (toward the 1-ring centroid); 0 = off", float,
                       min=0.0, max=1.0),
        "presmooth": Param("auto", "Gaussian σ (voxels) of the volume ∇φ and D²φ are computed from; 'auto' = 1 on "
                           "noisy volumes, 0 on clean ones", object),
        "start_smooth": Param("auto", "Gaussian σ (voxels) of the values the genus-0 start is grown from; 'auto' = "
                              "the least that brings the noise below one voxel", object),
        "unbias": Param(True, "on noisy volumes, subtract the estimated noise variance from φ² in the data term",
                        bool),
        "polish": Param("auto", "crease polish of the final mesh (vertices put on sharp creases of φ = 0); 'auto' = "
                        "on clean volumes only", str, choices=("auto", "on", "off")),
        "curvature": Param("tilted", "paraboloid fit for H: 'tilted' with linear terms, 'paper' as printed", str,
                           choices=("tilted", "paper")),
        "max_iter": Param(300, "maximum number of iterations", int, min=0, max=100000),
        "tol": Param(1e-4, "stop ('converged') when the relative energy change stays below this for 3 iterations; "
                     "0 = off", float, min=0.0),
        "move_tol": Param(0.01, "stop ('converged') when the largest normal move stays below this many voxels for 3 "
                          "iterations; 0 = off", float, min=0.0),
        "init": Param("genus0", "initial surface: 'genus0' = grown from the region φ < 0 as one genus-0 solid; "
                      "'auto' = an enclosing sphere; 'sphere' = the paper's Fibonacci sphere", str,
                      choices=("genus0", "auto", "sphere")),
        "join_below": Param(0.5, "genus-0 start: join the pieces of φ < 0 whose lowest saddle is below this many "
                            "voxels; 0 = never", float, min=0.0, max=10.0),
        "close_pinholes": Param(True, "genus-0 start on a noisy volume: close the one-sample holes noise made in a "
                                "thin sheet", bool),
        "sign_guard": Param(True, "genus-0 start on a clean volume: stop and roll back when the flow puts more grid "
                            "samples on the wrong side than its start did", bool),
        "edge_length": Param("auto", "target edge length of the remeshing (and of init='auto'), in voxels; 'auto' = "
                             "1 on a binary mask, else 0.5, on noise 3.5 noise stds up to 0.7", object),
        "remesh_every": Param(5, "isotropic remeshing every this many iterations (on a clean volume only where "
                              "the triangles drifted); 0 = fixed connectivity", int,
                              min=0, max=100000),
        "guard": Param(True, "keep the surface free of self-intersections (repair or roll back); a collapsed or "
                       "off-surface result is an error", bool),
        "projection": Param("auto", "final Newton projection of the vertices onto φ = 0; 'auto' = on clean volumes "
                            "only", str, choices=("auto", "on", "off")),
        "extend_tips": Param(True, "final tip extension: sharply convex vertices move out to the outside samples' "
                             "empty balls (at most a voxel)", bool),
        "reach_samples": Param(True, "last post-step on a signed distance: vertices move to band samples the mesh "
                               "lies farther from than their distance says", bool),
        "l2_fallback": Param(True, "where the H¹ direction's line search finds no decrease, search along the plain "
                             "(L²) gradient before stopping", bool),
        "start_choice": Param("auto", "'auto': where the usual start's result lacks a part of the data, also flow "
                              "from the carved starts and keep the best fit; 'off': one flow", str,
                              choices=("auto", "off")),
        "strict_topology": Param(False, "refuse (error) a volume whose region φ < 0 is not one genus-0 solid; "
                                 "otherwise a warning", bool),
        "max_faces": Param(1_000_000, "about the most faces the remeshing keeps (the edge length grows); 0 = no cap",
                           int, min=0),
        "max_topology_gap": Param(5, "refuse (error) a volume whose smoothed region φ < 0 is farther than this from "
                                  "one genus-0 solid ((components − 1) + |χ − 1|)", int, min=0),
        "init_radius": Param(PAPER_SPHERE_RADIUS, "radius of the initial Fibonacci sphere (init='sphere'), world "
                             "units", float, min=1e-9),
        "init_vertices": Param(PAPER_SPHERE_VERTICES, "vertices of the initial Fibonacci sphere (init='sphere')",
                               int, min=12, max=5_000_000),
        "init_mesh": Param(None, "a closed genus-0 mesh to start from instead (trimesh.Trimesh, (vertices, faces) or "
                           "a file path)", object),
        "snapshots": Param("1,50,100", "iterations whose vertices are kept in info['snapshots'] (0 always)",
                           object),
        "preset": Param("none", "'paper': the paper's algorithm as printed; 'paper+fixes': its experiment run by "
                        "the suite's flow; explicit parameters win", str, choices=tuple(PRESETS)),
    }

    def __init__(self, **params: Any) -> None:
        super().__init__(**params)
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

    @property
    def relative_cost(self) -> float:
        """The paper's fixed-connectivity sphere (1,896 vertices) costs about a marching-cubes cell; the default's
        remeshed ½-voxel surface (≈ 35k vertices at N = 96) ten times that."""
        return 2.0 if self.config["remesh_every"] == 0 and self.config["init"] == "sphere" else 12.0

    def prepare(self, volume: Volume, *, ops: MeshOperators | None = None,
                start: dict | None = None) -> "ShapeGradientFlow":
        """Check the input, build the initial surface, the (pre-smoothed) field and the operators, and
        return the flow before its first iteration (``reconstruct`` = ``prepare(volume).run()`` + packing).

        ``ops`` reuses a :class:`MeshOperators` built for the same initial connectivity (benchmarks);
        ``start`` sets the start's private settings for this flow (a candidate of the start choice,
        :data:`.choose.CANDIDATES`; the rest keep :data:`.choose.USUAL_START`).
        """
        check_volume(volume, self.name)
        # this flow's parameters: the method's, the start's private settings, the edge length in voxels
        flow_params = {**self.config, **start_settings(start)}
        t_start = time.perf_counter()
        topology = target_topology(volume)
        if not topology["compatible"] and flow_params["strict_topology"]:
            raise InputError(f"method 'shape_gradient' (strict_topology): {topology['message']}")
        noise = estimate_noise(volume)
        clean = noise < CLEAN_NOISE_VOXELS * volume.h
        flow_params["edge_length"] = edge_length_voxels(flow_params["edge_length"], volume.kind,
                                                         0.0 if clean else noise / volume.h)
        # a clean volume's raw reading is reliable; under noise one reading can look compatible by chance
        if (not topology["compatible"] or not clean) and flow_params["init_mesh"] is None:
            _refuse_far_topology(denoised_topology(volume, noise), flow_params["max_topology_gap"])
        sigma = flow_params["presmooth"]
        if sigma == "auto":
            sigma = 0.0 if clean else _AUTO_PRESMOOTH_SIGMA
        s0 = flow_params["start_smooth"]
        if s0 == "auto":
            s0 = start_smoothing(noise / volume.h)
        values = _start_values(volume, flow_params, s0)
        # under noise a saddle is lower by about a noise std (the lowest of many paths' highest samples): the
        # threshold is lowered by σ̂, so the speckles of 30 dB noise (σ̂ ≈ 0.6 voxel) are never joined
        join_below = float(flow_params["join_below"])
        if not clean:
            join_below = max(join_below - noise / volume.h, 0.0)
        pinhole_below = 0.0
        if flow_params["close_pinholes"] and not clean:
            pinhole_below = max(noise_after_smoothing(noise / volume.h, s0), _PINHOLE_FLOOR_VOXELS)
        x, faces, flipped, init_facts = initial_surface(
            volume, init=flow_params["init"], init_mesh=flow_params["init_mesh"],
            edge_length=flow_params["edge_length"], join_below=join_below, init_vertices=flow_params["init_vertices"],
            init_radius=flow_params["init_radius"], values=values, pinhole_below=pinhole_below)
        if init_facts["kind"] == "genus0":
            init_facts["pinhole_below_voxels"] = round(pinhole_below, 4)
            if flow_params["carved_start"]:
                x, faces, init_facts["carved"] = carved_surface(
                    volume, volume.values if values is None else values, x, faces, pinhole_below,
                    0.0 if clean else noise)
        flow_params["edge_length"] = _edge_length_voxels(flow_params, x, faces, volume.h, init_facts)
        settings = FlowSettings.resolve(flow_params, h=volume.h, clean=clean, noise=noise, presmooth=sigma,
                                        start_smooth=s0, join_below=join_below,
                                        remesh_start=init_facts["kind"] == "genus0")
        field = smoothed_field(volume, sigma)
        if ops is None or ops.n_vertices != len(x) or not np.array_equal(ops.faces, faces):
            ops = MeshOperators(faces, len(x))
        field.sample_t(np.ascontiguousarray(x[:1].T), 2)     # build the cached derivative grids now (setup)
        return ShapeGradientFlow(field, ops, x, settings, volume.h, setup_seconds=time.perf_counter() - t_start,
                                 init_flipped=flipped, noise=noise, topology=topology, init_facts=init_facts)

    def reconstruct(self, volume: Volume) -> Reconstruction:
        candidates = start_candidates(self.config, volume)
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
        for k, (name, start) in enumerate(candidates):
            t0 = time.perf_counter()
            try:
                flow = self.prepare(volume, start=start)
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


