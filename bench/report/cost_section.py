"""The report's cost section: mean time (``wall_s``) and peak memory (``peak_mem_mb``) of the ok cells per
method label × phantom, as a table with the lowest per phantom marked and as a grouped bar chart."""

from __future__ import annotations

import html

import numpy as np

from .colours import method_colour
from .tables import fmt_value, phantom_label

__all__ = ["COST_COLUMNS", "cost_section"]

COST_COLUMNS = (("wall_s", "time (s)"), ("peak_mem_mb", "memory (MiB)"))


#: with more places (phantom × N) than this, the cost table and chart show one column over all phantoms
MAX_PLACES = 16


def _cost_frame(df):
    """Mean ``wall_s`` and ``peak_mem_mb`` of the ok cells per method label × phantom (× N when the run has
    several): a DataFrame with columns label, where, wall_s, peak_mem_mb, cells."""
    import pandas as pd

    if df.empty or not any(c in df.columns for c, _ in COST_COLUMNS):
        return pd.DataFrame(columns=["label", "where", "wall_s", "peak_mem_mb", "cells"])
    d = df[df["status"] == "ok"].copy()
    many_n = "N" in d.columns and d["N"].nunique() > 1
    d["where"] = d["phantom"].astype(str).map(phantom_label) + (", N = " + d["N"].astype(str) if many_n else "")
    if d["where"].nunique() > MAX_PLACES:
        d["where"] = f"all {d['where'].nunique()} phantoms" + (" and N" if many_n else "")
    for c, _ in COST_COLUMNS:
        d[c] = pd.to_numeric(d[c], errors="coerce") if c in d.columns else np.nan
    g = d.groupby(["label", "where"], sort=False)
    out = g[[c for c, _ in COST_COLUMNS]].mean()
    out["cells"] = g.size()
    return out.reset_index()


def _value(cf, label: str, where: str, col: str) -> float:
    index = cf.attrs.get("_index")
    if index is None:                                    # (label, where) → row, built once per frame
        index = cf.attrs["_index"] = {(lab, w): i for i, (lab, w) in enumerate(zip(cf["label"], cf["where"]))}
    i = index.get((label, where))
    return float(cf[col].iloc[i]) if i is not None else np.nan



def _bars_svg(cf, labels: list[str], places: list[str], col: str, name: str, x0: float, w: float, h: float) -> str:
    """One panel of grouped bars (one group per place, one bar per label; log scale when the values span more
    than 30×) as SVG elements at x0."""
    import math

    vals = {(lab, p): _value(cf, lab, p, col) for lab in labels for p in places}
    pos = [v for v in vals.values() if np.isfinite(v) and v > 0]
    if not pos:
        return ""
    log = max(pos) / min(pos) > 30
    lo = math.floor(math.log10(min(pos))) if log else 0.0
    hi = math.ceil(math.log10(max(pos))) if log else max(pos) * 1.1
    top, bottom, left = 18, 34, 38

    def y(v: float) -> float:
        f = (math.log10(v) - lo) / (hi - lo) if log else v / hi
        return top + (h - top - bottom) * (1 - min(max(f, 0.0), 1.0))

    out = [f'<text x="{x0 + w / 2:.0f}" y="12" text-anchor="middle">{html.escape(name)}</text>',
           f'<rect x="{x0 + left}" y="{top}" width="{w - left - 4}" height="{h - top - bottom}" fill="none" '
           f'stroke="#999"/>']
    ticks = [10.0 ** k for k in range(int(lo), int(hi) + 1)] if log else list(np.linspace(0, hi, 5))
    for t in ticks:
        out.append(f'<text x="{x0 + left - 3}" y="{y(t) + 3:.1f}" text-anchor="end">{t:.3g}</text>')
    group = (w - left - 4) / max(1, len(places))
    bar = 0.8 * group / max(1, len(labels))
    for i, p in enumerate(places):
        gx = x0 + left + i * group + 0.1 * group
        out.append(f'<text x="{gx + 0.4 * group:.1f}" y="{h - bottom + 12}" text-anchor="middle">'
                   f'{html.escape(p)}</text>')
        for k, lab in enumerate(labels):
            v = vals[(lab, p)]
            if np.isfinite(v) and v > 0:
                yy = y(v)
                out.append(f'<rect x="{gx + k * bar:.1f}" y="{yy:.1f}" width="{bar:.1f}" '
                           f'height="{h - bottom - yy:.1f}" fill="{method_colour(lab)}">'
                           f'<title>{html.escape(lab)}: {v:.3g}</title></rect>')
    return "".join(out)


