"""Tip extension: a post-step that moves the vertices of sharply convex parts out to where the samples allow.

Why: where a part is about a voxel thick (a wing, an ear's tip), interpolating the samples rounds its zero set
inwards — φ's convex kink along the part's mid-surface is overestimated between samples — so the flow, which
follows the zero set, stops short of the true tip (pymeshlab's airplane at N = 64: the nose 0.8 h short, the
bunny's ears at N = 48 1.1 h).  The samples themselves say more: an outside sample q with distance d(q) to the
surface has no surface closer than d(q), so the ball of radius d(q) around it is empty (the observation Reach
for the Spheres builds its surface from).  A vertex may move outwards along its normal until it touches one of
these balls.  On a smooth or concave part that is no move at all, or a move into the loose gaps between small
balls (a groove's), so only vertices of sharply convex, thin parts move (mean curvature above ``min_curvature``
per voxel; 1.5 voxels inside along the normal φ is above −1 voxel): on a thick part the balls, about a voxel
apart, leave gaps the surface would bulge into wherever the samples' distance is a little short.  The move also
stops where the interpolated φ reaches ``max_phi``.  d(q) = φ(q)/g, g the median |∇φ| of the samples (central
differences) 1.5 voxels outside the mesh (1 for a distance volume), so the rule reads a level set that is not a
distance too.
"""

from __future__ import annotations

import numpy as np

from geometry.operators import MeshOperators

__all__ = ["extend_tips", "tip_vertices", "near_samples", "distance_scale", "sample_gradients", "TIP_CURVATURE"]

#: the least mean curvature, per voxel, of a vertex the tip extension moves (and of a tip the held remesh keeps)
TIP_CURVATURE = 0.3

_BLOCK = 16384        # vertices per block: (block, 64) arrays of the nearby samples
_OFFSETS = np.stack(np.meshgrid(*[np.arange(-1, 3)] * 3, indexing="ij"), -1).reshape(-1, 3)   # the 4×4×4
_NEAR_ZERO_VOXELS = 0.5   # only vertices this near φ = 0 move (a surface that reached the data)
_THIN_PROBE_VOXELS = 1.5  # a part is thin where φ this far inside along the normal ...
_THIN_DEPTH_VOXELS = 1.0  # ... is still above minus this: thick convex ends (a bone's) keep their zero set
_SCALE_POINTS = 20_000   # vertices (at most, evenly strided) where the distance scale is read
_BISECTIONS = 8       # of the move where φ would pass max_phi: to 1/256 of it


def extend_tips(field, ops: MeshOperators, x: np.ndarray, h: float, *, min_curvature: float = TIP_CURVATURE,
                max_move: float = 1.0, max_phi: float = 0.25) -> tuple[np.ndarray, dict]:
    """Move the vertices where the mean curvature exceeds ``min_curvature``/h outwards along their normal, up
    to ``max_move`` voxels, until each touches the empty ball of an outside sample among the 4×4×4 samples
    around it (see the module docstring), and not past where the interpolated φ exceeds ``max_phi`` voxels
    (bisection).  ``field``: the flow's sampler (``sample_t``, and ``volume`` for the samples).  Returns the
    new vertices (V, 3) and counts for ``info``."""
    def phi(pt):
        return field.sample_t(pt, 0)[0]

    x = np.asarray(x, float)
    geo = ops.geometry(x)
    H, _ = ops.curvature(geo)
    nu = geo.vertex_normals
    # candidates: sharply convex, on the zero set (a collapsed surface deep inside is not a tip) ...
    near = np.abs(phi(np.ascontiguousarray(x.T))) <= _NEAR_ZERO_VOXELS * h
    sel = np.flatnonzero(np.isfinite(H) & (H * h > min_curvature) & np.isfinite(nu).all(1) & near)
    if len(sel):            # ... and thin: 1.5 voxels in, φ has not reached −1 voxel (a bone's end has)
        inner = phi(np.ascontiguousarray((x[sel] - _THIN_PROBE_VOXELS * h * nu[sel]).T))
        sel = sel[inner > -_THIN_DEPTH_VOXELS * h]
    stats = {"candidates": int(len(sel)), "moved": 0, "max_move_voxels": 0.0}
    if len(sel) == 0:
        return x.copy(), stats
    volume = field.volume
    scale = distance_scale(volume, x, nu, h)
    t = np.zeros(len(x))
    for s in range(0, len(sel), _BLOCK):
        b = sel[s:s + _BLOCK]
        q, vq, inside_grid = near_samples(volume, x[b])
        ball = inside_grid & (vq > 0)                              # outside samples: empty balls
        w = x[b, None, :] - q
        bb = np.einsum("vkd,vd->vk", w, nu[b])                      # |x + τν − q|² = τ² + 2bτ + c
        c = (w * w).sum(-1) - (vq / scale) ** 2
        disc = bb * bb - c
        enter = -bb - np.sqrt(np.maximum(disc, 0.0))               # where the ray enters the ball
        limit = np.where(ball & (c < 0), 0.0, np.where(ball & (disc > 0) & (enter >= 0), enter, np.inf))
        t[b] = np.minimum(limit.min(1), max_move * h)
    go = sel[t[sel] > 0]
    if np.isfinite(max_phi) and len(go):     # no farther than where the interpolated φ reaches max_phi voxels
        lo, hi = np.zeros(len(go)), t[go].copy()
        end = phi(np.ascontiguousarray((x[go] + hi[:, None] * nu[go]).T)) <= max_phi * h
        lo[end] = hi[end]
        for _ in range(_BISECTIONS):
            mid = 0.5 * (lo + hi)
            ok = phi(np.ascontiguousarray((x[go] + mid[:, None] * nu[go]).T)) <= max_phi * h
            lo, hi = np.where(ok, mid, lo), np.where(ok, hi, mid)
        t[go] = lo
    out = x + t[:, None] * nu
    stats["moved"] = int((t > 0).sum())
    stats["max_move_voxels"] = float(t.max() / h)
    return out, stats


