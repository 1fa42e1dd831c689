"""The volume type: a level-set function sampled on a regular, axis-aligned 3-D grid.

Conventions
-----------
* ``values[i, j, k]`` is φ at the world point ``origin + (i, j, k) * spacing`` (array axis 0 = x).
* φ < 0 inside the surface, φ > 0 outside.
* Interpolation is trilinear.  The derivative grids (central differences, one-sided at the border,
  via :func:`numpy.gradient`) are computed once and cached (:meth:`Volume.channels`), and φ, ∇φ and the
  Hessian at a batch of points come from **one** gather of the 8 corner values of that stacked channel
  array (:func:`geometry.trilinear.trilinear_channels`, re-exported here).
* For many calls on one volume (an iterative method's inner loop), :meth:`Volume.sampler` returns a
  :class:`VolumeSampler`: the same interpolation without the per-call checks, points clamped onto the box.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from geometry import compiled
from geometry.errors import InputError
from geometry.grid_derivatives import derivative_stack
from geometry.trilinear import trilinear_channels

from .memory import available_memory, check_memory

__all__ = ["VOLUME_KINDS", "Volume", "Sample", "VolumeSampler", "trilinear_channels", "check_grid", "check_memory",
           "available_memory"]


#: what a volume's input was (:attr:`Volume.kind`)
VOLUME_KINDS = ("sdf", "mask", "intensity")


def _read_only(array: np.ndarray) -> np.ndarray:
    """A read-only view of ``array`` (the caller's own array keeps its flags)."""
    view = array.view()
    view.flags.writeable = False
    return view


def check_grid(origin, spacing, shape) -> tuple[np.ndarray, np.ndarray]:
    """``(origin, spacing)`` of a grid of ``shape`` points as (3,) float arrays, or an :class:`InputError`:
    origin 3 finite numbers, spacing 1 or 3 positive finite numbers, and the scale representable (below)."""
    given_origin, given_spacing = origin, spacing
    origin = _real_vector(origin, "origin", allow_scalar=False)
    if not np.isfinite(origin).all():
        raise InputError(f"volume origin must be 3 finite numbers; got {given_origin!r}")
    spacing = _real_vector(spacing, "spacing", allow_scalar=True)
    if not (np.isfinite(spacing).all() and (spacing > 0).all()):
        raise InputError(f"volume spacing must be positive and finite; got {given_spacing!r}")
    _check_scale(spacing, shape, origin)
    return origin, spacing


def _check_scale(spacing: np.ndarray, shape, origin: np.ndarray) -> None:
    """Refuse a grid whose cell or box is not representable: the cell volume (∏ spacing) and the box volume
    (∏ spacing·(N − 1)) must be normal floats, and the far corner finite — else every length, area and volume
    computed downstream underflows to 0 or overflows to inf, and the failure would be blamed on the method.
    Physical units of any kind (0.5 mm, 1e-3 m, 1e-9 m) are far inside these bounds."""
    tiny, huge = np.finfo(np.float64).tiny, np.finfo(np.float64).max
    with np.errstate(over="ignore", under="ignore"):
        extent = spacing * (np.asarray(shape, dtype=np.float64) - 1)
        cell, box = float(np.prod(spacing)), float(np.prod(extent))
        corner = origin + extent
    if not (tiny <= cell and box <= huge and np.isfinite(corner).all()):
        what = "cell volume (product of the spacings)" if not tiny <= cell else "grid's extent"
        raise InputError(f"volume spacing {[float(f'{v:.6g}') for v in spacing]} is out of range for a "
                         f"{'×'.join(map(str, shape))} grid: the {what} is not a normal float "
                         f"(cell volume {cell:.3g}, box volume {box:.3g}); rescale the units of the spacing")


@dataclass(frozen=True)
class Sample:
    """Interpolated values at a batch of P points (:meth:`Volume.sample`).

    Parameters
    ----------
    phi : numpy.ndarray, shape (P,)
        The field's values.
    grad : numpy.ndarray, shape (P, 3), optional
        Its gradient; None when not asked for.
    hess : numpy.ndarray, shape (P, 3, 3), optional
        Its Hessian; None when not asked for.
    """

    phi: np.ndarray
    grad: np.ndarray | None = None
    hess: np.ndarray | None = None


#: channels of the interpolation grids per derivative order: φ; φ, ∇φ; φ, ∇φ, the Hessian's six entries
_N_CHANNELS = {0: 1, 1: 4, 2: 10}
# Order of the six independent Hessian entries in the cached channel array.
_HESS_PAIRS = ((0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2))


def _derivative_channels(values: np.ndarray, spacing, order: int) -> np.ndarray:
    """:meth:`Volume.channels` in numpy (the reference of :func:`geometry.grid_derivatives.derivative_stack`),
    built in place: each grid is written into the (…, C) array as soon as it is computed, and only one gradient's
    three derivatives are alive beside it — at N = 256 and C = 10 the peak is C + 4 grids instead of C + 16
    (1.9 GB instead of 3.5 GB).  The values are those of stacking φ, ∇φ and the symmetrised Hessian
    ½(∂ᵢ∂ⱼφ + ∂ⱼ∂ᵢφ) (the two difference orders differ at the border)."""
    n_chan = _N_CHANNELS[order]
    check_memory(values.shape, n_chan + (4 if order >= 2 else 1), what=f"the interpolation grids (order {order})")
    out = np.empty(values.shape + (n_chan,))
    out[..., 0] = values
    if order >= 1:
        for c, g in enumerate(np.gradient(values, *spacing, edge_order=2)):
            out[..., 1 + c] = g
    if order >= 2:
        slot = {pair: 4 + k for k, pair in enumerate(_HESS_PAIRS)}
        for a in range(3):
            second = np.gradient(out[..., 1 + a], *spacing, edge_order=2)
            for b in range(3):
                i, j = min(a, b), max(a, b)
                if a == b:
                    out[..., slot[i, j]] = second[b]
                elif a < b:                                  # ∂_b ∂_a φ now, ∂_a ∂_b φ when a takes b's turn
                    out[..., slot[i, j]] = second[b]
                else:
                    out[..., slot[i, j]] = 0.5 * (out[..., slot[i, j]] + second[b])
            del second
    return out


def _real_vector(value, name: str, allow_scalar: bool) -> np.ndarray:
    """``value`` as 3 float64 numbers (a scalar spacing applies to every axis); InputError naming ``name``
    for another length, a non-numeric or complex type."""
    arr = np.asarray(value)
    if arr.dtype == object or not (np.issubdtype(arr.dtype, np.integer) or np.issubdtype(arr.dtype, np.floating)):
        raise InputError(f"volume {name} must be {'a number or ' if allow_scalar else ''}3 real numbers; got "
                         f"{value!r} (dtype {arr.dtype})")
    if allow_scalar and arr.size == 1:
        return np.full(3, float(arr.reshape(-1)[0]))
    if arr.size != 3:
        raise InputError(f"volume {name} must be {'a number or ' if allow_scalar else ''}3 numbers (x, y, z); "
                         f"got {arr.size} values: {arr.reshape(-1).tolist()!r}")
    return arr.astype(np.float64).reshape(3)


@dataclass(eq=False)
class Volume:
    """A scalar field on a regular grid with world-space ``origin`` and per-axis ``spacing``.

    Parameters
    ----------
    values : array_like, shape (nx, ny, nz)
        φ at the grid points; converted to float64.  Must be finite and at least 2 points per axis.
    origin : array_like, shape (3,)
        World position of ``values[0, 0, 0]``.
    spacing : float or array_like, shape (3,)
        Grid spacing per axis (positive).
    kind : {'sdf', 'mask', 'intensity'}
        What the input was before it became φ: a signed distance (or any level set) sampled directly, a binary
        mask, or an intensity image (a partial-volume image, a scan) read at an iso-level.  ``values`` is φ in
        every case (for a mask, its signed distance: :func:`phantoms.masks.mask_to_sdf`), so a level-set method
        needs nothing else; a mask-native method reads ``raw`` and ``level``.
    raw : array_like, shape (nx, ny, nz), optional
        The image as it came (0/1 for a mask, the intensity otherwise); required unless ``kind`` is ``'sdf'``.
    level : float, optional
        The iso-level of ``raw``: inside where ``raw > level`` (0.5 for a mask and a partial-volume image).

    Both ``values`` and ``raw`` are read-only: a method that writes to its input would change what the suite
    checks its mesh against.
    """

    values: np.ndarray
    origin: np.ndarray = field(default_factory=lambda: np.zeros(3))
    spacing: np.ndarray = field(default_factory=lambda: np.ones(3))
    kind: str = "sdf"
    raw: np.ndarray | None = None
    level: float | None = None

    def __post_init__(self) -> None:
        values = np.asarray(self.values)
        if values.ndim != 3:
            raise InputError(f"a volume must be a 3-D array; got an array of shape {values.shape}")
        if min(values.shape) < 2:
            raise InputError(f"a volume needs at least 2 samples per axis; got shape {values.shape}")
        if not np.issubdtype(values.dtype, np.number) and values.dtype != bool:
            raise InputError(f"volume values must be real numbers; got dtype {values.dtype}")
        if np.issubdtype(values.dtype, np.complexfloating):
            raise InputError(f"volume values must be real numbers; got complex dtype {values.dtype} (take the "
                             "real part or the modulus yourself: the imaginary part would be lost silently)")
        values = np.ascontiguousarray(values, dtype=np.float64)
        bad = ~np.isfinite(values)
        if bad.any():
            n_nan = int(np.isnan(values).sum())
            raise InputError(
                f"volume contains non-finite values ({n_nan} NaN, {int(bad.sum()) - n_nan} inf) "
                f"out of {values.size}; first at index {tuple(int(i) for i in np.argwhere(bad)[0])}"
            )
        origin, spacing = check_grid(self.origin, self.spacing, values.shape)
        self.values, self.origin, self.spacing = _read_only(values), origin, spacing
        self._check_kind()
        self._channels: dict[tuple[int, str], np.ndarray] = {}

    def _check_kind(self) -> None:
        """Validate ``kind``, ``raw`` and ``level`` (see the class docstring)."""
        if self.kind not in VOLUME_KINDS:
            raise InputError(f"volume kind must be one of {', '.join(VOLUME_KINDS)}; got {self.kind!r}")
        if self.kind == "sdf":
            if self.raw is not None or self.level is not None:
                raise InputError("a volume of kind 'sdf' takes no raw image or level")
            return
        if self.raw is None or self.level is None:
            raise InputError(f"a volume of kind {self.kind!r} needs its raw image and its iso-level")
        raw = np.asarray(self.raw)
        if raw.shape != self.values.shape:
            raise InputError(f"the raw image's shape {raw.shape} differs from the values' {self.values.shape}")
        raw = np.ascontiguousarray(raw, dtype=np.float64)
        level = float(self.level)
        if not (np.isfinite(raw).all() and np.isfinite(level)):
            raise InputError("the raw image and its level must be finite")
        self.raw, self.level = _read_only(raw), level

    # ------------------------------------------------------------------ geometry of the grid
    @property
    def inside_raw(self) -> np.ndarray:
        """The inside voxels (bool): ``raw > level`` for a mask or an intensity image, ``values < 0`` for a
        signed distance — what a mask-native method meshes."""
        if self.raw is None:
            return self.values < 0
        return self.raw > self.level

    @property
    def shape(self) -> tuple[int, int, int]:
        return tuple(self.values.shape)  # type: ignore[return-value]

    @property
    def h(self) -> float:
        """The grid spacing as one number (the smallest axis spacing)."""
        return float(self.spacing.min())

    @property
    def lower(self) -> np.ndarray:
        """World coordinates of the first grid point."""
        return self.origin.copy()

    @property
    def upper(self) -> np.ndarray:
        """World coordinates of the last grid point."""
        return self.origin + (np.asarray(self.shape) - 1) * self.spacing

    def world_to_index(self, points) -> np.ndarray:
        """Continuous (fractional) grid indices of world points, shape (..., 3)."""
        return (np.asarray(points, dtype=np.float64) - self.origin) / self.spacing

    def index_to_world(self, ijk) -> np.ndarray:
        """World coordinates of (possibly fractional) grid indices, shape (..., 3)."""
        return np.asarray(ijk, dtype=np.float64) * self.spacing + self.origin

    def grid_points(self) -> np.ndarray:
        """World coordinates of every grid point, shape (nx, ny, nz, 3)."""
        axes = [self.origin[d] + np.arange(self.shape[d]) * self.spacing[d] for d in range(3)]
        return np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1)

    def contains(self, points, *, margin: float = 0.0) -> np.ndarray:
        """Boolean mask: which points lie inside the grid box (shrunk by ``margin`` world units)."""
        p = np.asarray(points, dtype=np.float64)
        return np.all((p >= self.lower + margin) & (p <= self.upper - margin), axis=-1)

    def boundary_values(self) -> np.ndarray:
        """All values on the six boundary faces of the grid (1-D)."""
        v = self.values
        return np.concatenate([
            v[0].ravel(), v[-1].ravel(), v[:, 0].ravel(), v[:, -1].ravel(),
            v[:, :, 0].ravel(), v[:, :, -1].ravel(),
        ])

    def has_zero_crossing(self) -> bool:
        """True when φ takes both signs (a zero level set exists)."""
        return bool(self.values.min() < 0.0 < self.values.max())

    def is_closed(self) -> bool:
        """True when the zero level set exists and does not touch the boundary faces of the grid."""
        return self.has_zero_crossing() and bool((self.boundary_values() > 0).all())

    # ------------------------------------------------------------------ interpolation
    def forget_derived(self) -> None:
        """Drop the cached interpolation grids (:meth:`channels`): the next read recomputes them from
        ``values``.  The suite calls it after a method returns, so that what it checks the mesh against was not
        made by the method (a method can write into the cached arrays it was handed)."""
        self._channels.clear()

    def channels(self, order: int, dtype=np.float64) -> np.ndarray:
        """The stacked grids interpolation reads: an (nx, ny, nz, C) array, computed once and cached.

        ``order`` 0: φ (C = 1); 1: φ, ∂φ/∂x, ∂φ/∂y, ∂φ/∂z (C = 4); 2: those and the Hessian entries
        xx, xy, xz, yy, yz, zz (C = 10).  Derivatives are central differences (second order one-sided at
        the border, :func:`numpy.gradient`); the mixed second derivatives are symmetrised.  ``dtype``
        numpy.float32: the same values rounded to single precision (half the memory; a relative rounding of
        6e-8, far below the interpolation's own error).  The array is shared with the volume's cache:
        treat it as read-only (or copy it).
        """
        if order not in _N_CHANNELS:
            raise ValueError(f"channels: order must be 0, 1 or 2, got {order!r}")
        key = (order, np.dtype(dtype).str)
        if key not in self._channels:
            check_memory(self.values.shape, _N_CHANNELS[order], itemsize=np.dtype(dtype).itemsize,
                         what=f"the interpolation grids (order {order})")
            if compiled.AVAILABLE and (order >= 1 or np.dtype(dtype) != np.float64):
                # compiled, bit for bit the numpy form below: one pass, no temporary grid (at N = 256 about a
                # tenth of the time, and C grids instead of C + 4)
                self._channels[key] = derivative_stack(self.values, self.spacing, order, dtype=dtype)
            else:
                self._channels[key] = _derivative_channels(self.values, self.spacing, order).astype(dtype, copy=False)
        return self._channels[key]

    def sample(self, points, *, derivatives: int = 0, clamp: bool = False) -> Sample:
        """Trilinear interpolation of φ (and of its derivative grids) at world points.

        Parameters
        ----------
        points : array_like, shape (P, 3)
        derivatives : 0, 1 or 2
            0 → φ only; 1 → also ∇φ; 2 → also the Hessian.
        clamp : bool
            If False (default) a point outside the grid box raises :class:`InputError`.
            If True such points are moved onto the nearest point of the box.
        """
        if derivatives not in (0, 1, 2):
            raise ValueError("derivatives must be 0, 1 or 2")
        p = np.asarray(points, dtype=np.float64)
        single = p.ndim == 1
        p = np.atleast_2d(p)
        if p.shape[-1] != 3:
            raise InputError(f"points must have shape (P, 3); got {np.shape(points)}")
        idx = self.world_to_index(p)
        n = np.asarray(self.shape)
        if not np.isfinite(idx).all():
            raise InputError("points contain NaN or inf")
        # a tiny tolerance so that points exactly on the last grid plane are accepted
        tol = 1e-9
        outside = np.any((idx < -tol) | (idx > n - 1 + tol), axis=1)
        if outside.any() and not clamp:
            first = p[np.argmax(outside)]
            raise InputError(
                f"{int(outside.sum())} of {len(p)} points lie outside the volume box "
                f"[{self.lower.round(4).tolist()}, {self.upper.round(4).tolist()}] "
                f"(first: {first.round(4).tolist()}); pass clamp=True to clamp them"
            )
        idx_t = np.clip(idx, 0.0, n - 1).T
        chans = self.channels(derivatives)
        out = trilinear_channels(chans.reshape(-1, chans.shape[-1]), n, idx_t).T      # (P, C)
        phi = out[:, 0]
        grad = hess = None
        if derivatives >= 1:
            grad = out[:, 1:4]
        if derivatives >= 2:
            hess = np.empty((len(p), 3, 3))
            for c, (a, b) in enumerate(_HESS_PAIRS):
                hess[:, a, b] = hess[:, b, a] = out[:, 4 + c]
        if single:
            phi = phi[0]
            grad = None if grad is None else grad[0]
            hess = None if hess is None else hess[0]
        return Sample(phi, grad, hess)

    def sampler(self, derivatives: int = 1) -> "VolumeSampler":
        """A callable ``points (P, 3) -> Sample`` for fast repeated sampling (see :class:`VolumeSampler`)."""
        return VolumeSampler(self, derivatives)

    def __call__(self, points, *, clamp: bool = False) -> np.ndarray:
        """φ at world points (trilinear)."""
        return self.sample(points, clamp=clamp).phi

    def gradient(self, points, *, clamp: bool = False) -> np.ndarray:
        """∇φ at world points, shape (P, 3)."""
        return self.sample(points, derivatives=1, clamp=clamp).grad

    def hessian(self, points, *, clamp: bool = False) -> np.ndarray:
        """Hessian of φ at world points, shape (P, 3, 3)."""
        return self.sample(points, derivatives=2, clamp=clamp).hess

    # ------------------------------------------------------------------ misc
    def with_values(self, values) -> "Volume":
        """A new volume on the same grid with other values (φ); the kind, raw image and level are kept."""
        return Volume(values, self.origin.copy(), self.spacing.copy(), kind=self.kind, raw=self.raw,
                      level=self.level)

    def summary(self) -> dict:
        """Facts about the volume, as printed by ``python -m bench info``."""
        return {
            "shape": self.shape,
            "origin": self.origin.tolist(),
            "spacing": self.spacing.tolist(),
            "min": float(self.values.min()),
            "max": float(self.values.max()),
            "zero_crossing": self.has_zero_crossing(),
            "closed": self.is_closed(),
            "kind": self.kind if self.kind == "sdf" else f"{self.kind} (inside where raw > {self.level:g})",
        }

    def __repr__(self) -> str:
        return (f"Volume(shape={self.shape}, origin={self.origin.tolist()}, "
                f"spacing={self.spacing.tolist()})")


