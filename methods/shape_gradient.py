"""The paper's method: shape-gradient descent of E(Γ) = ∫_Γ α φ² + β |∇_Γ φ|² dΓ (MATH.md).

Before the loop: the initial surface (Fibonacci sphere, radius 2, 1,896 vertices / 3,788 triangles, or a
user's closed genus-0 mesh, checked to lie in the grid), the noise estimate of the volume and — on noisy
volumes (``presmooth='auto'``) — Gaussian pre-smoothing of the grids ∇φ and D²φ are computed from (φ
itself is kept, so the data term has no shrinkage bias).

One iteration, every step vectorised over all vertices/faces (the only Python loops are over the
≤ 3 coordinates, the ≤ 30 halvings of a line search and the CG iterations):

1. **interpolation** – φ, ∇φ and D²φ at every vertex in one gather of the 8 corner rows of the volume's
   cached, stacked derivative grids (:class:`GridSampler`, the interpolation of
   :meth:`phantoms.Volume.sample`);
2. **curvature** – area-weighted vertex normals and the batched paraboloid fit (H; κ = 2H) over the
   1-ring (:meth:`geometry.operators.MeshOperators.curvature`);
3. **gradient** – the shape gradient at every vertex

       G = 2αφφ_n + 2β[(D²φ∇φ)·n − φ_n nᵀD²φ n] + κ[αφ² + β(|∇φ|² − φ_n²)] − 2β div_Γ(φ_n ∇_Γφ)

   (``gradient='full'``, the gradient of E) or without the last term (``gradient='paper'``, the paper's
   eq. (dJ_finel)).  The divergence term is the weak divergence (transpose of the P1 gradient) of the
   per-face field φ_n∇_Γφ sampled at the face centroids with the face normals — the samples the discrete
   energy uses, so that this term is the exact derivative of the discrete energy;
4. **preconditioner** – ``precondition='h1'``: the Sobolev velocity V = (M + sK)⁻¹ M G (M lumped areas,
   K cotangent stiffness) by Jacobi-preconditioned CG, warm-started; ``'none'``: V = G;
5. **step** – ``step='capped'``: the largest vertex move is capped at ``max_move`` voxels, then halved
   until the discrete energy E = Σ_f a_f g(centroid_f, n_f) decreases (Armijo) and no face normal turns
   by more than 60° (no fold); ``step='fixed'``: x ← x − τVn with the constant ``tau`` (the paper's
   printed loop, unguarded);
6. **relaxation** – tangential smoothing (toward the 1-ring centroid, within the tangent plane), added
   to the trial step (retried without it if the line search fails);
7. **energy** – E of the new mesh (from the accepted trial); stop when its relative change stays below
   ``tol`` or the largest normal move below ``move_tol`` voxels for 3 iterations.

After the last iteration, on clean volumes (``polish='auto'``; ``'on'``/``'off'`` force it), the **crease
polish** (:func:`crease_polish`) — a geometric post-step, not part of the descent: edges whose endpoints'
∇φ (at their Newton projections onto φ = 0) differ by more than ``polish_angle`` (45°) cross a sharp crease;
their endpoints are Newton-projected onto φ = 0 and one endpoint of each such edge is moved onto the crease
(the dual-contouring quadric of its 1-ring's tangent planes).  Why: the discrete energy prefers to bridge a
concave crease (near the kink the interpolated ∇φ blends both sides, so faces lying in the groove pay
β|∇_Γφ|²) — the fused spheres at N = 96 end at 2.5 h without it, 0.70 h with it (marching cubes 0.83 h).
Smooth surfaces have no crease edges: the polish leaves them untouched.  Off on noisy volumes: at 20–30 dB
it finds spurious creases and roughens the mesh.  The connectivity never changes; ``info['snapshots']`` are
flow iterates (before the polish), ``info['polish']`` records what it did (counts, the energy after it).

Stop reasons: ``converged``, ``max_iter``, ``line_search_floor`` (no decrease of E down to a 1e-4-voxel
move: the gradient no longer predicts a decrease of the discrete energy), ``diverged`` (non-finite
gradient, the mesh leaving the grid under ``step='fixed'``) — always with the iteration in
``info['stop_message']``; the returned mesh is the last finite one.
"""

from __future__ import annotations

import time
import weakref
from dataclasses import dataclass
from typing import Any

import numpy as np
import trimesh

from geometry import levelset
from geometry.operators import MeshGeometry, MeshOperators, jacobi_cg
from geometry.sphere import PAPER_SPHERE_RADIUS, PAPER_SPHERE_VERTICES, fibonacci_sphere
from geometry.topology import connected_components, edge_face_counts, euler_characteristic, genus, is_oriented
from phantoms import InputError, Sample, Volume
from phantoms.volume import trilinear_channels

from .base import Method, Param, Reconstruction, check_volume

__all__ = ["ShapeGradient", "ShapeGradientFlow", "discrete_energy", "shape_gradient", "PRESETS",
           "STOP_REASONS", "prepare_init_mesh"]

