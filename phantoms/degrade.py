"""Degradations with exact truth: what a scanner and a segmentation make of a phantom (docs/PHANTOMS.md,
"Degradations").

A degradation is written as steps joined by ``+`` (order does not matter), each ``name`` or ``name@value``:

* ``mask`` — binary occupancy at the voxel centres (the sign of the exact φ there): what a segmentation gives;
* ``partial_volume`` — each voxel's inside fraction, an intensity image whose boundary is at 0.5.  Voxels whose
  centre is farther than half the voxel diagonal from the surface are wholly in or out; the others are
  supersampled on a ``PV_SAMPLES``³ sub-grid with the exact inside test (the summed fractions are within
  0.25 % of the exact volume on the sphere at N = 32–64: tests/test_phantoms_degrade.py);
* ``thick_slices@K`` — the spacing along z is K times the others over the same world box: every K-th z-plane
  of the N-grid, centred (the box is (N − 1) mod K in-plane steps shorter in z at most), applied before the
  steps above;
* ``blur@σ`` — a Gaussian point spread of σ in-plane voxels (isotropic in world units) applied to the inside
  fraction before it is read as a mask or an intensity (the partial-volume fraction is the box-filtered
  indicator, so the total spread is σ² + 1/12 voxel² per axis);
* ``label_noise@p`` — after ``mask``: each boundary voxel (one of its six neighbours has the other label) flips
  with probability p, seeded;
* ``downsample@K`` — with ``mask`` or ``partial_volume``, for a phantom that is a fine segmentation (the real tier,
  :mod:`phantoms.real_tier`): its voxels averaged over K × K × K blocks (times ``thick_slices@K`` along z, which
  there means 1 × 1 × K blocks) — the segmentation at a coarser resolution, scored against its own fine surface.

Exactly one of ``mask`` and ``partial_volume`` ends a degradation unless it is ``thick_slices`` alone (the exact
φ on the thick grid).  A method receives a :class:`~phantoms.volume.Volume` whose ``kind`` says what it is
(``mask`` / ``intensity``), whose ``raw`` is the image and ``level`` 0.5, and whose ``values`` is φ for level-set
methods: the mask's signed distance (:func:`phantoms.masks.mask_to_sdf`, the same conversion as a user's
``volume:`` mask); for a partial-volume image the same, with each boundary voxel's value replaced by
h·(0.5 − fraction), which keeps the image's sub-voxel position of the 0.5 level.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass

import numba
import numpy as np
from scipy import ndimage

from geometry.errors import InputError

from .base import DEFAULT_EXTENT, check_extent, check_n
from .masks import mask_sdf_values
from .volume import Volume, check_memory

__all__ = ["Degradation", "parse_degradation", "degrade", "partial_volume_fraction", "flip_boundary",
           "thick_grid", "image_input", "DEGRADATION_STEPS", "PV_SAMPLES"]

#: sub-samples per axis of a boundary voxel of the partial-volume image
PV_SAMPLES = 4
#: the steps a degradation is made of
DEGRADATION_STEPS = ("mask", "partial_volume", "thick_slices", "blur", "label_noise", "downsample")
_VALUED = {"thick_slices", "blur", "label_noise", "downsample"}
_INTEGER = {"thick_slices": "the slice spacing is K times the in-plane spacing",
            "downsample": "K x K x K fine voxels make one coarse voxel"}


@dataclass(frozen=True)
class Degradation:
    """One degradation (see the module docstring); ``Degradation()`` is none."""

    mask: bool = False
    partial_volume: bool = False
    thick_slices: int = 1
    blur: float = 0.0
    label_noise: float = 0.0
    downsample: int = 1

    @property
    def is_none(self) -> bool:
        return self == Degradation()

    @property
    def kind(self) -> str:
        """The input kind a method receives: ``mask``, ``intensity`` or ``sdf``."""
        return "mask" if self.mask else "intensity" if self.partial_volume else "sdf"

    @property
    def needs_subvoxel_truth(self) -> bool:
        """Whether it needs the exact φ between the voxel centres (not available from a user's image)."""
        return self.partial_volume or self.blur > 0 or self.thick_slices > 1 or self.downsample > 1

    def __str__(self) -> str:
        if self.is_none:
            return "none"
        parts = []
        if self.downsample > 1:
            parts.append(f"downsample@{self.downsample}")
        if self.thick_slices > 1:
            parts.append(f"thick_slices@{self.thick_slices}")
        if self.blur > 0:
            parts.append(f"blur@{_number(self.blur)}")
        if self.partial_volume:
            parts.append("partial_volume")
        if self.mask:
            parts.append("mask")
        if self.label_noise > 0:
            parts.append(f"label_noise@{_number(self.label_noise)}")
        return "+".join(parts)


def _number(x: float) -> str:
    """``x`` as the shortest text that reads back as the same float (``1.23456789``, ``1000000``, ``1e-07``): a
    degradation's text is its cells' identity and what the run reads back, so no digit is rounded off; no ``+``
    in an exponent (``1e+16`` → ``1e16``), which would read as a step separator."""
    text = repr(float(x)).replace("e+", "e")
    return text[:-2] if text.endswith(".0") else text


#: a ``+`` that joins two steps (not one in a number's exponent, ``blur@1e+06``)
_STEP_SEPARATOR = re.compile(r"(?<![0-9.][eE])\+")


def _step_value(name: str, value: str, where: str):
    try:
        x = float(value)
    except ValueError:
        raise InputError(f"{where}: {name}@{value}: {value!r} is not a number") from None
    if not math.isfinite(x):
        raise InputError(f"{where}: {name}@{value}: must be finite")
    if name in _INTEGER:
        if x != int(x) or x < 1:
            raise InputError(f"{where}: {name}@{value}: K must be an integer >= 1 ({_INTEGER[name]})")
        return int(x)
    if name == "blur" and x < 0:
        raise InputError(f"{where}: blur@{value}: sigma must be >= 0 (voxels)")
    if name == "label_noise" and not 0 <= x <= 1:
        raise InputError(f"{where}: label_noise@{value}: p must be in [0, 1] (a probability)")
    return x


def parse_degradation(text) -> Degradation:
    """``'thick_slices@3+mask'`` → :class:`Degradation`; ``'none'`` (or ``''``) → none.

    Raises
    ------
    InputError
        An unknown step, a step given twice, a bad value, or steps that do not combine (both ``mask`` and
        ``partial_volume``; ``blur`` or ``label_noise`` without what they act on).
    """
    if isinstance(text, Degradation):
        return text
    if not isinstance(text, str):
        raise InputError(f"degradation {text!r}: expected text such as 'mask' or 'thick_slices@3+partial_volume'")
    where = f"degradation {text!r}"
    spec = text.strip()
    if spec in ("", "none"):
        return Degradation()
    fields: dict = {}
    for part in _STEP_SEPARATOR.split(spec):
        name, at, value = part.strip().partition("@")
        if name not in DEGRADATION_STEPS:
            raise InputError(f"{where}: unknown step {name!r}; valid steps: {', '.join(DEGRADATION_STEPS)} "
                             "(joined by +, a value after @: thick_slices@3, blur@1, label_noise@0.1, downsample@2)")
        if name in fields:
            raise InputError(f"{where}: {name} is given twice")
        if name in _VALUED and not at:
            raise InputError(f"{where}: {name} needs a value: {name}@VALUE")
        if name not in _VALUED and at:
            raise InputError(f"{where}: {name} takes no value")
        fields[name] = _step_value(name, value, where) if at else True
    d = Degradation(**fields)
    if d.mask and d.partial_volume:
        raise InputError(f"{where}: mask and partial_volume exclude each other (a mask is binary, a partial-volume "
                         "image is not)")
    if d.label_noise and not d.mask:
        raise InputError(f"{where}: label_noise flips mask voxels; add +mask")
    if d.blur and not (d.mask or d.partial_volume):
        raise InputError(f"{where}: blur acts on the image a scanner reads; add +mask or +partial_volume")
    if d.downsample > 1 and not (d.mask or d.partial_volume):
        raise InputError(f"{where}: downsample coarsens a segmentation into the image a scanner reads; add +mask or "
                         "+partial_volume")
    return d


def thick_grid(n: int, extent: float, k: int) -> tuple[tuple[int, int, int], np.ndarray, np.ndarray, int]:
    """(shape, origin, spacing, first) of the N-grid over [−extent, extent]³ with z spacing K times the others:
    every K-th z-plane of the N-grid from plane ``first``, centred in the box ((N − 1) mod K in-plane steps
    short of it at most, split between the two ends)."""
    h = 2.0 * extent / (n - 1)
    nz = (n - 1) // k + 1
    first = ((n - 1) - (nz - 1) * k) // 2
    origin = np.array([-extent, -extent, -extent + first * h])
    return (n, n, nz), origin, np.array([h, h, k * h]), first


def _exact_grid(phantom, n: int, extent: float, k: int, first: int) -> np.ndarray:
    """The exact φ (sign exact; a mesh phantom's distance exact near the surface) at the thick grid's points:
    planes of the phantom's N³ volume."""
    from .mesh import MeshPhantom

    full = (MeshPhantom.volume(phantom, n, extent) if isinstance(phantom, MeshPhantom)
            else phantom.volume(n=n, extent=extent))          # MeshPhantom's: the exact distance (brain_mri too)
    return np.ascontiguousarray(full.values[:, :, first::k]) if k > 1 else np.asarray(full.values)


#: the grid points whose distance balls decide a sub-sample's side without the inside test: the voxel's centre
#: and its 6 face and 12 edge neighbours (the 8 corner neighbours decide few more sub-samples than they cost)
_BALL_OFFSETS = np.array([d for d in np.ndindex(3, 3, 3) if sum(abs(x - 1) for x in d) <= 2]) - 1


def partial_volume_fraction(phantom, phi: np.ndarray, origin, spacing, samples: int = PV_SAMPLES,
                            reference: bool = False) -> np.ndarray:
    """Each voxel's inside fraction (voxel = the box of ``spacing`` centred on the grid point): 0 / 1 where
    the centre's |φ| exceeds half the voxel diagonal, else the share of a ``samples``³ sub-grid of the exact φ
    that is inside (the phantom's exact inside test: the sign of its φ, a mesh's winding number).

    φ is 1-Lipschitz, so a sub-sample nearer a grid point g than |φ(g)| is on g's side: the balls of the
    voxel's centre and its face and edge neighbours decide most sub-samples (a compiled kernel), and only the
    others are asked the inside test; ``reference=True`` asks it of every sub-sample.  ``phi`` must be the exact
    distance (or a lower bound of it, with the exact sign) within two voxels of the surface."""
    origin, spacing = np.asarray(origin, float), np.asarray(spacing, float)
    phi = np.asarray(phi, np.float64)
    frac, band = _sides_and_band(phi, 0.5 * float(np.linalg.norm(spacing)))
    if len(band) == 0:
        return frac
    offs = (np.arange(samples) + 0.5) / samples - 0.5
    sub = np.stack(np.meshgrid(offs, offs, offs, indexing="ij"), axis=-1).reshape(-1, 3) * spacing
    if reference:
        side = np.full((len(band), len(sub)), -1, np.int8)
    else:
        # reach[k, s]: the distance of sub-sample s from ball centre k, with a margin for φ's rounding
        reach = np.linalg.norm(sub[None, :, :] - (_BALL_OFFSETS * spacing)[:, None, :], axis=2)
        reach += 1e-9 * float(spacing.min())
        side = _ball_sides(phi, band, _BALL_OFFSETS, reach)
    chunk = max(1, (1 << 20) // len(sub))                     # the inside test on at most ~1 M points at a time
    for c0 in range(0, len(band), chunk):
        part = side[c0:c0 + chunk]
        rows, cols = np.nonzero(part < 0)
        if len(rows):
            centres = origin + band[c0 + rows] * spacing
            part[rows, cols] = np.asarray(phantom.inside(centres + sub[cols]), bool)
    frac[tuple(band.T)] = side.mean(axis=1)
    return frac


@numba.njit(cache=True, nogil=True)
def _sides_and_band(phi, limit):
    """(φ < 0 as 0 / 1 floats, the (k, 3) indices of the points with |φ| < ``limit``) in one pass."""
    nx, ny, nz = phi.shape
    frac = np.empty(phi.shape)
    count = 0
    for i in range(nx):
        for j in range(ny):
            for k in range(nz):
                v = phi[i, j, k]
                frac[i, j, k] = 1.0 if v < 0 else 0.0
                if abs(v) < limit:
                    count += 1
    band = np.empty((count, 3), np.int64)
    c = 0
    for i in range(nx):
        for j in range(ny):
            for k in range(nz):
                if abs(phi[i, j, k]) < limit:
                    band[c, 0], band[c, 1], band[c, 2] = i, j, k
                    c += 1
    return frac, band


@numba.njit(cache=True, nogil=True)
def _ball_sides(phi, band, offsets, reach):
    """(band voxels, sub-samples) int8: 1 inside, 0 outside where the distance ball of φ at the voxel + one of
    the ``offsets`` (inside the grid) reaches the sub-sample (``reach[offset, sub-sample]``), −1 where none does."""
    n_sub = reach.shape[1]
    nx, ny, nz = phi.shape
    side = np.full((band.shape[0], n_sub), -1, np.int8)
    for v in range(band.shape[0]):
        for b in range(offsets.shape[0]):
            i, j, k = band[v, 0] + offsets[b, 0], band[v, 1] + offsets[b, 1], band[v, 2] + offsets[b, 2]
            if i < 0 or j < 0 or k < 0 or i >= nx or j >= ny or k >= nz:
                continue
            val = phi[i, j, k]
            a = abs(val)
            for s in range(n_sub):
                if side[v, s] < 0 and a > reach[b, s]:
                    side[v, s] = 1 if val < 0 else 0
    return side


def flip_boundary(mask: np.ndarray, p: float, seed: int) -> np.ndarray:
    """``mask`` with each boundary voxel (a six-neighbour has the other label) flipped with probability ``p``
    (PCG64 seeded with ``seed``: the same seed flips the same voxels)."""
    m = np.asarray(mask, bool)
    if p <= 0:
        return m.copy()
    boundary = (ndimage.binary_dilation(m) & ~m) | (m & ~ndimage.binary_erosion(m, border_value=1))
    idx = np.flatnonzero(boundary)
    flip = idx[np.random.default_rng(int(seed)).random(len(idx)) < p]
    out = m.copy().reshape(-1)
    out[flip] = ~out[flip]
    return out.reshape(m.shape)


def _level_set_of(image: np.ndarray, kind: str, origin, spacing) -> np.ndarray:
    """φ for level-set methods: the mask's signed distance; for an intensity its boundary voxels get
    h·(0.5 − fraction)."""
    inside = image > 0.5
    if not inside.any() or inside.all():
        raise InputError(f"the degraded {kind} has no {'inside' if not inside.any() else 'outside'} voxels: "
                         "there is no surface to reconstruct (a larger N or a milder degradation)")
    phi = mask_sdf_values(inside, spacing)
    if kind == "intensity":
        part = (image > 0) & (image < 1)
        phi[part] = float(np.min(spacing)) * (0.5 - image[part])
    return phi


def degrade(phantom, degradation, n: int, extent: float = DEFAULT_EXTENT, seed: int = 0,
            clean: Volume | None = None) -> Volume:
    """The phantom's volume at N as the degradation makes it (module docstring), in world units.

    Parameters
    ----------
    phantom : Phantom
        A phantom with an exact φ (analytic or mesh); a user's volume (``volume:``) takes only ``mask`` and
        ``label_noise`` (its voxels are all there is); a fine segmentation (``coarse_input``, the real tier) makes
        its own coarse input.
    degradation : Degradation or str
        What to do (:func:`parse_degradation`).
    n, extent : int, float
        The grid (N³ over [−extent, extent]³ before ``thick_slices``); a fine segmentation's own grid ignores them.
    seed : int
        Seed of ``label_noise``.
    clean : Volume, optional
        A user volume's own level set (its native grid), needed for such a phantom.

    Raises
    ------
    InputError
        Bad grid or degradation, sub-voxel steps on a user volume, or nothing left inside / outside.
    """
    d = parse_degradation(degradation)
    if d.is_none:
        raise InputError("degrade: no degradation given")
    if getattr(phantom, "coarse_input", None) is not None:  # a fine segmentation: its own grid, coarsened
        return phantom.coarse_input(d, seed)
    if d.downsample > 1:
        raise InputError(f"degradation {d}: downsample@K coarsens a fine segmentation (the real tier, "
                         f"docs/PHANTOMS.md); phantom {getattr(phantom, 'name', phantom)!r} is not one — for an "
                         "exact phantom a coarser grid is a smaller N")
    if getattr(phantom, "level_set", None) is not None:     # a user's volume: only its voxels are known
        if d.needs_subvoxel_truth:
            raise InputError(f"degradation {d}: a user volume has no sub-voxel truth (partial_volume, blur and "
                             "thick_slices need the exact surface between voxels); use mask or label_noise")
        vol = clean if clean is not None else phantom.volume()
        shape, origin, spacing, phi = vol.shape, vol.origin, vol.spacing, vol.values
    else:
        n, extent = check_n(n), check_extent(extent)
        shape, origin, spacing, first = thick_grid(n, extent, d.thick_slices)
        check_memory(shape, 4, what=f"the degraded N = {n} volume")
        phi = _exact_grid(phantom, n, extent, d.thick_slices, first)
    if d.kind == "sdf":                                        # thick slices alone: the exact φ, coarser in z
        return Volume(phi, origin, spacing)
    if d.partial_volume or d.blur:
        image = partial_volume_fraction(phantom, phi, origin, spacing)
    else:
        image = (phi < 0).astype(np.float64)
    return image_input(image, d, origin, spacing, seed)


def image_input(fraction: np.ndarray, degradation, origin, spacing, seed: int = 0) -> Volume:
    """The volume a method gets from an inside-fraction image (1 inside, 0 outside, between on the boundary):
    ``blur``, then ``mask`` (more than half inside), then ``label_noise`` as the degradation says, with its level
    set (module docstring) — kind ``mask`` or ``intensity``, raw the image, level 0.5."""
    d = parse_degradation(degradation)
    origin, spacing = np.asarray(origin, float), np.broadcast_to(np.asarray(spacing, float), (3,))
    image = np.asarray(fraction, np.float64)
    if d.blur:
        h = float(np.min(spacing))
        image = ndimage.gaussian_filter(image, sigma=[d.blur * h / s for s in spacing], mode="nearest")
    if d.mask:
        image = (image > 0.5).astype(np.float64)
    if d.label_noise:
        image = flip_boundary(image > 0.5, d.label_noise, seed).astype(np.float64)
    values = _level_set_of(image, d.kind, origin, spacing)
    return Volume(values, origin, spacing, kind=d.kind, raw=image, level=0.5)
