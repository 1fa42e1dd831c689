"""How much two values of a metric may differ and still be "the same": the tolerances of the metric columns.

One home for the resolution of each gated metric (:data:`TOLERANCES`), read by the quality gate
(:mod:`bench.perf.quality`: how much worse a value may get before a cell fails) and by the report (ties in the
rankings, pairwise wins, ``compare``'s verdicts: two values within the tolerance are the same).  Distances and
errors are *relative* (``rel``: 5 % on the distances in units of h, plus an absolute floor ``abs`` so a value
near zero cannot differ on round-off), scores *absolute* (normal consistency, F-score), counts exactly, the Euler
characteristic and component count by their distance to the truth's, ``watertight`` as a flag.
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["Tolerance", "TOLERANCES", "same_within_tolerance"]


@dataclass(frozen=True)
class Tolerance:
    """How much worse a metric may get: ``better`` is ``"min"``, ``"max"``, ``"count"`` (an integer to keep
    as low: any increase fails), ``"target"`` (distance to the truth's value may not grow) or ``"true"`` (may
    not turn false); the allowed worsening is ``rel · |baseline| + abs``.

    Parameters
    ----------
    better : {"min", "max", "count", "target", "true"}
        Which direction is better and how values are compared.
    rel : float
        The allowed difference relative to the baseline's magnitude.
    abs : float
        The allowed absolute difference on top of ``rel``.
    """

    better: str
    rel: float = 0.0
    abs: float = 0.0


#: the gated metrics (results.csv columns) and their tolerances
TOLERANCES: dict[str, Tolerance] = {
    "hausdorff_h": Tolerance("min", 0.05, 0.01),
    "hausdorff_95_h": Tolerance("min", 0.05, 0.005),
    "mean_dist_h": Tolerance("min", 0.05, 0.002),
    "rms_dist_h": Tolerance("min", 0.05, 0.002),
    "normal_consistency": Tolerance("max", 0.0, 0.002),
    "fscore@h": Tolerance("max", 0.0, 0.01),
    "coverage_pct": Tolerance("max", 0.0, 0.1),
    "H_rms_err": Tolerance("min", 0.10, 0.01),
    "K_rms_err": Tolerance("min", 0.10, 0.01),
    "roughness_deg": Tolerance("min", 0.10, 0.1),
    "min_angle_deg": Tolerance("max", 0.10, 0.1),
    "pct_angle_lt_10": Tolerance("min", 0.10, 0.5),
    "sdf_rms_h": Tolerance("min", 0.05, 0.005),
    "sdf_p95_h": Tolerance("min", 0.05, 0.005),
    "phi_mean_h": Tolerance("min", 0.05, 0.002),
    "phi_p95_h": Tolerance("min", 0.05, 0.005),
    "sign_err_pct": Tolerance("min", 0.05, 0.01),
    "self_intersections": Tolerance("count"),
    "euler": Tolerance("target"),
    "components": Tolerance("target"),
    "watertight": Tolerance("true"),
}


def same_within_tolerance(metric: str, a: float, b: float) -> bool:
    """Whether two values of ``metric`` are the same at its resolution: ``|a − b| ≤ rel · max(|a|, |b|) + abs``
    of its tolerance (integers and flags exactly; a metric without a tolerance: 1e-9 relative).

    Parameters
    ----------
    metric : str
        The results.csv column.
    a, b : float
        The two values.
    """
    tol = TOLERANCES.get(metric, Tolerance("min", 1e-9, 0.0))
    if tol.better in ("count", "target", "true"):
        return a == b
    return abs(a - b) <= tol.rel * max(abs(a), abs(b)) + tol.abs
