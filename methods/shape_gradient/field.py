"""The field the flow samples: trilinear φ, ∇φ, D²φ of a volume (optionally Gaussian pre-smoothed), and the
volume's noise estimate that decides the pre-smoothing."""

from __future__ import annotations

import weakref

import numpy as np

from geometry.trilinear import trilinear_channels
from phantoms import Sample, Volume

__all__ = ["GridSampler", "FLOAT32_ABOVE_BYTES", "stack_dtype", "as_field", "estimate_noise", "CLEAN_NOISE_VOXELS",
           "smoothed_field", "start_smoothing", "noise_after_smoothing"]

_NOISE: "weakref.WeakKeyDictionary[Volume, float]" = weakref.WeakKeyDictionary()

#: per volume, the channel grids of its pre-smoothed versions {σ: {order: (N, C)}}, so that
#: repeated runs on one volume filter and differentiate it once (freed with the volume)
_SMOOTHED: "weakref.WeakKeyDictionary[Volume, dict]" = weakref.WeakKeyDictionary()


#: a volume whose estimated noise std is below this many voxels is clean (its samples read as they are: no
#: pre-smoothing; the polish, the projection and the sign guard on)
CLEAN_NOISE_VOXELS = 0.05


def estimate_noise(volume: Volume) -> float:
    """Robust estimate of the std of additive i.i.d. noise in the volume (world units).

    Fourth differences along each axis annihilate the smooth part of φ (a cubic locally) and multiply
    i.i.d. noise by √70; the median absolute deviation ignores the few voxels at kinks of φ (medial
    surfaces, creases).  Accurate to about 1 % on the paper phantoms (0 on the clean ones).
    """
    if volume in _NOISE:
        return _NOISE[volume]
    a = volume.values
    mads = []
    for ax in range(3):
        if a.shape[ax] < 5:
            continue
        d = np.diff(a, n=4, axis=ax)
        mads.append(float(np.median(np.abs(d - np.median(d)))))
    out = 1.4826 * float(np.median(mads)) / np.sqrt(70.0) if mads else 0.0
    _NOISE[volume] = out
    return out


# ====================================================================== fast trilinear sampling
_HESS_INDEX = np.array([[0, 1, 2], [1, 3, 4], [2, 4, 5]]).ravel()


_N_CHANNELS = {0: 1, 1: 4, 2: 10}   # φ; φ, ∇φ; φ, ∇φ, the Hessian's six entries

#: above this many bytes in float64 (N ≈ 150 for a cube) the flow's interpolation grids are stored in single
#: precision (computed in double): ten grids of N³ are the flow's largest array (1.34 GB in float64 at N = 256,
#: beside a 0.13 GB volume); rounding them moves a sampled value by 6e-8 of its size, far below trilinear
#: interpolation's own O(h²) error.  Below it they stay float64: the compiled gather reads float32 more slowly,
#: and memory is no concern there
FLOAT32_ABOVE_BYTES = 2 ** 28


def stack_dtype(shape) -> type:
    """The dtype of the flow's 10-channel interpolation grids for a volume of ``shape``."""
    return np.float32 if 10 * 8 * float(np.prod([float(n) for n in shape])) > FLOAT32_ABOVE_BYTES else np.float64


class GridSampler:
    """Trilinear φ, ∇φ, D²φ of a :class:`phantoms.Volume` at many points: one gather of the 8 corners.

    The interpolation of :meth:`phantoms.Volume.sample` (the same kernel,
    :func:`geometry.trilinear.trilinear_channels`, on the volume's own cached stacked derivative grids),
    laid out for an inner loop: points given and results returned by coordinate/channel ((3, P) in,
    (C, P) out), no bounds check.  Points outside the grid box are clamped onto it; callers check
    :meth:`contains_t` first.
    """

    def __init__(self, volume: Volume, channels: dict[int, np.ndarray] | None = None):
        self.volume = volume
        self._given = channels or {}     # {order: (N, C) array} used instead of the volume's own grids
        self._shape = tuple(int(k) for k in volume.shape)
        self._nmax = np.asarray(self._shape, float) - 1.0
        self._origin = volume.origin
        self._inv_spacing = 1.0 / volume.spacing
        self._lower, self._upper = volume.lower, volume.upper

    def _channels(self, order: int) -> np.ndarray:
        """The stacked grids as an (N, C) array with at least the channels of ``order``: the given ones, else
        the volume's own order-2 stack (cached by the volume; the flow reads every order from one stack)."""
        for o in (order, 2):
            if o in self._given:
                return self._given[o]
        ch = self.volume.channels(2, dtype=stack_dtype(self._shape))
        return ch.reshape(-1, ch.shape[-1])

    def contains(self, points: np.ndarray) -> np.ndarray:
        return np.all((points >= self._lower) & (points <= self._upper), axis=-1)

    def contains_t(self, xt: np.ndarray) -> bool:
        """True when every point of the (3, P) array lies in the grid box."""
        lo, up = self._lower, self._upper
        return bool(all((xt[c].min() >= lo[c]) and (xt[c].max() <= up[c]) for c in range(3)))

    def sample_t(self, xt: np.ndarray, derivatives: int = 2) -> np.ndarray:
        """Channels at the points of the (3, P) array: (C, P) with rows φ, ∇φ (3), Hessian (xx xy xz yy yz zz)."""
        idx = np.empty_like(xt)
        for c in range(3):
            np.multiply(xt[c] - self._origin[c], self._inv_spacing[c], out=idx[c])
            np.clip(idx[c], 0.0, self._nmax[c], out=idx[c])
        return trilinear_channels(self._channels(derivatives), self._shape, idx, channels=_N_CHANNELS[derivatives])

    def sample(self, points, derivatives: int = 0, clamp: bool = True) -> Sample:
        """Like :meth:`phantoms.Volume.sample` (points (P, 3)), always clamping."""
        out = self.sample_t(np.ascontiguousarray(np.asarray(points, float).T), derivatives)
        grad = np.ascontiguousarray(out[1:4].T) if derivatives >= 1 else None
        hess = np.ascontiguousarray(out[4:10].T)[:, _HESS_INDEX].reshape(-1, 3, 3) if derivatives >= 2 else None
        return Sample(out[0].copy(), grad, hess)


