"""The carved start (``carved_start``): the genus-0 start grown from the region no sample's empty ball reaches,
read on a grid twice as fine, so that a part every sample misses is in the start.

Why: a limb or blade thinner than a voxel that lies between sample rows leaves every sample outside (φ > 0); the
genus-0 start of φ < 0 has no part there, and a constraint of the flow (``hold_carved``, carve.py) can only keep
what the start has.  Every outside sample q has an empty ball of radius φ(q)/g (g: the distance scale of
tips.py); the object lies in the complement of their union, the *carved hull* — where Reach for the Spheres
grows its surface.  At a sample the sample's own ball covers the point, so the hull is read between samples: on
the grid refined by 2 per axis, s = min(φ₀, b) with φ₀ the start's values (pre-smoothed on noisy volumes),
linearly interpolated, and b(x) = max_q (φ(q)/g − |x − q|) over the 4×4×4 raw samples around x (carve.py's
:func:`ball_depth`; b < 0: no ball reaches x).  b is read only in the band 0 ≤ φ₀ < ``_BAND_VOXELS`` voxels (a
point farther out is covered by its nearest sample's ball; a point inside already has s ≤ φ₀ < 0).  The region
s < 0 then goes through the same genus-0 growth as φ < 0 does (start.py's :func:`genus0_surface`), on the fine
grid.  No ball covers a gap narrower than a voxel between two parts either (a sulcus between its banks): a point
with an inside sample ahead of it along ∇φ (:func:`between_inside`) is in a gap, not beside a part, and is left as
φ₀ says.
"""

from __future__ import annotations

import numpy as np
from scipy.ndimage import zoom

from phantoms import Volume

from .carve import ball_depth
from .tips import near_samples

__all__ = ["carved_values", "carved_surface", "between_inside", "fine_grid_fits", "FINE_MAX_SAMPLES"]

_FACTOR = 2                 # the fine grid: samples per voxel edge
_BAND_VOXELS = 1.5          # b is read where 0 ≤ φ₀ < this many voxels
_NOISE_STDS = 2.0           # on a noisy volume each ball is smaller by this many noise stds (a one-sided 98 % bound)
_BLOCK = 16384              # points per block of the gap test: (block, 64) arrays
#: the largest fine grid read (a 128³ volume refines to 255³ = 16.6 M samples); above it the start is the usual one
FINE_MAX_SAMPLES = 2 ** 24


def fine_shape(shape) -> tuple[int, ...]:
    """The refined grid's shape: (n − 1)·2 + 1 samples per axis (every coarse sample and one between each pair)."""
    return tuple((int(n) - 1) * _FACTOR + 1 for n in shape)


def fine_grid_fits(shape) -> bool:
    """Whether the refined grid of a volume of ``shape`` has at most :data:`FINE_MAX_SAMPLES` samples."""
    return float(np.prod([float(n) for n in fine_shape(shape)])) <= FINE_MAX_SAMPLES


def carved_values(volume: Volume, start_values: np.ndarray, scale: float, shrink: float = 0.0) -> Volume | None:
    """The fine grid of s = min(φ₀, b) as a Volume (same box, spacing / 2), or None when it would exceed
    :data:`FINE_MAX_SAMPLES` samples.

    Parameters
    ----------
    volume : Volume
        The raw samples: the balls' centres and radii.
    start_values : ndarray
        φ₀, the samples the start is grown from (the volume's, or pre-smoothed ones), on the volume's grid.
    scale : float
        g: a ball's radius is φ(q)/g.
    shrink : float
        Every ball's radius is less by this much (world units): on a noisy volume a sample's ball is empty only
        with a margin for its noise.
    """
    if not fine_grid_fits(volume.shape):
        return None
    shape = fine_shape(volume.shape)
    # order-1 zoom to (n − 1)·r + 1 samples puts fine sample i at coarse position i / r exactly: trilinear φ₀
    fine = zoom(np.asarray(start_values, float), [s / n for s, n in zip(shape, volume.shape)], order=1,
                mode="nearest", grid_mode=False)
    spacing = np.asarray(volume.spacing, float) * np.ones(3) / _FACTOR
    h = volume.h
    band = np.flatnonzero(((fine >= 0.0) & (fine < _BAND_VOXELS * h)).ravel())
    if len(band):
        idx = np.stack(np.unravel_index(band, shape), axis=1)
        points = np.asarray(volume.origin, float) + idx * spacing
        b = ball_depth(volume, points, scale) - shrink
        b = np.where(np.isfinite(b), b, np.inf)
        carved = np.flatnonzero(b < 0.0)
        b[carved[between_inside(volume, points[carved])]] = np.inf        # a gap, not a part: left as φ₀ says
        flat = fine.reshape(-1)
        flat[band] = np.minimum(flat[band], b)
    return Volume(fine, origin=np.asarray(volume.origin, float), spacing=spacing)


