"""Which frame a surface is in, when it is not in its volume's world coordinates: voxel indices of the file (in its
own axis order, before the re-orientation to RAS+ and any ``pad=``) or LPS — named in the refusal of a ``truth=``
(:mod:`phantoms.user`) and of a ``mesh_file`` method's file."""

from __future__ import annotations

import itertools
import math

import numpy as np

from .volume import Volume

__all__ = ["TRUTH_TOLERANCE_VOXELS", "distance_in_voxels", "fitting_frame"]


#: how far (90th percentile of its vertices, in voxels of the largest spacing) a truth surface may lie from the
#: volume's zero level set: a truth from the same segmentation lies within half a voxel, another rater's within
#: one or two; a frame mix-up (voxel indices, LPS) or a shift moves most of it further
TRUTH_TOLERANCE_VOXELS = 2.5


def distance_in_voxels(points: np.ndarray, vol: Volume) -> float:
    """90th percentile of the first-order distance |φ| / |∇φ| from ``points`` to the zero level set, in voxels
    (inf when a point is outside the box)."""
    if len(points) == 0 or not vol.contains(points, margin=-float(vol.spacing.max())).all():
        return math.inf
    s = vol.sample(points, derivatives=1, clamp=True)
    grad = np.maximum(np.linalg.norm(s.grad, axis=1), 1e-12)
    return float(np.percentile(np.abs(s.phi) / grad, 90)) / float(vol.spacing.max())


def _index_frames(v: np.ndarray, vol: Volume, pad: int):
    """``v`` read as voxel indices of the file, in world coordinates: the array was re-oriented to RAS+ (axes
    permuted and flipped, :mod:`phantoms.images`) and maybe padded, so each of the 48 axis orders and flips is a
    candidate (the identity first)."""
    n = np.asarray(vol.shape) - 2 * pad
    for perm in itertools.permutations(range(3)):
        for flips in itertools.product((False, True), repeat=3):
            idx = np.empty_like(v)
            for a, d in enumerate(perm):              # the file's axis a is the array's axis d
                idx[:, d] = n[d] - 1 - v[:, a] if flips[a] else v[:, a]
            yield vol.index_to_world(idx + pad)


def fitting_frame(points, vol: Volume, pad: int = 0) -> str | None:
    """The frame in which ``points`` (a surface's vertices) lie on ``vol``'s zero level set when they do not in
    its world coordinates: ``"voxel-index coordinates ..."`` or ``"LPS coordinates (negate x and y for RAS+)"``;
    None when no such frame fits (or they fit as they are).  ``pad``: the outside voxels the volume's ``pad=``
    added around the file's grid."""
    v = np.asarray(points, float)[:: max(1, len(points) // 5000)]
    if distance_in_voxels(v, vol) <= TRUTH_TOLERANCE_VOXELS:
        return None
    if distance_in_voxels(v * np.array([-1.0, -1.0, 1.0]), vol) <= TRUTH_TOLERANCE_VOXELS:
        return "LPS coordinates (negate x and y for RAS+)"
    if any(distance_in_voxels(w, vol) <= TRUTH_TOLERANCE_VOXELS for w in _index_frames(v, vol, pad)):
        return "voxel-index coordinates of the file (convert with the image's affine)"
    return None
