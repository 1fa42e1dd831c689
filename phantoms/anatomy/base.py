"""The anatomy phantoms' shared part: :class:`AnatomyPhantom` (a manifold3d polyhedron as a
:class:`~phantoms.mesh.MeshPhantom`, its voxel-sized parameters and designed topology checked) and the primitives'
tessellation bounds and exact distances (the ideal shapes' CSG bounds for the tests)."""

from __future__ import annotations

import math
from typing import ClassVar

import numpy as np

from geometry.errors import InputError

from ..base import DEFAULT_EXTENT, check_extent, check_n
from ..mesh import MeshPhantom

__all__ = ["AnatomyPhantom", "ANATOMY_N", "INT_PARAMS"]

#: the grid size the voxel sizes refer to by default
ANATOMY_N = 48
#: the shape parameters that are counts
INT_PARAMS = ("n", "seed", "foramina", "count", "cells", "levels")


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


class AnatomyPhantom(MeshPhantom):
    """A manifold3d-built polyhedron as a phantom (module docstring).  A subclass implements :meth:`_build`
    (the manifold, setting ``expected_components``, ``expected_genus``, ``tessellation_error`` and what
    :meth:`ideal_sdf` needs); its constructor's arguments are its ``parameter_names`` (the spec's options).

    Parameters
    ----------
    n : int
        The grid size the voxel sizes refer to (h = 2·extent / (n − 1)); default 48 (the anatomy tier's grid).
    extent : float
        Half-width of that grid's box; default 2.5.
    seed : int
        Seed of the random positions and directions.
    """

    parameter_names: ClassVar[tuple[str, ...]] = ()
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
        # split edges longer than two voxels (the same flat triangles, more of them): a long sliver — a capsule's
        # side, a disc's cap — puts its vertices far from most of its points, and the certified distance query's
        # first bound (the faces around the nearest vertex) then admits thousands of candidates
        mesh = solid.refine_to_length(2.0 * self.h).to_mesh64()
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
        cls.parameter_names = tuple(cls.__init__.__code__.co_varnames[1:cls.__init__.__code__.co_argcount])

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
        for key in self.parameter_names:
            if key not in out:
                value = getattr(self, key)
                out[key] = int(value) if key in INT_PARAMS else value
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
