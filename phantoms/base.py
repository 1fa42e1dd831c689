"""What every phantom shares: the :class:`Phantom` interface, its :class:`Truth` record, the default grid
and the input checks.

Every phantom offers

* ``sdf(points)`` – the exact Euclidean signed distance (negative inside) everywhere;
* ``paper(points)`` – the implicit function as printed in the paper (same zero set);
* ``truth(points)`` – a :class:`Truth`: closest point on the true surface, unsigned and signed distance,
  outward unit normal, mean curvature H and Gaussian curvature K there (H > 0 on a sphere; NaN where the
  surface has a crease or rim) and the distance from the closest point to the nearest crease/rim
  (``inf`` on smooth phantoms);
* ``sample_surface(n, seed)`` – ``n`` seeded, area-uniform points on the true surface with their normals;
* ``volume(n, extent, variant)`` – the level set sampled on an ``n³`` grid over ``[-extent, extent]³``.

All computations are vectorised over the points.  The analytic phantoms are in :mod:`phantoms.analytic`,
the mesh-backed ones in :mod:`phantoms.mesh` and :mod:`phantoms.real`, the names in :mod:`phantoms.registry`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from geometry.errors import InputError

from .volume import Volume, check_memory

__all__ = [
    "SHAPE_KINDS", "Truth", "Phantom", "DEFAULT_N", "DEFAULT_EXTENT", "VARIANTS", "grid_volume",
    "as_points", "unit", "arc_positions", "check_n", "check_extent", "check_sample_count",
]

DEFAULT_N = 96
DEFAULT_EXTENT = 2.5
#: float64 arrays per grid point :func:`grid_volume` holds at least (grid points, values): the memory check
GRID_CHANNELS = 8
#: points per slab of :func:`grid_volume`
GRID_CHUNK = 1 << 20
VARIANTS = ("sdf", "paper")
#: the values of :attr:`Phantom.shape_kind`
SHAPE_KINDS = ("smooth solid", "thin shell", "tubes", "cavities", "many parts", "high genus", "touching parts")


@dataclass(frozen=True)
class Truth:
    """Ground truth at the closest true-surface point of each of P query points (:meth:`Phantom.truth`).

    Parameters
    ----------
    closest : numpy.ndarray, shape (P, 3)
        The closest point on the true surface.
    distance : numpy.ndarray, shape (P,)
        The unsigned distance to the true surface.
    signed : numpy.ndarray, shape (P,)
        The signed distance (negative inside).
    normal : numpy.ndarray, shape (P, 3)
        The outward unit normal at the closest point.
    H, K : numpy.ndarray, shape (P,)
        Mean and Gaussian curvature at the closest point (NaN on a crease or rim).
    crease_distance : numpy.ndarray, shape (P,)
        Distance from the closest point to the nearest crease (inf if the phantom has none).
    """

    closest: np.ndarray          # (P, 3) closest point on the true surface
    distance: np.ndarray         # (P,) unsigned distance to the true surface
    signed: np.ndarray           # (P,) signed distance (negative inside)
    normal: np.ndarray           # (P, 3) outward unit normal at the closest point
    H: np.ndarray                # (P,) mean curvature (NaN on a crease/rim)
    K: np.ndarray                # (P,) Gaussian curvature (NaN on a crease/rim)
    crease_distance: np.ndarray  # (P,) distance from the closest point to the nearest crease (inf if none)


def as_points(points) -> np.ndarray:
    """``points`` as a float64 (P, 3) array; InputError for any other shape."""
    p = np.asarray(points, dtype=np.float64)
    if p.ndim != 2 or p.shape[1] != 3:
        raise InputError(f"points must have shape (P, 3); got {p.shape}")
    return p


def unit(v: np.ndarray, fallback) -> np.ndarray:
    """Normalise rows of ``v``; rows of (near) zero length become ``fallback``."""
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    small = n[..., 0] < 1e-300
    out = v / np.where(small[..., None], 1.0, n)
    if small.any():
        out[small] = fallback
    return out


def grid_volume(fn, n: int = DEFAULT_N, extent: float = DEFAULT_EXTENT) -> Volume:
    """Sample a function on an n³ grid over [-extent, extent]³.

    Parameters
    ----------
    fn : callable
        Points (P, 3) → values (P,).
    n : int
        Grid points per axis (>= 8).
    extent : float
        Half-width of the cubic grid box (positive).

    Returns
    -------
    Volume
        Spacing 2·extent / (n − 1), origin (−extent, −extent, −extent).

    Raises
    ------
    InputError
        A bad ``n`` or ``extent``, or a grid that does not fit in memory.
    """
    n = check_n(n)
    extent = check_extent(extent)
    check_memory((n, n, n), 2, what=f"an N = {n} volume")        # the values, and the Volume's own checks
    spacing = 2.0 * extent / (n - 1)
    axis = -extent + spacing * np.arange(n)
    values = np.empty((n, n, n))
    # slabs of whole x-planes, ~GRID_CHUNK points each: ``fn``'s temporaries (points, gathers, ...) stay a few
    # MB to a few hundred MB instead of dozens of float64 per grid point (N = 256: 16.7M points); up to
    # N ≈ 100 the grid is one slab.  ``fn`` is pointwise, so the values are the same either way.
    planes = max(1, GRID_CHUNK // (n * n))
    yz = np.stack(np.meshgrid(axis, axis, indexing="ij"), axis=-1).reshape(-1, 2)
    for i0 in range(0, n, planes):
        i1 = min(n, i0 + planes)
        pts = np.empty(((i1 - i0) * n * n, 3))
        pts[:, 0] = np.repeat(axis[i0:i1], n * n)
        pts[:, 1:] = np.tile(yz, (i1 - i0, 1))
        values[i0:i1] = np.asarray(fn(pts), dtype=np.float64).reshape(i1 - i0, n, n)
    return Volume(values, origin=[-extent] * 3, spacing=spacing)


def check_n(n) -> int:
    """The grid size N as an int; InputError unless it is an integer >= 8."""
    try:
        n_int = int(n)
    except (TypeError, ValueError):
        raise InputError(f"grid size N must be an integer; got {n!r}") from None
    if n_int != n or n_int < 8:
        raise InputError(f"grid size N must be an integer >= 8; got {n!r}")
    return n_int


def check_extent(extent) -> float:
    """The grid half-width as a float; InputError unless it is a positive finite number."""
    extent = float(extent)
    if not (np.isfinite(extent) and extent > 0):
        raise InputError(f"extent must be a positive number; got {extent}")
    return extent


def arc_positions(lengths, n: int) -> tuple[np.ndarray, np.ndarray]:
    """For curves of the given lengths laid end to end: which curve and which fraction along it holds the
    arc positions (i + ½)·L/n, i = 0..n−1 (evenly spaced samples; see :meth:`Phantom.crease_samples`)."""
    lengths = np.asarray(lengths, float)
    cum = np.concatenate([[0.0], np.cumsum(lengths)])
    s = (np.arange(n) + 0.5) * cum[-1] / n
    k = np.clip(np.searchsorted(cum, s, side="right") - 1, 0, len(lengths) - 1)
    return k, (s - cum[k]) / np.where(lengths[k] > 0, lengths[k], 1.0)


def check_sample_count(n) -> int:
    """The number of surface samples as an int; InputError below 1."""
    n = int(n)
    if n < 1:
        raise InputError(f"number of surface samples must be >= 1; got {n}")
    return n


class Phantom:
    """Base class of the phantoms: a closed surface with exact ground truth.

    A subclass sets ``name``, ``description``, ``genus``, ``has_creases`` and ``shape_kind`` and implements
    :meth:`sdf` (exact signed distance, negative inside), :meth:`paper` (the paper's level-set polynomial),
    :meth:`truth` and :meth:`sample_surface` (seeded area-uniform samples and their normals); its constructor
    takes the phantom's geometric parameters (:attr:`params`).
    """

    name: ClassVar[str] = ""
    description: ClassVar[str] = ""
    genus: ClassVar[int] = 0
    has_creases: ClassVar[bool] = False
    #: SNR (dB) used in the paper's noisy experiments (None when the paper has no such phantom)
    paper_snr_db: ClassVar[float | None] = None
    #: what kind of shape it is, for the report's recommendation per input kind: "smooth solid", "thin shell",
    #: "tubes", "cavities", "many parts", "high genus" or "touching parts" (None: not said, e.g. a user's volume)
    shape_kind: ClassVar[str | None] = None

    @property
    def params(self) -> dict:
        """The phantom's geometric parameters (for listings and result records)."""
        return {}

    # ---- to implement
    def sdf(self, points) -> np.ndarray:
        """The exact signed distance to the true surface, negative inside.

        Parameters
        ----------
        points : array_like, shape (P, 3)
            World coordinates.

        Returns
        -------
        numpy.ndarray, shape (P,)
        """
        raise NotImplementedError

    def paper(self, points) -> np.ndarray:
        """The paper's printed level-set function (variant ``'paper'``): same zero set, not a distance.

        Parameters
        ----------
        points : array_like, shape (P, 3)
            World coordinates.

        Returns
        -------
        numpy.ndarray, shape (P,)

        Raises
        ------
        InputError
            The phantom has no such polynomial (mesh phantoms, user volumes).
        """
        raise NotImplementedError

    def truth(self, points) -> Truth:
        """The ground truth at each point's closest true-surface point.

        Parameters
        ----------
        points : array_like, shape (P, 3)
            World coordinates.

        Returns
        -------
        Truth
        """
        raise NotImplementedError

    def sample_surface(self, n: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
        """``n`` seeded, area-uniform i.i.d. samples on the true surface (same seed → same samples).

        Parameters
        ----------
        n : int
            The number of samples (>= 1).
        seed : int
            Seed of the generator.

        Returns
        -------
        points : numpy.ndarray, shape (n, 3)
        normals : numpy.ndarray, shape (n, 3)
            The outward unit normals at the samples.
        """
        raise NotImplementedError

    # ---- shared
    #: whether the phantom knows its true surface (a user volume without ``truth=`` does not)
    has_truth: bool = True

    def ground_truth(self) -> "Phantom | None":
        """The phantom the truth metrics are computed against: itself (a user volume: its reference surface,
        or None without one)."""
        return self

    #: the volume the true surface encloses (world units³); None where unknown
    solid_volume: float | None = None

    #: total length of the true crease / rim curves (0 on smooth phantoms)
    crease_length: float = 0.0

    def crease_samples(self, n: int) -> np.ndarray:
        """``n`` points evenly spaced by arc length on the true crease / rim curves, (n, 3); (0, 3) without
        creases.  Point i sits at arc length (i + ½)·L/n of the concatenated curves, so every curve point is
        within L/(2n) (along the curve) of a sample."""
        return np.zeros((0, 3))

    def inside(self, points) -> np.ndarray:
        """Is each point inside the true solid (φ < 0)?  Exact: the sign of the exact signed distance."""
        return self.sdf(points) < 0

    def distance(self, points) -> np.ndarray:
        """Exact unsigned distance to the true surface."""
        return np.abs(self.sdf(points))

    def volume(self, n: int = DEFAULT_N, extent: float = DEFAULT_EXTENT, variant: str = "sdf") -> Volume:
        """The phantom's level set on an n³ grid over [-extent, extent]³.

        Parameters
        ----------
        n : int
            Grid points per axis (>= 8).
        extent : float
            Half-width of the grid box.
        variant : {'sdf', 'paper'}
            ``'sdf'`` samples the exact signed distance (:meth:`sdf`), ``'paper'`` the printed polynomial
            (:meth:`paper`).

        Returns
        -------
        Volume

        Raises
        ------
        InputError
            An unknown variant, a bad ``n`` or ``extent``, or a grid that does not fit in memory.
        """
        if variant not in VARIANTS:
            raise InputError(f"unknown variant {variant!r}; valid variants: {', '.join(VARIANTS)}")
        fn = self.sdf if variant == "sdf" else self.paper
        return grid_volume(fn, n, extent)

    @staticmethod
    def _rejection(n: int, seed: int, propose, accept_prob) -> np.ndarray:
        """Seeded i.i.d. rejection sampling: ``propose(rng, m) -> points``; accept with ``accept_prob``."""
        n = check_sample_count(n)
        rng = np.random.default_rng(seed)
        out, have = [], 0
        while have < n:
            cand = propose(rng, max(1024, 2 * (n - have) + 1024))
            keep = rng.random(len(cand)) < accept_prob(cand)
            out.append(cand[keep])
            have += int(keep.sum())
        return np.concatenate(out)[:n]

    def __repr__(self) -> str:
        args = ", ".join(f"{k}={v}" for k, v in self.params.items())
        return f"{type(self).__name__}({args})"