class VolumeSampler:
    """φ (and ∇φ with ``derivatives`` = 1) at points (P, 3), clamped onto the grid box.

    :meth:`Volume.sample` with ``clamp=True`` without its per-call checks (shape, finiteness, box), for
    an inner loop: the volume's cached channel grids (:meth:`Volume.channels`) and the shared kernel
    :func:`trilinear_channels`.  Returns a :class:`Sample` with C-contiguous ``phi`` (P,) and ``grad``
    (P, 3).
    """

    def __init__(self, volume: Volume, derivatives: int = 1):
        if derivatives not in (0, 1):
            raise ValueError("derivatives must be 0 or 1")
        ch = volume.channels(derivatives)
        self.derivatives = derivatives
        self.flat = ch.reshape(-1, ch.shape[-1])
        self.shape = volume.shape
        self.origin, self.spacing = volume.origin, volume.spacing
        self.nmax = np.asarray(volume.shape, float) - 1.0

    def __call__(self, points) -> Sample:
        idx = np.clip((points - self.origin) / self.spacing, 0.0, self.nmax)
        out = trilinear_channels(self.flat, self.shape, np.ascontiguousarray(idx.T))
        grad = np.ascontiguousarray(out[1:].T) if self.derivatives else None
        return Sample(out[0], grad)
