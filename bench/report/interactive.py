"""The report's interactive parts (plotly): 3-D mesh viewers with error maps, robustness curves, the Pareto view.

* **Viewers** — each finished cell's mesh, decimated for viewing by a library decimator (trimesh's quadric
  decimation, ``fast_simplification``; the metrics always come from the full mesh) to at most
  :data:`VIEW_FACES` faces — in the worker, :mod:`bench.run.view` — with two colourings: the mean curvature H the
  cell stored (the paper's colouring) and the signed distance to the true surface in grid steps h (positive
  outside).  One colour scale per summary
  table (phantom × noise): the 2nd–98th percentile of H over its cells, and ±the 98th percentile of |distance|.
  The page stores the data once as JSON and draws a viewer when a table row is clicked.
* **Robustness curves** — a key metric against SNR and against N, a line per method, when the run varies them;
  each method's *breakdown point* is marked: the lowest SNR (or N) from which on, going down, its results stop
  being valid, unflagged and within 1 h Hausdorff.
* **Pareto view** — Hausdorff distance (h) against the method's wall time, a point per method per phantom
  (log axes): what accuracy costs.

Every figure is plain plotly JSON; :func:`plotly_js` embeds plotly.js once in the page (no network).
"""

from __future__ import annotations

import json
import math

import numpy as np

from ..run.view import VIEW_FACES, decimate_to_tolerance
from .colours import method_colour
from .tables import phantom_label

__all__ = ["VIEW_FACES", "plotly_js", "viewer_payload", "robustness_figures", "pareto_figure", "breakdown"]



def plotly_js() -> str:
    """plotly.js, minified, to embed once in a ``<script>`` (the page fetches nothing when viewed)."""
    from plotly.offline import get_plotlyjs

    return get_plotlyjs()


def _round(a: np.ndarray, digits: int = 4) -> list:
    return np.round(np.asarray(a, dtype=np.float64), digits).tolist()


def _phantom_sdf(name: str):
    from phantoms import get_phantom

    try:
        ph = get_phantom(name).ground_truth()
    except Exception:  # noqa: BLE001 — a phantom that cannot be rebuilt: no distance map
        return None
    return None if ph is None else ph.sdf


def _b64(a: np.ndarray) -> str:
    import base64

    return base64.b64encode(np.ascontiguousarray(a).tobytes()).decode("ascii")


def _quantised(values: np.ndarray, rng: list[float]) -> str:
    """``values`` on 0..255 over the colour range ``rng`` (the viewer clamps to it anyway), base64."""
    lo, hi = rng
    q = np.clip(np.round((np.nan_to_num(values, nan=lo) - lo) / (hi - lo) * 255.0), 0, 255)
    return _b64(q.astype(np.uint8))


def _pack(v: np.ndarray, f: np.ndarray, faces_full: int) -> dict:
    """Vertices as uint16 over their bounding box, faces as uint16 (uint32 beyond 65,535 vertices), base64
    little-endian — a quarter of the size of the same numbers as JSON text."""
    lo, hi = v.min(0), v.max(0)
    span = np.where(hi > lo, hi - lo, 1.0)
    q = np.round((v - lo) / span * 65535.0).astype("<u2")
    big = len(v) > 65535
    return {"n": int(len(v)), "lo": lo.tolist(), "hi": hi.tolist(), "v": _b64(q),
            "f": _b64(f.astype("<u4" if big else "<u2")), "f32": big, "nf": int(len(f)), "faces_full": faces_full}


def _range(values: list[np.ndarray], symmetric: bool) -> list[float] | None:
    vals = np.concatenate(values) if values else np.zeros(0)
    vals = vals[np.isfinite(vals)]
    if not vals.size:
        return None
    if symmetric:
        m = float(np.percentile(np.abs(vals), 98)) or 1e-3
        return [-m, m]
    lo, hi = (float(x) for x in np.percentile(vals, [2, 98]))
    return [lo, hi if hi > lo else lo + 1e-9]


