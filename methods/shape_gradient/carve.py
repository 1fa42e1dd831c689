"""The carved hull as a constraint of the flow (``hold_carved``): the surface may not retreat into the region no
sample's empty ball reaches, farther than a margin.

Why: every outside sample q (φ(q) > 0) has an empty ball of radius d(q) = φ(q)/g around it — no surface is
closer (the observation Reach for the Spheres builds its surface from, and the tip extension, tips.py, uses on the
final mesh).  The object lies in the complement of the union of these balls, the *carved hull*.  A part thinner
than a voxel shows in φ only as a dip; interpolated φ is above 0 along it, so the data term αφ² pulls its surface
inwards and the flow cuts it (on clean volumes the sign guard then stops the run), although no ball covers the
part: the samples never said it is empty.  The constraint lets a vertex move inwards (against its outward normal)
only as far as it stays within ``margin`` of the union of the balls: with b(x) = max_q (d(q) − |x − q|) (> 0 in a
ball, its depth; < 0 outside all of them, minus the distance to the nearest one), b is 1-Lipschitz, so an inward
move of at most max(b(x) + margin, 0) keeps b ≥ −margin.  Where the surface lies in a ball (too far out) it
retreats freely; where it lies on the carved hull (a thin limb, a tip) it holds.  Outward moves are never limited.
A vertex with no allowance left also gets no tangential relaxation (at a thin part's rim the shift toward the
1-ring's centre shortens the part as an inward move would), and the remesher keeps such vertices where they are
tips (:func:`remesh_keep`).  The limits clamp the trial moves of the capped line search.

b is read from the 4×4×4 samples around each vertex (the balls that reach a point near the surface are those of
the samples next to it; a far sample's ball missed only makes the limit stricter), d(q) = φ(q)/g with g the
median |∇φ| of the raw samples 1.5 voxels outside the start (tips.py's scale), so a level set that is not a
distance reads the same.
"""

from __future__ import annotations

import math

import numpy as np

from geometry.compiled import jit, wanted

from .tips import TIP_CURVATURE, distance_scale, near_samples, tip_vertices

__all__ = ["CarvedHull", "ball_depth", "ball_depth_numpy", "remesh_keep"]

_BLOCK = 16384            # vertices per block: (block, 64) arrays of the nearby samples


def ball_depth(volume, points: np.ndarray, scale: float) -> np.ndarray:
    """b at ``points`` (P, 3): the largest d(q) − |x − q| over the outside samples q among the 4×4×4 around x
    (−inf where none is outside); d(q) = φ(q)/scale.  Compiled (:func:`_ball_depth_compiled`, point by point,
    without the (P, 64, 3) gather) from :data:`geometry.compiled.MIN_SIZE` points on; :func:`ball_depth_numpy`
    is the reference."""
    if wanted(len(points)):
        out = np.empty(len(points))
        _ball_depth_compiled(np.ascontiguousarray(volume.values), np.asarray(volume.origin, float) * np.ones(3),
                             np.asarray(volume.spacing, float) * np.ones(3),
                             np.ascontiguousarray(points, dtype=float), float(scale), out)
        return out
    return ball_depth_numpy(volume, points, scale)


@jit
def _ball_depth_compiled(values, origin, spacing, points, scale, out):
    """:func:`ball_depth` into ``out``, ``values`` on the grid ``origin + index·spacing``."""
    n0, n1, n2 = values.shape
    for p in range(points.shape[0]):
        x, y, z = points[p, 0], points[p, 1], points[p, 2]
        i0 = int(math.floor((x - origin[0]) / spacing[0]))
        j0 = int(math.floor((y - origin[1]) / spacing[1]))
        k0 = int(math.floor((z - origin[2]) / spacing[2]))
        best = -np.inf
        for i in range(max(i0 - 1, 0), min(i0 + 3, n0)):
            dx = x - (origin[0] + i * spacing[0])
            for j in range(max(j0 - 1, 0), min(j0 + 3, n1)):
                dy = y - (origin[1] + j * spacing[1])
                for k in range(max(k0 - 1, 0), min(k0 + 3, n2)):
                    v = values[i, j, k]
                    if v > 0:
                        dz = z - (origin[2] + k * spacing[2])
                        d = v / scale - math.sqrt(dx * dx + dy * dy + dz * dz)
                        if d > best:
                            best = d
        out[p] = best


def ball_depth_numpy(volume, points: np.ndarray, scale: float) -> np.ndarray:
    """:func:`ball_depth` by a (block, 64) gather of the nearby samples (the compiled kernel's reference)."""
    out = np.full(len(points), -np.inf)
    for s in range(0, len(points), _BLOCK):
        p = points[s:s + _BLOCK]
        q, vq, on_grid = near_samples(volume, p)
        dist = np.linalg.norm(p[:, None, :] - q, axis=-1)
        depth = np.where(on_grid & (vq > 0), vq / scale - dist, -np.inf)
        out[s:s + _BLOCK] = depth.max(1)
    return out


