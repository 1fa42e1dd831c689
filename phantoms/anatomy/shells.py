"""Anatomy phantoms made of spherical pieces: a vault shell with foramina, a solid with cavities, a ball in a
socket (closed-form volume and area)."""

from __future__ import annotations

import math

import numpy as np

from geometry.errors import InputError

from ..base import DEFAULT_EXTENT, as_points
from .base import (ANATOMY_N, AnatomyPhantom, _affine, _cap_area, _cap_volume, _cylinder_error,
                   _cylinder_sdf, _frame, _manifold, _random_rotation, _sphere_sdf)

__all__ = ["VaultShell", "CavitySolid", "TouchingPair"]


class VaultShell(AnatomyPhantom):
    """A skull-vault-like shell: the part above z = z0 of a spherical shell (outer radius 0.6·extent) of
    ``thickness`` voxels, with ``foramina`` round through-holes of ``foramen_radius`` voxels in seeded
    directions.  One component; genus = the number of foramina (the cut shell is a thick disc; each through-hole
    adds a handle).  Closed-form volume and area."""

    name = "vault_shell"
    description = "thin spherical cap shell (skull-vault-like, 0.5-3 voxels) with round foramina: genus = holes"
    shape_kind = "thin shell"
    genus = 3
    has_creases = True

    def __init__(self, n: int = ANATOMY_N, extent: float = DEFAULT_EXTENT, seed: int = 0,
                 thickness: float = 1.5, foramina: int = 3, foramen_radius: float = 3.0):
        super().__init__(n, extent, seed, thickness=thickness, foramina=foramina, foramen_radius=foramen_radius)

    def _build(self, rng):
        M = _manifold().Manifold
        t = self._voxels("thickness", 0.25, 6.0)
        k = self._count("foramina", 0, 8)
        rho = self._voxels("foramen_radius", 1.0, 8.0)
        self.r_out = 0.6 * self.extent_ref
        self.r_in = self.r_out - t
        self.z0 = -0.25 * self.r_out                        # the cut: a little below the equator, as a vault's
        self.rho = rho
        shift = np.array([0.0, 0.0, -0.5 * (self.r_out + self.z0)])   # centre the vault's height in the box
        self.shift = shift
        shell = (self._sphere(self.r_out) - self._sphere(self.r_in)).trim_by_plane((0.0, 0.0, 1.0), self.z0)
        # foramina: directions whose hole stays 2 voxels above the cut and 2 voxels apart from the others
        half_angle = math.asin(rho / self.r_in)
        dirs = []
        for _ in range(10000):
            if len(dirs) == k:
                break
            uz = rng.uniform(0.15, 0.95)
            az = rng.uniform(0.0, 2.0 * math.pi)
            u = np.array([math.sqrt(1 - uz * uz) * math.cos(az), math.sqrt(1 - uz * uz) * math.sin(az), uz])
            z_low = self.r_in * math.cos(half_angle) * uz - rho * math.sqrt(1 - uz * uz)
            if z_low < self.z0 + 2.0 * self.h:
                continue
            if all(math.acos(float(np.clip(u @ w, -1, 1))) * self.r_in > 2 * rho + 2.0 * self.h for w in dirs):
                dirs.append(u)
        if len(dirs) < k:
            raise InputError(f"phantom {self.name!r}: {k} foramina of radius {self.foramen_radius:g} voxels do not "
                             "fit on the vault (fewer or smaller ones)")
        self.foramen_dirs = np.array(dirs).reshape(-1, 3)
        self.foramen_length = 1.2 * self.r_out
        seg = 4 * math.ceil(max(24, math.pi / math.acos(1 - 0.01 * self.h / rho)) / 4)
        seg = min(seg, 128)
        self.tessellation_error = max(self.tessellation_error, _cylinder_error(rho, seg))
        holes = [M.cylinder(self.foramen_length, rho, rho, seg).transform(_affine(_frame(u))) for u in dirs]
        solid = M.batch_boolean([shell] + holes, _manifold().OpType.Subtract) if holes else shell
        self.expected_components, self.expected_genus = 1, k
        return solid.translate(tuple(shift))

    def ideal_sdf(self, points):
        p = as_points(points) - self.shift
        r = np.linalg.norm(p, axis=1)
        d = np.maximum(np.maximum(r - self.r_out, self.r_in - r), self.z0 - p[:, 2])
        for u in self.foramen_dirs:
            d = np.maximum(d, -_cylinder_sdf(p, np.zeros(3), u, self.foramen_length, self.rho))
        return d

    def _foramen(self) -> tuple[float, float]:
        """(volume, area change) of one foramen through the shell."""
        ro, ri, rho = self.r_out, self.r_in, self.rho
        so, si = math.sqrt(ro * ro - rho * rho), math.sqrt(ri * ri - rho * rho)
        vol = 2.0 * math.pi / 3.0 * ((ro ** 3 - so ** 3) - (ri ** 3 - si ** 3))
        area = -2 * math.pi * ro * (ro - so) - 2 * math.pi * ri * (ri - si) + 2 * math.pi * rho * (so - si)
        return vol, area

    def ideal_volume(self):
        fv, _ = self._foramen()
        return _cap_volume(self.r_out, self.z0) - _cap_volume(self.r_in, self.z0) - len(self.foramen_dirs) * fv

    def ideal_area(self):
        _, fa = self._foramen()
        return (_cap_area(self.r_out, self.z0) + _cap_area(self.r_in, self.z0)
                + math.pi * (self.r_out ** 2 - self.r_in ** 2) + len(self.foramen_dirs) * fa)


