"""The quality gate: the metric values of a small fixed set of grid cells against a committed baseline.

The time gate (:mod:`.gate`) catches a change that makes the suite slower; this one catches a change that makes a
result *worse*.  :func:`run_quality` runs the grids of :data:`QUALITY_CONFIGS` — the quick grid (two phantoms ×
clean / paper noise × three methods at N = 48) and ``quality_real`` (the bunny at N = 48, clean, the shape
gradient and marching cubes) — and keeps per cell its status, its flags and the metrics of :data:`TOLERANCES`
(:mod:`bench.metrics.tolerances`, re-exported here).
:func:`quality_gate` (pure) compares two such summaries; a cell **fails** when

* its status was ``ok`` and is not (``invalid``, ``failed``, ``timeout``), or it gained a flag
  (``self_intersecting``, ``topology_mismatch``, …), or it is missing from the run;
* a metric got worse than the baseline beyond its tolerance (:data:`TOLERANCES`): distances and errors
  *relative* (``rel``: 5 % on the distances in units of h, plus an absolute floor ``abs`` so a value near zero
  cannot fail on round-off), scores *absolute* (normal consistency, F-score), counts exactly (one more
  self-intersection fails), the Euler characteristic and component count by moving away from the truth's, and
  ``watertight`` by turning false.

Better than the baseline never fails (the row says ``better``: refresh the baseline to keep the gate sharp).
The grids are seeded: on one machine a rerun gives the same values bit for bit, so the tolerances only absorb
differences of floating-point libraries between machines.

The rows of :data:`EXACT_METHODS` (marching cubes: no iteration, no randomness) are the suite's fixed points:
their metrics depend only on the volume and the scoring code, so a refactor of either must leave them exactly
as they were.  On the machine and libraries that recorded the baseline (:func:`machine_fingerprint`) any
change of such a value — better or worse — fails (``changed``); elsewhere they may differ by floating-point
reassociation only (:data:`EXACT_REL_ELSEWHERE`).
"""

from __future__ import annotations

import datetime as _dt
import json
import platform
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

from phantoms import InputError

from ..metrics.tolerances import (TOLERANCES, Tolerance, cells_from_rows, compare_value, same_within_tolerance,
                                  stable_cell_id)
from .baseline import read_json_file

__all__ = ["QUALITY_FORMAT", "QUALITY_BASELINE", "QUALITY_CONFIGS", "TOLERANCES", "Tolerance", "run_quality",
           "same_within_tolerance",
           "cells_from_rows", "load_quality", "save_quality", "quality_gate", "QualityResult",
           "format_quality", "compare_value", "stable_cell_id", "EXACT_METHODS", "EXACT_REL_ELSEWHERE",
           "machine_fingerprint"]

QUALITY_FORMAT = "levelset-bench-quality/1"
#: the committed quality baseline the CI gate compares with (package data)
QUALITY_BASELINE = Path(__file__).resolve().parent / "quality.json"
#: built-in grid configurations (bench/configs/<name>.toml) the quality gate runs
QUALITY_CONFIGS = ("quick", "quality_real")
#: methods whose rows must not change at all (see the module docstring)
EXACT_METHODS = ("marching_cubes",)
#: the relative difference an exact row's value may have on another machine or other library versions
EXACT_REL_ELSEWHERE = 1e-9


def machine_fingerprint() -> dict:
    """What makes floating-point results bit-identical between two runs: the CPU model, the platform and the
    versions of the numerical libraries (numpy, scipy, scikit-image, numba, trimesh, pymeshlab)."""
    import importlib.metadata as md

    cpu = platform.processor()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    libs = {}
    for name in ("numpy", "scipy", "scikit-image", "numba", "trimesh", "pymeshlab"):
        try:
            libs[name] = md.version(name)
        except md.PackageNotFoundError:
            libs[name] = None
    return {"cpu": cpu, "machine": platform.machine(), "system": platform.system(),
            "python": platform.python_version(), "libraries": libs}


def _commit() -> dict:
    from ..run.provenance import git_commit

    try:
        return git_commit() or {}
    except Exception:  # noqa: BLE001 — provenance is information only
        return {}


def run_quality(configs=None, *, jobs: int | None = 2, progress: bool = False) -> dict:
    """Run each grid of ``configs`` (built-in names or paths of .toml files) in a temporary folder and return
    the quality summary (``"format": "levelset-bench-quality/1"``)."""
    from ..config import CONFIG_DIR, load_config
    from ..run import run_grid
    from ..run.results import read_results

    cells: dict[str, dict] = {}
    names = []
    for c in (QUALITY_CONFIGS if configs is None else configs):
        cfg = load_config(c if str(c).endswith(".toml") else CONFIG_DIR / f"{c}.toml")
        names.append(cfg.name)
        with tempfile.TemporaryDirectory(prefix="lsb-quality-") as tmp:
            run_grid(cfg, Path(tmp) / "run", jobs=jobs, progress=progress, argv=["perf", "--quality"])
            df = read_results(Path(tmp) / "run")
        rows = df.astype(object).where(df.notna(), None).to_dict("records")
        cells.update(cells_from_rows(rows, cfg.name))
    return {"format": QUALITY_FORMAT, "created": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"),
            "commit": _commit(), "machine": machine_fingerprint(), "configs": names, "cells": cells}


