"""How much two values of a metric may differ and still be "the same": the tolerances of the metric columns.

One home for the resolution of each gated metric (:data:`TOLERANCES`) and for how a value compares with a
baseline's under it (:func:`compare_value`, over the gated values of a results row, :func:`cells_from_rows`), read
by the quality gate (:mod:`bench.perf.quality`: how much worse a value may get before a cell fails) and by the
report (ties in the rankings, pairwise wins, ``compare``'s verdicts: two values within the tolerance are the
same).  Distances and errors are *relative* (``rel``: 5 % on the distances in units of h, plus an absolute floor
``abs`` so a value near zero cannot differ on round-off), scores *absolute* (normal consistency, F-score), counts
exactly, the Euler characteristic and component count by their distance to the truth's, ``watertight`` as a flag.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass

__all__ = ["Tolerance", "TOLERANCES", "same_within_tolerance", "compare_value", "cells_from_rows", "stable_cell_id",
           "finite"]


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


def finite(v) -> float | None:
    """``v`` as a float, or None where it is not a finite number (missing, text, NaN, ±inf)."""
    try:
        x = float(v)
    except (TypeError, ValueError):
        return None
    return x if math.isfinite(x) else None


def _truthy(v) -> bool | None:
    if isinstance(v, bool):
        return v
    if v is None or (isinstance(v, float) and math.isnan(v)):
        return None
    return str(v).strip().lower() in ("true", "1", "1.0", "yes")


def _flags(v) -> list[str]:
    if v is None or (isinstance(v, float) and math.isnan(v)):
        return []
    return sorted(f for f in str(v).split(";") if f.strip())


def stable_cell_id(cell_id: str) -> str:
    """The cell id without its parameter hash: a new method parameter (which changes every hash) must not turn
    the whole baseline into "missing" cells; the label, phantom, N, noise and seed still name the cell."""
    return re.sub(r"_[0-9a-f]{8}$", "", cell_id)


def cells_from_rows(rows: list[dict], prefix: str) -> dict[str, dict]:
    """The quality record of each results.csv row: ``{prefix/cell: {status, flags, metrics}}`` (cell: the cell id
    without its parameter hash)."""
    out = {}
    for r in rows:
        metrics = {}
        for name, tol in TOLERANCES.items():
            if name not in r:
                continue
            metrics[name] = _truthy(r[name]) if tol.better == "true" else finite(r[name])
        key = f"{prefix}/{stable_cell_id(str(r['cell_id']))}"
        out[key] = {"status": str(r.get("status") or "?"), "flags": _flags(r.get("flags")), "metrics": metrics,
                    "method": str(r.get("method") or "")}
    return out


def _target(metric: str, flags, base_value, truth: float | None) -> float:
    # the truth's value: 2 − 2g for euler is not in the results; the baseline's own value when the baseline
    # had no topology flag, else ``truth`` or the sphere's (2 / 1) — the gated cells are genus 0
    if "topology_mismatch" not in (flags or []) and base_value is not None:
        return float(base_value)
    if truth is not None:
        return float(truth)
    return 2.0 if metric == "euler" else 1.0


def compare_value(metric: str, tol: Tolerance, base, cur, base_flags=(), truth: float | None = None
                  ) -> tuple[str, bool, float | None]:
    """``(status, failed, limit)`` of one value ``cur`` against ``base`` under ``tol``: status ``"ok"`` (within
    the tolerance), ``"better"``, ``"worse"`` (then failed), ``"no baseline"`` or ``"missing value"``.

    ``base_flags`` are the baseline cell's flags and ``truth`` the truth's value of a ``"target"`` metric (Euler
    characteristic, components): it is the target only when the baseline was flagged ``topology_mismatch``
    (else the baseline's own value is; without ``truth`` the sphere's)."""
    if base is None:
        return "no baseline", False, None
    if cur is None:
        return "missing value", True, None
    if tol.better == "true":
        return ("ok", False, None) if (cur or not base) else ("worse", True, None)
    if tol.better == "count":
        return ("worse", True, base) if cur > base else (("better" if cur < base else "ok"), False, base)
    if tol.better == "target":
        t = _target(metric, base_flags, base, truth)
        d0, d1 = abs(base - t), abs(cur - t)
        return ("worse", True, base) if d1 > d0 else (("better" if d1 < d0 else "ok"), False, base)
    slack = tol.rel * abs(base) + tol.abs
    if tol.better == "min":
        limit = base + slack
        return ("worse", True, limit) if cur > limit else (("better" if cur < base - slack else "ok"), False, limit)
    limit = base - slack
    return ("worse", True, limit) if cur < limit else (("better" if cur > base + slack else "ok"), False, limit)
