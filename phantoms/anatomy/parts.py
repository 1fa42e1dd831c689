"""Anatomy phantoms made of many pieces: a branching tube tree, separate vertebra-like discs, a strut lattice
of high genus."""

from __future__ import annotations

import math

import numpy as np

from geometry.errors import InputError

from ..base import DEFAULT_EXTENT, as_points
from .base import (ANATOMY_N, AnatomyPhantom, _affine, _capsule_sdf, _cylinder_error,
                   _cylinder_sdf, _frame, _manifold, _random_rotation, _segment_distance, _segments_for,
                   _sphere_error)

__all__ = ["VesselTree", "SpineParts", "Lattice"]


class VesselTree(AnatomyPhantom):
    """A branching tube tree (vessel / airway-like): ``levels`` generations of bifurcating capsules from a root of
    ``root_radius`` voxels, each child's radius ``ratio`` times its parent's (default: 3 voxels down to 0.58), in
    seeded directions that keep non-adjacent branches 1.5 voxels apart.  One component, genus 0; no closed-form
    volume (the capsules overlap at the joints)."""

    name = "vessel_tree"
    description = "branching tube tree (vessel-like): capsule radii from 3 voxels down to below one voxel"
    shape_kind = "tubes"
    genus = 0
    has_creases = False

    def __init__(self, n: int = ANATOMY_N, extent: float = DEFAULT_EXTENT, seed: int = 0,
                 root_radius: float = 3.0, ratio: float = 0.72, levels: int = 6):
        super().__init__(n, extent, seed, root_radius=root_radius, ratio=ratio, levels=levels)

    def _build(self, rng):
        M = _manifold().Manifold
        r0 = self._voxels("root_radius", 0.5, 10.0)
        levels = self._count("levels", 1, 7)
        if not 0.4 <= self.ratio <= 1.0:
            raise InputError(f"phantom {self.name!r}: ratio must be in [0.4, 1]; got {self.ratio:g}")
        e = self.extent_ref
        bound = 0.78 * e
        margin = 1.5 * self.h
        segments: list[tuple[np.ndarray, np.ndarray, float, int]] = []   # (start, end, radius, parent)
        start = np.array([0.0, 0.0, -0.68 * e])
        segments.append((start, start + np.array([0.0, 0.0, 0.36 * e]), r0, -1))
        frontier = [0]
        length = 0.36 * e
        for _ in range(1, levels):
            length *= 0.8
            nxt = []
            for parent in frontier:
                a, b, r, _ = segments[parent]
                axis = (b - a) / np.linalg.norm(b - a)
                rc = r * self.ratio
                frame = _frame(axis)
                for attempt in range(300):                        # a bifurcation in a random plane
                    phi = rng.uniform(0, 2 * math.pi)
                    side = frame[:, 0] * math.cos(phi) + frame[:, 1] * math.sin(phi)
                    angles = (rng.uniform(0.35, 0.75), -rng.uniform(0.35, 0.75))
                    reach = length * (1.0 if attempt < 100 else 0.7 if attempt < 200 else 0.45)
                    ends = [b + reach * (math.cos(t) * axis + math.sin(t) * side) for t in angles]
                    # siblings diverge from their common start, so they close no loop: only the others count
                    # near its start a branch lies inside its parent's end sphere: clearance is asked beyond it
                    if all(np.all(np.abs(q) <= bound) and self._clear(segments, parent, b + (r + margin) * (q - b) /
                                                                      np.linalg.norm(q - b), q, rc, margin)
                           for q in ends):
                        break
                else:
                    continue                                      # no room: this branch ends here
                for q in ends:
                    segments.append((b, q, rc, parent))
                    nxt.append(len(segments) - 1)
            frontier = nxt
        self.segments = segments
        tol = max(0.05 * self.h, 2e-3 * min(s[2] for s in segments))
        capsules = []
        for a, b, r, _ in segments:
            seg = _segments_for(r, tol, lo=16, hi=96)
            self.tessellation_error = max(self.tessellation_error, _sphere_error(r, seg))
            s = M.sphere(r, seg)
            capsules.append(M.batch_hull([s.translate(tuple(a)), s.translate(tuple(b))]))
        self.expected_components, self.expected_genus = 1, 0
        return M.batch_boolean(capsules, _manifold().OpType.Add)

    @staticmethod
    def _clear(segments, parent, a, b, r, margin) -> bool:
        """The new branch a→b of radius r keeps ``margin`` from every branch but its parent and the parent's
        other children (its start is the parent's end; the genus check after the union is the last word)."""
        for i, (c, d, rr, _) in enumerate(segments):
            if i == parent or segments[i][3] == parent:
                continue
            if _segment_distance(a, b, c, d) <= r + rr + margin:
                return False
        return True

    def ideal_sdf(self, points):
        p = as_points(points)
        return np.min([_capsule_sdf(p, a, b, r) for a, b, r, _ in self.segments], axis=0)

    @property
    def radii(self) -> np.ndarray:
        """The branch radii (world units), root first."""
        return np.array([s[2] for s in self.segments])