STOP_REASONS = ("converged", "max_iter", "line_search_floor", "diverged")

#: values a preset imposes on every parameter it names (parameters passed explicitly win)
PRESETS: dict[str, dict[str, Any]] = {
    "none": {},
    # the paper's algorithm as printed: no divergence term, plain (unpreconditioned) descent, the paper's
    # paraboloid fit, no relaxation, no pre-smoothing.  The step stays capped + backtracked: taken literally
    # (step='fixed', tau=0.1) the first step throws Γ0 past the target and the mesh tangles.
    "paper": {"gradient": "paper", "precondition": "none", "relax": 0.0, "presmooth": 0.0,
              "curvature": "paper", "polish": "off"},
}

_CONVERGE_PATIENCE = 3     # consecutive iterations with relative energy change < tol
_FLOOR_MOVE_VOXELS = 1e-4  # the line search gives up when the largest trial move falls below this
_ARMIJO = 1e-4             # sufficient-decrease constant of the backtracking line search
_CG_RTOL = 1e-3            # relative residual of the H¹ solve (an inexact solve is still a descent direction)
_CG_MAXITER = 100
_FOLD_DEGREES = 60.0       # a trial step that turns any face normal by more than this is rejected
_FOLD_COS = float(np.cos(np.radians(_FOLD_DEGREES)))

_AUTO_PRESMOOTH_SIGMA = 1.0   # presmooth='auto': σ (voxels) used on noisy volumes ...
_AUTO_PRESMOOTH_NOISE = 0.05  # ... i.e. when the estimated noise is at least this many voxels

_NOISE: "weakref.WeakKeyDictionary[Volume, float]" = weakref.WeakKeyDictionary()

#: per volume, the channel grids of its pre-smoothed versions {(σ, presmooth_phi): {order: (N, C)}}, so that
#: repeated runs on one volume filter and differentiate it once (freed with the volume)
_SMOOTHED: "weakref.WeakKeyDictionary[Volume, dict]" = weakref.WeakKeyDictionary()


def estimate_noise(volume: Volume) -> float:
    """Robust estimate of the std of additive i.i.d. noise in the volume (world units).

    Fourth differences along each axis annihilate the smooth part of φ (a cubic locally) and multiply
    i.i.d. noise by √70; the median absolute deviation ignores the few voxels at kinks of φ (medial
    surfaces, creases).  Accurate to about 1 % on the paper phantoms (0 on the clean ones).
    """
    if volume in _NOISE:
        return _NOISE[volume]
    a = volume.values
    mads = []
    for ax in range(3):
        if a.shape[ax] < 5:
            continue
        d = np.diff(a, n=4, axis=ax)
        mads.append(float(np.median(np.abs(d - np.median(d)))))
    out = 1.4826 * float(np.median(mads)) / np.sqrt(70.0) if mads else 0.0
    _NOISE[volume] = out
    return out


# ====================================================================== fast trilinear sampling
_HESS_INDEX = np.array([[0, 1, 2], [1, 3, 4], [2, 4, 5]]).ravel()


class GridSampler:
    """Trilinear φ, ∇φ, D²φ of a :class:`phantoms.Volume` at many points: one gather of the 8 corners.

    The interpolation of :meth:`phantoms.Volume.sample` (the same kernel,
    :func:`phantoms.volume.trilinear_channels`, on the volume's own cached stacked derivative grids),
    laid out for an inner loop: points given and results returned by coordinate/channel ((3, P) in,
    (C, P) out), no bounds check.  Points outside the grid box are clamped onto it; callers check
    :meth:`contains_t` first.
    """

    def __init__(self, volume: Volume, channels: dict[int, np.ndarray] | None = None):
        self.volume = volume
        self._given = channels or {}     # {order: (N, C) array} used instead of the volume's own grids
        self._shape = tuple(int(k) for k in volume.shape)
        self._nmax = np.asarray(self._shape, float) - 1.0
        self._origin = volume.origin
        self._inv_spacing = 1.0 / volume.spacing
        self._lower, self._upper = volume.lower, volume.upper

    def _channels(self, order: int) -> np.ndarray:
        """The stacked grids as an (N, C) array: given ones, else the volume's own (cached by the volume)."""
        if order in self._given:
            return self._given[order]
        ch = self.volume.channels(order)
        return ch.reshape(-1, ch.shape[-1])

    def contains(self, points: np.ndarray) -> np.ndarray:
        return np.all((points >= self._lower) & (points <= self._upper), axis=-1)

    def contains_t(self, xt: np.ndarray) -> bool:
        """True when every point of the (3, P) array lies in the grid box."""
        lo, up = self._lower, self._upper
        return bool(all((xt[c].min() >= lo[c]) and (xt[c].max() <= up[c]) for c in range(3)))

    def sample_t(self, xt: np.ndarray, derivatives: int = 2) -> np.ndarray:
        """Channels at the points of the (3, P) array: (C, P) with rows φ, ∇φ (3), Hessian (xx xy xz yy yz zz)."""
        idx = np.empty_like(xt)
        for c in range(3):
            np.multiply(xt[c] - self._origin[c], self._inv_spacing[c], out=idx[c])
            np.clip(idx[c], 0.0, self._nmax[c], out=idx[c])
        return trilinear_channels(self._channels(derivatives), self._shape, idx)

    def sample(self, points, derivatives: int = 0, clamp: bool = True) -> Sample:
        """Like :meth:`phantoms.Volume.sample` (points (P, 3)), always clamping."""
        out = self.sample_t(np.ascontiguousarray(np.asarray(points, float).T), derivatives)
        grad = np.ascontiguousarray(out[1:4].T) if derivatives >= 1 else None
        hess = np.ascontiguousarray(out[4:10].T)[:, _HESS_INDEX].reshape(-1, 3, 3) if derivatives >= 2 else None
        return Sample(out[0].copy(), grad, hess)


