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

They read the volume the method was given: on a noisy volume that is the noisy φ (all a user has), so even a
perfect surface scores about the noise's std in ``sdf_*`` and ``phi_*`` and a few per cent of ``sign_err_pct``
near the surface; compare methods on the same volume, not across noise levels.  h is the smallest spacing.
"""

from __future__ import annotations

import numpy as np

from geometry.mesh import scored_mesh
from geometry.raster import grid_winding

__all__ = ["fidelity_metrics", "band_query", "BAND_SAMPLES", "MESH_SAMPLES", "FIDELITY_NAMES"]

#: at most this many grid samples of the band |φ| < 3h enter the SDF agreement.  Each costs an exact
#: point-to-mesh distance at up to 3h from the surface (~3 µs, four times an on-surface point's); with 10,000
#: the block added 15-24 % to a cell's scoring at N = 96 (docs/NOTES.md), with 5,000 about 8 %
BAND_SAMPLES = 5_000
#: at most this many of the mesh's surface samples are read for |φ| (i.i.d., so the first ones are a uniform subset)
MESH_SAMPLES = 25_000
FIDELITY_NAMES = ("sdf_rms_h", "sdf_p95_h", "phi_mean_h", "phi_p95_h", "sign_err_pct")


def band_query(volume, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """(flat grid indices, world points) of the band samples |φ| < 3h the SDF agreement reads (seeded subset)."""
    phi = volume.values.reshape(-1)
    band = np.flatnonzero(np.abs(phi) < 3.0 * volume.h)
    if len(band) > BAND_SAMPLES:
        rng = np.random.default_rng(seed)
        band = np.sort(rng.choice(band, BAND_SAMPLES, replace=False))
    ijk = np.stack(np.unravel_index(band, volume.shape), axis=1)
    return band, volume.index_to_world(ijk)


def fidelity_metrics(V, F: np.ndarray | None, volume, mesh_samples: np.ndarray, band: np.ndarray,
                     band_distance: np.ndarray) -> dict:
    """The fidelity block (see the module docstring).

    Parameters
    ----------
    V, F : the mesh (compacted), world coordinates: a :class:`geometry.mesh.ScoredMesh` and None, or the arrays.
    volume : phantoms.Volume — the φ the method was given.
    mesh_samples : (S, 3) area-uniform i.i.d. samples on the mesh (the first :data:`MESH_SAMPLES` are read).
    band, band_distance : the band samples' flat grid indices (:func:`band_query`) and their unsigned distances
        to the mesh.
    """
    h = volume.h
    phi = volume.values
    at_mesh = np.abs(volume.sample(mesh_samples[:MESH_SAMPLES], clamp=True).phi) / h
    m = scored_mesh(V, F)
    inside = grid_winding(m.vertices, m.faces, volume.origin, volume.spacing, volume.shape).reshape(-1) != 0
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
