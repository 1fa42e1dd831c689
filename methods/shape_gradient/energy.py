"""The discrete energy E = Σ_f a_f [αφ² + β|∇_Γφ|²] at the face centroids and its shape gradient (docs/METHOD.md)."""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from geometry import compiled
from geometry.operators import MeshGeometry, MeshOperators
from phantoms import InputError

from .field import as_field

__all__ = ["face_energies", "face_energies_compiled", "discrete_energy", "FlowState", "evaluate_state",
           "gradient_from_state", "shape_gradient", "no_fold"]

_FOLD_DEGREES = 60.0       # a trial step that turns any face normal by more than this is rejected
_FOLD_COS = float(np.cos(np.radians(_FOLD_DEGREES)))


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


def discrete_energy(field, vertices: np.ndarray, faces: np.ndarray, alpha: float, beta: float,
                    density: float = 0.0) -> float:
    """The discrete energy E = Σ_f a_f g(c_f, n_f), g = αφ² + β(|∇φ|² − (∇φ·n_f)²), c_f the centroid.

    ``field`` is a Volume, a :class:`GridSampler` or any object with ``sample(points, derivatives)``.
    """
    field = as_field(field)
    x = np.asarray(vertices, float)
    ops = MeshOperators(faces, len(x))
    zero = dict.fromkeys(("energy", "interpolation"), 0.0)
    return evaluate_state(field, ops, x, alpha, beta, zero, density=density).E


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
                   timings: dict | None = None, *, density: float = 0.0) -> FlowState:
    """Geometry and the discrete energy at ``x`` (V, 3); E is +inf when a vertex leaves the field's box.

    ``density``: a constant added to the integrand (E += density · area).  The flow passes −α(2/3)³σ̂² on a
    noisy volume: trilinear φ of noise with variance σ² has E[φ²] = φ_true² + (2/3)³σ² on average over a cell,
    so ∫αφ² carries (2/3)³ασ²·area — a mean-curvature flow that shrinks thin parts and tips; this removes it."""
    t0 = time.perf_counter()
    geo = ops.geometry(x)
    if not field.contains_t(geo.vertices_t):
        if timings is not None:
            timings["energy"] += time.perf_counter() - t0
        return FlowState(x, geo, np.inf, None)
    c = geo.centroids_t                                                     # (3, F) centroids
    t1 = time.perf_counter()
    ch = field.sample_t(c, 1)
    t2 = time.perf_counter()
    if compiled.wanted(len(geo.face_areas)) and ch.dtype == np.float64 and ch.flags.c_contiguous:
        Ef, X = face_energies_compiled(ch, geo.normals_t, geo.face_areas, alpha, beta)   # same arithmetic
    else:
        Ef, X = face_energies(ch[0], ch[1:4], geo.normals_t, geo.face_areas, alpha, beta)
    E = float(Ef.sum()) + (density * float(geo.face_areas.sum()) if density else 0.0)
    if timings is not None:
        timings["interpolation"] += t2 - t1
        timings["energy"] += (t1 - t0) + (time.perf_counter() - t2)
    return FlowState(x, geo, E, X)


def gradient_from_state(field, state: FlowState, ops: MeshOperators, alpha: float, beta: float, *,
                        kind: str = "full", linear: bool = True, timings: dict | None = None,
                        density: float = 0.0):
    """(G, H): the shape gradient (V,) at every vertex of ``state`` and the mean curvature used for it.

    G = 2αφφ_n + 2β[(D²φ∇φ)·n − φ_n nᵀD²φn] + 2H[αφ² + β(|∇φ|² − φ_n²) + density]  (− 2β div_Γ X if
    kind='full'; ``density``: see :func:`evaluate_state`).
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
        + 2.0 * H * (alpha * phi * phi + beta * (g0 * g0 + g1 * g1 + g2 * g2 - phi_n * phi_n) + density)
    if kind == "full" and beta != 0.0:
        G -= 2.0 * beta * ops.divergence(geo, state.X, transposed=True)
    if timings is not None:
        timings["interpolation"] += ti - t0
        timings["curvature"] += t1 - ti
        timings["gradient"] += time.perf_counter() - t1
    return G, H


def shape_gradient(field, vertices: np.ndarray, faces: np.ndarray, alpha: float = 5.0, beta: float = 1.0, *,
                   kind: str = "full", linear: bool = True, density: float = 0.0
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Standalone (G, H, lumped vertex areas) for a mesh in a field (see :func:`gradient_from_state`)."""
    field = as_field(field)
    x = np.asarray(vertices, float)
    ops = MeshOperators(faces, len(x))
    zero = dict.fromkeys(("energy", "interpolation", "curvature", "gradient"), 0.0)
    state = evaluate_state(field, ops, x, alpha, beta, zero, density=density)
    if state.X is None:
        raise InputError("shape_gradient: some vertices lie outside the field's box")
    G, H = gradient_from_state(field, state, ops, alpha, beta, kind=kind, linear=linear, density=density)
    return G, H, state.geo.vertex_areas


def no_fold(old: MeshGeometry, new: MeshGeometry) -> bool:
    """True when no face normal turns by more than _FOLD_DEGREES in one step (a step that would fold or
    invert a triangle is rejected by the line search: the evolution stays fold-free)."""
    a, b = old.normals_t, new.normals_t
    return bool((a[0] * b[0] + a[1] * b[1] + a[2] * b[2]).min() > _FOLD_COS)


# ------------------------------------------------------------------------------ the compiled face energies
@compiled.jit
def _face_energies(ch, nrm, areas, alpha, beta, Ef, X):
    for f in range(areas.shape[0]):
        phi, d0, d1, d2 = ch[0, f], ch[1, f], ch[2, f], ch[3, f]
        m0, m1, m2 = nrm[0, f], nrm[1, f], nrm[2, f]
        phi_n = d0 * m0 + d1 * m1 + d2 * m2
        g0, g1, g2 = d0 - phi_n * m0, d1 - phi_n * m1, d2 - phi_n * m2
        Ef[f] = areas[f] * (alpha * phi * phi + beta * (g0 * g0 + g1 * g1 + g2 * g2))
        X[0, f], X[1, f], X[2, f] = phi_n * g0, phi_n * g1, phi_n * g2


def face_energies_compiled(ch: np.ndarray, normals_t: np.ndarray, areas: np.ndarray, alpha: float, beta: float):
    """(E_f, X_f) of :func:`face_energies` (its numpy reference) from the sampled channels ``ch`` (≥ 4, F) —
    φ, ∇φ at the centroids — face by face, compiled with numba (the same arithmetic, nothing of size (3, F) but
    the result).

    Parameters
    ----------
    ch : ndarray, shape (>= 4, F)
        φ and ∇φ at the face centroids (float64, C order).
    normals_t : ndarray, shape (3, F)
        Unit face normals.
    areas : ndarray, shape (F,)
        Face areas.
    alpha, beta : float
        The energy's weights.
    """
    F = len(areas)
    Ef, X = np.empty(F), np.empty((3, F))
    _face_energies(ch, normals_t, areas, float(alpha), float(beta), Ef, X)
    return Ef, X
