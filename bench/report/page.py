"""``index.html`` of a run folder: load the results table (:func:`bench.run.results.read_results`), ``run.json``
and the cells' records, build the template's context from the report's sections and write the page atomically."""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path

from geometry.files import atomic_write
from markupsafe import Markup

from ..run.store import scan_cells
from ..run.results import read_results
from ..run.values import cap_tail, cap_text
from ..terminal import printable
from .artifacts import Artifacts
from .claims import VARIANTS as CLAIM_VARIANTS
from .claims import claims_section, variant_of
from .colours import method_colour
from .cost_section import cost_section
from .interactive import VIEW_FACES, pareto_figure, plotly_js, robustness_figures, viewer_payload
from .pairwise import pairwise_html
from .recommend import RULE, recommendation_html, recommendation_table
from .paper import gallery_tables, paper_layout, paper_tables
from .tables import BEST_DIRECTION, complete_inputs, summary_tables
from .verdicts import board_html, cd_figure, leaderboards

__all__ = ["TEMPLATE_DIR", "write_report", "preload"]

TEMPLATE_DIR = Path(__file__).resolve().parent / "templates"

_TEXT_COLUMNS = ("error", "label", "method", "noise", "phantom", "variant", "status", "parameters", "cell_id",
                 "flags", "shape_kind", "topology_vs_data_detail")


def warn(message: str) -> None:
    """A problem the report works around (an unreadable cell, a broken run.json), on stderr."""
    print(f"warning: {message}", file=sys.stderr)


def _load_results(out: Path):
    df = complete_inputs(read_results(out))
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
    for _, r in df[~df["status"].isin(["ok", "skipped"])].iterrows():     # a skipped input is not a failure
        rec = records.get(r["cell_id"], {})
        where = f"cells/{r['cell_id']}.json"          # the full texts; the page shows the capped ones
        tb = rec.get("traceback")
        failed.append({"cell_id": r["cell_id"], "label": r["label"], "status": r["status"],
                       "error": cap_text(r["error"], where=where),
                       "traceback": cap_tail(tb, where=where) if isinstance(tb, str) else tb})
    return failed


def _facts(df, records: dict) -> list[dict]:
    """Each cell's method info (``row.method_info`` of its json) as one line of ``key=value`` pairs."""
    facts = []
    for _, r in df.iterrows():
        row = (records.get(r["cell_id"]) or {}).get("row")       # a ResultRow (bench.run.store.scan_cells)
        info = row.method_info if row is not None else None
        if info:
            text = "; ".join(f"{k}={json.dumps(v, default=str)[:200]}" for k, v in info.items())
            facts.append({"cell_id": r["cell_id"], "label": r["label"], "text": text})
    return facts


#: the picture tables (rendered images per phantom) cover at most this many phantoms, in grid order
MAX_PICTURE_PHANTOMS = 8


def _picture_subset(df):
    """The rows of the first :data:`MAX_PICTURE_PHANTOMS` phantoms (the paper's four come first when present),
    and a note when phantoms were left out (a dataset of hundreds of shapes would render thousands of images)."""
    names = list(dict.fromkeys(df["phantom"]))
    if len(names) <= MAX_PICTURE_PHANTOMS:
        return df, ""
    paper = [p for p in ("sphere", "ellipsoid", "fused_spheres", "cylinder") if p in names]
    keep = (paper + [p for p in names if p not in paper])[:MAX_PICTURE_PHANTOMS]
    note = (f"Pictures for {len(keep)} of the run's {len(names)} phantoms ({', '.join(keep)}); the summary tables "
            "and their 3-D viewers cover every phantom.")
    return df[df["phantom"].isin(keep)], note


def _sections(df, arts: Artifacts, config: dict) -> dict:
    if not len(df):
        return {"summaries": [], "paper_tables": [], "galleries": [], "picture_note": "",
                "cost": {"html": "", "chart": None, "n_cells": 0}}
    pictures, note = _picture_subset(df)
    layout = paper_layout(config, pictures, arts)
    return {"summaries": summary_tables(df), "paper_tables": paper_tables(pictures, arts, layout),
            "galleries": gallery_tables(pictures, arts, layout), "picture_note": note, "cost": cost_section(df)}