def load_quality(path: str | Path) -> dict:
    p = Path(path)
    raw = read_json_file(p)
    if not isinstance(raw, dict) or raw.get("format") != QUALITY_FORMAT or not isinstance(raw.get("cells"), dict):
        raise InputError(f"{str(p)!r}: not a quality summary (format {QUALITY_FORMAT})")
    return raw


def save_quality(summary: dict, path: str | Path) -> Path:
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    tmp = p.with_name(p.name + ".tmp")
    tmp.write_text(json.dumps(summary, indent=1) + "\n", encoding="utf-8")
    tmp.replace(p)
    return p


@dataclass
class QualityResult:
    """Rows ``{cell, metric, baseline, value, limit, status, failed}`` (one per compared value, plus one per cell
    for its status / flags / absence) and the verdict."""

    rows: list[dict] = field(default_factory=list)

    @property
    def failures(self) -> list[dict]:
        return [r for r in self.rows if r["failed"]]

    @property
    def passed(self) -> bool:
        return not self.failures


def _exact_value(base, cur, rel: float) -> tuple[str, bool]:
    """An exact row's value: ``ok`` when equal (within ``rel`` relative; None / NaN equal only to themselves)."""
    if base is None or cur is None or isinstance(base, bool) or isinstance(cur, bool):
        return ("ok", False) if base == cur else ("changed", True)
    return ("ok", False) if abs(cur - base) <= rel * max(abs(base), abs(cur)) else ("changed", True)


def _is_exact(key: str, cell: dict) -> bool:
    method = cell.get("method") or ""
    return method in EXACT_METHODS if method else any(key.endswith("_" + m) for m in EXACT_METHODS)


def quality_gate(baseline: dict, current: dict, tolerances: dict[str, Tolerance] | None = None) -> QualityResult:
    """Compare the cells of ``current`` with those of ``baseline`` (quality summaries).  Pure: no I/O.

    The cells of :data:`EXACT_METHODS` are compared value by value without tolerance when both summaries carry
    the same :func:`machine_fingerprint`, else within :data:`EXACT_REL_ELSEWHERE`."""
    tolerances = TOLERANCES if tolerances is None else tolerances
    same_machine = baseline.get("machine") is not None and baseline.get("machine") == current.get("machine")
    exact_rel = 0.0 if same_machine else EXACT_REL_ELSEWHERE
    rows = []
    cur_cells = current.get("cells", {})
    for key, b in sorted(baseline.get("cells", {}).items()):
        c = cur_cells.get(key)
        if c is None:
            rows.append({"cell": key, "metric": "(cell)", "baseline": b["status"], "value": None, "limit": None,
                         "status": "missing", "failed": True})
            continue
        if b["status"] == "ok" and c["status"] != "ok":
            rows.append({"cell": key, "metric": "status", "baseline": "ok", "value": c["status"], "limit": None,
                         "status": "worse", "failed": True})
        new_flags = sorted(set(c.get("flags", [])) - set(b.get("flags", [])))
        if new_flags:
            rows.append({"cell": key, "metric": "flags", "baseline": ";".join(b.get("flags", [])),
                         "value": ";".join(c.get("flags", [])), "limit": None, "status": "worse", "failed": True})
        for metric, tol in tolerances.items():
            base, cur = b["metrics"].get(metric), c.get("metrics", {}).get(metric)
            if metric not in b["metrics"]:
                continue
            if _is_exact(key, b):
                status, failed = _exact_value(base, cur, exact_rel)
                limit = base if failed else None
            else:
                status, failed, limit = compare_value(metric, tol, base, cur, b.get("flags", []))
            rows.append({"cell": key, "metric": metric, "baseline": base, "value": cur, "limit": limit,
                         "status": status, "failed": failed})
    for key in sorted(set(cur_cells) - set(baseline.get("cells", {}))):
        rows.append({"cell": key, "metric": "(cell)", "baseline": None, "value": cur_cells[key]["status"],
                     "limit": None, "status": "new", "failed": False})
    return QualityResult(rows=rows)


def _fmt(v) -> str:
    if v is None:
        return "–"
    if isinstance(v, float):
        return f"{v:.4g}"
    return str(v)


def format_quality(result: QualityResult, *, all_rows: bool = False) -> str:
    """The failing (and ``better`` / ``new``) rows of a quality comparison, one line each, plus a count line."""
    shown = [r for r in result.rows if all_rows or r["status"] not in ("ok", "no baseline")]
    lines = [f"  {'FAIL' if r['failed'] else r['status']:<8} {r['cell']}  {r['metric']}: {_fmt(r['value'])} "
             f"(baseline {_fmt(r['baseline'])}" + (f", limit {_fmt(r['limit'])}" if r["limit"] is not None else "")
             + ")" for r in shown]
    n_cells = len({r["cell"] for r in result.rows})
    lines.append(f"quality: {len(result.rows)} values of {n_cells} cells compared, {len(result.failures)} worse "
                 f"than the baseline beyond tolerance")
    return "\n".join(lines)