class CarvedHull:
    """The inward-move limits of the flow's vertices (see the module docstring).

    Parameters
    ----------
    volume : Volume
        The raw samples (not the flow's pre-smoothed field).
    h : float
        The grid spacing.
    x, normals : ndarray
        The start's vertices and outward vertex normals, where the distance scale is read.
    margin : float
        How far (world units) the surface may retreat past the union of the balls.
    """

    def __init__(self, volume, h: float, x: np.ndarray, normals: np.ndarray, margin: float):
        self.volume, self.h, self.margin = volume, float(h), float(margin)
        self.scale = distance_scale(volume, x, normals, h)
        self.held = 0          # vertex-iterations whose inward velocity was set to 0 (reported)
        self._last: tuple[np.ndarray, np.ndarray] | None = None   # (x, b at x) of the last hold(): still() reads it

    def depth(self, x: np.ndarray) -> np.ndarray:
        """b at each point of ``x`` (:func:`ball_depth` with this hull's scale)."""
        return ball_depth(self.volume, np.asarray(x, float), self.scale)

    def limits(self, x: np.ndarray) -> np.ndarray:
        """The largest inward move (world units, ≥ 0) of each vertex of ``x``."""
        return np.maximum(self.depth(x) + self.margin, 0.0)

    @classmethod
    def of(cls, field, settings, state, h: float) -> "CarvedHull | None":
        """The flow's limits (``settings.hold_carved``, margin ``settings.carve_margin`` voxels) at its start
        ``state``, or None when off or when the field has no samples (a callable field)."""
        if not settings.hold_carved or getattr(field, "volume", None) is None:
            return None
        return cls(field.volume, h, state.x, state.geo.vertex_normals, settings.carve_margin * h)

    def hold(self, x: np.ndarray, Vel: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(limits at ``x``, the velocity with the inward part — Vel > 0: the flow moves along −Vel·ν — of the
        vertices that may not move inwards at all set to 0, so the line search does not wait on them)."""
        b = self.depth(x)
        self._last = (x, b)
        limit = np.maximum(b + self.margin, 0.0)
        self.held += int(((Vel > 0) & (limit <= 0)).sum())
        return limit, self.stopped(Vel, limit)

    @staticmethod
    def stopped(Vel: np.ndarray, limit: np.ndarray) -> np.ndarray:
        """``Vel`` with the inward part (Vel > 0) of the vertices whose ``limit`` is 0 set to 0."""
        return np.where((Vel > 0) & (limit <= 0), 0.0, Vel)

    def still(self, x: np.ndarray, shift: np.ndarray | None, limit: np.ndarray) -> np.ndarray | None:
        """The tangential relaxation ``shift`` (V, 3) of ``x`` without the moves of the vertices that may not move
        inwards into the region no ball reaches: at a thin part's rim a tangential move toward the 1-ring's centre
        shortens the part as an inward one would.  Such a vertex keeps its shift where it stays as near the balls
        as it was (b does not fall): sideways along a limb or over a flat part — without that its neighbours
        crowd it into slivers."""
        if shift is None:
            return None
        held = np.flatnonzero(limit <= 0.0)
        if len(held) == 0:
            return shift
        b0 = self._last[1][held] if self._last is not None and self._last[0] is x else self.depth(x[held])
        b1 = self.depth(x[held] + shift[held])
        out = shift.copy()
        out[held[~(b1 >= b0)]] = 0.0
        return out

    @staticmethod
    def clamp(step: np.ndarray, normals: np.ndarray, limit: np.ndarray) -> np.ndarray:
        """``step`` (V, 3) with each vertex's inward normal part cut to its limit (tangential parts kept)."""
        inward = -np.einsum("vd,vd->v", step, normals)
        cut = np.maximum(inward - limit, 0.0)
        return step + cut[:, None] * normals


def remesh_keep(ops, geo, h: float, carve: "CarvedHull | None") -> np.ndarray:
    """The vertices a remesh keeps in place: with ``hold_carved`` the tips of sharply convex parts (mean
    curvature above :data:`~.tips.TIP_CURVATURE` per voxel) that the carved hull holds (no inward move allowed: no
    ball says the space there is empty) — the remesher's collapses would otherwise shorten a thin limb that the flow
    may not shorten; else none."""
    if carve is None:
        return np.zeros(0, dtype=np.int64)
    tips = tip_vertices(ops, geo, h, TIP_CURVATURE)
    if len(tips) == 0:
        return tips
    return tips[carve.limits(geo.vertices[tips]) <= 0.0]