def _claims(df, arts: Artifacts, config: dict) -> dict:
    """The claims section's entries: ``claims`` (empty: no section), ``paper_grid`` and the ``untested`` ids."""
    rows = df.to_dict("records") if len(df) else []
    if not any(variant_of(r) for r in rows):     # no shape-gradient row: nothing of the paper's to check
        return {"claims": [], "claims_paper_grid": False, "claims_untested": []}
    extent = float(((config.get("grid") or {}).get("extent")) or 2.5)
    section = claims_section(rows, arts.get, config=config, extent=extent)
    return {"claims": section.claims, "claims_paper_grid": section.paper_grid, "claims_untested": section.untested}


def _finite_only(obj):
    """``obj`` with every NaN / infinity replaced by None (JSON has neither)."""
    if isinstance(obj, float):
        return obj if math.isfinite(obj) else None
    if isinstance(obj, dict):
        return {k: _finite_only(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_finite_only(v) for v in obj]
    return obj


def _shown_deep(obj):
    """``obj`` with every text in it, keys too, as the page shows text (:func:`_shown`): the scripts' data (a chart's
    hover text, the viewer's groups and labels) says the same as the tables and matches their text."""
    if isinstance(obj, str):
        return printable(obj)
    if isinstance(obj, dict):
        return {_shown_deep(k): _shown_deep(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_shown_deep(v) for v in obj]
    return obj


def _json_in_html(obj) -> str:
    """JSON safe inside a ``<script>`` element (no ``</`` that would end it), its texts as the page shows them."""
    return json.dumps(_shown_deep(_finite_only(obj)), separators=(",", ":"), allow_nan=False).replace("</", "<\\/")


#: at most this many meshes are embedded for the 3-D viewers (the cells the summary tables open, in table order)
MAX_VIEWER_MESHES = 2000


def _interactive(df, arts: Artifacts, config: dict, shown: list[str] | None = None) -> dict:
    rows = df.to_dict("records") if len(df) else []
    extent = float(((config.get("grid") or {}).get("extent")) or 2.5)
    boards = leaderboards(rows) if rows else []
    colours = {str(lab): method_colour(lab) for lab in {r.get("label") for r in rows}}
    verdict_charts = [cd_figure(b, colours) for b in boards]
    for b in boards:
        b["html"] = board_html(b, colours)
        b["pairwise_html"] = pairwise_html(b["pairwise"], [r["label"] for r in b["rows"]])
        if b.get("raw_board"):
            b["raw_board"]["html"] = board_html(b["raw_board"], colours)
        b["chart"] = None
    charts = [f for f in verdict_charts if f is not None]
    k = 0
    for b, fig in zip(boards, verdict_charts):
        if fig is not None:
            k += 1
            b["chart"] = k
    n_verdict = len(charts)
    charts += robustness_figures(rows)
    pareto = pareto_figure(rows) or pareto_figure(rows, "sdf_rms_h")   # without truth: data fidelity
    if pareto is not None:
        charts.append(pareto)
    wanted = list(dict.fromkeys(shown if shown is not None else [r["cell_id"] for r in rows]))
    embed = set(wanted[:MAX_VIEWER_MESHES])
    view_rows = [r for r in rows if r["cell_id"] in embed]
    meshes = viewer_payload(view_rows, arts.get, extent=extent) if view_rows else {"cells": {}, "ranges": {}}
    meshes["note"] = (f"3-D meshes are embedded for the first {MAX_VIEWER_MESHES} of the {len(wanted)} table rows; "
                      "the others: the cell's arrays in cells/<cell_id>.npz (or --save-meshes)"
                      if len(wanted) > MAX_VIEWER_MESHES else "")
    recommend = recommendation_html(recommendation_table(rows)) if rows else ""
    return {"plotly_js": plotly_js(), "meshes_json": _json_in_html(meshes), "charts": charts[n_verdict:],
            "recommend_html": recommend, "recommend_rule": RULE,
            "verdict_charts": charts[:n_verdict], "chart_offset": n_verdict, "boards": boards,
            "charts_json": _json_in_html(charts), "page_js": (TEMPLATE_DIR / "report.js").read_text("utf-8"),
            "view_faces": VIEW_FACES}


def _context(df, meta: dict, records: dict, arts: Artifacts) -> dict:
    config = meta.get("config") or {}
    sections = _sections(df, arts, config)
    shown = [cid for t in sections["summaries"] for cid in t["cells"].values()]   # what a table row opens
    for t in sections["summaries"]:                 # label → cell, matched against the table's (escaped) text
        t["cells"] = _shown_deep(t["cells"])
    return {
        "title": f"levelset-bench — {config.get('name', 'run')}",
        "config_name": config.get("name", "run"),
        "description": config.get("description", ""),
        "n_rows": len(df), "n_total": (meta.get("cells") or {}).get("total", len(df)),
        "counts": df["status"].value_counts().to_dict() if len(df) else {},
        **sections,
        **_claims(df, arts, config), "claim_variants": CLAIM_VARIANTS,
        **_interactive(df, arts, config, shown),
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


def preload() -> None:
    """Import what :func:`write_report` loads on its way (pandas, pyarrow, plotly, matplotlib's colour maps,
    Pillow's encoders, jinja2, scipy.stats, the rasteriser's compiled kernel): seconds that ``bench run`` spends
    in a thread while its cells run in their own processes, instead of after them."""
    import jinja2  # noqa: F401
    import matplotlib.colors  # noqa: F401
    import narwhals  # noqa: F401  (plotly reads data frames through it)
    import numpy as np
    import pandas
    import plotly.graph_objects as go
    import plotly.io
    import plotly.offline  # noqa: F401
    import pyarrow.dataset  # noqa: F401
    import pyarrow.parquet  # noqa: F401
    import scipy.stats  # noqa: F401
    from matplotlib import colormaps  # noqa: F401
    from PIL import Image, features

    from .picture import rasterize

    Image.init()
    features.check("webp")
    pandas.DataFrame({"a": [1]}).to_dict("records")
    fig = go.Figure(go.Scatter(x=[0], y=[0], mode="markers", marker={"line": {"width": 1}}))
    fig.update_layout(title="t", margin={"l": 0}, xaxis={"title": "x"}, yaxis={"title": "y"})
    plotly.io.to_json(fig)
    rasterize(np.zeros((1, 3, 2)), np.zeros((1, 3)), 2, 2)


class Verbatim(Markup):
    """Text the page embeds as it is (plotly.js, whose string literals hold control characters)."""


def _shown(value):
    """Every value the template prints, control characters shown as ``\\xNN`` (:func:`bench.terminal.printable`):
    a phantom's file name or a method label can hold ESC / BEL, which autoescaping leaves in the page."""
    if isinstance(value, Verbatim):
        return value
    if isinstance(value, Markup):
        return Markup(printable(value))
    return printable(value) if isinstance(value, str) else value


def write_report(out: str | Path, problems: list[str] | None = None) -> Path:
    """Render ``out/index.html`` from the results table, ``out/cells`` and ``out/run.json``; ``problems``
    (the damaged cell files of :func:`bench.run.store.check_run_folder`, rendered anyway) head the page."""
    import matplotlib

    matplotlib.use("Agg")
    from jinja2 import Environment, FileSystemLoader, select_autoescape

    out = Path(out)
    df = _load_results(out)
    records, unreadable = scan_cells(out)
    for msg in unreadable:
        warn(f"{msg}; the report leaves the cell's details out")
    context = _context(df, _load_meta(out), records, Artifacts(out, warn=warn))
    context["integrity_problems"] = list(problems or [])
    context["plotly_js"] = Verbatim(context["plotly_js"])
    env = Environment(loader=FileSystemLoader(str(TEMPLATE_DIR)), autoescape=select_autoescape(["html"]),
                      finalize=_shown)
    page = env.get_template("report.html").render(**context)
    return atomic_write(out / "index.html", page)
