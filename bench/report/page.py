"""``index.html`` of a run folder: load ``results.csv``, ``run.json`` and the cells' records, build the
template's context from the report's sections and write the page atomically."""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path

from geometry.files import atomic_write
from phantoms import InputError

from ..run.store import scan_cells
from .artifacts import Artifacts
from .claims import VARIANTS as CLAIM_VARIANTS
from .claims import check_claims
from .cost import cost_section
from .interactive import VIEW_FACES, pareto_figure, plotly_js, robustness_figures, viewer_payload
from .paper import gallery_tables, paper_layout, paper_tables
from .tables import BEST_DIRECTION, summary_tables

__all__ = ["TEMPLATE_DIR", "write_report"]

TEMPLATE_DIR = Path(__file__).resolve().parent / "templates"

_TEXT_COLUMNS = ("error", "label", "method", "noise", "phantom", "variant", "status", "parameters", "cell_id",
                 "flags")


def warn(message: str) -> None:
    """A problem the report works around (an unreadable cell, a broken run.json), on stderr."""
    print(f"warning: {message}", file=sys.stderr)


def _load_results(out: Path):
    import pandas as pd

    path = out / "results.csv"
    try:
        df = pd.read_csv(path, keep_default_na=True)
    except (OSError, ValueError, pd.errors.ParserError, pd.errors.EmptyDataError, UnicodeDecodeError) as exc:
        raise InputError(f"{str(path)!r} is not a readable results table ({type(exc).__name__}: "
                         f"{str(exc).strip().splitlines()[0] if str(exc).strip() else 'empty'}); rerun the grid "
                         "with --resume to rewrite it") from None
    missing = [c for c in ("cell_id", "status", "label") if c not in df.columns]
    if missing:
        raise InputError(f"{str(path)!r} is not a results table of levelset-bench (no column "
                         f"{', '.join(missing)}); rerun the grid with --resume to rewrite it")
    for col in _TEXT_COLUMNS:
        if col in df.columns:
            df[col] = df[col].astype(object).where(df[col].notna(), "").astype(str)
    return df


def _load_meta(out: Path) -> dict:
    path = out / "run.json"
    if not path.exists():
        return {}
    try:
        meta = json.loads(path.read_text())
    except (OSError, ValueError) as exc:
        warn(f"{path} is unreadable ({type(exc).__name__}); the report omits the run's metadata")
        return {}
    if not isinstance(meta, dict):
        warn(f"{path} holds a {type(meta).__name__}, not the run's metadata; the report omits it")
        return {}
    return meta


def _failed(df, records: dict) -> list[dict]:
    failed = []
    for _, r in df[df["status"] != "ok"].iterrows():
        rec = records.get(r["cell_id"], {})
        failed.append({"cell_id": r["cell_id"], "label": r["label"], "status": r["status"], "error": r["error"],
                       "traceback": rec.get("traceback")})
    return failed


def _facts(df, records: dict) -> list[dict]:
    """Each cell's method info (``row.method_info`` of its json) as one line of ``key=value`` pairs."""
    facts = []
    for _, r in df.iterrows():
        info = ((records.get(r["cell_id"]) or {}).get("row") or {}).get("method_info")
        if info:
            text = "; ".join(f"{k}={json.dumps(v, default=str)[:200]}" for k, v in info.items())
            facts.append({"cell_id": r["cell_id"], "label": r["label"], "text": text})
    return facts


def _sections(df, arts: Artifacts, config: dict) -> dict:
    if not len(df):
        return {"summaries": [], "paper_tables": [], "galleries": [],
                "cost": {"html": "", "chart": None, "n_cells": 0}}
    layout = paper_layout(config, df, arts)
    return {"summaries": summary_tables(df), "paper_tables": paper_tables(df, arts, layout),
            "galleries": gallery_tables(df, arts, layout), "cost": cost_section(df)}


def _claims(df, arts: Artifacts, config: dict) -> list:
    rows = df.to_dict("records") if len(df) else []
    extent = float(((config.get("grid") or {}).get("extent")) or 2.5)
    return check_claims(rows, arts.get, extent=extent)


def _finite_only(obj):
    """``obj`` with every NaN / infinity replaced by None (JSON has neither)."""
    if isinstance(obj, float):
        return obj if math.isfinite(obj) else None
    if isinstance(obj, dict):
        return {k: _finite_only(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_finite_only(v) for v in obj]
    return obj


def _json_in_html(obj) -> str:
    """JSON safe inside a ``<script>`` element (no ``</`` that would end it)."""
    return json.dumps(_finite_only(obj), separators=(",", ":"), allow_nan=False).replace("</", "<\\/")


def _interactive(df, arts: Artifacts, config: dict) -> dict:
    rows = df.to_dict("records") if len(df) else []
    extent = float(((config.get("grid") or {}).get("extent")) or 2.5)
    charts = robustness_figures(rows)
    pareto = pareto_figure(rows)
    if pareto is not None:
        charts.append(pareto)
    meshes = viewer_payload(rows, arts.get, extent=extent) if rows else {"cells": {}, "ranges": {}}
    return {"plotly_js": plotly_js(), "meshes_json": _json_in_html(meshes), "charts": charts,
            "charts_json": _json_in_html(charts), "page_js": (TEMPLATE_DIR / "report.js").read_text("utf-8"),
            "view_faces": VIEW_FACES}


def _context(df, meta: dict, records: dict, arts: Artifacts) -> dict:
    config = meta.get("config") or {}
    return {
        "title": f"levelset-bench — {config.get('name', 'run')}",
        "config_name": config.get("name", "run"),
        "description": config.get("description", ""),
        "n_rows": len(df), "n_total": (meta.get("cells") or {}).get("total", len(df)),
        "counts": df["status"].value_counts().to_dict() if len(df) else {},
        **_sections(df, arts, config),
        "claims": _claims(df, arts, config), "claim_variants": CLAIM_VARIANTS,
        **_interactive(df, arts, config),
        "failed": _failed(df, records),
        "facts": _facts(df, records),
        "meta": meta,
        "config_json": json.dumps(config, indent=1),
        "deps": (meta.get("dependencies") or {}),
        "git": meta.get("git"), "machine": meta.get("machine") or {},
        "sessions": [x for x in (meta.get("sessions") or []) if isinstance(x, dict)],
        "mixed_code": meta.get("mixed_code") or {},
        "best_rules": {k: (v if isinstance(v, str) else f"closest to {v[1]}") for k, v in BEST_DIRECTION.items()},
    }


def write_report(out: str | Path) -> Path:
    """Render ``out/index.html`` from ``out/results.csv``, ``out/cells`` and ``out/run.json``."""
    import matplotlib

    matplotlib.use("Agg")
    from jinja2 import Environment, FileSystemLoader, select_autoescape

    out = Path(out)
    df = _load_results(out)
    records, problems = scan_cells(out)
    for msg in problems:
        warn(f"{msg}; the report leaves the cell's details out")
    context = _context(df, _load_meta(out), records, Artifacts(out, warn=warn))
    env = Environment(loader=FileSystemLoader(str(TEMPLATE_DIR)), autoescape=select_autoescape(["html"]))
    page = env.get_template("report.html").render(**context)
    return atomic_write(out / "index.html", page)