class SpineParts(AnatomyPhantom):
    """``count`` vertebral-body-like discs (cylinders of radius 0.28·extent) stacked on a seeded tilted axis, the
    gaps between neighbours drawn uniformly in [``gap_min``, ``gap_max``] voxels: ``count`` components, genus 0.
    Closed-form volume and area (of the cylinders; the mesh's are the inscribed prisms')."""

    name = "spine_parts"
    description = "stack of separate vertebra-like discs, gaps 0.5-2 voxels: count components"
    shape_kind = "many parts"
    genus = 0
    has_creases = True

    def __init__(self, n: int = ANATOMY_N, extent: float = DEFAULT_EXTENT, seed: int = 0,
                 count: int = 5, gap_min: float = 0.5, gap_max: float = 2.0):
        super().__init__(n, extent, seed, count=count, gap_min=gap_min, gap_max=gap_max)

    def _build(self, rng):
        M = _manifold().Manifold
        k = self._count("count", 2, 12)
        gmin = self._voxels("gap_min", 0.1, 10.0)
        gmax = self._voxels("gap_max", self.gap_min, 10.0)
        e = self.extent_ref
        self.radius = 0.28 * e
        self.gaps = rng.uniform(gmin, gmax, k - 1)
        span = 1.3 * e                                          # the stack's length along its axis
        self.height = (span - self.gaps.sum()) / k
        # a tilt of 10-25 degrees: the gaps are not grid planes
        tilt, az = math.radians(rng.uniform(10, 25)), rng.uniform(0, 2 * math.pi)
        self.axis = np.array([math.sin(tilt) * math.cos(az), math.sin(tilt) * math.sin(az), math.cos(tilt)])
        self.rotation = _frame(self.axis)
        seg = _segments_for(self.radius, 0.02 * self.h, lo=32, hi=192)
        self.segments_per_circle = seg
        self.tessellation_error = _cylinder_error(self.radius, seg)
        z = -0.5 * span
        self.bottoms = []
        discs = []
        for i in range(k):
            self.bottoms.append(z)
            discs.append(M.cylinder(self.height, self.radius, self.radius, seg).translate((0.0, 0.0, z)))
            z += self.height + (self.gaps[i] if i < k - 1 else 0.0)
        self.expected_components, self.expected_genus = k, 0
        return M.batch_boolean(discs, _manifold().OpType.Add).transform(_affine(self.rotation))

    def ideal_sdf(self, points):
        p = as_points(points)
        return np.min([_cylinder_sdf(p, z * self.axis, self.axis, self.height, self.radius) for z in self.bottoms],
                      axis=0)

    def ideal_volume(self):
        return len(self.bottoms) * math.pi * self.radius ** 2 * self.height

    def ideal_area(self):
        return len(self.bottoms) * 2 * math.pi * self.radius * (self.radius + self.height)

    def prism_volume(self) -> float:
        """The inscribed regular-prism discs' volume (what the mesh encloses exactly)."""
        n = self.segments_per_circle
        return len(self.bottoms) * 0.5 * n * self.radius ** 2 * math.sin(2 * math.pi / n) * self.height