class CavitySolid(AnatomyPhantom):
    """A ball (radius 0.64·extent) with ``count`` internal spherical cavities of radii from ``small`` to ``large``
    voxels, at seeded positions at least ``wall`` voxels from each other and from the outer surface: 1 + count surface
    components (the inner ones facing inward, into the cavity), genus 0.  Closed-form volume and area."""

    name = "cavity_solid"
    description = "ball with internal spherical cavities (organ-like): 1 + count surface components, inner facing in"
    shape_kind = "cavities"
    genus = 0
    has_creases = False

    def __init__(self, n: int = ANATOMY_N, extent: float = DEFAULT_EXTENT, seed: int = 0,
                 count: int = 3, small: float = 3.0, large: float = 5.0, wall: float = 2.0):
        super().__init__(n, extent, seed, count=count, small=small, large=large, wall=wall)

    def _build(self, rng):
        M = _manifold().Manifold
        k = self._count("count", 1, 8)
        small = self._voxels("small", 1.0, 30.0)
        large = self._voxels("large", self.small, 30.0)
        wall = self._voxels("wall", 0.5, 10.0)
        self.r_out = 0.64 * self.extent_ref
        radii = np.linspace(small, large, k) if k > 1 else np.array([large])
        centres: list[np.ndarray] = []
        for r in radii[::-1]:                                  # the largest first
            for _ in range(10000):
                c = rng.uniform(-1, 1, 3) * (self.r_out - r - wall)
                if np.linalg.norm(c) > self.r_out - r - wall:
                    continue
                if all(np.linalg.norm(c - cc) > r + rr + wall for cc, rr in zip(centres, radii[::-1])):
                    centres.append(c)
                    break
            else:
                raise InputError(f"phantom {self.name!r}: {k} cavities do not fit (fewer, smaller, or thinner walls)")
        self.cavity_radii = radii[::-1].copy()
        self.cavity_centres = np.array(centres)
        cavities = [self._sphere(r, c) for c, r in zip(self.cavity_centres, self.cavity_radii)]
        self.expected_components, self.expected_genus = 1 + k, 0
        return M.batch_boolean([self._sphere(self.r_out)] + cavities, _manifold().OpType.Subtract)

    def ideal_sdf(self, points):
        p = as_points(points)
        d = _sphere_sdf(p, np.zeros(3), self.r_out)
        for c, r in zip(self.cavity_centres, self.cavity_radii):
            d = np.maximum(d, -_sphere_sdf(p, c, r))
        return d

    def ideal_volume(self):
        return 4.0 / 3.0 * math.pi * (self.r_out ** 3 - float((self.cavity_radii ** 3).sum()))

    def ideal_area(self):
        return 4.0 * math.pi * (self.r_out ** 2 + float((self.cavity_radii ** 2).sum()))


class TouchingPair(AnatomyPhantom):
    """Two parts a fraction of a voxel apart (a joint: ball and socket): a ball of radius 0.4·extent in a cup —
    the part of a spherical shell (``socket`` voxels thick) below z = 0.3·radius — with a gap of ``gap`` voxels
    between them.  Two components, genus 0; merging them is the error.  Closed-form volume and area."""

    name = "touching_pair"
    description = "ball in a socket, gap 0.25 voxel (joint-like): 2 components that must not merge"
    shape_kind = "touching parts"
    genus = 0
    has_creases = True

    def __init__(self, n: int = ANATOMY_N, extent: float = DEFAULT_EXTENT, seed: int = 0,
                 gap: float = 0.25, socket: float = 4.0):
        super().__init__(n, extent, seed, gap=gap, socket=socket)

    def _build(self, rng):
        M = _manifold().Manifold
        g = self._voxels("gap", 0.05, 3.0)
        t = self._voxels("socket", 1.0, 10.0)
        self.r_ball = 0.4 * self.extent_ref
        self.r1, self.r2 = self.r_ball + g, self.r_ball + g + t
        self.z_cut = 0.3 * self.r_ball
        # a seeded tilt of the joint's axis (the rim is not a grid plane)
        self.rotation = _random_rotation(rng) if self.seed else _frame(np.array([0.3, 0.2, 1.0]))
        self.shift = np.zeros(3)
        ball = self._sphere(self.r_ball)
        cup = (self._sphere(self.r2) - self._sphere(self.r1)).trim_by_plane((0.0, 0.0, -1.0), -self.z_cut)
        if self.tessellation_error >= 0.25 * g:
            raise InputError(f"phantom {self.name!r}: a gap of {self.gap:g} voxels is below the tessellation's "
                             "resolution")
        self.expected_components, self.expected_genus = 2, 0
        return M.batch_boolean([ball, cup], _manifold().OpType.Add).transform(_affine(self.rotation))

    def ideal_sdf(self, points):
        q = as_points(points) @ self.rotation
        ball = _sphere_sdf(q, np.zeros(3), self.r_ball)
        r = np.linalg.norm(q, axis=1)
        cup = np.maximum(np.maximum(r - self.r2, self.r1 - r), q[:, 2] - self.z_cut)
        return np.minimum(ball, cup)

    def ideal_volume(self):
        # the cup below z_cut is the cap above −z_cut by symmetry
        cup = _cap_volume(self.r2, -self.z_cut) - _cap_volume(self.r1, -self.z_cut)
        return 4.0 / 3.0 * math.pi * self.r_ball ** 3 + cup

    def ideal_area(self):
        cup = (_cap_area(self.r2, -self.z_cut) + _cap_area(self.r1, -self.z_cut)
               + math.pi * (self.r2 ** 2 - self.r1 ** 2))
        return 4.0 * math.pi * self.r_ball ** 2 + cup
