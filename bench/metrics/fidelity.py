"""Data fidelity: does the mesh lie on the data?  Truth-free metrics read against the volume φ (docs/METRICS.md).

Computed for every cell — phantoms with a truth and user scans without — so they compare across both:

* ``sdf_rms_h`` / ``sdf_p95_h`` — SDF agreement: at the grid samples near the surface (|φ| < 3h) the mesh's
  own signed distance (exact unsigned point-to-triangle distance; its sign from the mesh's winding
  number on the grid) minus φ, RMS and 95th percentile of the absolute difference, in h.  At most
  :data:`BAND_SAMPLES` band samples are used (seeded, uniformly chosen): the statistics' sampling error is then
  about 1.5 % of their value while the cost stays bounded at any N.
* ``phi_mean_h`` / ``phi_p95_h`` — |φ| (trilinear) at the first :data:`MESH_SAMPLES` of the area-uniform
  i.i.d. samples of the mesh, mean and 95th percentile, in h: how far off the zero level set the surface lies.
* ``sign_err_pct`` — the share (%) of grid samples with |φ| > h/2 that the mesh puts on the other side (its
  winding number on the grid, :func:`geometry.raster.grid_winding`, non-zero = inside): a dropped or an extra
  part shows here whatever its distance.

A φ that is not a distance (an intensity read at ``level=``: its |∇φ| at the zero set is the intensity's slope)
is read as φ / |∇φ| (:func:`as_distance`), a first-order distance in world units; the row's ``phi_gradient``
gives the median |∇φ| found.  They read the volume the method was given: on a noisy volume that is the noisy φ
(all a user has), so even a perfect surface scores about the noise's std in ``sdf_*`` and ``phi_*`` and a few
per cent of ``sign_err_pct`` near the surface; compare methods on the same volume, not across noise levels.
h is the smallest spacing.
"""

from __future__ import annotations

import numpy as np

from geometry.mesh import scored_mesh
from geometry.raster import grid_winding

__all__ = [
    "fidelity_metrics", "mesh_inside", "band_query", "zero_set_gradient", "as_distance", "DISTANCE_LIKE",
    "BAND_SAMPLES", "MESH_SAMPLES", "FIDELITY_NAMES",
]

#: at most this many grid samples of the band |φ| < 3h enter the SDF agreement.  Each costs an exact
#: point-to-mesh distance at up to 3h from the surface (four times an on-surface point's): the cap keeps the block
#: a small part of a cell's scoring
BAND_SAMPLES = 5_000
#: at most this many of the mesh's surface samples are read for |φ| (i.i.d., so the first ones are a uniform subset)
MESH_SAMPLES = 25_000
FIDELITY_NAMES = ("sdf_rms_h", "sdf_p95_h", "phi_mean_h", "phi_p95_h", "sign_err_pct")


#: the range of the median |∇φ| at the zero set within which φ is read as a distance as it is
DISTANCE_LIKE = (0.8, 1.25)


def zero_set_gradient(volume) -> float:
    """The median |∇φ| (central differences, world units) at the grid points next to a sign change of φ: 1 for a
    signed distance, the intensity's slope across the boundary for an intensity image; NaN without a zero set."""
    phi = volume.values
    near = np.zeros(phi.shape, bool)
    neg = phi < 0
    for axis in range(3):
        change = np.diff(neg, axis=axis)
        lo = [slice(None)] * 3
        hi = [slice(None)] * 3
        lo[axis], hi[axis] = slice(0, -1), slice(1, None)
        near[tuple(lo)] |= change
        near[tuple(hi)] |= change
    if not near.any():
        return float("nan")
    idx = np.argwhere(near)
    shape = np.asarray(phi.shape)
    sq = np.zeros(len(idx))
    for axis in range(3):                                     # central differences (one-sided at the border)
        up, down = idx.copy(), idx.copy()
        up[:, axis] = np.minimum(idx[:, axis] + 1, shape[axis] - 1)
        down[:, axis] = np.maximum(idx[:, axis] - 1, 0)
        step = (up[:, axis] - down[:, axis]) * volume.spacing[axis]
        sq += ((phi[tuple(up.T)] - phi[tuple(down.T)]) / step) ** 2
    return float(np.median(np.sqrt(sq)))