def _gradient_scale(v, origin: np.ndarray, spacing: np.ndarray, points: np.ndarray) -> float:
    """The median |∇φ| by central differences of the samples at the grid samples nearest ``points``."""
    idx = np.rint((points - origin) / spacing).astype(np.int64)
    g = sample_gradients(v, idx, spacing)
    return float(np.median(np.linalg.norm(g, axis=1))) if len(g) else 1.0


def sample_gradients(v, idx: np.ndarray, spacing: np.ndarray) -> np.ndarray:
    """∇φ (P, 3) by central differences of the samples ``v`` at the grid indices ``idx`` (P, 3), each clamped to
    the samples that have both neighbours — the raw samples' gradient, not a pre-smoothed field's."""
    shape = np.asarray(v.shape)
    idx = np.clip(np.asarray(idx, np.int64), 1, shape - 2)
    g = np.zeros((len(idx), 3))
    for axis in range(3):
        up, down = idx.copy(), idx.copy()
        up[:, axis] += 1
        down[:, axis] -= 1
        g[:, axis] = (np.asarray(v[tuple(up.T)], float) - np.asarray(v[tuple(down.T)], float)) / (2.0 * spacing[axis])
    return g


def tip_vertices(ops: MeshOperators, geo, h: float, min_curvature: float) -> np.ndarray:
    """The vertices of sharply convex parts (mean curvature above ``min_curvature`` per voxel, the tip extension's
    threshold): the candidates ``hold_carved`` has the remesher keep, whose collapses would otherwise shorten a thin
    leg's hoof (the start's marching-cubes mesh, with its slivers, is remeshed freely)."""
    H, _ = ops.curvature(geo)
    return np.flatnonzero(np.isfinite(H) & (H * h > min_curvature))


def near_samples(volume, points: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The 4×4×4 grid samples around each of ``points`` (P, 3): their world positions (P, 64, 3), values (P, 64)
    and whether each lies on the grid (P, 64; positions and values off the grid are those of the clamped index).
    The balls of these samples are the ones that reach a point near the surface (tips, the carved hull)."""
    v = volume.values                                   # read where needed: no copy of an MRI-sized grid
    spacing = np.asarray(volume.spacing, float) * np.ones(3)
    origin = np.asarray(volume.origin, float)
    shape = np.asarray(v.shape)
    idx = np.floor((points - origin) / spacing).astype(np.int64)[:, None, :] + _OFFSETS
    on_grid = ((idx >= 0) & (idx < shape)).all(-1)
    idx = np.clip(idx, 0, shape - 1)
    return origin + idx * spacing, np.asarray(v[idx[..., 0], idx[..., 1], idx[..., 2]], float), on_grid


def distance_scale(volume, x: np.ndarray, normals: np.ndarray, h: float) -> float:
    """g of the samples' distances φ/g: one scale for the whole volume, the median |∇φ| 1.5 voxels outside the
    mesh ``x`` along its ``normals`` (at most ``_SCALE_POINTS`` vertices, evenly strided; 1 when unreadable).
    Per sample — or on the mesh — differences across a part thinner than two voxels read |∇φ| far below 1 and
    would inflate the balls; the raw samples' differences, not the flow's (pre-smoothed on noisy volumes)."""
    stride = max(1, len(x) // _SCALE_POINTS)
    scale = _gradient_scale(volume.values, np.asarray(volume.origin, float),
                            np.asarray(volume.spacing, float) * np.ones(3),
                            x[::stride] + _THIN_PROBE_VOXELS * h * normals[::stride])
    return scale if np.isfinite(scale) and scale > 0 else 1.0
