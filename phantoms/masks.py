"""A binary mask as a signed distance volume (docs/PHANTOMS.md, "Mask → signed distance")."""

from __future__ import annotations

import numpy as np
from scipy import ndimage

from geometry.errors import InputError

from .mask_edt import outside_distance, true_box
from .volume import Volume

__all__ = ["mask_to_sdf", "mask_sdf_values", "mask_distances"]


def mask_distances(m: np.ndarray, spacing: np.ndarray, reference: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """(distance of each outside voxel to the nearest inside voxel centre, of each inside voxel to the nearest
    outside one), 0 elsewhere, world units: exact Euclidean distance transforms with the per-axis ``spacing``.

    :func:`phantoms.mask_edt.outside_distance` (compiled, its passes restricted to the inside voxels' box) computes
    both; the ``reference`` the tests compare it with is :func:`scipy.ndimage.distance_transform_edt`."""
    if reference:
        return (ndimage.distance_transform_edt(~m, sampling=spacing),
                ndimage.distance_transform_edt(m, sampling=spacing))
    box = _grown_box(m)
    d_in = np.zeros(m.shape)
    d_in[box] = _inside_distance(m[box], spacing)
    return outside_distance(m, spacing), d_in


def _inside_distance(m_box: np.ndarray, spacing) -> np.ndarray:
    """The inside distances of the inside voxels' box grown by one voxel: an inside voxel's nearest outside voxel
    lies in it (every voxel beyond it is outside, and the box's outer layer is nearer)."""
    return outside_distance(~m_box, spacing)


def _grown_box(m: np.ndarray, box: tuple[np.ndarray, np.ndarray] | None = None) -> tuple[slice, ...]:
    """The bounding box of the true voxels of ``m`` (:func:`~phantoms.mask_edt.true_box`, or ``box``), one voxel
    larger on each side, clipped to the array."""
    lo, hi = true_box(m) if box is None else box
    return tuple(slice(max(int(a) - 1, 0), min(int(b) + 1, n)) for a, b, n in zip(lo, hi, m.shape))


def mask_to_sdf(mask, origin=(0.0, 0.0, 0.0), spacing=(1.0, 1.0, 1.0)) -> Volume:
    """Signed distance volume of a binary mask (negative inside), zero half-way between voxels.

    Inside voxels get −(distance to the nearest outside voxel centre) + s/2, outside voxels
    (distance to the nearest inside voxel centre) − s/2: exact Euclidean distance transforms
    (:func:`mask_distances`) with the real, possibly anisotropic ``spacing``, s its
    smallest entry, world units.  On an isotropic grid the two voxels of every edge joining inside and outside
    get −s/2 and +s/2, so the trilinear zero level set crosses the edge half-way between their centres: the
    boundary of the voxelised object.  With anisotropic spacing that holds on the faces of the voxel set; near
    its edges and corners the crossing moves by at most (s_max − s_min)/2 towards the inside voxel.

    Parameters
    ----------
    mask : array_like, shape (nx, ny, nz)
        True (non-zero) inside.
    origin : array_like, shape (3,)
        The world position of voxel (0, 0, 0).
    spacing : float or array_like, shape (3,)
        The per-axis voxel spacing, world units.

    Returns
    -------
    Volume
        The signed distance, world units, negative inside.

    Raises
    ------
    InputError
        Not 3-D, or no inside / no outside voxel.
    """
    spacing = np.broadcast_to(np.asarray(spacing, dtype=float), (3,))
    return Volume(mask_sdf_values(mask, spacing), origin, spacing)


def mask_sdf_values(mask, spacing) -> np.ndarray:
    """The values of :func:`mask_to_sdf` (float64, C order, a new array): for callers that build their own
    :class:`~phantoms.volume.Volume` around them (a degraded volume keeps its raw image beside them).

    Raises
    ------
    InputError
        Not 3-D, or no inside / no outside voxel.
    """
    m = np.asarray(mask).astype(bool)
    if m.ndim != 3:
        raise InputError(f"a mask must be a 3-D array; got shape {m.shape}")
    if not m.any():
        raise InputError("the mask has no inside voxels (all zero): there is no surface to reconstruct")
    if m.all():
        raise InputError("the mask has no outside voxels (all one): there is no surface to reconstruct")
    spacing = np.broadcast_to(np.asarray(spacing, dtype=float), (3,))
    half = 0.5 * float(spacing.min())
    tight = true_box(m)
    values = outside_distance(m, spacing, tight)  # outside: distance − s/2; inside: s/2 − distance (in place)
    values -= half
    box = _grown_box(m, tight)
    inside = values[box]
    np.subtract(half, _inside_distance(m[box], spacing), out=inside, where=m[box])
    return values
