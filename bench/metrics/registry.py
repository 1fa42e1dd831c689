"""One place for what each metric column means and how to read it (definitions: ``docs/METRICS.md``).

The registry is the schema: :func:`bench.metrics.evaluate` returns these keys, results.csv has a column
each in this order, and the report reads how to rank and show them from here.

``best`` tells a table which value of a column is the best: ``"min"``, ``"max"``, ``("target", value)``
(closest to value wins; for ``euler`` the report uses 2 − 2·genus of the phantom instead of the stored 2) or
``None`` (not ranked).  ``dtype`` is how a value is shown: ``"float"``, ``"int"`` or ``"bool"`` (a mean over
seeds of a bool column is a share of yes).  ``kind`` says who computes it: ``"distance"`` (a distance to the
true surface in world units, also reported divided by h as ``"distance_h"``), ``"truth"`` (needs the true
surface), ``"truth_free"`` (computed for any mesh, also for user volumes), ``"fidelity"`` (truth-free, read
against the volume the method was given) or ``"runner"`` (filled by the cell
runner from the method's info and the cost measurement, not by ``evaluate``).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

__all__ = ["Metric", "METRICS"]


@dataclass(frozen=True)
class Metric:
    """One metric column: its name, how to rank and show it, and who computes it (see the module docstring).

    Parameters
    ----------
    name : str
        The column name (a key of :func:`bench.metrics.evaluate`'s row).
    best : {"min", "max"} or ("target", value) or None
        Which value is the best in a table; None: not ranked.
    dtype : {"float", "int", "bool"}
        How a value is shown.
    meaning : str
        One line.
    unit : str
        "" for a pure number.
    kind : {"distance", "distance_h", "truth", "truth_free", "fidelity", "runner"}
        Who computes it and what it needs.
    """

    name: str
    best: Any          # "min", "max", ("target", value) or None
    dtype: str         # "float", "int" or "bool"
    meaning: str       # one line
    unit: str          # "" for a pure number
    kind: str = "truth"  # "distance", "distance_h", "truth", "truth_free", "fidelity" or "runner"


_DISTANCES = {
    "hausdorff": "symmetric Hausdorff distance between the mesh and the true surface",
    "hausdorff_95": "symmetric Hausdorff distance with the 95th percentile in place of each max",
    "hausdorff_90": "symmetric Hausdorff distance with the 90th percentile in place of each max (HD90)",
    "mean_dist": "mean of both directed distance sets (Chamfer-L1 style)",
    "rms_dist": "RMS of both directed distance sets",
    "chamfer_l2": "RMS of each directed distance set, summed (Reach for the Arcs / Carrera et al. Chamfer)",
    "edge_chamfer": "mean of both directed distances between reconstructed and true sharp-edge samples",
}

_ROWS = [
    *(Metric(k, "min", "float", m, "world units", "distance") for k, m in _DISTANCES.items()),
    *(Metric(f"{k}_h", "min", "float", f"{k} divided by the grid spacing h", "h", "distance_h") for k in _DISTANCES),
    Metric("sdf_energy", "min", "float",
           "1000 · mean over grid points of (|S| − d)², d the distance to the mesh (the papers' SDF energy)",
           "10⁻³ world units²"),
    Metric("normal_consistency", "max", "float", "mean |n_mesh · n_true| at the closest true point", ""),
    Metric("fscore@h", "max", "float", "F-score of the two sample sets at threshold h", ""),
    Metric("coverage_pct", "max", "float", "share of the true surface's samples within 2h of the mesh", "%"),
    Metric("edge_fscore", "max", "float", "F-score of the sharp-edge samples at threshold h", ""),
    Metric("iou", "max", "float", "volumetric intersection over union of the inside regions", ""),
    Metric("volume_err_pct", ("target", 0), "float",
           "enclosed volume of the mesh minus the true volume, relative to it (signed: smoothing shrinks)", "%"),
    Metric("H_rms_err", "min", "float", "RMS error of the vertex mean curvature away from creases", "1/world units"),
    Metric("H_max_err", "min", "float", "max error of the vertex mean curvature away from creases", "1/world units"),
    Metric("K_rms_err", "min", "float", "RMS error of the vertex Gaussian curvature away from creases",
           "1/world units²"),
    Metric("H_std", "min", "float", "std of the vertex mean curvature over regions of constant true curvature",
           "1/world units", "truth_free"),
    Metric("roughness_deg", "min", "float", "mean angle between normals of faces sharing an edge, away from creases",
           "°", "truth_free"),
    Metric("min_angle_deg", "max", "float", "smallest triangle angle", "°", "truth_free"),
    Metric("pct_angle_lt_10", "min", "float", "share of triangles with an angle below 10°", "%", "truth_free"),
    Metric("watertight", "max", "bool", "every edge in exactly two faces", "", "truth_free"),
    Metric("boundary_edges", "min", "int", "edges in exactly one face", "", "truth_free"),
    Metric("nonmanifold_edges", "min", "int", "edges in three or more faces", "", "truth_free"),
    Metric("euler", ("target", 2), "int", "Euler characteristic V − E + F", "", "truth_free"),
    Metric("components", ("target", 1), "int", "connected components", "", "truth_free"),
    Metric("self_intersections", "min", "int", "intersecting non-adjacent face pairs", "", "truth_free"),
    Metric("sif_pct", "min", "float", "share of faces intersecting a non-adjacent face (SIF)", "%", "truth_free"),
    Metric("sdf_rms_h", "min", "float", "RMS of (the mesh's signed distance − φ) at grid samples with |φ| < 3h",
           "h", "fidelity"),
    Metric("sdf_p95_h", "min", "float", "95th percentile of |mesh signed distance − φ| at grid samples with |φ| < 3h",
           "h", "fidelity"),
    Metric("phi_mean_h", "min", "float", "mean |φ| (trilinear) at area-uniform samples of the mesh", "h", "fidelity"),
    Metric("phi_p95_h", "min", "float", "95th percentile of |φ| at area-uniform samples of the mesh", "h", "fidelity"),
    Metric("sign_err_pct", "min", "float", "share of grid samples with |φ| > h/2 the mesh puts on the wrong side",
           "%", "fidelity"),
    Metric("data_parts", None, "int",
           "parts of the input's inside set of ≥ 8 voxels (6-connected; the mesh is compared with the 6/26 range)",
           "", "fidelity"),
    Metric("data_cavities", None, "int",
           "enclosed background components of the input of ≥ 8 voxels (26-connected background)", "", "fidelity"),
    Metric("data_handles", None, "int", "handles of the input's inside set, b0 + b2 − χ (6/26 connectivity)", "",
           "fidelity"),
    Metric("mesh_voids", None, "int", "shells of the mesh wound inward (negative enclosed volume): its cavities", "",
           "fidelity"),
    Metric("mesh_genus", None, "int", "summed genus of the mesh's closed shells: its handles", "", "fidelity"),
    Metric("topology_diffs", "min", "int",
           "kinds of topology difference between the mesh and its input (the topology_vs_data flag's detail)", "",
           "fidelity"),
    Metric("n_vertices", None, "int", "vertices of the mesh as given", "", "truth_free"),
    Metric("n_faces", None, "int", "faces of the mesh as given", "", "truth_free"),
    Metric("iterations", None, "int", "iterations of an iterative method", "", "runner"),
    Metric("energy_final", None, "float", "energy at the last iteration of an iterative method", "", "runner"),
    Metric("wall_s", "min", "float", "wall-clock time of the method's reconstruction call", "s", "runner"),
    Metric("peak_mem_mb", "min", "float", "peak resident memory of the method's reconstruction call", "MiB", "runner"),
]

#: metric name -> its facts, in the order of :data:`bench.metrics.METRIC_NAMES`
METRICS: dict[str, Metric] = {m.name: m for m in _ROWS}
