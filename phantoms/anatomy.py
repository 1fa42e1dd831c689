"""Anatomy-like phantoms with exact truth: the shapes medical segmentations hold and smooth solids do not —
a thin vault with foramina, a branching vessel tree, a solid with cavities, separate vertebra-like parts, a
porous lattice of high genus and two parts a fraction of a voxel apart.

Each is a boolean combination of finely tessellated primitives (spheres, capsules, cylinders, boxes) computed
by manifold3d, whose booleans are exact in topology and robust (no crossing, no gap: a closed, oriented,
embedded polyhedron); the phantom is that polyhedron as a :class:`~phantoms.mesh.MeshPhantom` (not normalised),
so the truth *is* the polyhedron: the certified exact distance, the winding-number inside test, area-uniform
surface samples, and exact volume, area, components and genus of the mesh.  A ``min`` of primitive distances
would have the right zero set but not the right distance inside; it is kept only as :meth:`ideal_sdf`, the
ideal (untessellated) shape's CSG bound, for the tests: its sign is exact and its magnitude a lower bound of the
distance, so wherever ``|ideal_sdf| > tessellation_error`` the mesh and the ideal shape agree on the side.

Sizes: the body fits the default box [−2.5, 2.5]³ as the smooth phantoms do (in fractions of ``extent``); the
thin features — thickness, gaps, radii, struts — are given **in voxels** of the grid with ``n`` points per axis
over [−extent, extent]³ (h = 2·extent / (n − 1)); ``seed`` draws the positions and directions.  The designed
number of components and genus are computed from the parameters (:attr:`expected_components`,
:attr:`expected_genus`) and checked against the built mesh: parameters that would merge or cut parts are refused.
Where the ideal shape has a closed-form volume and area (:meth:`ideal_volume`, :meth:`ideal_area`), the mesh's
differ from them by the tessellation error only.

A phantom with non-default parameters is named ``NAME?key=value&...`` (``vault_shell?thickness=0.75&seed=2``),
see :func:`parse_anatomy_spec`.
"""

from __future__ import annotations

import math
from typing import ClassVar

import numpy as np

from geometry.errors import InputError

from .base import DEFAULT_EXTENT, as_points, check_extent, check_n
from .mesh import MeshPhantom

__all__ = ["ANATOMY", "AnatomyPhantom", "VaultShell", "VesselTree", "CavitySolid", "SpineParts", "Lattice",
           "TouchingPair", "parse_anatomy_spec", "ANATOMY_N"]

#: the grid size the voxel sizes refer to by default
ANATOMY_N = 64
#: the shape parameters that are counts
_INT_PARAMS = ("n", "seed", "foramina", "count", "cells", "levels")


# ----------------------------------------------------------------------------------------------- primitives
def _manifold():
    try:
        import manifold3d
    except ImportError:                                       # pragma: no cover - a core dependency
        raise InputError("the anatomy phantoms need the Python package manifold3d: pip install manifold3d") from None
    return manifold3d


def _segments_for(radius: float, tolerance: float, lo: int = 12, hi: int = 160) -> int:
    """Circular segments (a multiple of 4) so that a manifold3d sphere of ``radius`` lies within ``tolerance``
    of the ideal one (:func:`_sphere_error`)."""
    if radius <= tolerance:
        return lo
    n = math.ceil(2.0 * math.pi / math.acos(1.0 - tolerance / radius))
    return int(min(hi, max(lo, 4 * math.ceil(n / 4))))


def _sphere_error(radius: float, segments: int) -> float:
    """Bound of the distance between manifold3d's ``sphere(radius, segments)`` (a subdivided octahedron, its
    vertices on the sphere) and the sphere: r·(1 − cos(2π/n)) (measured deviation r·1.33(π/n)², below it)."""
    return radius * (1.0 - math.cos(2.0 * math.pi / segments))


