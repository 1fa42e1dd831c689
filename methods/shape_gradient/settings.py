"""What the flow is told: :class:`FlowSettings`, every setting the shape-gradient flow reads, resolved once from
the method's parameters and the volume (``beta='auto'``, ``polish='auto'``, the noise term, the stages), so
the flow reads fields and never falls back on a default of its own."""

from __future__ import annotations

import copy
from dataclasses import dataclass, field
from typing import Any, Mapping

import numpy as np

__all__ = ["FlowSettings", "Stage"]

_AUTO_BETA = (1.0, 0.01)      # beta='auto': on clean / noisy volumes
_INTERP_NOISE_GAIN = (2.0 / 3.0) ** 3   # mean of Σwᵢ² of trilinear weights over a cell


#: edge_length='auto': the remeshing's edge length (voxels) on a binary mask, which resolves nothing finer (as close
#: and faster), and on a level set (keeps parts a voxel thin) ...
AUTO_EDGE_VOXELS = {"mask": 1.0, "other": 0.5}
#: ... which on a noisy level set grows with the noise: this many noise stds (voxels), up to NOISY_EDGE_MAX_VOXELS —
#: the noise blurs the zero set by more than finer triangles resolve, and every step scales with the face count
NOISY_EDGE_PER_STD = 3.5
NOISY_EDGE_MAX_VOXELS = 0.7


def edge_length_voxels(value: Any, kind: str, noise_voxels: float = 0.0) -> float:
    """``edge_length`` in voxels: the number given, or for ``'auto'`` :data:`AUTO_EDGE_VOXELS` of the volume's kind,
    on a level set with ``noise_voxels`` (the estimated noise std, voxels; 0 on a clean volume) at least
    :data:`NOISY_EDGE_PER_STD` of it up to :data:`NOISY_EDGE_MAX_VOXELS`."""
    if value != "auto":
        return float(value)
    if kind == "mask":
        return AUTO_EDGE_VOXELS["mask"]
    base = AUTO_EDGE_VOXELS["other"]
    return float(min(max(base, NOISY_EDGE_PER_STD * noise_voxels), max(base, NOISY_EDGE_MAX_VOXELS)))


@dataclass(frozen=True)
class Stage:
    """One stage of the flow: the weight β and the remeshing's edge length it runs with.

    Parameters
    ----------
    beta : float
        The weight β of the alignment term during the stage.
    edge_length : float
        The remeshing's target edge length during the stage, in voxels.
    """

    beta: float
    edge_length: float


