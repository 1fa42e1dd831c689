"""Analytic phantoms with exact ground truth (see ``docs/PHANTOMS.md``): sphere, ellipsoid, fused spheres,
finite cylinder and torus, each implementing the :class:`phantoms.base.Phantom` interface in closed form.
"""

from __future__ import annotations

import numba
import numpy as np

from geometry.errors import InputError

from .base import Phantom, Truth, arc_positions, as_points, check_sample_count, unit

__all__ = ["Sphere", "Ellipsoid", "FusedSpheres", "Cylinder", "Torus"]


def _sphere_points(rng: np.random.Generator, n: int) -> np.ndarray:
    v = rng.standard_normal((n, 3))
    return unit(v, [1.0, 0.0, 0.0])


class Sphere(Phantom):
    name = "sphere"
    shape_kind = "smooth solid"
    description = "unit sphere, H = 1 everywhere"
    paper_snr_db = 44.5

    def __init__(self, radius: float = 1.0):
        self.radius = float(radius)

    @property
    def params(self):
        return {"radius": self.radius}

    @property
    def solid_volume(self):
        return 4.0 / 3.0 * np.pi * self.radius ** 3

    def sdf(self, points):
        return np.linalg.norm(as_points(points), axis=1) - self.radius

    def paper(self, points):
        p = as_points(points)
        return (p ** 2).sum(1) - self.radius ** 2

    def truth(self, points):
        p = as_points(points)
        n = unit(p, [1.0, 0.0, 0.0])
        r = np.linalg.norm(p, axis=1)
        P = len(p)
        return Truth(self.radius * n, np.abs(r - self.radius), r - self.radius, n,
                     np.full(P, 1.0 / self.radius), np.full(P, 1.0 / self.radius ** 2), np.full(P, np.inf))

    def sample_surface(self, n, seed=0):
        n = check_sample_count(n)
        u = _sphere_points(np.random.default_rng(seed), n)
        return self.radius * u, u

@numba.njit(cache=True, nogil=True, error_model="numpy")
def _root_compiled(ey, e2, lo, hi, max_iter):  # pragma: no cover - compiled; Ellipsoid._root is its reference
    """:meth:`Ellipsoid._root` row by row, compiled: the same safeguarded Newton steps in the same bracket, so
    the same roots (tests compare the two)."""
    eps4 = 4.0 * np.finfo(np.float64).eps
    n = ey.shape[0]
    t_out = np.empty(n)
    for r in range(n):
        a, b = lo[r], hi[r]
        t = b
        for _ in range(max_iter):
            f = -1.0
            fp = 0.0
            for i in range(3):
                q = ey[r, i] / (e2[i] + t)
                if not np.isfinite(q):
                    q = 0.0
                f += q * q
                fp -= 2.0 * q * q / (e2[i] + t)
            newton = t - f / fp
            if f > 0:
                a = t
            else:
                b = t
            ok = newton > a and newton < b and np.isfinite(newton)
            nxt = newton if ok else 0.5 * (a + b)
            tol = eps4 * max(1.0, abs(nxt))
            done = (ok and abs(nxt - t) <= tol) or b - a <= tol or f == 0
            if f != 0:
                t = nxt
            if done:
                break
        t_out[r] = t
    return t_out