class _FieldAdapter:
    """Gives any object with ``sample(points, derivatives)`` (and optionally ``contains``) the
    channel-first interface of :class:`GridSampler` (used for analytic fields in tests)."""

    def __init__(self, field):
        self.field = field

    def contains_t(self, xt: np.ndarray) -> bool:
        f = getattr(self.field, "contains", None)
        return True if f is None else bool(np.all(f(xt.T)))

    def sample_t(self, xt: np.ndarray, derivatives: int = 2) -> np.ndarray:
        s = self.field.sample(np.ascontiguousarray(xt.T), derivatives=derivatives)
        rows = [np.asarray(s.phi, float)[None]]
        if derivatives >= 1:
            rows.append(np.asarray(s.grad, float).T)
        if derivatives >= 2:
            hh = np.asarray(s.hess, float)
            rows.append(np.stack([hh[:, 0, 0], hh[:, 0, 1], hh[:, 0, 2], hh[:, 1, 1], hh[:, 1, 2], hh[:, 2, 2]]))
        return np.ascontiguousarray(np.concatenate(rows))


def as_field(field):
    """A :class:`GridSampler` for a Volume; other fields (``sample(points, derivatives)``) are adapted."""
    if isinstance(field, (GridSampler, _FieldAdapter)):
        return field
    return GridSampler(field) if isinstance(field, Volume) else _FieldAdapter(field)


# ====================================================================== the discrete energy and its gradient
def face_energies(phi: np.ndarray, grad: np.ndarray, normals: np.ndarray, areas: np.ndarray,
                  alpha: float, beta: float) -> tuple[np.ndarray, np.ndarray]:
    """Per-face energy by the one-point (centroid) rule and the per-face field X = φ_n ∇_Γφ.

    Arrays by coordinate: φ at the centroids ``phi`` (F,), ∇φ there ``grad`` (3, F), face ``normals``
    (3, F), ``areas`` (F,).  E_f = a_f [αφ² + β(|∇φ|² − (∇φ·n_f)²)].  X_f (3, F) = φ_n(∇φ − φ_n n_f)
    = −∂g/∂n_f / (2β), tangential to the face: the divergence term of the gradient is built from it,
    which makes that term the exact derivative of the discrete energy.

    (The centroid rule, not a vertex rule: with ∇φ taken at the vertices and n_f on the face, a curved
    mesh pays β sin²(angle between face and vertex normal) ≈ β(ℓκ/2)² per unit area — a spurious
    bending energy that holds the mesh out of concave creases.  At the centroid of an inscribed face,
    n_f ∥ ∇φ to second order.)
    """
    phi_n = grad[0] * normals[0] + grad[1] * normals[1] + grad[2] * normals[2]
    gt = grad - phi_n * normals                                              # ∇_Γφ
    Ef = areas * (alpha * phi * phi + beta * (gt[0] * gt[0] + gt[1] * gt[1] + gt[2] * gt[2]))
    return Ef, phi_n * gt


def discrete_energy(field, vertices: np.ndarray, faces: np.ndarray, alpha: float, beta: float) -> float:
    """The discrete energy E = Σ_f a_f g(c_f, n_f), g = αφ² + β(|∇φ|² − (∇φ·n_f)²), c_f the centroid.

    ``field`` is a Volume, a :class:`GridSampler` or any object with ``sample(points, derivatives)``.
    """
    field = as_field(field)
    x = np.asarray(vertices, float)
    ops = MeshOperators(faces, len(x))
    zero = dict.fromkeys(("energy", "interpolation"), 0.0)
    return evaluate_state(field, ops, x, alpha, beta, zero).E


@dataclass
class FlowState:
    """Everything known at one vertex configuration: geometry, energy, samples."""

    x: np.ndarray
    geo: MeshGeometry
    E: float
    X: np.ndarray | None                 # (3, F) per-face φ_n∇_Γφ at the centroids (see face_energies)
    channels: np.ndarray | None = None   # (10, V): φ, ∇φ, D²φ (xx xy xz yy yz zz) at the vertices, on demand
    curvature_fallbacks: int = 0         # vertices whose paraboloid fit was undetermined (cotangent H used)


