"""A user's reference surface for a volume: ``volume:PATH?truth=FILE`` (docs/PHANTOMS.md, "Your own volumes").

The truth is a closed mesh in the volume's world coordinates (RAS+), or a label image whose surface is the zero
level set of its mask's signed distance; either becomes a :class:`~phantoms.mesh.MeshPhantom` (so a mesh whose parts
cross is resolved to its solid as every mesh phantom is).  Before any cell uses it, it is checked to lie on the
volume's zero level set: a truth in another frame (voxel indices, LPS) or shifted is refused, naming the frame.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from geometry.errors import InputError

from .frames import TRUTH_TOLERANCE_VOXELS, distance_in_voxels, fitting_frame
from .image_checks import check_file_kind
from .images import IMAGE_SUFFIXES, image_suffix, read_image
from .volume import Volume

__all__ = ["read_truth", "TRUTH_TOLERANCE_VOXELS"]


def _truth_from_labels(path: str, opts: dict, where: str):
    from skimage.measure import marching_cubes

    from .masks import mask_to_sdf
    from .mesh import MeshPhantom

    img = read_image(path)
    if not (img.values.dtype.kind in "biu" or bool(np.all(np.mod(img.values, 1) == 0))):
        raise InputError(f"{where}: the truth image {Path(path).name} holds non-integer values (range "
                         f"[{float(img.values.min()):g}, {float(img.values.max()):g}]): an intensity image, not a "
                         "label map; give a label image (inside > 0, or label=L) or a closed surface mesh")
    label = opts.get("label")
    inside = img.values == label if label is not None else img.values > 0
    if not inside.any():
        raise InputError(f"{where}: the truth label image {path} has no voxel "
                         f"{'equal to ' + str(label) if label is not None else 'above 0'}")
    inside = np.pad(inside, 1, constant_values=False)            # a closed surface even where it meets the border
    spacing = np.asarray(img.spacing, float)
    sdf = mask_to_sdf(inside, np.asarray(img.origin, float) - spacing, spacing)
    v, f, _, _ = marching_cubes(sdf.values, 0.0, spacing=tuple(sdf.spacing), allow_degenerate=False)
    ph = MeshPhantom(v + sdf.origin, f, normalize=False, name=f"truth:{path}", source=str(path),
                     curvature_radius=2.0 * float(spacing.min()))
    ph.truth_note = (f"ground truth = the label image {Path(path).name}: the zero level set of its mask's signed "
                     "distance (marching cubes; vertices half-way between inside and outside voxel centres)")
    return ph


def _truth_from_mesh(path: str, where: str):
    from .mesh import MeshPhantom

    try:
        ph = MeshPhantom.from_file(path, normalize=False, name=f"truth:{path}")
    except InputError as exc:
        raise InputError(f"{where}: truth mesh: {exc}") from None
    ph.truth_note = f"ground truth = the mesh {Path(path).name} (exact point-to-triangle distances)"
    if ph.resolution is not None:
        ph.truth_note += f"; {ph.resolution.note()}"
    return ph


def _grid_slopes(vol: Volume, nodes: np.ndarray) -> np.ndarray:
    """At grid nodes (K, 3) of index triples: the largest |Δφ| / spacing over the six grid edges leaving each — at
    most 1 where φ is a distance (1-Lipschitz), at least 1/√3 away from a ridge, 1 at a ridge too (the slope down
    either side); far from 1 where φ is a level set of another scale."""
    vals, shape = vol.values, np.asarray(vol.shape)
    here = vals[nodes[:, 0], nodes[:, 1], nodes[:, 2]]
    best = np.zeros(len(nodes))
    for axis in range(3):
        for step in (-1, 1):
            other = nodes.copy()
            other[:, axis] += step
            ok = (other[:, axis] >= 0) & (other[:, axis] < shape[axis])
            there = vals[other[ok, 0], other[ok, 1], other[ok, 2]]
            best[ok] = np.maximum(best[ok], np.abs(there - here[ok]) / float(vol.spacing[axis]))
    return best


def _distance_mismatch_in_voxels(truth, points: np.ndarray, vol: Volume) -> float:
    """90th percentile over ``points`` (on the truth) of the largest |φ − d_truth| at the 8 corners of the cell
    holding each, in voxels: where φ is a signed distance, the truth's own exact signed distance must equal it at
    the grid nodes, however thin the shape (a first-order estimate |φ| / |∇φ| is no distance at a ridge, where
    |∇φ| vanishes).  |d_A − d_B| ≤ the Hausdorff distance of two surfaces A and B, so a truth within k voxels of
    the volume's surface passes at k; a shifted one differs by its shift.  inf when φ does not read as a distance
    at those nodes (median edge slope below ½ or its 90th percentile above 1.1: a level set of another scale, an
    intensity) or a point is outside the box."""
    if vol.kind == "intensity" or not len(points) or not vol.contains(points).all():
        return math.inf
    shape = np.asarray(vol.shape)
    base = np.clip(np.floor(vol.world_to_index(points)).astype(np.int64), 0, shape - 2)
    corners = base[:, None, :] + np.array([[i, j, k] for i in (0, 1) for j in (0, 1) for k in (0, 1)])[None]
    flat = np.ravel_multi_index(corners.reshape(-1, 3).T, vol.shape)
    keys, inverse = np.unique(flat, return_inverse=True)
    nodes = np.stack(np.unravel_index(keys, vol.shape), axis=1)
    slopes = _grid_slopes(vol, nodes)
    if np.median(slopes) < 0.5 or np.percentile(slopes, 90) > 1.1:
        return math.inf
    phi = vol.values[nodes[:, 0], nodes[:, 1], nodes[:, 2]]
    err = np.abs(phi - truth.sdf(vol.index_to_world(nodes)))[inverse].reshape(len(points), 8).max(axis=1)
    return float(np.percentile(err, 90)) / float(vol.spacing.max())


def _check_truth_inside(truth, vol: Volume, where: str, pad: int = 0) -> None:
    """Refuse a truth surface that is not where the volume's surface is: outside its box, or its vertices further
    than :data:`TRUTH_TOLERANCE_VOXELS` (90th percentile) from the zero level set — naming the frame it looks to be
    in when that frame fits (voxel indices, LPS).  The first-order distance |φ| / |∇φ| decides where it passes; where
    it does not and φ is a distance, the truth's own signed distance at the grid nodes decides
    (:func:`_distance_mismatch_in_voxels`): a thin part's ridge makes the first estimate large, not the second."""
    v = truth.vertices[:: max(1, len(truth.vertices) // 5000)]
    d = distance_in_voxels(v, vol)
    if d <= TRUTH_TOLERANCE_VOXELS or _distance_mismatch_in_voxels(truth, v, vol) <= TRUTH_TOLERANCE_VOXELS:
        return
    frame = fitting_frame(v, vol, pad)
    hint = f"; it fits the volume in {frame}" if frame else ""
    lo, hi = truth.vertices.min(0), truth.vertices.max(0)
    if not np.isfinite(d):
        what = (f"lies outside the volume (truth box {lo.round(3).tolist()} – {hi.round(3).tolist()}, volume box "
                f"{vol.lower.round(3).tolist()} – {vol.upper.round(3).tolist()})")
    else:
        what = (f"is not on the volume's surface: 10 % of its vertices lie {d:.1f} voxels or more from the zero "
                f"level set (tolerance {TRUTH_TOLERANCE_VOXELS:g})")
    name = Path(getattr(truth, "source", "") or "").name
    raise InputError(f"{where}: the truth surface{' ' + name if name else ''} {what}{hint}; it must be in the "
                     "volume's world coordinates (RAS+, docs/PHANTOMS.md)")


def read_truth(options: dict, level_set: Volume, where: str):
    """The ``truth=`` file of a volume's ``options`` as a mesh phantom, checked against the volume's ``level_set``
    (:func:`_check_truth_inside`); InputError naming ``where`` for a missing, unreadable or misplaced truth."""
    truth = options["truth"]
    tp = Path(truth).expanduser()
    if not tp.exists():
        raise InputError(f"{where}: no such truth file: {truth}")
    check_file_kind(tp)            # a FIFO or a device as truth would block the mesh reader
    is_image = tp.is_dir() or image_suffix(tp) in IMAGE_SUFFIXES
    phantom = _truth_from_labels(str(tp), options, where) if is_image else _truth_from_mesh(str(tp), where)
    _check_truth_inside(phantom, level_set, where, int(options.get("pad", 0)))
    return phantom