def _render_cost_chart(cf, labels: list[str], places: list[str]) -> str | None:
    """Grouped bars, time and memory side by side, one group per phantom, one bar per method, the legend
    below: an SVG data URI (vector, a few kB, no plotting library)."""
    import base64

    if cf.empty:
        return None
    w, h = max(320, 60 * len(places) * max(1, len(labels)) ** 0.5 + 80), 230
    legend_rows = (len(labels) + 2) // 3
    total_h = h + 14 * legend_rows + 6
    parts = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{2 * w:.0f}" height="{total_h}" '
             f'font-family="sans-serif" font-size="9"><rect width="100%" height="100%" fill="white"/>']
    for i, (col, name) in enumerate(COST_COLUMNS):
        parts.append(_bars_svg(cf, labels, places, col, name, i * w, w, h))
    for k, lab in enumerate(labels):
        lx, ly = 40 + (k % 3) * (2 * w - 40) / 3, h + 4 + 14 * (k // 3)
        parts.append(f'<rect x="{lx:.0f}" y="{ly}" width="9" height="9" fill="{method_colour(lab)}"/>'
                     f'<text x="{lx + 13:.0f}" y="{ly + 8}">{html.escape(lab)}</text>')
    svg = "".join(parts) + "</svg>"
    return "data:image/svg+xml;base64," + base64.b64encode(svg.encode("utf-8")).decode("ascii")


def _cost_table(cf, labels: list[str], places: list[str]) -> str:
    head1 = "".join(f'<th colspan="{len(COST_COLUMNS)}">{html.escape(p)}</th>' for p in places)
    head2 = "".join(f"<th>{html.escape(n)}</th>" for _ in places for _, n in COST_COLUMNS)
    best = {}
    for p in places:
        for c, _ in COST_COLUMNS:
            col = cf[cf["where"] == p][c]
            best[(p, c)] = float(col.min()) if col.notna().sum() >= 2 else None
    body = []
    for lab in labels:
        cells = []
        for p in places:
            for c, _ in COST_COLUMNS:
                v = _value(cf, lab, p, c)
                text = fmt_value(v, c)
                if best[(p, c)] is not None and np.isfinite(v) and np.isclose(v, best[(p, c)]):
                    text = f'<span class="best" title="lowest">{text}</span>'
                cells.append(f"<td>{text}</td>")
        body.append(f"<tr><td>{html.escape(str(lab))}</td>{''.join(cells)}</tr>")
    return (f'<table class="summary cost"><thead><tr><th rowspan="2">method</th>{head1}</tr><tr>{head2}</tr>'
            f"</thead><tbody>{''.join(body)}</tbody></table>")


def cost_section(df) -> dict:
    """The report's cost section: ``{"html": table, "chart": SVG data URI or None, "n_cells": int}``.

    Rows are method labels, columns phantoms (× N), each with the mean time and peak memory of its ok cells
    (over noise settings and seeds); the lowest per phantom is marked."""
    cf = _cost_frame(df)
    if cf.empty:
        return {"html": "", "chart": None, "n_cells": 0}
    labels = list(dict.fromkeys(cf["label"]))
    places = list(dict.fromkeys(cf["where"]))
    full = sorted({str(p) for p in df["phantom"]} if "phantom" in df.columns else set())
    legend = [(phantom_label(p), p) for p in full if phantom_label(p) != p]
    note = ("<p class=\"caption\">inputs: " + "; ".join(f"{html.escape(a)} = <code>{html.escape(b)}</code>"
                                                   for a, b in legend) + "</p>") if legend else ""
    return {"html": _cost_table(cf, labels, places) + note, "chart": _render_cost_chart(cf, labels, places),
            "n_cells": int(cf["cells"].sum())}