def as_distance(volume):
    """``(volume, g)``: φ as it is when its median |∇φ| at the zero set ``g`` is within :data:`DISTANCE_LIKE` (a
    distance), else φ / max(|∇φ|, g/10) (central differences): a first-order distance near the zero set, so
    that the fidelity columns and the validity check read world units on an intensity image too."""
    g = zero_set_gradient(volume)
    if not np.isfinite(g) or DISTANCE_LIKE[0] <= g <= DISTANCE_LIKE[1]:
        return volume, g
    grads = np.gradient(volume.values, *volume.spacing, edge_order=2)
    norm = np.sqrt(sum(c * c for c in grads))
    return volume.with_values(volume.values / np.maximum(norm, 0.1 * g)), g


def band_query(volume, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """(flat grid indices, world points) of the band samples |φ| < 3h the SDF agreement reads (seeded subset)."""
    phi = volume.values.reshape(-1)
    band = np.flatnonzero(np.abs(phi) < 3.0 * volume.h)
    if len(band) > BAND_SAMPLES:
        rng = np.random.default_rng(seed)
        band = np.sort(rng.choice(band, BAND_SAMPLES, replace=False))
    ijk = np.stack(np.unravel_index(band, volume.shape), axis=1)
    return band, volume.index_to_world(ijk)


def mesh_inside(V, F: np.ndarray | None, volume) -> np.ndarray:
    """Which grid points of ``volume`` the mesh encloses (bool, the grid's shape): its winding number on the grid
    (:func:`geometry.raster.grid_winding`) is not zero."""
    m = scored_mesh(V, F)
    return grid_winding(m.vertices, m.faces, volume.origin, volume.spacing, volume.shape) != 0


def fidelity_metrics(V, F: np.ndarray | None, volume, mesh_samples: np.ndarray, band: np.ndarray,
                     band_distance: np.ndarray, inside: np.ndarray | None = None) -> dict:
    """The fidelity block (see the module docstring).

    Parameters
    ----------
    V, F : the mesh (compacted), world coordinates: a :class:`geometry.mesh.ScoredMesh` and None, or the arrays.
    volume : phantoms.Volume — the φ the method was given.
    mesh_samples : (S, 3) area-uniform i.i.d. samples on the mesh (the first :data:`MESH_SAMPLES` are read).
    band, band_distance : the band samples' flat grid indices (:func:`band_query`) and their unsigned distances
        to the mesh.
    inside : (nx, ny, nz) bool array, optional — the grid points the mesh encloses (:func:`mesh_inside`), when
        computed already.
    """
    h = volume.h
    phi = volume.values
    at_mesh = np.abs(volume.sample(mesh_samples[:MESH_SAMPLES], clamp=True).phi) / h
    inside = (mesh_inside(V, F, volume) if inside is None else np.asarray(inside, bool)).reshape(-1)
    flat = phi.reshape(-1)
    far = np.abs(flat) > 0.5 * h
    n_far = int(far.sum())
    wrong = int((far & (inside != (flat < 0))).sum())
    out = {
        "phi_mean_h": float(at_mesh.mean()) if len(at_mesh) else np.nan,
        "phi_p95_h": float(np.percentile(at_mesh, 95)) if len(at_mesh) else np.nan,
        "sign_err_pct": 100.0 * wrong / n_far if n_far else np.nan,
    }
    if len(band):
        signed = np.where(inside[band], -band_distance, band_distance)
        err = np.abs(signed - flat[band]) / h
        out["sdf_rms_h"] = float(np.sqrt(np.mean(err ** 2)))
        out["sdf_p95_h"] = float(np.percentile(err, 95))
    else:
        out["sdf_rms_h"] = out["sdf_p95_h"] = np.nan
    return out
