"""``iou``: volumetric intersection over union of the inside regions of the mesh and of the truth (docs/METRICS.md).

IoU = |A ∩ B| / |A ∪ B|, A the solid the mesh bounds, B the true solid, estimated on one point per cell of a
48³ grid of cells (stratified, "jittered" sampling: a seeded uniform point in each cell) over the box
[lo − 2h, hi + 2h], lo/hi the bounds of the mesh vertices and of the truth's surface samples.  The cells of
one column (fixed i, j) share their point's (x, y) — still one uniform point per cell, so the estimate stays
unbiased — which lets a closed mesh's inside be read off the column's piercings in one pass
(:func:`geometry.raster.column_winding`, far cheaper than a winding-number query per point).

* inside the mesh: |winding number| ≥ ½ — for a closed mesh the exact count of the column's piercings above
  the point, else (an open mesh, invalid anyway; its metrics are kept) gpytoolbox's generalised winding
  number (``fast_winding_number``, Barnes–Hut), which still decides inside-ness there.  The absolute value
  makes an inward mesh bound the same solid as an outward one.
* inside the truth: the phantom's own exact test (``phantom.inside``: the sign of the exact φ; the ellipsoid's
  implicit equation); a mesh phantom (closed by construction) by the same column count on its mesh.

Accuracy: only cells cut by one of the two surfaces can be misjudged; with jittered sampling the estimate of
|A Δ B| has a standard error of about √(cells cut) cells.  For a fine sphere mesh against the sphere the
estimate is 1 − O(1e-3) (the tests state the bound).
"""

from __future__ import annotations

import numpy as np

from geometry.mesh import scored_mesh
from geometry.raster import column_winding

__all__ = ["iou", "IOU_CELLS"]

#: cells per axis of the stratified sample grid
IOU_CELLS = 48


def _jittered_columns(lo: np.ndarray, hi: np.ndarray, m: int, seed) -> tuple[np.ndarray, np.ndarray]:
    """(columns (m, m, 2), z (m, m, m)): one uniform point per cell, shared (x, y) within a column."""
    step = (hi - lo) / m
    rng = np.random.default_rng(seed)
    ij = np.stack(np.meshgrid(np.arange(m), np.arange(m), indexing="ij"), axis=-1)
    columns = lo[:2] + (ij + rng.random((m, m, 2))) * step[:2]
    z = lo[2] + (np.arange(m)[None, None, :] + rng.random((m, m, m))) * step[2]
    return columns, z


def _mesh_of(truth):
    """(vertices, faces) of a phantom that is a closed triangle mesh, else None."""
    v, f = getattr(truth, "vertices", None), getattr(truth, "faces", None)
    if isinstance(v, np.ndarray) and isinstance(f, np.ndarray) and v.ndim == 2 and f.ndim == 2:
        return v, f
    return None


def iou(vertices, faces: np.ndarray | None, truth, h: float, truth_points: np.ndarray, *,
        seed=0, cells: int = IOU_CELLS, closed: bool | None = None) -> float:
    """Volumetric IoU of the mesh's and the phantom's inside regions (see the module docstring).

    Parameters
    ----------
    vertices, faces : the reconstructed mesh: a :class:`geometry.mesh.ScoredMesh` and None, or the arrays.
    truth : the phantom (its ``inside``, or its mesh for a mesh phantom).
    h : grid step; the sample box is padded by 2h.
    truth_points : samples of the true surface (they bound the box with the mesh's vertices).
    seed : the sample points' seed.
    cells : cells per axis of the stratified sample.
    closed : whether the mesh is closed (no boundary or non-manifold edge); None = the mesh's ``watertight``.

    Returns
    -------
    float: IoU in [0, 1], NaN when neither solid holds a sample point.
    """
    m = scored_mesh(vertices, faces)
    vertices, faces = m.vertices, m.faces
    lo = np.minimum(vertices.min(0), truth_points.min(0)) - 2 * h
    hi = np.maximum(vertices.max(0), truth_points.max(0)) + 2 * h
    step = (hi - lo) / cells
    columns, z = _jittered_columns(lo, hi, cells, seed)
    if closed is None:
        closed = m.watertight
    if closed:
        a = np.abs(column_winding(vertices, faces, lo, step, columns, z)) >= 1
    else:
        from gpytoolbox import fast_winding_number

        w = fast_winding_number(_points(columns, z), np.ascontiguousarray(vertices),
                                np.ascontiguousarray(faces, np.int32))
        a = (np.abs(w) >= 0.5).reshape(z.shape)
    mesh = _mesh_of(truth)
    if mesh is not None:
        b = column_winding(mesh[0], mesh[1], lo, step, columns, z) >= 1
    else:
        b = np.asarray(truth.inside(_points(columns, z)), bool).reshape(z.shape)
    union = int((a | b).sum())
    return float((a & b).sum() / union) if union else float("nan")


def _points(columns: np.ndarray, z: np.ndarray) -> np.ndarray:
    """(m0 * m1 * K, 3) world points of the columns' query heights, in ``z``'s order."""
    xy = np.broadcast_to(columns[:, :, None, :], z.shape + (2,))
    return np.concatenate([xy, z[..., None]], axis=-1).reshape(-1, 3)

