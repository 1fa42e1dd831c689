"""The SDF energy of Reach for the Arcs (Sellán et al. 2024) and Carrera et al. (2026) (docs/METRICS.md).

``sdf_energy`` = 1000 · mean over the grid points of (|S| − d)², S the signed distance the grid holds (the clean
input, before noise or a degradation) and d the unsigned distance from the grid point to the reconstructed mesh
— Reach for the Arcs' ``our_energy`` in ``scripts/fig_many-shapes-experiment.py``
(``g = np.abs(S) - d; 1000 * np.sum(g**2) / U.shape[0]``, d from ``gpytoolbox.squared_distance``), the column
``sdf_energy`` Carrera et al.'s ``scripts/many-shapes-experiment.py`` reports beside it.  It asks whether the
mesh's unsigned distance field is the one the data describe, everywhere on the grid, not only near the surface
(``sdf_rms_h`` is the band-limited, signed, truth-free cousin).

The papers take every grid point.  Most grid points are far from the surface, where an exact point-to-mesh
query costs far more than near it, so the suite takes every point of a grid of at most :data:`ENERGY_POINTS`
points (N ≤ 20) and a seeded uniform subset of that many points otherwise: an unbiased estimate of the full-grid
mean whose standard error, √(var((|S| − d)²) / m), is about 2 % of the value (marching cubes on the bunny at
N = 64: 1.8 / √m, the energy coming 98 % from points farther than 3h from the surface, so a band-weighted
subset would not help; tests/test_bench_metrics_sdf_energy.py checks it against the full grid).  d is the exact
distance of :func:`geometry.bvh.point_mesh_distance_far`, the search suited to points far from the surface.
"""

from __future__ import annotations

import numpy as np

from geometry.bvh import point_mesh_distance_far

__all__ = ["ENERGY_POINTS", "energy_query", "energy_distances", "sdf_energy"]

#: at most this many grid points enter the SDF energy (all of them up to N = 20)
ENERGY_POINTS = 8_192
#: the papers' scale factor of the mean
SCALE = 1000.0


def energy_query(volume, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """(flat grid indices, world points) of the grid points the SDF energy reads: all of them when the grid
    holds at most :data:`ENERGY_POINTS`, else a seeded uniform subset of that many (without replacement)."""
    total = int(np.prod(volume.shape))
    if total <= ENERGY_POINTS:
        idx = np.arange(total)
    else:
        idx = np.sort(np.random.default_rng(seed).choice(total, ENERGY_POINTS, replace=False))
    ijk = np.stack(np.unravel_index(idx, volume.shape), axis=1)
    return idx, volume.index_to_world(ijk)


def energy_distances(points: np.ndarray, vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Exact unsigned distance from the (far and near) grid points to the mesh."""
    return point_mesh_distance_far(points, vertices, faces)


def sdf_energy(S: np.ndarray, d: np.ndarray) -> float:
    """1000 · mean (|S| − d)² (world units²; NaN without points)."""
    S = np.asarray(S, float)
    d = np.asarray(d, float)
    if not len(S):
        return float("nan")
    g = np.abs(S) - d
    return float(SCALE * np.mean(g * g))
