"""``index.html`` of a run folder: load ``results.csv``, ``run.json`` and the cells' records, build the
template's context from the report's sections and write the page atomically."""

from __future__ import annotations

import json
import math
from pathlib import Path

from ..run.store import load_cells
from .artifacts import Artifacts
from .claims import check_claims
from .cost import cost_section
from .interactive import VIEW_FACES, pareto_figure, plotly_js, robustness_figures, viewer_payload
from .paper import gallery_tables, paper_layout, paper_tables
from .tables import BEST_DIRECTION, summary_tables

__all__ = ["TEMPLATE_DIR", "write_report"]

TEMPLATE_DIR = Path(__file__).resolve().parent / "templates"

_TEXT_COLUMNS = ("error", "label", "method", "noise", "phantom", "variant", "status", "parameters", "cell_id",
                 "flags")


def _load_results(out: Path):
    import pandas as pd

    df = pd.read_csv(out / "results.csv", keep_default_na=True)
    for col in _TEXT_COLUMNS:
        if col in df.columns:
            df[col] = df[col].astype(object).where(df[col].notna(), "").astype(str)
    return df


def _load_meta(out: Path) -> dict:
    if not (out / "run.json").exists():
        return {}
    try:
        return json.loads((out / "run.json").read_text())
    except ValueError:
        return {}


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
        "claims": _claims(df, arts, config),
        **_interactive(df, arts, config),
        "failed": _failed(df, records),
        "facts": _facts(df, records),
        "meta": meta,
        "config_json": json.dumps(config, indent=1),
        "deps": (meta.get("dependencies") or {}),
        "git": meta.get("git"), "machine": meta.get("machine") or {},
        "sessions": meta.get("sessions") or [],
        "best_rules": {k: (v if isinstance(v, str) else f"closest to {v[1]}") for k, v in BEST_DIRECTION.items()},
    }


def write_report(out: str | Path) -> Path:
    """Render ``out/index.html`` from ``out/results.csv``, ``out/cells`` and ``out/run.json``."""
    import matplotlib

    matplotlib.use("Agg")
    from jinja2 import Environment, FileSystemLoader, select_autoescape

    out = Path(out)
    df = _load_results(out)
    context = _context(df, _load_meta(out), load_cells(out), Artifacts(out))
    env = Environment(loader=FileSystemLoader(str(TEMPLATE_DIR)), autoescape=select_autoescape(["html"]))
    page = env.get_template("report.html").render(**context)
    path = out / "index.html"
    tmp = out / ".index.html.tmp"
    tmp.write_text(page, encoding="utf-8")
    tmp.replace(path)
    return path