def _cell_view(r: dict, a: dict, sdf, extent: float, faces: int) -> tuple[dict, dict] | None:
    """(packed mesh, {"H": values, "d": values}) of one cell, or None without a usable mesh."""
    from scipy.spatial import cKDTree

    if "view_vertices" in a and "view_faces" in a and len(a["view_faces"]):    # made by the worker
        colours = {k: np.asarray(a[f"view_{k}"], float) for k in ("H", "d") if f"view_{k}" in a}
        n_full = len(a["faces"]) if "faces" in a else len(a["view_faces"])
        return _pack(np.asarray(a["view_vertices"], float), np.asarray(a["view_faces"], np.int64), n_full), colours
    if "vertices" not in a or "faces" not in a or len(a["faces"]) == 0:
        return None
    v0, f0 = np.asarray(a["vertices"], float), np.asarray(a["faces"], np.int64)
    if not np.isfinite(v0).all() or f0.min() < 0 or f0.max() >= len(v0):
        return None
    v, f = decimate_to_tolerance(v0, f0, faces)
    full = {}
    H0 = a.get("H")
    if H0 is not None and len(H0) == len(v0):
        full["H"] = np.asarray(H0, float)
    try:
        if sdf is not None:      # on the full mesh: the map shows the reconstruction's error, not the decimation's
            h = _num(r, "h")
            h = h if math.isfinite(h) and h > 0 else 2.0 * extent / (float(r["N"]) - 1)
            full["d"] = np.asarray(sdf(v0), float) / h
    except Exception:  # noqa: BLE001 — the distance map is optional
        full.pop("d", None)
    colours = {}
    if full:
        idx = np.arange(len(v0)) if len(v) == len(v0) else cKDTree(v0).query(v)[1]
        colours = {k: x[idx] for k, x in full.items()}
    return _pack(v, f, int(len(f0))), colours


def viewer_payload(rows: list[dict], arrays, *, extent: float = 2.5, faces: int = VIEW_FACES) -> dict:
    """The viewers' data: ``{"cells": {cell_id: packed mesh + quantised colours}, "ranges": {"phantom|noise":
    {"H": [lo, hi], "d": [-m, m]}}}`` for every row whose arrays (``arrays(cell_id)``) hold a mesh."""
    views, sdfs = {}, {}
    for r in rows:
        phantom = str(r.get("phantom"))
        if phantom not in sdfs:
            source = r.get("source")
            sdfs[phantom] = _phantom_sdf(source if isinstance(source, str) and source else phantom)
        got = _cell_view(r, arrays(r["cell_id"]) or {}, sdfs[phantom], extent, faces)
        if got is not None:
            views[r["cell_id"]] = (f"{phantom}|{r.get('noise')}", *got)
    ranges: dict[str, dict] = {}
    for group in {g for g, _, _ in views.values()}:
        mine = [c for g, _, c in views.values() if g == group]
        ranges[group] = {k: rng for k in ("H", "d")
                         if (rng := _range([c[k] for c in mine if k in c], symmetric=k == "d")) is not None}
    cells = {}
    for cid, (group, packed, colours) in views.items():
        for k, values in colours.items():
            if k in ranges[group]:
                packed[k] = _quantised(values, ranges[group][k])
        cells[cid] = packed
    return {"cells": cells, "ranges": ranges}


def _num(r: dict, col: str) -> float:
    try:
        return float(r.get(col))
    except (TypeError, ValueError):
        return math.nan


def _good(r: dict) -> bool:
    flags = str(r.get("flags") or "").strip()
    return r.get("status") == "ok" and flags in ("", "nan") and _num(r, "hausdorff_h") <= 1.0


def breakdown(points: list[tuple[float, bool]]) -> float | None:
    """The breakdown point of a curve: ``points`` are (x, good) with x = SNR or N; going from the largest x
    down, the last x reached while every result so far is good (None: already bad at the largest x)."""
    last = None
    for x, good in sorted(points, key=lambda p: -p[0]):
        if not good:
            break
        last = x
    return last


def _curve_fig(title: str, xtitle: str, series: dict[str, list[tuple[float, float, bool]]], metric: str,
               log_x: bool = False) -> dict:
    import plotly.graph_objects as go

    fig = go.Figure()
    for label, pts in sorted(series.items()):
        pts = sorted(pts)
        fig.add_trace(go.Scatter(x=[p[0] for p in pts], y=[p[1] for p in pts], mode="lines+markers", name=label,
                                 line={"color": method_colour(label)},
                                 marker={"symbol": ["circle" if p[2] else "x" for p in pts],
                                         "color": method_colour(label)}))
        b = breakdown([(p[0], p[2]) for p in pts])
        if b is not None:
            y = next(p[1] for p in pts if p[0] == b)
            fig.add_trace(go.Scatter(x=[b], y=[y], mode="markers", showlegend=False, hoverinfo="text",
                                     text=[f"{label}: breakdown point {b:g}"],
                                     marker={"symbol": "diamond-open", "size": 16, "line": {"width": 2}}))
    fig.update_layout(title=title, xaxis_title=xtitle, yaxis_title=metric, height=380,
                      margin={"l": 60, "r": 20, "t": 50, "b": 50}, yaxis_type="log")
    if log_x:
        fig.update_xaxes(type="log")
    return json.loads(fig.to_json())


