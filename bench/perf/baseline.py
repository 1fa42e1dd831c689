"""Perf summaries: the small JSON a run is saved as and a baseline is read from (``"format":
"levelset-bench-perf/1"``: per benchmark the median/min/max seconds, rounds and ratios, plus the reference,
the load averages and the machine), built from pytest-benchmark's ``--benchmark-json``; merging several runs
into one (medians over runs); the committed baseline :data:`BASELINE`."""

from __future__ import annotations

import datetime as _dt
import json
import os
import platform
import statistics
from pathlib import Path
from typing import Any, Iterable

from ..metrics.tolerances import finite
from phantoms import InputError

__all__ = ["FORMAT", "BASELINE", "summarise", "load_summary", "merge_runs", "machine_note",
           "save_summary"]

FORMAT = "levelset-bench-perf/1"
#: the committed baseline the CI gate compares with (package data)
BASELINE = Path(__file__).resolve().parent / "baseline.json"


def summarise(raw: dict) -> dict:
    """The summary of a pytest-benchmark ``--benchmark-json`` document (a summary is returned unchanged)."""
    if raw.get("format") == FORMAT:
        return raw
    if "benchmarks" not in raw or not isinstance(raw["benchmarks"], list):
        raise InputError("not a pytest-benchmark JSON file nor a levelset-bench perf summary")
    names = [b.get("name") for b in raw["benchmarks"]]
    benches: dict[str, dict] = {}
    for b in raw["benchmarks"]:
        st = b.get("stats") or {}
        extra = b.get("extra_info") or {}
        key = b["name"] if names.count(b["name"]) == 1 else b.get("fullname", b["name"])
        benches[key] = {
            "group": b.get("group"),
            "fullname": b.get("fullname"),
            "median_s": finite(st.get("median")),
            "min_s": finite(st.get("min")),
            "max_s": finite(st.get("max")),
            "iqr_s": finite(st.get("iqr")),
            "rounds": st.get("rounds"),
            "ratio": finite(extra.get("ratio")),
            "cpu_mean_s": finite(extra.get("cpu_mean_s")),
            "cpu_ratio": finite(extra.get("cpu_ratio")),
            "loadavg_1min": extra.get("loadavg_1min"),
        }
    lb = raw.get("levelset_bench") or {}
    mi = raw.get("machine_info") or {}
    cpu = mi.get("cpu") or {}
    commit = raw.get("commit_info") or {}
    return {
        "format": FORMAT,
        "created": raw.get("datetime") or _dt.datetime.now(_dt.timezone.utc).isoformat(),
        "mode": lb.get("mode"),
        "machine": {"node": mi.get("node"), "cpu": cpu.get("brand_raw") or mi.get("processor"),
                    "cpu_count": lb.get("cpu_count") or cpu.get("count"), "system": mi.get("system"),
                    "python": mi.get("python_version")},
        "commit": {"id": commit.get("id"), "dirty": commit.get("dirty")},
        "loadavg": {"start": lb.get("loadavg_start"), "end": lb.get("loadavg_end")},
        "reference": lb.get("reference"),
        "skipped": sorted(lb.get("skipped") or []),
        "benchmarks": dict(sorted(benches.items())),
    }


def read_json_file(path: str | Path):
    """The parsed JSON of ``path``; an unreadable or non-JSON file → :class:`InputError` naming it."""
    p = Path(path)
    try:
        return json.loads(p.read_text(encoding="utf-8"))
    except OSError as exc:
        raise InputError(f"cannot read {str(p)!r}: {exc.strerror or exc}") from None
    except ValueError as exc:
        raise InputError(f"{str(p)!r} is not JSON: {exc}") from None


def load_summary(path: str | Path) -> dict:
    """Read a perf summary or a raw pytest-benchmark JSON file (:class:`InputError` if unreadable)."""
    p = Path(path)
    raw = read_json_file(p)
    if not isinstance(raw, dict):
        raise InputError(f"{str(p)!r}: not a perf summary")
    try:
        return summarise(raw)
    except InputError as exc:
        raise InputError(f"{str(p)!r}: {exc}") from None


def _median(values: Iterable) -> float | None:
    v = [x for x in values if x is not None]
    return statistics.median(v) if v else None


def merge_runs(runs: list[dict]) -> dict:
    """Several summaries of the same suite → one: per benchmark the median over runs of the median time and of
    each ratio (``runs`` keeps every run's values).  Summaries that are themselves merges count with each of
    their runs.  Metadata of the first summary; every run's load averages and reference."""
    if not runs:
        raise ValueError("no runs to merge")
    if len(runs) == 1:
        return runs[0]
    keys = ("median_s", "ratio", "cpu_mean_s", "cpu_ratio")

    def values(b: dict, k: str) -> list:
        return list(b["runs"][k]) if isinstance(b.get("runs"), dict) and k in b["runs"] else [b.get(k)]

    out = json.loads(json.dumps(runs[0]))
    names = sorted({n for r in runs for n in r["benchmarks"]})
    benches = {}
    for n in names:
        rows = [r["benchmarks"][n] for r in runs if n in r["benchmarks"]]
        b = {k: v for k, v in rows[0].items() if k not in ("runs", "attempts")}
        allv = {k: [x for r in rows for x in values(r, k)] for k in keys}
        for k in keys:
            b[k] = _median(allv[k])
        b["min_s"] = min((r["min_s"] for r in rows if r.get("min_s") is not None), default=None)
        b["max_s"] = max((r["max_s"] for r in rows if r.get("max_s") is not None), default=None)
        b["rounds"] = sum(int(r.get("rounds") or 0) for r in rows)
        b["runs"] = allv
        benches[n] = b
    out["benchmarks"] = benches

    def each(r: dict, key: str) -> list:
        v = r.get(key) or {}
        return list(v["runs"]) if isinstance(v, dict) and "runs" in v else [v]

    out["loadavg"] = {"runs": [x for r in runs for x in each(r, "loadavg")]}
    refs = [x for r in runs for x in each(r, "reference")]
    out["reference"] = {k: _median((x or {}).get(k) for x in refs) for k in ("median_s", "cpu_mean_s")}
    out["reference"]["runs"] = refs
    out["skipped"] = sorted(set.intersection(*(set(r.get("skipped") or []) for r in runs)))
    out["repeats"] = sum(int(r.get("repeats") or 1) for r in runs)
    return out


def machine_note() -> dict:
    """Load average and core count now (for the metadata of a saved summary)."""
    try:
        load = [round(x, 2) for x in os.getloadavg()]
    except (AttributeError, OSError):
        load = None
    return {"loadavg_now": load, "cpu_count": os.cpu_count(), "platform": platform.platform()}


def save_summary(summary: dict, path: str | Path, note: dict[str, Any] | None = None) -> Path:
    data = dict(summary)
    if note:
        data["note"] = note
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    tmp = p.with_name(p.name + ".tmp")
    tmp.write_text(json.dumps(data, indent=1, sort_keys=False) + "\n", encoding="utf-8")
    tmp.replace(p)
    return p