class _FieldAdapter:
    """Gives any object with ``sample(points, derivatives)`` (and optionally ``contains``) the
    channel-first interface of :class:`GridSampler` (used for analytic fields in tests)."""

    def __init__(self, field):
        self.field = field

    def contains_t(self, xt: np.ndarray) -> bool:
        f = getattr(self.field, "contains", None)
        return True if f is None else bool(np.all(f(xt.T)))

    def sample_t(self, xt: np.ndarray, derivatives: int = 2) -> np.ndarray:
        s = self.field.sample(np.ascontiguousarray(xt.T), derivatives=derivatives)
        rows = [np.asarray(s.phi, float)[None]]
        if derivatives >= 1:
            rows.append(np.asarray(s.grad, float).T)
        if derivatives >= 2:
            hh = np.asarray(s.hess, float)
            rows.append(np.stack([hh[:, 0, 0], hh[:, 0, 1], hh[:, 0, 2], hh[:, 1, 1], hh[:, 1, 2], hh[:, 2, 2]]))
        return np.ascontiguousarray(np.concatenate(rows))


def as_field(field):
    """A :class:`GridSampler` for a Volume; other fields (``sample(points, derivatives)``) are adapted."""
    if isinstance(field, (GridSampler, _FieldAdapter)):
        return field
    return GridSampler(field) if isinstance(field, Volume) else _FieldAdapter(field)




def smoothed_field(volume: Volume, sigma: float) -> GridSampler:
    """The sampler: the volume itself, or with its derivative grids ∇φ, D²φ computed after Gaussian pre-smoothing
    (σ voxels); φ itself stays the data's, so the data term sees the data's zero set, not the smoothed volume's
    shrunken one."""
    if sigma <= 0:
        return GridSampler(volume)
    cache = _SMOOTHED.setdefault(volume, {})
    key = float(sigma)
    if key not in cache:
        from scipy.ndimage import gaussian_filter
        smooth = volume.with_values(gaussian_filter(volume.values, sigma=sigma, mode="nearest"))
        ch2 = smooth.channels(2, dtype=stack_dtype(volume.shape)).reshape(-1, 10)   # owned by ``smooth``
        ch2[:, 0] = volume.values.ravel()
        cache[key] = {2: ch2}
        del smooth                                               # its own cache goes with it
    return GridSampler(volume, channels=cache[key])


def _gaussian_noise_gain(sigma: float) -> float:
    """Factor by which scipy's 3-D ``gaussian_filter`` (σ voxels, truncate 4) scales the std of i.i.d. noise."""
    if sigma <= 0:
        return 1.0
    r = int(4.0 * sigma + 0.5)
    k = np.exp(-0.5 * (np.arange(-r, r + 1) / sigma) ** 2)
    k /= k.sum()
    return float(np.sum(k ** 2)) ** 1.5


def noise_after_smoothing(noise_voxels: float, sigma: float) -> float:
    """The std (voxels) of i.i.d. noise of ``noise_voxels`` std after scipy's Gaussian filter of σ voxels."""
    return float(noise_voxels) * _gaussian_noise_gain(sigma)


def start_smoothing(noise_voxels: float, target_voxels: float = 1.0) -> float:
    """The smallest Gaussian σ (voxels) that brings i.i.d. noise of ``noise_voxels`` std down to
    ``target_voxels`` (0 when it already is): what the genus-0 start is grown from on a noisy volume — no more
    smoothing than needed, since every voxel of σ also erases parts about that thin (the bunny's ears)."""
    if not np.isfinite(noise_voxels) or noise_voxels <= target_voxels:
        return 0.0
    lo, hi = 0.0, 10.0
    if noise_voxels * _gaussian_noise_gain(hi) > target_voxels:
        return hi
    for _ in range(40):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if noise_voxels * _gaussian_noise_gain(mid) > target_voxels else (lo, mid)
    return hi