class Ellipsoid(Phantom):
    name = "ellipsoid"
    shape_kind = "smooth solid"
    description = "ellipsoid with semi-axes (1, 2, 1); K in [1/4, 4]"
    paper_snr_db = 42.0

    def __init__(self, axes=(1.0, 2.0, 1.0)):
        self.axes = np.asarray(axes, dtype=np.float64)

    @property
    def params(self):
        return {"axes": tuple(float(a) for a in self.axes)}

    @property
    def solid_volume(self):
        return 4.0 / 3.0 * np.pi * float(np.prod(self.axes))

    def paper(self, points):
        p = as_points(points)
        return (p ** 2 / self.axes ** 2).sum(1) - 1.0

    def inside(self, points):
        """Exact and fast: the implicit equation Σ (x_i / a_i)² < 1 (the exact sdf needs a root find)."""
        return self.paper(points) < 0

    @staticmethod
    def _root(ey, e2, lo, hi, max_iter: int = 200):
        """Root of F(t) = Σ (ey_i / (e2_i + t))² − 1 in [lo, hi] (F(lo) > 0 ≥ F(hi)), per row.

        Newton steps (F is convex and decreasing, so after one step every iterate approaches the root from
        the left) inside the bracket, a bisection step whenever Newton would leave it; each evaluation
        shrinks the bracket.  A row stops when the step or the bracket is within 4 ulp; about 6–10 rounds
        instead of ~50 of plain bisection.
        """
        eps4 = 4 * np.finfo(float).eps
        t = hi.copy()
        act = np.arange(len(t))
        for _ in range(max_iter):
            if not len(act):
                break
            ta = t[act]
            with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
                q = ey[act] / (e2 + ta[:, None])
                q = np.where(np.isfinite(q), q, 0.0)
                f = (q * q).sum(1) - 1.0
                fp = -2.0 * (q * q / (e2 + ta[:, None])).sum(1)
                newton = ta - f / fp
            pos = f > 0
            lo[act] = np.where(pos, ta, lo[act])
            hi[act] = np.where(pos, hi[act], ta)
            la, ha = lo[act], hi[act]
            ok = (newton > la) & (newton < ha) & np.isfinite(newton)
            nxt = np.where(ok, newton, 0.5 * (la + ha))
            tol = eps4 * np.maximum(1.0, np.abs(nxt))
            done = (ok & (np.abs(nxt - ta) <= tol)) | (ha - la <= tol) | (f == 0)
            t[act] = np.where(f == 0, ta, nxt)
            act = act[~done]
        return t

    def closest_point(self, points) -> np.ndarray:
        """Closest point on the ellipsoid by a robust 1-D root find on the Lagrange multiplier.

        x_i = e_i² y_i / (e_i² + t) with t the root of F(t) = Σ (e_i y_i / (e_i² + t))² − 1 on
        (−min e², ∞), where F is strictly decreasing and convex: safeguarded Newton in a bracket that always
        holds the root (:meth:`_root`); the point is on the ellipsoid to ~1e-13 (bisection: slightly closer, but
        slower).
        The degenerate case (the query lies on the plane(s) of the smallest semi-axis, inside, where the root sits
        at the end of the bracket) is handled in closed form.
        """
        p = as_points(points)
        y = np.abs(p)
        e = self.axes
        e2 = e ** 2
        m = e2.min()
        deg = np.isclose(e2, m, rtol=0, atol=1e-15)
        ey = e * y

        lo = np.full(len(p), -m)
        hi = np.maximum(e.max() * np.linalg.norm(y, axis=1) - m, 0.0)
        hi = np.maximum(hi, lo + 1e-12)
        t = _root_compiled(np.ascontiguousarray(ey), e2, lo, hi, 200)
        with np.errstate(invalid="ignore", divide="ignore"):
            x = e2 * y / (e2 + t[:, None])
        x = np.where(np.isfinite(x), x, 0.0)  # 0/0 on a degenerate axis: fixed just below
        # degenerate: y = 0 on every smallest axis and the root is at t = -m
        ydeg_zero = np.all(y[:, deg] == 0.0, axis=1)
        if ydeg_zero.any() and (~deg).any():
            nd = ~deg
            xnd = e2[nd] * y[:, nd] / (e2[nd] - m)
            f_end = ((xnd ** 2) / e2[nd]).sum(1)
            case = ydeg_zero & (f_end <= 1.0)
            if case.any():
                xc = np.zeros((int(case.sum()), 3))
                xc[:, nd] = xnd[case]
                first_deg = int(np.flatnonzero(deg)[0])
                xc[:, first_deg] = np.sqrt(np.maximum(0.0, m * (1.0 - f_end[case])))
                x[case] = xc
        return np.copysign(x, np.where(p == 0, 1.0, p))

    def sdf(self, points):
        p = as_points(points)
        x = self.closest_point(p)
        d = np.linalg.norm(p - x, axis=1)
        return np.where((p ** 2 / self.axes ** 2).sum(1) < 1.0, -d, d)

    def curvature_at(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(H, K) at points on the ellipsoid (docs/PHANTOMS.md formulas)."""
        a, b, c = self.axes
        s = (x ** 2 / self.axes ** 4).sum(1)
        K = 1.0 / ((a * b * c) ** 2 * s ** 2)
        H = np.abs((x ** 2).sum(1) - (self.axes ** 2).sum()) / (2.0 * (a * b * c) ** 2 * s ** 1.5)
        return H, K

    def truth(self, points):
        p = as_points(points)
        x = self.closest_point(p)
        d = np.linalg.norm(p - x, axis=1)
        inside = (p ** 2 / self.axes ** 2).sum(1) < 1.0
        n = unit(x / self.axes ** 2, [1.0, 0.0, 0.0])
        H, K = self.curvature_at(x)
        return Truth(x, d, np.where(inside, -d, d), n, H, K, np.full(len(p), np.inf))

    def sample_surface(self, n, seed=0):
        e = self.axes
        emin = e.min()

        def propose(rng, m):
            return _sphere_points(rng, m)

        def accept(u):  # area element of u -> e*u relative to its maximum
            return np.sqrt((u ** 2 / e ** 2).sum(1)) * emin

        pts = self._rejection(n, seed, propose, accept) * e
        return pts, unit(pts / e ** 2, [1.0, 0.0, 0.0])


class FusedSpheres(Phantom):
    name = "fused_spheres"
    shape_kind = "smooth solid"
    description = "union of two balls r = 0.8 at z = ±0.7; concave crease circle at z = 0, radius √0.15"
    has_creases = True
    paper_snr_db = 43.2

    def __init__(self, radius: float = 0.8, offset: float = 0.7):
        self.radius, self.offset = float(radius), float(offset)
        if not 0 < self.offset < self.radius:
            raise InputError("fused_spheres needs 0 < offset < radius")
        self.crease_radius = float(np.sqrt(self.radius ** 2 - self.offset ** 2))
        self.centres = np.array([[0.0, 0.0, self.offset], [0.0, 0.0, -self.offset]])

    @property
    def params(self):
        return {"radius": self.radius, "offset": self.offset}

    @property
    def solid_volume(self):
        """Two balls minus their lens (the overlap of two balls of radius r, centres d apart: π(4r + d)(2r − d)²/12)."""
        r, d = self.radius, 2 * self.offset
        return 2 * 4.0 / 3.0 * np.pi * r ** 3 - np.pi * (4 * r + d) * (2 * r - d) ** 2 / 12

    @property
    def crease_length(self):
        return 2 * np.pi * self.crease_radius

    def crease_samples(self, n):
        """Evenly spaced points on the crease circle (radius √(r² − offset²) at z = 0)."""
        t = 2 * np.pi * (np.arange(n) + 0.5) / n
        return np.column_stack([self.crease_radius * np.cos(t), self.crease_radius * np.sin(t), np.zeros(n)])

    def paper(self, points):
        p = as_points(points)
        return np.minimum(((p - self.centres[0]) ** 2).sum(1), ((p - self.centres[1]) ** 2).sum(1)) \
            - self.radius ** 2

    def truth(self, points):
        p = as_points(points)
        r, rc = self.radius, self.crease_radius
        cand_d, cand_x, cand_n = [], [], []
        dists = []
        for k, c in enumerate(self.centres):
            w = p - c
            dk = np.linalg.norm(w, axis=1)
            dists.append(dk)
            u = unit(w, [1.0, 0.0, 0.0] if k == 0 else [1.0, 0.0, 0.0])
            q = c + r * u
            valid = q[:, 2] >= 0.0 if k == 0 else q[:, 2] <= 0.0
            cand_d.append(np.where(valid, np.abs(dk - r), np.inf))
            cand_x.append(q)
            cand_n.append(u)
        inside = np.minimum(dists[0], dists[1]) < r
        # crease circle
        rho = np.hypot(p[:, 0], p[:, 1])
        radial = unit(np.column_stack([p[:, 0], p[:, 1], np.zeros(len(p))]), [1.0, 0.0, 0.0])
        cc = rc * radial
        wc = p - cc
        dc = np.linalg.norm(wc, axis=1)
        nc = unit(wc, [1.0, 0.0, 0.0]) * np.where(inside, -1.0, 1.0)[:, None]
        nc[dc < 1e-300] = radial[dc < 1e-300]
        cand_d.append(np.sqrt((rho - rc) ** 2 + p[:, 2] ** 2))
        cand_x.append(cc)
        cand_n.append(nc)
        D = np.stack(cand_d, axis=1)
        which = np.argmin(D, axis=1)
        rows = np.arange(len(p))
        d = D[rows, which]
        x = np.stack(cand_x, axis=1)[rows, which]
        n = np.stack(cand_n, axis=1)[rows, which]
        crease = np.hypot(np.hypot(x[:, 0], x[:, 1]) - rc, x[:, 2])
        crease[which == 2] = 0.0
        on_crease = crease <= 1e-12
        H = np.where(on_crease, np.nan, 1.0 / r)
        K = np.where(on_crease, np.nan, 1.0 / r ** 2)
        return Truth(x, d, np.where(inside, -d, d), n, H, K, crease)

    def sdf(self, points):
        return self.truth(points).signed

    def inside(self, points):
        """Exactly ``sdf(points) < 0`` without the closest points: inside a ball and off the surface.  Only a point
        at distance exactly r from a centre, or exactly on the crease circle, may be on the surface (φ = 0, not
        inside): those take the full :meth:`truth`."""
        p = as_points(points)
        d0 = np.linalg.norm(p - self.centres[0], axis=1)         # as truth() computes them
        d1 = np.linalg.norm(p - self.centres[1], axis=1)
        out = np.minimum(d0, d1) < self.radius
        on_crease = np.sqrt((np.hypot(p[:, 0], p[:, 1]) - self.crease_radius) ** 2 + p[:, 2] ** 2) == 0.0
        unsure = out & ((d0 == self.radius) | (d1 == self.radius) | on_crease)
        if unsure.any():
            out[unsure] = self.sdf(p[unsure]) < 0
        return out

    def sample_surface(self, n, seed=0):
        c = self.centres

        def propose(rng, m):
            k = rng.integers(0, 2, m)
            return c[k] + self.radius * _sphere_points(rng, m)

        def accept(q):
            keep = np.minimum(np.linalg.norm(q - c[0], axis=1), np.linalg.norm(q - c[1], axis=1))
            return (keep >= self.radius - 1e-12).astype(float)

        pts = self._rejection(n, seed, propose, accept)
        return pts, self.truth(pts).normal


class Cylinder(Phantom):
    name = "cylinder"
    shape_kind = "smooth solid"
    description = "finite cylinder r = 0.4, |z| <= 1 (flat caps; rims are creases)"
    has_creases = True
    paper_snr_db = 42.0

    def __init__(self, radius: float = 0.4, half_height: float = 1.0):
        self.radius, self.half_height = float(radius), float(half_height)

    @property
    def params(self):
        return {"radius": self.radius, "half_height": self.half_height}

    @property
    def solid_volume(self):
        return np.pi * self.radius ** 2 * 2 * self.half_height

    @property
    def crease_length(self):
        return 4 * np.pi * self.radius

    def crease_samples(self, n):
        """Evenly spaced points on the two rim circles (radius r at z = ±half_height), by arc length."""
        k, frac = arc_positions([2 * np.pi * self.radius] * 2, n)
        t = 2 * np.pi * frac
        return np.column_stack([self.radius * np.cos(t), self.radius * np.sin(t),
                                np.where(k == 0, -self.half_height, self.half_height)])

    def paper(self, points):
        p = as_points(points)
        return np.maximum.reduce([p[:, 2] - self.half_height, -p[:, 2] - self.half_height,
                                  p[:, 0] ** 2 + p[:, 1] ** 2 - self.radius ** 2])

    def sdf(self, points):
        p = as_points(points)
        a = np.hypot(p[:, 0], p[:, 1]) - self.radius
        b = np.abs(p[:, 2]) - self.half_height
        return np.minimum(np.maximum(a, b), 0.0) + np.hypot(np.maximum(a, 0.0), np.maximum(b, 0.0))

    def truth(self, points):
        p = as_points(points)
        r, hh = self.radius, self.half_height
        rho = np.hypot(p[:, 0], p[:, 1])
        u = unit(np.column_stack([p[:, 0], p[:, 1], np.zeros(len(p))]), [1.0, 0.0, 0.0])
        sz = np.where(p[:, 2] >= 0, 1.0, -1.0)
        a, b = rho - r, np.abs(p[:, 2]) - hh
        rim = (a > 0) & (b > 0)
        side = ((a > 0) & (b <= 0)) | ((a <= 0) & (b <= 0) & (-a <= -b))
        cap = ~rim & ~side
        x = np.empty_like(p)
        n = np.empty_like(p)
        x[side] = r * u[side] + np.column_stack([0 * rho, 0 * rho, p[:, 2]])[side]
        n[side] = u[side]
        x[cap] = np.column_stack([p[:, 0], p[:, 1], sz * hh])[cap]
        n[cap] = np.column_stack([0 * rho, 0 * rho, sz])[cap]
        x[rim] = (r * u + np.column_stack([0 * rho, 0 * rho, sz * hh]))[rim]
        n[rim] = unit(p[rim] - x[rim], [1.0, 0.0, 0.0])
        d = np.linalg.norm(p - x, axis=1)
        signed = self.sdf(p)
        crease = np.where(side, hh - np.abs(x[:, 2]), np.where(cap, r - np.hypot(x[:, 0], x[:, 1]), 0.0))
        crease = np.maximum(crease, 0.0)
        on = crease <= 1e-12
        H = np.where(on, np.nan, np.where(side, 1.0 / (2 * r), 0.0))
        K = np.where(on, np.nan, 0.0)
        return Truth(x, d, signed, n, H, K, crease)

    def sample_surface(self, n, seed=0):
        r, hh = self.radius, self.half_height
        a_side, a_cap = 2 * np.pi * r * 2 * hh, np.pi * r ** 2

        def propose(rng, m):
            part = rng.choice(3, size=m, p=np.array([a_side, a_cap, a_cap]) / (a_side + 2 * a_cap))
            th = rng.uniform(0, 2 * np.pi, m)
            z = rng.uniform(-hh, hh, m)
            rr = r * np.sqrt(rng.random(m))
            pts = np.column_stack([r * np.cos(th), r * np.sin(th), z])
            capz = np.where(part == 1, hh, -hh)
            cap_pts = np.column_stack([rr * np.cos(th), rr * np.sin(th), capz])
            return np.where((part == 0)[:, None], pts, cap_pts)

        pts = self._rejection(n, seed, propose, lambda q: np.ones(len(q)))
        return pts, self.truth(pts).normal


class Torus(Phantom):
    name = "torus"
    shape_kind = "smooth solid"
    description = "torus R = 1, r = 0.35 about the z axis (genus 1: a sphere-topology method must fail visibly)"
    genus = 1
    paper_snr_db = 42.0

    def __init__(self, major: float = 1.0, minor: float = 0.35):
        self.major, self.minor = float(major), float(minor)

    @property
    def params(self):
        return {"major": self.major, "minor": self.minor}

    @property
    def solid_volume(self):
        return 2 * np.pi ** 2 * self.major * self.minor ** 2

    def paper(self, points):
        p = as_points(points)
        R, r = self.major, self.minor
        rho2 = p[:, 0] ** 2 + p[:, 1] ** 2
        return ((p ** 2).sum(1) + R ** 2 - r ** 2) ** 2 - 4 * R ** 2 * rho2

    def sdf(self, points):
        p = as_points(points)
        return np.hypot(np.hypot(p[:, 0], p[:, 1]) - self.major, p[:, 2]) - self.minor

    def truth(self, points):
        p = as_points(points)
        R, r = self.major, self.minor
        u = unit(np.column_stack([p[:, 0], p[:, 1], np.zeros(len(p))]), [1.0, 0.0, 0.0])
        c = R * u
        w = p - c
        dw = np.linalg.norm(w, axis=1)
        n = unit(w, [0.0, 0.0, 1.0])
        small = dw < 1e-300
        n[small] = u[small]
        x = c + r * n
        cosv = (n * u).sum(1)
        k1, k2 = 1.0 / r, cosv / (R + r * cosv)
        return Truth(x, np.abs(dw - r), dw - r, n, 0.5 * (k1 + k2), k1 * k2, np.full(len(p), np.inf))

    def sample_surface(self, n, seed=0):
        R, r = self.major, self.minor

        def propose(rng, m):
            th = rng.uniform(0, 2 * np.pi, m)
            v = rng.uniform(0, 2 * np.pi, m)
            rho = R + r * np.cos(v)
            return np.column_stack([rho * np.cos(th), rho * np.sin(th), r * np.sin(v)])

        def accept(q):
            return np.hypot(q[:, 0], q[:, 1]) / (R + r)

        pts = self._rejection(n, seed, propose, accept)
        return pts, self.truth(pts).normal
