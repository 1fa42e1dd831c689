"""Distances between a reconstructed mesh and the true surface (METRICS.md).

Two directed distance sets:

* **recon → truth**: the exact distance from reconstructed points to the true surface, by the phantom's
  analytic ``truth`` (closed form, or a 1-D root find for the ellipsoid).  The points are every mesh
  vertex plus ``n_samples`` seeded area-uniform samples on the mesh (:func:`sample_mesh_surface`).
* **truth → recon**: the exact point-to-triangle distance from ``n_samples`` seeded area-uniform samples
  of the true surface (``phantom.sample_surface``) to the mesh (:func:`point_mesh_distance`).

Library choice for the exact point-to-triangle distance (measured on this 2-core machine: 100,000 true
ellipsoid samples against a 101,564-face marching-cubes mesh of the ellipsoid):

==========================================================  ===============  ==========================
library / call                                               time             agreement
==========================================================  ===============  ==========================
pymeshlab ``compute_scalar_by_distance_from_another_mesh``    0.39 s (+0.07 s   reference
(VCG uniform grid, double precision)                         mesh transfer)
trimesh ``proximity.closest_point`` (rtree + numpy)          8.2 s (0.82 s     max |Δ| = 1.4e-11
                                                             per 10k points)
==========================================================  ===============  ==========================

pymeshlab is ~20× faster, so it is used.  MeshLab computes the distance in double precision and returns
it as a float32 per-vertex quality: relative rounding ≤ 1e-7 of the distance itself (1e-11 absolute on
that mesh, whose distances are ~1e-4), far below anything the metrics resolve.  (libigl / open3d are not
dependencies of the suite.)  The VCG filter takes a search radius ``maxdist``; we pass an upper bound of
every point's distance (its distance to one mesh vertex), so no point is ever clamped.

Statistics (see :func:`distance_metrics`): maxima use every point of a set (mesh vertices included, so a
single pulled-out vertex shows); percentiles, means, RMS and the F-score use the area-uniform samples only,
so they are area-weighted and do not depend on how the method distributes its vertices.
"""

from __future__ import annotations

import numpy as np
import pymeshlab

from geometry.topology import sample_surface

__all__ = ["sample_mesh_surface", "point_mesh_distance", "distance_metrics", "DISTANCE_LIBRARY", "COVERAGE_RADIUS"]

#: ``coverage_pct``: the share of the true surface's samples within this many h of the mesh
COVERAGE_RADIUS = 2.0

DISTANCE_LIBRARY = "pymeshlab (VCG) compute_scalar_by_distance_from_another_mesh_per_vertex"


def sample_mesh_surface(vertices: np.ndarray, faces: np.ndarray, n: int, seed: int = 0
                        ) -> tuple[np.ndarray, np.ndarray]:
    """``n`` seeded, area-uniform i.i.d. samples on a triangle mesh: (points (n, 3), face index (n,)).

    Faces are chosen with probability ∝ area (inverse CDF on the cumulative areas), points uniformly in
    the face by the square-root barycentric map.  Same seed → same samples.
    """
    return sample_surface(vertices, faces, n, seed)


def point_mesh_distance(points: np.ndarray, vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Exact unsigned distance from each point to the closest point of the triangle mesh (pymeshlab)."""
    p = np.ascontiguousarray(points, dtype=np.float64)
    v = np.ascontiguousarray(vertices, dtype=np.float64)
    f = np.ascontiguousarray(faces, dtype=np.int32)
    if len(p) == 0:
        return np.zeros(0)
    ms = pymeshlab.MeshSet()
    ms.add_mesh(pymeshlab.Mesh(vertex_matrix=v, face_matrix=f), "mesh")
    ms.add_mesh(pymeshlab.Mesh(vertex_matrix=p), "points")
    # every point is within its distance to vertex f[0, 0] of the mesh: a safe search radius
    bound = float(np.sqrt(((p - v[f[0, 0]]) ** 2).sum(1).max()))
    bound = 1.01 * bound + 1e-9 * (1.0 + np.abs(v).max())
    ms.compute_scalar_by_distance_from_another_mesh_per_vertex(
        measuremesh=1, refmesh=0, signeddist=False, maxdist=pymeshlab.PureValue(bound))
    m = ms.mesh(1)
    if m.vertex_number() != len(p):  # pragma: no cover - pymeshlab keeps point clouds as given
        raise RuntimeError("pymeshlab changed the number of query points")
    return np.asarray(m.vertex_scalar_array(), dtype=np.float64)


def distance_metrics(d_rt_samples: np.ndarray, d_rt_max: float, d_tr: np.ndarray, h: float,
                     sample_normals: np.ndarray, true_normals: np.ndarray) -> dict:
    """The METRICS.md distance block from the two directed distance sets.

    d_rt_samples : recon → truth distance of the area-uniform mesh samples
    d_rt_max     : max recon → truth distance over vertices and samples
    d_tr         : truth → recon distance of the area-uniform true-surface samples
    h            : grid spacing (F-score threshold and the unit of the ``*_h`` values)
    sample_normals, true_normals : unit normals of the mesh at its samples and of the truth at their
                   closest true points (``normal_consistency`` = mean |n_mesh · n_true|)
    """
    a = np.asarray(d_rt_samples, float)
    b = np.asarray(d_tr, float)
    out = {
        "hausdorff": float(max(d_rt_max, b.max())),
        "hausdorff_95": float(max(np.percentile(a, 95), np.percentile(b, 95))),
        "hausdorff_90": float(max(np.percentile(a, 90), np.percentile(b, 90))),
        "mean_dist": float(0.5 * (a.mean() + b.mean())),
        "rms_dist": float(np.sqrt(0.5 * (np.mean(a * a) + np.mean(b * b)))),
    }
    for k in ("hausdorff", "hausdorff_95", "hausdorff_90", "mean_dist", "rms_dist"):
        out[f"{k}_h"] = out[k] / h
    out["normal_consistency"] = float(np.mean(np.abs(np.einsum("ij,ij->i", sample_normals, true_normals))))
    precision = float(np.mean(a <= h))
    recall = float(np.mean(b <= h))
    out["fscore@h"] = 0.0 if precision + recall == 0 else 2 * precision * recall / (precision + recall)
    # how much of the true surface the mesh covers: a dropped limb shows here whatever the method reports
    out["coverage_pct"] = 100.0 * float(np.mean(b <= COVERAGE_RADIUS * h))
    return out
