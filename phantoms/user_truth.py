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


#: how far (90th percentile of its vertices, in voxels of the largest spacing) a truth surface may lie from the
#: volume's zero level set: a truth from the same segmentation lies within half a voxel, another rater's within
#: one or two; a frame mix-up (voxel indices, LPS) or a shift moves most of it further
TRUTH_TOLERANCE_VOXELS = 2.5


def _distance_in_voxels(points: np.ndarray, vol: Volume) -> float:
    """90th percentile of the first-order distance |φ| / |∇φ| from ``points`` to the zero level set, in voxels
    (inf when a point is outside the box)."""
    if len(points) == 0 or not vol.contains(points, margin=-float(vol.spacing.max())).all():
        return math.inf
    s = vol.sample(points, derivatives=1, clamp=True)
    grad = np.maximum(np.linalg.norm(s.grad, axis=1), 1e-12)
    return float(np.percentile(np.abs(s.phi) / grad, 90)) / float(vol.spacing.max())


def _check_truth_inside(truth, vol: Volume, where: str) -> None:
    """Refuse a truth surface that is not where the volume's surface is: outside its box, or its vertices'
    distance to the zero level set over :data:`TRUTH_TOLERANCE_VOXELS` (90th percentile) — naming the frame it looks to
    be in when that frame fits (voxel indices, LPS)."""
    v = truth.vertices[:: max(1, len(truth.vertices) // 5000)]
    d = _distance_in_voxels(v, vol)
    if d <= TRUTH_TOLERANCE_VOXELS:
        return
    frames = (("voxel-index coordinates (convert with the image's affine)", vol.index_to_world(v)),
              ("LPS coordinates (negate x and y for RAS+)", v * np.array([-1.0, -1.0, 1.0])))
    hint = next((f"; it fits the volume in {name}" for name, w in frames
                 if _distance_in_voxels(w, vol) <= TRUTH_TOLERANCE_VOXELS), "")
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
    _check_truth_inside(phantom, level_set, where)
    return phantom
