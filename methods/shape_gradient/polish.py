"""The crease polish: a geometric post-step that puts vertices on the sharp creases of the level set."""

from __future__ import annotations

import numpy as np

from geometry import levelset
from geometry.operators import MeshOperators

__all__ = ["newton_project", "crease_polish", "CREASE_ANGLE_DEGREES", "CREASE_WEIGHT"]

_POLISH_NEWTON_STEPS = 3      # Newton projections x ← x − φ∇φ/|∇φ|² of the crease-zone vertices
_POLISH_MAX_ROUNDS = 50       # rounds of the vectorised greedy choice of the vertices put on the crease
_CREASE_OFF_ZERO_VOXELS = 1.0  # a crease point where |φ| exceeds this many voxels is not on the surface: not snapped

#: an edge crosses a crease where ∇φ at its two (projected) endpoints differs by more than this many degrees
CREASE_ANGLE_DEGREES = 45.0
#: weight of |y − p_i|² in the crease-point quadric, relative to one tangent plane (smaller: sharper, less stable)
CREASE_WEIGHT = 0.1


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


def crease_polish(field, ops: MeshOperators, x: np.ndarray, h: float, *, angle: float = CREASE_ANGLE_DEGREES,
                  weight: float = CREASE_WEIGHT) -> tuple[np.ndarray, dict]:
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

    A crease point where |φ| exceeds a voxel is not snapped (the ring's planes met far from the surface, as in
    the saddle between two lobes: they are nearly parallel there).

    Vertices outside the crease zone do not move: on a smooth surface the polish is a no-op.
    Returns the new vertices and counts for ``info['polish']``.
    """
    x = np.asarray(x, float)
    V = len(x)
    stats = {"crease_edges": 0, "zone_vertices": 0, "snapped": 0, "reverted": 0, "off_zero_set": 0,
             "max_move_voxels": 0.0}
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
    # a crease point lies on the zero set: where the ring's planes meet far from it (a saddle between two
    # lobes, where the planes are nearly parallel) the point is not a crease — not snapped
    yz = np.where(np.isfinite(y[zone]), y[zone], xp[zone])
    off = np.abs(field.sample_t(np.ascontiguousarray(yz.T), 0)[0]) > _CREASE_OFF_ZERO_VOXELS * h
    cost[zone[off]] = np.inf
    stats["off_zero_set"] = int(off.sum())
    # at a convex crease the sharp edge lies outside the sampled zero set (interpolating φ's convex kink
    # overestimates φ, so the zero set is rounded inwards): a crease point inside a convex vertex's tangent plane
    # is the quadric's pull towards the centre of a rounded tip, not a crease — not snapped
    a, bb = crease[:, 0], crease[:, 1]
    concave_vertex = np.zeros(V, bool)
    is_concave = np.einsum("ed,ed->e", nu[a] - nu[bb], xp[a] - xp[bb]) < 0.0
    concave_vertex[a[is_concave]] = concave_vertex[bb[is_concave]] = True
    inward = np.einsum("zd,zd->z", nu[zone], y[zone] - xp[zone]) < 0.0
    cost[zone[inward & ~concave_vertex[zone]]] = np.inf
    # greedy, vectorised in rounds: a crease edge proposes its cheaper endpoint; it wins when its
    # (cost, index) rank is the smallest of all open crease edges at both its endpoints
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
    stats["reverted"] = _put_back_flipped(ops, x, out, chosen)
    stats["snapped"] = int(chosen.sum())
    stats["max_move_voxels"] = float(np.linalg.norm(out - x, axis=1).max() / h)
    return out, stats


def _put_back_flipped(ops: MeshOperators, x: np.ndarray, out: np.ndarray, chosen: np.ndarray) -> int:
    """Put back (in ``out``, from ``x``) the vertices of faces the polish turned upside down, a few rounds since
    putting back can expose more; they are no longer ``chosen``.  Returns how many were put back."""
    n_old = ops.geometry(x).normals_t
    reverted = 0
    for _ in range(5):
        n_new = ops.geometry(out).normals_t
        bad = (n_old * n_new).sum(0) <= 0.0
        if not bad.any():
            break
        back = np.unique(ops.faces[bad])
        back = back[np.any(out[back] != x[back], axis=1)]
        if len(back) == 0:
            break
        reverted += int(len(back))
        out[back] = x[back]
        chosen[back] = False
    return reverted