def between_inside(volume: Volume, points: np.ndarray) -> np.ndarray:
    """Whether each of ``points`` (P, 3) has an inside sample (φ < 0) among the 4×4×4 around it on its outward
    side: (q − x)·∇φ(x) > 0, ∇φ the volume's trilinear gradient at x.  Where ∇φ vanishes (a point mid-way
    between symmetric samples: a limb's axis, a gap's mid-plane) any inside sample around it decides.

    Why: no ball covers the air in a gap narrower than a voxel between two parts (a sulcus between its banks) any
    more than it covers a part thinner than a voxel; what tells them apart is where the object is — beside a
    protrusion (a limb, a blade, also at its root) every inside sample lies behind the point, against ∇φ; in a
    gap the banks reach past the point towards the gap's mouth, the way φ grows.  The carved region keeps only
    the former."""
    out = np.zeros(len(points), bool)
    for s in range(0, len(points), _BLOCK):
        p = points[s:s + _BLOCK]
        q, vq, on_grid = near_samples(volume, p)
        g = volume.sample(p, derivatives=1).grad
        gn = np.linalg.norm(g, axis=1)
        u = g / np.where(gn > 0, gn, 1.0)[:, None]
        ahead = np.einsum("pkd,pd->pk", q - p[:, None, :], u) > 0.0
        inside = on_grid & (vq < 0.0)
        out[s:s + _BLOCK] = np.where(gn > 1e-12, (inside & ahead).any(1), inside.any(1))
    return out


def carved_surface(volume: Volume, start_values: np.ndarray, x: np.ndarray, faces: np.ndarray,
                   pinhole_below: float, noise: float = 0.0) -> tuple[np.ndarray, np.ndarray, dict]:
    """(vertices, faces, facts): the genus-0 surface of the carved region s < 0 (see the module docstring), or the
    usual start ``x``, ``faces`` (grown from φ₀ < 0) when the fine grid is too large or the growth gave no surface.

    ``pinhole_below`` is in voxels of the volume (as for the usual start); pieces are not joined through saddles
    (see below); the distance scale g is read outside the usual start."""
    from geometry.operators import MeshOperators

    from .start import genus0_surface
    from .tips import distance_scale

    geo = MeshOperators(faces, len(x)).geometry(x)
    scale = distance_scale(volume, x, geo.vertex_normals, volume.h)
    fine = carved_values(volume, start_values, scale, _NOISE_STDS * noise / scale)
    if fine is None:
        return x, faces, {"used": False, "why": f"the fine grid would exceed {FINE_MAX_SAMPLES} samples"}
    coarse_inside = int((np.asarray(start_values) < 0).sum())
    # no joins on the fine grid: between samples b reads less than the distance (down to φ − 0.87 voxel), so a
    # gap of a few voxels would read as a shallow saddle; a neck no ball covers is in the region already
    xf, ff, more = genus0_surface(fine, fine.values, 0.0, pinhole_below * _FACTOR)
    facts = {"used": xf is not None, "distance_scale": round(float(scale), 4),
             "fine_inside_samples": int((fine.values < 0).sum()), "coarse_inside_samples": coarse_inside,
             "fine_solid_samples": more["solid_samples"], "fine_pieces": more["pieces"],
             "fine_disambiguation": more["disambiguation"]}
    if xf is None:
        facts["why"] = "the genus-0 growth on the fine grid gave no surface"
        return x, faces, facts
    return xf, ff, facts