def evaluate_state(field, ops: MeshOperators, x: np.ndarray, alpha: float, beta: float,
                   timings: dict | None = None) -> FlowState:
    """Geometry and the discrete energy at ``x`` (V, 3); E is +inf when a vertex leaves the field's box."""
    t0 = time.perf_counter()
    geo = ops.geometry(x)
    if not field.contains_t(geo.vertices_t):
        if timings is not None:
            timings["energy"] += time.perf_counter() - t0
        return FlowState(x, geo, np.inf, None)
    c = geo.corners_t.sum(axis=1) / 3.0                                     # (3, F) centroids
    t1 = time.perf_counter()
    ch = field.sample_t(c, 1)
    t2 = time.perf_counter()
    Ef, X = face_energies(ch[0], ch[1:4], geo.normals_t, geo.face_areas, alpha, beta)
    E = float(Ef.sum())
    if timings is not None:
        timings["interpolation"] += t2 - t1
        timings["energy"] += (t1 - t0) + (time.perf_counter() - t2)
    return FlowState(x, geo, E, X)


def gradient_from_state(field, state: FlowState, ops: MeshOperators, alpha: float, beta: float, *,
                        kind: str = "full", linear: bool = True, timings: dict | None = None):
    """(G, H): the shape gradient (V,) at every vertex of ``state`` and the mean curvature used for it.

    G = 2αφφ_n + 2β[(D²φ∇φ)·n − φ_n nᵀD²φn] + 2H[αφ² + β(|∇φ|² − φ_n²)]  (− 2β div_Γ X if kind='full').
    G_i × (lumped area of i) approximates ∂E/∂(move of vertex i along its normal).
    """
    if kind not in ("full", "paper"):
        raise InputError(f"unknown gradient kind {kind!r}; use 'full' or 'paper'")
    geo = state.geo
    t0 = time.perf_counter()
    if state.channels is None:
        state.channels = field.sample_t(geo.vertices_t, 2)
    ti = time.perf_counter()
    H, _ = ops.curvature(geo, linear=linear)
    bad = ~np.isfinite(H)
    if bad.any():
        # undetermined fit (a collapsed 1-ring): fall back to the cotangent mean curvature there,
        # H = (K x)·n / (2A); still non-finite → the flow reports 'diverged'
        Kx = ops.stiffness(geo) @ geo.vertices
        Hc = np.einsum("vd,vd->v", Kx, geo.vertex_normals) / (2.0 * np.where(geo.vertex_areas > 0,
                                                                               geo.vertex_areas, np.nan))
        H = np.where(bad, Hc, H)
        state.curvature_fallbacks = int(bad.sum())
    t1 = time.perf_counter()
    n0, n1, n2 = geo.vertex_normals_t
    ch = state.channels
    phi, g0, g1, g2 = ch[0], ch[1], ch[2], ch[3]
    hxx, hxy, hxz, hyy, hyz, hzz = ch[4], ch[5], ch[6], ch[7], ch[8], ch[9]
    hn0 = hxx * n0 + hxy * n1 + hxz * n2
    hn1 = hxy * n0 + hyy * n1 + hyz * n2
    hn2 = hxz * n0 + hyz * n1 + hzz * n2
    phi_n = g0 * n0 + g1 * n1 + g2 * n2
    G = 2.0 * alpha * phi * phi_n \
        + 2.0 * beta * ((hn0 * g0 + hn1 * g1 + hn2 * g2) - phi_n * (hn0 * n0 + hn1 * n1 + hn2 * n2)) \
        + 2.0 * H * (alpha * phi * phi + beta * (g0 * g0 + g1 * g1 + g2 * g2 - phi_n * phi_n))
    if kind == "full" and beta != 0.0:
        G -= 2.0 * beta * ops.divergence(geo, state.X, transposed=True)
    if timings is not None:
        timings["interpolation"] += ti - t0
        timings["curvature"] += t1 - ti
        timings["gradient"] += time.perf_counter() - t1
    return G, H


