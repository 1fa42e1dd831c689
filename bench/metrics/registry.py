"""One place for what each metric column means and how to read it (definitions: ``METRICS.md``).

``best`` tells a table which value of a column is the best: ``"min"``, ``"max"``, ``("target", value)``
(closest to value wins; for ``euler`` the report uses 2 − 2·genus of the phantom instead of the stored 2) or
``None`` (not ranked).  ``dtype`` is how a value is shown: ``"float"``, ``"int"`` or ``"bool"`` (a mean over
seeds of a bool column is a share of yes).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

__all__ = ["Metric", "METRICS"]


@dataclass(frozen=True)
class Metric:
    name: str
    best: Any          # "min", "max", ("target", value) or None
    dtype: str         # "float", "int" or "bool"
    meaning: str       # one line
    unit: str          # "" for a pure number


_DISTANCES = {
    "hausdorff": "symmetric Hausdorff distance between the mesh and the true surface",
    "hausdorff_95": "symmetric Hausdorff distance with the 95th percentile in place of each max",
    "mean_dist": "mean of both directed distance sets (Chamfer-L1 style)",
    "rms_dist": "RMS of both directed distance sets",
}

_ROWS = [
    *(Metric(k, "min", "float", m, "world units") for k, m in _DISTANCES.items()),
    *(Metric(f"{k}_h", "min", "float", f"{k} divided by the grid spacing h", "h") for k in _DISTANCES),
    Metric("normal_consistency", "max", "float", "mean |n_mesh · n_true| at the closest true point", ""),
    Metric("fscore@h", "max", "float", "F-score of the two sample sets at threshold h", ""),
    Metric("H_rms_err", "min", "float", "RMS error of the vertex mean curvature away from creases", "1/world units"),
    Metric("H_max_err", "min", "float", "max error of the vertex mean curvature away from creases", "1/world units"),
    Metric("K_rms_err", "min", "float", "RMS error of the vertex Gaussian curvature away from creases",
           "1/world units²"),
    Metric("H_std", "min", "float", "std of the vertex mean curvature over regions of constant true curvature",
           "1/world units"),
    Metric("roughness_deg", "min", "float", "mean angle between normals of faces sharing an edge, away from creases",
           "°"),
    Metric("min_angle_deg", "max", "float", "smallest triangle angle", "°"),
    Metric("pct_angle_lt_10", "min", "float", "share of triangles with an angle below 10°", "%"),
    Metric("watertight", "max", "bool", "every edge in exactly two faces", ""),
    Metric("euler", ("target", 2), "int", "Euler characteristic V − E + F", ""),
    Metric("components", ("target", 1), "int", "connected components", ""),
    Metric("self_intersections", "min", "int", "intersecting non-adjacent face pairs", ""),
    Metric("n_vertices", None, "int", "vertices of the mesh as given", ""),
    Metric("n_faces", None, "int", "faces of the mesh as given", ""),
    Metric("iterations", None, "int", "iterations of an iterative method", ""),
    Metric("energy_final", None, "float", "energy at the last iteration of an iterative method", ""),
    Metric("wall_s", "min", "float", "wall-clock time of the method's reconstruction call", "s"),
    Metric("peak_mem_mb", "min", "float", "peak resident memory of the method's reconstruction call", "MiB"),
]

#: metric name -> its facts, in the order of :data:`bench.metrics.METRIC_NAMES`
METRICS: dict[str, Metric] = {m.name: m for m in _ROWS}