class Lattice(AnatomyPhantom):
    """A trabecular-like lattice: round rods of ``strut`` voxels diameter along the lines of a cubic grid of
    (cells + 1)³ nodes spanning 0.72·extent (each rod 1.5 radii longer than the grid at both ends), in a seeded
    rotation (not grid-aligned).  One component of genus 3k²(k − 1) − k³ + 1 for k = cells + 1 nodes per axis (81
    by default: the cycle rank of the lattice graph).  Closed-form volume and area: at every node three equal
    orthogonal cylinders cross, whose union loses 8√2 r³ of volume and 24√2 r² of area to the overlaps
    (Steinmetz bicylinder 16r³/3 and 16r², tricylinder 8(2 − √2) r³ and 24(2 − √2) r²)."""

    name = "lattice"
    description = "rotated cubic lattice of round rods (trabecular-like): genus 81 by default"
    shape_kind = "high genus"
    genus = 81
    has_creases = True
    #: the rods' polygon phases per axis (fractions of a segment): generic, so no two rods' facets or edges
    #: coincide (coplanar facets make a boolean's output carry zero-area slivers)
    _PHASES = (0.31, 0.57, 0.83)

    def __init__(self, n: int = ANATOMY_N, extent: float = DEFAULT_EXTENT, seed: int = 0,
                 cells: int = 3, strut: float = 2.5):
        super().__init__(n, extent, seed, cells=cells, strut=strut)

    def _build(self, rng):
        M = _manifold().Manifold
        cells = self._count("cells", 1, 6)
        r = 0.5 * self._voxels("strut", 0.5, 20.0)
        k = cells + 1
        span = 0.72 * self.extent_ref
        a = span / cells
        if a - 2 * r < 1.0 * self.h:
            raise InputError(f"phantom {self.name!r}: struts of {self.strut:g} voxels leave holes under one voxel "
                             f"with {cells} cells (thinner struts or fewer cells)")
        self.k, self.a, self.r = k, a, r
        self.length = span + 3.0 * r
        self.nodes = -0.5 * span + a * np.arange(k)
        self.rotation = _random_rotation(rng)
        seg = 4 * math.ceil(max(24, math.pi / math.acos(1 - 0.02 * self.h / r)) / 4)
        self.segments_per_circle = seg = min(seg, 96)
        self.tessellation_error = _cylinder_error(r, seg)
        # rotations taking the cylinder's z axis to x, y, z, after turning it by the axis's phase
        to_axis = (np.array([[0.0, 0, 1], [0, 1, 0], [-1, 0, 0]]), np.array([[1.0, 0, 0], [0, 0, 1], [0, -1, 0]]),
                   np.eye(3))
        self.axes = np.eye(3)
        bars = []
        for ax in range(3):
            t = 2 * math.pi / seg * self._PHASES[ax]
            rz = np.array([[math.cos(t), -math.sin(t), 0], [math.sin(t), math.cos(t), 0], [0, 0, 1]])
            rod = M.cylinder(self.length, r, r, seg, True).transform(_affine(to_axis[ax] @ rz))
            for i in self.nodes:
                for j in self.nodes:
                    c = np.insert(np.array([i, j], float), ax, 0.0)
                    bars.append(rod.translate(tuple(c)))
        self.expected_components, self.expected_genus = 1, 3 * k * k * (k - 1) - k ** 3 + 1
        return M.batch_boolean(bars, _manifold().OpType.Add).transform(_affine(self.rotation))

    def ideal_sdf(self, points):
        q = as_points(points) @ self.rotation                  # into the lattice's frame
        d = np.full(len(q), np.inf)
        for ax in range(3):
            u = self.axes[ax]
            for i in self.nodes:
                for j in self.nodes:
                    start = np.insert(np.array([i, j], float), ax, -0.5 * self.length)
                    d = np.minimum(d, _cylinder_sdf(q, start, u, self.length, self.r))
        return d

    def ideal_volume(self):
        k, r = self.k, self.r
        return 3 * k * k * math.pi * r * r * self.length - k ** 3 * 8 * math.sqrt(2) * r ** 3

    def ideal_area(self):
        k, r = self.k, self.r
        return 3 * k * k * 2 * math.pi * r * (self.length + r) - k ** 3 * 24 * math.sqrt(2) * r * r