@dataclass(frozen=True)
class FlowSettings:
    """Every setting :class:`~methods.shape_gradient.flow.ShapeGradientFlow` reads, with the values the
    parameters leave to the volume (``'auto'``) decided; lengths in voxels unless named ``_world``.

    Built by :meth:`resolve`; the parameters are those of :class:`~methods.shape_gradient.ShapeGradient`.

    Parameters
    ----------
    alpha : float
        Weight α of the data term φ².
    beta : float
        The configured weight β of the alignment term (``'auto'`` decided); the stages carry β per stage.
    gradient : {'full', 'paper'}
        Which shape gradient is descended.
    curvature : {'tilted', 'paper'}
        The paraboloid fit for H.
    max_move : float
        Step cap: the largest vertex move per iteration, in voxels.
    precondition : {'h1', 'none'}
        Whether the velocity is the H¹ (Sobolev) gradient.
    s_world : float
        The H¹ smoothing weight in world units² (the parameter ``s`` times h²).
    relax : float
        Tangential relaxation weight per iteration.
    max_iter : int
        Iteration limit.
    tol : float
        Relative energy change below which an iteration counts towards the
        ``converged`` stop (0 = off).
    move_tol : float
        Largest normal move, in voxels, below which an iteration counts towards the
        ``converged`` stop (0 = off).
    remesh_every : int
        Remesh every this many iterations (0 = fixed connectivity).
    remesh_start : bool
        The start is a marching-cubes mesh (the genus-0 start): remesh it before the first iteration.
    guard : bool
        The self-intersection guard is on.
    remesh_when_drifted : bool
        At a remesh point the mesh is remeshed only where its triangles drifted from isotropic (a clean volume:
        a flow there moves a fraction of a voxel once it has grown); on a noisy one every remesh point remeshes
        (the remesher's relaxation and projection also even out what the noise leaves in the mesh).
    sign_guard : bool
        The sign guard runs (the parameter on, a clean volume and the genus-0 start).
    polish : bool
        The crease polish runs on the final mesh.
    projection : bool
        The final Newton projection onto φ = 0 runs.
    extend_tips : bool
        The tip extension runs on the final mesh.
    noise_variance : float
        The noise variance subtracted from φ² in the data term (0 on clean volumes or with ``unbias=False``).
    stages : tuple of Stage
        The stages, first first (one: the configured β and edge length).
    snapshots : tuple of int
        Iterations whose vertices are kept.
    presmooth, start_smooth : float
        The Gaussian σ (voxels) of the derivative grids and of the start's values, as decided (reported).
    hold_carved, carve_margin : bool, float
        The flow's inward moves stay within ``carve_margin`` voxels of the union of the outside samples' empty
        balls (carve.py); the start's private settings (:data:`.choose.USUAL_START`), not parameters.
    l2_fallback : bool
        Where the H¹ direction's line search finds no decrease, search along the plain (L²) gradient before
        stopping on the line-search floor.
    reach_samples : bool
        The final mesh moves to the surface the band samples' distances say is nearer than it (reach.py).
    parameters : Mapping
        The parameters as the run reports them (``info['parameters']``): every parameter with ``'auto'``
        decided, plus the values derived from them.
    """

    alpha: float
    beta: float
    gradient: str
    curvature: str
    max_move: float
    precondition: str
    s_world: float
    relax: float
    max_iter: int
    tol: float
    move_tol: float
    remesh_every: int
    remesh_start: bool
    guard: bool
    remesh_when_drifted: bool
    sign_guard: bool
    polish: bool
    projection: bool
    extend_tips: bool
    noise_variance: float
    stages: tuple[Stage, ...]
    snapshots: tuple[int, ...]
    presmooth: float
    start_smooth: float
    hold_carved: bool
    carve_margin: float
    l2_fallback: bool
    reach_samples: bool
    parameters: Mapping[str, Any] = field(default_factory=dict, repr=False, compare=False)

    @classmethod
    def resolve(cls, config: Mapping[str, Any], *, h: float, clean: bool, noise: float, presmooth: float,
                start_smooth: float, join_below: float, remesh_start: bool, kind: str = "sdf") -> "FlowSettings":
        """The settings of one run.

        Parameters
        ----------
        config : Mapping
            The method's parameters (``ShapeGradient.config``: every parameter, presets applied).
        h : float
            The grid spacing.
        clean : bool
            The volume counts as clean (estimated noise below 0.05 voxel): decides ``beta``, ``polish``,
            ``projection`` and ``sign_guard`` where they are ``'auto'``.
        noise : float
            The estimated noise std (world units), for the noise-variance term.
        presmooth, start_smooth : float
            The σ (voxels) the method used for the derivative grids and for the start's values.
        join_below : float
            The saddle depth (voxels) below which the genus-0 start joined pieces.
        remesh_start : bool
            The start is the genus-0 (marching-cubes) surface.
        kind : str
            The volume's kind (``sdf``, ``mask``, ``intensity``): decides ``edge_length`` where it is ``'auto'``.

        Returns
        -------
        settings : FlowSettings
        """
        beta = config["beta"]
        if beta == "auto":
            beta = _AUTO_BETA[0] if clean else _AUTO_BETA[1]
        edge = edge_length_voxels(config["edge_length"], kind)
        stages = [{"beta": beta, "edge_length": edge}]
        # the noise variance of φ where the flow reads it: trilinear interpolation of i.i.d. noise has variance
        # σ²Σwᵢ², on average (∫₀¹ t² + (1 − t)² dt)³ = (2/3)³ of σ² over positions in a cell
        derived = {
            "stages": stages,
            "s_world": config["s"] * h ** 2,
            "join_below_used": join_below,
            "remesh_start": remesh_start,
            "presmooth_used": float(presmooth),
            "noise_variance": _INTERP_NOISE_GAIN * float(noise) ** 2 if (config["unbias"] and not clean) else 0.0,
            "start_smooth_used": float(start_smooth),
            "polish_used": config["polish"] == "on" or (config["polish"] == "auto" and clean),
            "projection_used": config["projection"] == "on" or (config["projection"] == "auto" and clean),
            "sign_guard_used": bool(config["sign_guard"]) and clean and remesh_start,
        }
        # every parameter is in ``config`` (the Params' defaults filled in): each is read by its key, never with a
        # fallback of its own that could contradict the declared default
        cfg = {**config, "beta": beta, **derived}
        return cls(
            alpha=cfg["alpha"], beta=beta, gradient=cfg["gradient"], curvature=cfg["curvature"],
            max_move=cfg["max_move"], precondition=cfg["precondition"], s_world=cfg["s_world"],
            relax=cfg["relax"], max_iter=cfg["max_iter"], tol=cfg["tol"],
            move_tol=cfg["move_tol"], remesh_every=int(cfg["remesh_every"]),
            remesh_start=bool(remesh_start), guard=bool(cfg["guard"]),
            remesh_when_drifted=bool(clean), sign_guard=bool(cfg["sign_guard_used"]), polish=bool(cfg["polish_used"]),
            projection=bool(cfg["projection_used"]), extend_tips=bool(cfg["extend_tips"]),
            noise_variance=float(cfg["noise_variance"]),
            stages=tuple(Stage(float(st["beta"]), float(st["edge_length"])) for st in stages),
            snapshots=tuple(cfg["snapshots"]), presmooth=cfg["presmooth_used"], start_smooth=cfg["start_smooth_used"],
            hold_carved=bool(cfg["hold_carved"]),
            carve_margin=float(cfg["carve_margin"]), l2_fallback=bool(cfg["l2_fallback"]),
            reach_samples=bool(cfg["reach_samples"]), parameters=_reported(cfg))

    def reported_parameters(self) -> dict[str, Any]:
        """A fresh copy of :attr:`parameters` (``info['parameters']``), safe to change."""
        return copy.deepcopy(dict(self.parameters))


def _reported(config: Mapping[str, Any]) -> dict[str, Any]:
    """The parameters in plain values: arrays as lists, a user's mesh named, not stored."""
    out = {k: (v.tolist() if isinstance(v, np.ndarray) else v) for k, v in config.items()}
    out["init_mesh"] = None if config["init_mesh"] is None else "user mesh"
    out["snapshots"] = list(config["snapshots"])
    return out