def shape_gradient(field, vertices: np.ndarray, faces: np.ndarray, alpha: float = 5.0, beta: float = 1.0, *,
                   kind: str = "full", linear: bool = True) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Standalone (G, H, lumped vertex areas) for a mesh in a field (see :func:`gradient_from_state`)."""
    field = as_field(field)
    x = np.asarray(vertices, float)
    ops = MeshOperators(faces, len(x))
    zero = dict.fromkeys(("energy", "interpolation", "curvature", "gradient"), 0.0)
    state = evaluate_state(field, ops, x, alpha, beta, zero)
    if state.X is None:
        raise InputError("shape_gradient: some vertices lie outside the field's box")
    G, H = gradient_from_state(field, state, ops, alpha, beta, kind=kind, linear=linear)
    return G, H, state.geo.vertex_areas


def _no_fold(old: MeshGeometry, new: MeshGeometry) -> bool:
    """True when no face normal turns by more than _FOLD_DEGREES in one step (a step that would fold or
    invert a triangle is rejected by the line search: the evolution stays fold-free)."""
    a, b = old.normals_t, new.normals_t
    return bool((a[0] * b[0] + a[1] * b[1] + a[2] * b[2]).min() > _FOLD_COS)


# ====================================================================== the crease polish
_POLISH_NEWTON_STEPS = 3      # Newton projections x ← x − φ∇φ/|∇φ|² of the crease-zone vertices
_POLISH_MAX_ROUNDS = 50       # rounds of the vectorised greedy choice of the vertices put on the crease


def newton_project(field, x: np.ndarray, steps: int = _POLISH_NEWTON_STEPS, max_step: float = np.inf,
                   ) -> tuple[np.ndarray, np.ndarray]:
    """``steps`` Newton projections onto φ = 0 along ∇φ (:func:`geometry.levelset.newton_project`: points
    with |∇φ|² ≤ 1e-12 stay), each capped at ``max_step``; returns the projected points (P, 3) and the unit
    ∇φ there (P, 3)."""
    def phi_grad(xt):
        ch = field.sample_t(xt, 1)
        return ch[0], ch[1:4]

    xt = np.ascontiguousarray(np.asarray(x, float).T)
    # flat below the next double above 1e-12: exactly the points with |∇φ|² <= 1e-12
    xt, _ = levelset.newton_project(phi_grad, xt, steps, max_step=max_step,
                                    flat_g2=float(np.nextafter(1e-12, np.inf)), coords_first=True)
    _, g = phi_grad(xt)
    g2 = g[0] * g[0] + g[1] * g[1] + g[2] * g[2]
    nu = g / np.maximum(np.sqrt(g2), 1e-300)
    return xt.T.copy(), nu.T.copy()


def crease_polish(field, ops: MeshOperators, x: np.ndarray, h: float, *, angle: float = 45.0,
                  weight: float = 0.1) -> tuple[np.ndarray, dict]:
    """Put vertices on the sharp creases of the level set (run once on the final mesh; ``polish``).

    Why: on a concave crease (the fused spheres' groove) the discrete energy prefers a bridge over the
    groove — near the kink the interpolated ∇φ is a blend of the two sides, so faces lying in the groove
    pay β|∇_Γφ|² while a bridging face is aligned with the blended gradient — and no mesh vertex sits on
    the crease.  Nothing here changes where the flow goes; this is a geometric post-step:

    1. every vertex is Newton-projected onto φ = 0 (3 steps, each capped at 2 voxels) and ν = ∇φ/|∇φ| is
       sampled there (for the test only);
    2. crease edges: edges whose endpoints' ν differ by more than ``angle`` degrees (on a smooth surface
       meshed at ~2 voxels neighbouring normals differ by a few degrees);
    3. crease zone: the endpoints of crease edges.  For each of them the crease point
       y = argmin Σ_j (ν_j·(y − p_j))² + w|y − p_i|² over the vertex and its 1-ring (p the projected
       positions, w = ``weight``) — the quadric error function of dual contouring: where the ring's
       planes come from both sides of the crease y is the nearest point of their intersection line;
    4. one endpoint of every crease edge goes onto its crease point: a vectorised greedy choice, cheapest
       move first, no two chosen vertices on one crease edge, so that the chosen vertices form a chain of
       edges along the crease and no edge crosses it; the other zone vertices take their Newton projection;
    5. vertices of faces that this turns upside down (normal reversed) are put back.

    Vertices outside the crease zone do not move: on a smooth surface the polish is a no-op.
    Returns the new vertices and counts for ``info['polish']``.
    """
    x = np.asarray(x, float)
    V = len(x)
    stats = {"crease_edges": 0, "zone_vertices": 0, "snapped": 0, "reverted": 0, "max_move_voxels": 0.0}
    xp, nu = newton_project(field, x, max_step=2.0 * h)
    ok = np.isfinite(xp).all(1) & np.isfinite(nu).all(1)
    e = ops.edges
    c = np.einsum("ed,ed->e", nu[e[:, 0]], nu[e[:, 1]])
    crease = e[(c < np.cos(np.radians(angle))) & ok[e[:, 0]] & ok[e[:, 1]]]
    stats["crease_edges"] = int(len(crease))
    if len(crease) == 0:
        return x.copy(), stats
    zone = np.unique(crease)
    stats["zone_vertices"] = int(len(zone))
    # QEF of each zone vertex over itself and its 1-ring (padded slots point at the vertex itself, weight 0)
    idx = np.concatenate([zone[:, None], np.where(ops.ring_valid[zone], ops.ring[zone], zone[:, None])], 1)
    wgt = np.concatenate([np.ones((len(zone), 1)), ops.ring_weight[zone]], 1) * ok[idx]
    N, P = nu[idx], xp[idx]                                                   # (Z, W+1, 3)
    A = np.einsum("zw,zwi,zwj->zij", wgt, N, N) + weight * np.eye(3)
    b = np.einsum("zw,zwi->zi", wgt * np.einsum("zwd,zwd->zw", N, P), N) + weight * xp[zone]
    y = np.full_like(x, np.nan)
    y[zone] = np.linalg.solve(A, b[..., None])[..., 0]
    cost = np.full(V, np.inf)
    cost[zone] = np.linalg.norm(y[zone] - xp[zone], axis=1)
    # greedy, vectorised in rounds: a crease edge proposes its cheaper endpoint; it wins when its
    # (cost, index) rank is the smallest of all open crease edges at both its endpoints
    a, bb = crease[:, 0], crease[:, 1]
    cand = np.where(cost[a] <= cost[bb], a, bb)
    rank = np.empty(len(crease), np.int64)
    rank[np.lexsort((np.arange(len(crease)), cost[cand]))] = np.arange(len(crease))
    chosen = np.zeros(V, bool)
    open_ = np.isfinite(cost[cand])
    for _ in range(_POLISH_MAX_ROUNDS):
        if not open_.any():
            break
        best = np.full(V, np.iinfo(np.int64).max)
        r = np.where(open_, rank, np.iinfo(np.int64).max)
        np.minimum.at(best, a, r)
        np.minimum.at(best, bb, r)
        win = open_ & (best[a] == rank) & (best[bb] == rank)
        chosen[cand[win]] = True
        open_ &= ~(chosen[a] | chosen[bb])
    out = x.copy()
    zone_ok = zone[ok[zone]]
    out[zone_ok] = xp[zone_ok]
    out[chosen] = y[chosen]
    # put back the vertices of faces the polish turned upside down (a few rounds: putting back can expose more)
    n_old = ops.geometry(x).normals_t
    for _ in range(5):
        n_new = ops.geometry(out).normals_t
        bad = (n_old * n_new).sum(0) <= 0.0
        if not bad.any():
            break
        back = np.unique(ops.faces[bad])
        back = back[np.any(out[back] != x[back], axis=1)]
        if len(back) == 0:
            break
        stats["reverted"] += int(len(back))
        out[back] = x[back]
        chosen[back] = False
    stats["snapped"] = int(chosen.sum())
    stats["max_move_voxels"] = float(np.linalg.norm(out - x, axis=1).max() / h)
    return out, stats


# ====================================================================== input checks
def _parse_snapshots(value) -> tuple[int, ...]:
    if value is None or (isinstance(value, str) and value.strip().lower() in ("", "none")):
        return ()
    if isinstance(value, str):
        items = [v for v in value.replace(";", ",").replace(" ", ",").split(",") if v]
    elif isinstance(value, (int, np.integer)):
        items = [value]
    else:
        try:
            items = list(value)
        except TypeError:
            raise InputError(f"method 'shape_gradient', parameter 'snapshots': expected iteration numbers, "
                             f"got {value!r}") from None
    out = []
    for v in items:
        try:
            f = float(v)
        except (TypeError, ValueError):
            raise InputError(f"method 'shape_gradient', parameter 'snapshots': {v!r} is not an iteration "
                             "number") from None
        if f != int(f) or f < 0:
            raise InputError(f"method 'shape_gradient', parameter 'snapshots': {v!r} is not an iteration "
                             "number (>= 0)")
        out.append(int(f))
    return tuple(sorted(set(out)))


def prepare_init_mesh(mesh) -> tuple[np.ndarray, np.ndarray, bool]:
    """Validate a user's initial mesh: (vertices, faces, flipped).

    Accepts a ``trimesh.Trimesh``, a ``(vertices, faces)`` pair or a path trimesh can load.  Raises
    InputError unless the mesh is a single closed, consistently oriented, genus-0 surface without
    degenerate faces; an inward-oriented mesh is flipped (``flipped`` = True).
    """
    where = "method 'shape_gradient', parameter 'init_mesh'"
    if isinstance(mesh, str):
        try:
            mesh = trimesh.load(mesh, force="mesh", process=False)
        except Exception as exc:  # noqa: BLE001 - any loader failure is a user error here
            raise InputError(f"{where}: cannot load {mesh!r}: {exc}") from None
    if isinstance(mesh, trimesh.Trimesh):
        v, f = np.asarray(mesh.vertices, float), np.asarray(mesh.faces)
    else:
        try:
            v, f = mesh
            v = np.asarray(v, dtype=float)
            f = np.asarray(f)
        except (TypeError, ValueError):
            raise InputError(f"{where}: expected a trimesh.Trimesh, a (vertices, faces) pair or a path; "
                             f"got {type(mesh).__name__}") from None
    if v.ndim != 2 or v.shape[1] != 3 or f.ndim != 2 or f.shape[1] != 3 or len(f) == 0:
        raise InputError(f"{where}: vertices must be (V, 3) and faces (F, 3); got {v.shape} and {f.shape}")
    if not np.issubdtype(f.dtype, np.integer):
        if not np.all(f == np.round(f)):
            raise InputError(f"{where}: faces must hold integer vertex indices")
        f = f.astype(np.int64)
    f = f.astype(np.int64)
    if not np.isfinite(v).all():
        raise InputError(f"{where}: vertices contain NaN or inf")
    if f.min() < 0 or f.max() >= len(v):
        raise InputError(f"{where}: face indices out of range [0, {len(v) - 1}]")
    used = np.unique(f)
    if len(used) != len(v):
        raise InputError(f"{where}: {len(v) - len(used)} vertices are not used by any face")
    if np.any((f[:, 0] == f[:, 1]) | (f[:, 1] == f[:, 2]) | (f[:, 0] == f[:, 2])):
        raise InputError(f"{where}: some faces repeat a vertex")
    # every undirected edge in exactly two faces, once in each direction (closed and consistently oriented)
    _, counts = edge_face_counts(f, len(v))
    if np.any(counts != 2):
        bad = int((counts != 2).sum())
        raise InputError(f"{where}: the mesh is not closed — {bad} edges are not shared by exactly two faces "
                         "(the method needs a closed surface)")
    if not is_oriented(f, len(v)):
        raise InputError(f"{where}: the faces are not consistently oriented")
    euler = euler_characteristic(f, len(v))
    n_comp, _ = connected_components(f, len(v), by="face")
    if n_comp != 1:
        raise InputError(f"{where}: the mesh has {n_comp} connected components; the method needs one surface")
    if euler != 2:
        raise InputError(f"{where}: the mesh has Euler characteristic {euler} (genus {genus(euler)}); "
                         "the method needs a genus-0 (sphere-like) surface")
    cross = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    dbl = np.linalg.norm(cross, axis=1)
    if np.any(dbl <= 1e-12 * max(1.0, float(np.ptp(v, axis=0).max())) ** 2):
        raise InputError(f"{where}: {int((dbl <= 0).sum()) or 'some'} faces are degenerate (zero area)")
    signed_volume = float(np.einsum("ij,ij->i", v[f[:, 0]], cross).sum() / 6.0)
    flipped = signed_volume < 0
    if flipped:
        f = f[:, ::-1].copy()
    return v.copy(), np.ascontiguousarray(f), flipped


# ====================================================================== the method
class ShapeGradient(Method):
    name = "shape_gradient"
    description = ("the paper's shape-gradient descent of E = ∫ αφ² + β|∇_Γφ|² from a sphere (full gradient, "
                   "H¹ preconditioning, capped backtracking)")
    params = {
        "alpha": Param(5.0, "weight α of the data term φ² (pulls Γ onto φ = 0)", float, min=0.0),
        "beta": Param(1.0, "weight β of the alignment term |∇_Γφ|² (wants n ∥ ∇φ); 0 = the paper's ablation",
                      float, min=0.0),
        "gradient": Param("full", "'full': the true shape gradient of E (MATH.md, with the divergence term); "
                          "'paper': the paper's eq. (dJ_finel) without it", str, choices=("full", "paper")),
        "step": Param("capped", "'capped': largest move capped at max_move voxels, then halved until E "
                      "decreases (Armijo); 'fixed': x ← x − τVn with τ = tau, unguarded (the paper's loop)",
                      str, choices=("capped", "fixed")),
        "max_move": Param(1.0, "step cap: the largest vertex move per iteration, in voxels (step='capped')",
                          float, min=1e-3, max=10.0),
        "tau": Param(0.1, "the constant step τ of step='fixed' (world units per unit of G)", float, min=0.0),
        "precondition": Param("h1", "'h1': Sobolev velocity V = (M + sK)⁻¹MG (M lumped areas, K cotangent "
                              "stiffness; Jacobi-preconditioned CG); 'none': V = G", str, choices=("h1", "none")),
        "s": Param(0.05, "H¹ smoothing weight s in world units² (precondition='h1')", float, min=0.0),
        "relax": Param(0.5, "tangential relaxation weight per iteration (move toward the 1-ring centroid "
                       "within the tangent plane); 0 = off", float, min=0.0, max=1.0),
        "presmooth": Param("auto", "Gaussian pre-smoothing of the volume the derivative grids ∇φ, D²φ are "
                           "computed from, σ in voxels (0 = off); 'auto': σ = 1 voxel when the estimated noise "
                           "(robust std of 4th differences) is at least 0.05 voxel, else off", object),
        "presmooth_phi": Param(False, "pre-smooth φ itself too (True: the data term then sees the shrunken "
                               "level set of the smoothed volume), or only the derivative grids (False)", bool),
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
        "max_iter": Param(100, "maximum number of iterations (paper: 100; 150 for the fused spheres)", int,
                          min=0, max=100000),
        "tol": Param(1e-4, "stop ('converged') when the relative energy change stays below tol for 3 "
                     "iterations (0 = off)", float, min=0.0),
        "move_tol": Param(0.01, "stop ('converged') when the largest normal move per iteration stays below "
                          "move_tol voxels for 3 iterations (0 = off): the surface has stopped and the energy "
                          "only changes by the tangential relaxation", float, min=0.0),
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
                        "precondition='none', curvature='paper', relax=0, presmooth=0); explicitly passed "
                        "parameters still win", str, choices=tuple(PRESETS)),
    }

    def __init__(self, **params: Any) -> None:
        super().__init__(**params)
        preset = PRESETS[self.config["preset"]]
        for key, value in preset.items():
            if key not in params:
                self.config[key] = value
        self.config["snapshots"] = _parse_snapshots(self.config["snapshots"])
        ps = self.config["presmooth"]
        if not (isinstance(ps, str) and ps.strip().lower() == "auto"):
            try:
                ps = float(ps)
            except (TypeError, ValueError):
                ps = -1.0
            if not (np.isfinite(ps) and 0.0 <= ps <= 10.0):
                raise InputError("method 'shape_gradient', parameter 'presmooth': expected 'auto' or a number "
                                 f"of voxels in [0, 10]; got {self.config['presmooth']!r}")
        else:
            ps = "auto"
        self.config["presmooth"] = ps
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

    # ------------------------------------------------------------------ helpers
    def _initial_surface(self, volume: Volume):
        cfg = self.config
        flipped = False
        if cfg["init_mesh"] is not None:
            x, faces, flipped = prepare_init_mesh(cfg["init_mesh"])
        else:
            center = cfg["init_center"]
            if center is None:
                center = 0.5 * (volume.lower + volume.upper)
            x, faces = fibonacci_sphere(cfg["init_vertices"], cfg["init_radius"], center)
        inside = volume.contains(x)
        if not inside.all():
            raise InputError(
                f"method 'shape_gradient': {int((~inside).sum())} of {len(x)} vertices of the initial surface "
                f"lie outside the volume box [{volume.lower.round(4).tolist()}, {volume.upper.round(4).tolist()}]"
                " — the volume must contain the initial surface (pass a smaller init_radius or init_mesh)")
        return x, faces, flipped

    # ------------------------------------------------------------------ the flow
    def _field(self, volume: Volume, sigma: float) -> GridSampler:
        """The sampler: the volume itself, or its grids after Gaussian pre-smoothing (σ voxels) — by default
        only the derivative grids, φ itself stays the data's (presmooth_phi=False)."""
        if sigma <= 0:
            return GridSampler(volume)
        cache = _SMOOTHED.setdefault(volume, {})
        key = (float(sigma), bool(self.config["presmooth_phi"]))
        if key not in cache:
            from scipy.ndimage import gaussian_filter
            smooth = volume.with_values(gaussian_filter(volume.values, sigma=sigma, mode="nearest"))
            ch2 = smooth.channels(2).reshape(-1, 10)                # a new array, owned by ``smooth``
            if not key[1]:
                ch2[:, 0] = volume.values.ravel()
            cache[key] = {2: ch2, 1: np.ascontiguousarray(ch2[:, :4])}
            del smooth                                               # its own cache goes with it
        return GridSampler(volume, channels=cache[key])

    def prepare(self, volume: Volume, *, ops: MeshOperators | None = None) -> "ShapeGradientFlow":
        """Check the input, build the initial surface, the (pre-smoothed) field and the operators, and
        return the flow before its first iteration (``reconstruct`` = ``prepare(volume).run()`` + packing).

        ``ops`` reuses a :class:`MeshOperators` built for the same initial connectivity (benchmarks).
        """
        check_volume(volume, self.name)
        cfg = dict(self.config)
        t_start = time.perf_counter()
        x, faces, flipped = self._initial_surface(volume)
        noise = estimate_noise(volume)
        sigma = cfg["presmooth"]
        if sigma == "auto":
            sigma = _AUTO_PRESMOOTH_SIGMA if noise >= _AUTO_PRESMOOTH_NOISE * volume.h else 0.0
        cfg["presmooth_used"] = float(sigma)
        cfg["polish_used"] = (cfg["polish"] == "on"
                              or (cfg["polish"] == "auto" and noise < _AUTO_PRESMOOTH_NOISE * volume.h))
        field = self._field(volume, sigma)
        if ops is None or ops.n_vertices != len(x) or not np.array_equal(ops.faces, faces):
            ops = MeshOperators(faces, len(x))
        field.sample_t(np.ascontiguousarray(x[:1].T), 2)     # build the cached derivative grids now (setup)
        flow = ShapeGradientFlow(field, ops, x, cfg, volume.h, setup_seconds=time.perf_counter() - t_start)
        flow.init_flipped = flipped
        flow.noise = noise
        return flow

    def reconstruct(self, volume: Volume) -> Reconstruction:
        flow = self.prepare(volume)
        flow.run()
        return flow.result()


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
                            and _no_fold(geo, cand.geo):
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