def _snr(r: dict) -> float:
    """The SNR a noisy cell asked for (the achieved one when it asked for the paper's)."""
    s = _num(r, "snr_requested")
    return s if math.isfinite(s) else _num(r, "snr_achieved")


def robustness_figures(rows: list[dict], metric: str = "hausdorff_h") -> list[dict]:
    """Per phantom: ``metric`` against SNR (noisy cells of the most common N) and against N (clean cells), a line
    per method label; only axes the run actually varies (≥ 3 values)."""
    figs = []
    for phantom in sorted({str(r.get("phantom")) for r in rows}):
        pr = [r for r in rows if str(r.get("phantom")) == phantom and math.isfinite(_num(r, metric))]
        ns = [int(_num(r, "N")) for r in pr if math.isfinite(_num(r, "N"))]
        if not ns:
            continue
        n0 = max(set(ns), key=ns.count)
        noisy = [r for r in pr if r.get("noise") not in ("none", None) and int(_num(r, "N")) == n0
                 and math.isfinite(_snr(r))]
        if len({_snr(r) for r in noisy}) >= 3:
            series: dict[str, list] = {}
            for r in noisy:
                series.setdefault(str(r["label"]), []).append((_snr(r), _num(r, metric), _good(r)))
            figs.append(_curve_fig(f"{phantom_label(phantom)}: {metric} against SNR (N = {n0}; ◇ breakdown point, "
                                   f"✕ not valid / flagged / > 1 h)", "SNR (dB)", series, metric))
        clean = [r for r in pr if r.get("noise") == "none"]
        if len({int(_num(r, "N")) for r in clean}) >= 3:
            series = {}
            for r in clean:
                series.setdefault(str(r["label"]), []).append((_num(r, "N"), _num(r, metric), _good(r)))
            figs.append(_curve_fig(f"{phantom_label(phantom)}: {metric} against N (clean; ◇ breakdown point)",
                                   "N (grid points per axis)", series, metric, log_x=True))
    return figs


def pareto_figure(rows: list[dict], metric: str = "hausdorff_h") -> dict | None:
    """``metric`` against wall time, a point per (method label, phantom, noise setting) — the mean over its
    seeds' valid cells; circles clean, diamonds noisy, hollow where a cell was flagged; hover names the input."""
    import plotly.graph_objects as go

    agg: dict[tuple[str, str, str], list] = {}
    for r in rows:
        if r.get("status") != "ok" or not (math.isfinite(_num(r, metric)) and _num(r, "wall_s") > 0):
            continue
        noise = str(r.get("noise"))
        if noise != "none" and math.isfinite(_snr(r)):
            noise = f"{noise} {_snr(r):g} dB"
        flagged = str(r.get("flags") or "").strip(" ;") not in ("", "nan")
        agg.setdefault((str(r["label"]), phantom_label(str(r["phantom"])), noise), []).append(
            (_num(r, "wall_s"), _num(r, metric), flagged))
    if not agg:
        return None
    fig = go.Figure()
    for label in sorted({k[0] for k in agg}):
        keys = sorted(k for k in agg if k[0] == label)
        xs = [float(np.mean([p[0] for p in agg[k]])) for k in keys]
        ys = [float(np.mean([p[1] for p in agg[k]])) for k in keys]
        symbols = [("circle" if k[2] == "none" else "diamond") + ("-open" if any(p[2] for p in agg[k]) else "")
                   for k in keys]
        text = [f"{label}: {k[1]}, {'clean' if k[2] == 'none' else k[2]}"
                + (" (flagged)" if any(p[2] for p in agg[k]) else "") for k in keys]
        fig.add_trace(go.Scatter(x=xs, y=ys, mode="markers", name=label, text=text,
                                 marker={"color": method_colour(label), "symbol": symbols, "size": 9,
                                         "line": {"width": 2, "color": method_colour(label)}},
                                 hovertemplate="%{text}<br>%{y:.3g} at %{x:.3g} s<extra></extra>"))
    fig.update_layout(title=f"Accuracy against cost: {metric} vs wall time (a point per method, phantom and noise "
                            "setting, mean over its valid cells; ○ clean, ◇ noisy, hollow: flagged)",
                      xaxis_title="wall time of the method (s)",
                      yaxis_title=metric, xaxis_type="log", yaxis_type="log", height=420,
                      margin={"l": 60, "r": 20, "t": 50, "b": 50})
    return json.loads(fig.to_json())