def _cylinder_error(radius: float, segments: int) -> float:
    """The inscribed regular n-gon's largest gap to its circle: r·(1 − cos(π/n))."""
    return radius * (1.0 - math.cos(math.pi / segments))


def _frame(u: np.ndarray) -> np.ndarray:
    """A rotation (3, 3) taking +z to the unit vector ``u``."""
    u = np.asarray(u, float) / np.linalg.norm(u)
    a = np.array([1.0, 0.0, 0.0]) if abs(u[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    x = np.cross(a, u)
    x /= np.linalg.norm(x)
    y = np.cross(u, x)
    return np.stack([x, y, u], axis=1)


def _affine(rot: np.ndarray, shift=(0.0, 0.0, 0.0)) -> list:
    """manifold3d's 3 × 4 affine matrix."""
    return np.concatenate([np.asarray(rot, float), np.asarray(shift, float)[:, None]], axis=1).tolist()


def _random_rotation(rng: np.random.Generator) -> np.ndarray:
    """A uniformly random rotation (3, 3): the Q of a Gaussian matrix's QR, signs fixed."""
    q, r = np.linalg.qr(rng.standard_normal((3, 3)))
    q = q * np.sign(np.diag(r))
    if np.linalg.det(q) < 0:
        q[:, 0] = -q[:, 0]
    return q


def _cap_volume(radius: float, z0: float) -> float:
    """Volume of the ball of ``radius`` (centred at 0) above the plane z = z0 (|z0| ≤ radius)."""
    return math.pi * (radius - z0) ** 2 * (2.0 * radius + z0) / 3.0


def _cap_area(radius: float, z0: float) -> float:
    """Area of the sphere of ``radius`` above the plane z = z0."""
    return 2.0 * math.pi * radius * (radius - z0)


def _sphere_sdf(p: np.ndarray, centre, radius: float) -> np.ndarray:
    return np.linalg.norm(p - np.asarray(centre, float), axis=1) - radius


def _capsule_sdf(p: np.ndarray, a, b, radius: float) -> np.ndarray:
    a, b = np.asarray(a, float), np.asarray(b, float)
    ab = b - a
    t = np.clip((p - a) @ ab / float(ab @ ab), 0.0, 1.0)
    return np.linalg.norm(p - (a + t[:, None] * ab), axis=1) - radius


def _cylinder_sdf(p: np.ndarray, a, u, length: float, radius: float) -> np.ndarray:
    """Exact signed distance to the solid cylinder of ``radius`` on the axis from ``a`` along unit ``u``."""
    q = p - np.asarray(a, float)
    t = q @ np.asarray(u, float)
    r = np.linalg.norm(q - t[:, None] * np.asarray(u, float), axis=1)
    dr = r - radius
    dz = np.abs(t - 0.5 * length) - 0.5 * length
    out = np.hypot(np.maximum(dr, 0.0), np.maximum(dz, 0.0))
    return out + np.minimum(np.maximum(dr, dz), 0.0)


def _box_sdf(p: np.ndarray, centre, half) -> np.ndarray:
    """Exact signed distance to an axis-aligned box (``p`` in the box's frame)."""
    q = np.abs(p - np.asarray(centre, float)) - np.asarray(half, float)
    return np.linalg.norm(np.maximum(q, 0.0), axis=1) + np.minimum(q.max(axis=1), 0.0)


def _segment_distance(a0, a1, b0, b1, samples: int = 24) -> float:
    """Distance between segments [a0, a1] and [b0, b1] (dense sampling of one, exact distance to the other):
    exact to within half the sampling step, which the callers' margins cover."""
    t = np.linspace(0.0, 1.0, samples)[:, None]
    pts = a0 + t * (a1 - a0)
    ab = b1 - b0
    s = np.clip((pts - b0) @ ab / max(float(ab @ ab), 1e-300), 0.0, 1.0)
    return float(np.linalg.norm(pts - (b0 + s[:, None] * ab), axis=1).min())


# ----------------------------------------------------------------------------------------------- the base
class AnatomyPhantom(MeshPhantom):
    """A manifold3d-built polyhedron as a phantom (module docstring).  A subclass implements :meth:`_build`
    (the manifold, setting ``expected_components``, ``expected_genus``, ``tessellation_error`` and what
    :meth:`ideal_sdf` needs) and lists its own parameters in ``_shape_params``.

    Parameters
    ----------
    n : int
        The grid size the voxel sizes refer to (h = 2·extent / (n − 1)); default 64.
    extent : float
        Half-width of that grid's box; default 2.5.
    seed : int
        Seed of the random positions and directions.
    """

    _shape_params: ClassVar[tuple[str, ...]] = ()
    expected_components: int = 1
    expected_genus: int = 0

    def __init__(self, n: int = ANATOMY_N, extent: float = DEFAULT_EXTENT, seed: int = 0, **shape):
        self.n_ref = check_n(n)
        self.extent_ref = check_extent(extent)
        try:
            self.seed = int(seed)
        except (TypeError, ValueError):
            raise InputError(f"phantom {self.name!r}: seed must be an integer; got {seed!r}") from None
        if self.seed != seed:
            raise InputError(f"phantom {self.name!r}: seed must be an integer; got {seed!r}")
        self.h = 2.0 * self.extent_ref / (self.n_ref - 1)
        self.tessellation_error = 0.0
        for key, value in shape.items():
            try:
                setattr(self, key, float(value))
            except (TypeError, ValueError):
                raise InputError(f"phantom {self.name!r}: {key} must be a number; got {value!r}") from None
        solid = self._build(np.random.default_rng(self.seed))
        mesh = solid.to_mesh64()
        v = np.asarray(mesh.vert_properties, np.float64)[:, :3]
        f = np.asarray(mesh.tri_verts, np.int64)
        super().__init__(v, f, normalize=False, source=f"manifold3d:{self.name}")
        if (self.n_components, self.genus) != (self.expected_components, self.expected_genus):
            raise InputError(
                f"phantom {self.name!r} with {self._param_text()}: the built surface has {self.n_components} "
                f"components and genus {self.genus}, not the designed {self.expected_components} and "
                f"{self.expected_genus}: parts merged or were cut (larger gaps or thicker parts, in voxels)")

    def __init_subclass__(cls, **kwargs):
        super().__init_subclass__(**kwargs)
        cls._shape_params = tuple(cls.__init__.__code__.co_varnames[1:cls.__init__.__code__.co_argcount])

    def _param_text(self) -> str:
        return ", ".join(f"{k}={v:g}" if isinstance(v, float) else f"{k}={v}" for k, v in self.params.items())

    def _voxels(self, name: str, lo: float, hi: float = math.inf) -> float:
        """Parameter ``name`` (voxels) in world units, checked to lie in [lo, hi] voxels."""
        value = float(getattr(self, name))
        if not (math.isfinite(value) and lo <= value <= hi):
            bound = f"[{lo:g}, {hi:g}]" if math.isfinite(hi) else f">= {lo:g}"
            raise InputError(f"phantom {self.name!r}: {name} must be {bound} voxels; got {value:g}")
        return value * self.h

    def _count(self, name: str, lo: int, hi: int) -> int:
        value = getattr(self, name)
        if value != int(value) or not lo <= value <= hi:
            raise InputError(f"phantom {self.name!r}: {name} must be an integer in [{lo}, {hi}]; got {value:g}")
        return int(value)

    def _sphere(self, radius: float, centre=(0.0, 0.0, 0.0)):
        """manifold3d sphere within 0.02 voxel (or 0.2 % of its radius) of the ideal one."""
        seg = _segments_for(radius, max(0.02 * self.h, 2e-3 * radius))
        self.tessellation_error = max(self.tessellation_error, _sphere_error(radius, seg))
        return _manifold().Manifold.sphere(radius, seg).translate(tuple(float(c) for c in centre))

    @property
    def params(self) -> dict:
        out = {"n": self.n_ref, "extent": self.extent_ref, "seed": self.seed}
        for key in self._shape_params:
            if key not in out:
                value = getattr(self, key)
                out[key] = int(value) if key in _INT_PARAMS else value
        return out

    # ---- the ideal shape (tests)
    def ideal_sdf(self, points) -> np.ndarray:
        """The untessellated shape's CSG bound (min / max of exact primitive distances): exact sign, magnitude a
        lower bound of the distance to the ideal surface."""
        raise NotImplementedError

    def ideal_volume(self) -> float | None:
        """The untessellated shape's volume in closed form (None where there is none)."""
        return None

    def ideal_area(self) -> float | None:
        """The untessellated shape's surface area in closed form (None where there is none)."""
        return None

    @property
    def surface_area(self) -> float:
        """The mesh's surface area."""
        return float(self.face_areas.sum())

    def _build(self, rng: np.random.Generator):
        raise NotImplementedError

    def __repr__(self) -> str:
        return f"{type(self).__name__}({self._param_text()})"


# ----------------------------------------------------------------------------------------------- the six shapes
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


class VesselTree(AnatomyPhantom):
    """A branching tube tree (vessel / airway-like): ``levels`` generations of bifurcating capsules from a root of
    ``root_radius`` voxels, each child's radius ``ratio`` times its parent's (default: 4 voxels down to 0.67), in
    seeded directions that keep non-adjacent branches 1.5 voxels apart.  One component, genus 0; no closed-form
    volume (the capsules overlap at the joints)."""

    name = "vessel_tree"
    description = "branching tube tree (vessel-like): capsule radii from 4 voxels down to below one voxel"
    shape_kind = "tubes"
    genus = 0
    has_creases = False

    def __init__(self, n: int = ANATOMY_N, extent: float = DEFAULT_EXTENT, seed: int = 0,
                 root_radius: float = 4.0, ratio: float = 0.7, levels: int = 6):
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
                    if all(np.all(np.abs(q) <= bound) and self._clear(segments, parent, b, q, rc, margin)
                           for q in ends):
                        break
                else:
                    continue                                      # no room: this branch ends here
                for q in ends:
                    segments.append((b, q, rc, parent))
                    nxt.append(len(segments) - 1)
            frontier = nxt
        self.segments = segments
        tol = max(0.02 * self.h, 2e-3 * min(s[2] for s in segments))
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
        """The new branch a→b of radius r keeps ``margin`` from every branch but its parent and siblings
        (which share its start point)."""
        for i, (c, d, rr, _) in enumerate(segments):
            if i == parent or np.allclose(c, a):
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


class CavitySolid(AnatomyPhantom):
    """A ball (radius 0.64·extent) with ``count`` internal spherical cavities of radii ``radii`` voxels (cycled),
    at seeded positions at least ``wall`` voxels from each other and from the outer surface: 1 + count surface
    components (the inner ones facing inward, into the cavity), genus 0.  Closed-form volume and area."""

    name = "cavity_solid"
    description = "ball with internal spherical cavities (organ-like): 1 + count surface components, inner facing in"
    shape_kind = "cavities"
    genus = 0
    has_creases = False

    def __init__(self, n: int = ANATOMY_N, extent: float = DEFAULT_EXTENT, seed: int = 0,
                 count: int = 3, small: float = 3.0, large: float = 8.0, wall: float = 2.0):
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
    """A trabecular-like lattice: square struts of ``strut`` voxels along the edges of a cubic grid of
    (cells + 1)³ nodes spanning 0.72·extent, seeded rotation (the struts are not grid-aligned).  One component of
    genus 3k²(k − 1) − k³ + 1 for k = cells + 1 nodes per axis (81 by default: the cycle rank of the lattice
    graph).  The polyhedron is the ideal shape: its closed-form volume and area are exact."""

    name = "lattice"
    description = "rotated cubic lattice of square struts (trabecular-like): genus 81 by default"
    shape_kind = "high genus"
    genus = 81
    has_creases = True

    def __init__(self, n: int = ANATOMY_N, extent: float = DEFAULT_EXTENT, seed: int = 0,
                 cells: int = 3, strut: float = 2.5):
        super().__init__(n, extent, seed, cells=cells, strut=strut)

    def _build(self, rng):
        M = _manifold().Manifold
        cells = self._count("cells", 1, 6)
        s = self._voxels("strut", 0.5, 20.0)
        k = cells + 1
        span = 0.72 * self.extent_ref
        a = span / cells
        if a - s < 1.0 * self.h:
            raise InputError(f"phantom {self.name!r}: struts of {self.strut:g} voxels leave holes under one voxel "
                             f"with {cells} cells (thinner struts or fewer cells)")
        self.k, self.a, self.s = k, a, s
        self.nodes = -0.5 * span + a * np.arange(k)
        self.rotation = _random_rotation(rng)
        bars = []
        length = span + s
        for i in self.nodes:
            for j in self.nodes:
                bars.append(M.cube((length, s, s), True).translate((0.0, float(i), float(j))))
                bars.append(M.cube((s, length, s), True).translate((float(i), 0.0, float(j))))
                bars.append(M.cube((s, s, length), True).translate((float(i), float(j), 0.0)))
        self.expected_components, self.expected_genus = 1, 3 * k * k * (k - 1) - k ** 3 + 1
        return M.batch_boolean(bars, _manifold().OpType.Add).transform(_affine(self.rotation))

    def ideal_sdf(self, points):
        q = as_points(points) @ self.rotation                  # into the lattice's frame
        half_len = 0.5 * (self.a * (self.k - 1) + self.s)
        hs = 0.5 * self.s
        d = np.full(len(q), np.inf)
        for i in self.nodes:
            for j in self.nodes:
                d = np.minimum(d, _box_sdf(q, (0.0, i, j), (half_len, hs, hs)))
                d = np.minimum(d, _box_sdf(q, (i, 0.0, j), (hs, half_len, hs)))
                d = np.minimum(d, _box_sdf(q, (i, j, 0.0), (hs, hs, half_len)))
        return d

    def ideal_volume(self):
        k, a, s = self.k, self.a, self.s
        return k ** 3 * s ** 3 + 3 * k * k * (k - 1) * s * s * (a - s)

    def ideal_area(self):
        # the struts' free lateral faces between nodes, and the node cubes' faces no strut covers (6k² of them)
        k, a, s = self.k, self.a, self.s
        return 3 * k * k * (k - 1) * 4 * s * (a - s) + 6 * k * k * s * s


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


#: the anatomy phantoms by name
ANATOMY: dict[str, type[AnatomyPhantom]] = {
    cls.name: cls for cls in (VaultShell, VesselTree, CavitySolid, SpineParts, Lattice, TouchingPair)
}


def parse_anatomy_spec(spec: str) -> tuple[str, dict]:
    """``'vault_shell?thickness=0.75&seed=2'`` → ``('vault_shell', {'thickness': 0.75, 'seed': 2})``.

    Raises
    ------
    InputError
        Not an anatomy phantom, an option it does not take, or a value that is not a number.
    """
    name, _, query = str(spec).partition("?")
    if name not in ANATOMY:
        raise InputError(f"{spec!r}: {name!r} is not an anatomy phantom ({', '.join(ANATOMY)})")
    valid = ANATOMY[name]._shape_params
    params: dict = {}
    for item in filter(None, query.split("&")):
        key, eq, value = item.partition("=")
        if key not in valid or not eq:
            raise InputError(f"phantom {spec!r}: unknown option {item!r}; valid: {', '.join(valid)} (key=value)")
        try:
            num = float(value)
        except ValueError:
            raise InputError(f"phantom {spec!r}: {key} must be a number, got {value!r}") from None
        params[key] = int(num) if num.is_integer() and key in _INT_PARAMS else num
    return name, params
