"""The report's cost section: mean time (``wall_s``) and peak memory (``peak_mem_mb``) of the ok cells per
method label × phantom, as a table with the lowest per phantom marked and as a grouped bar chart."""

from __future__ import annotations

import html

import numpy as np

from .colours import method_colour

from .render import png_uri
from .tables import fmt_value

__all__ = ["COST_COLUMNS", "cost_section"]

COST_COLUMNS = (("wall_s", "time (s)"), ("peak_mem_mb", "memory (MiB)"))


#: with more places (phantom × N) than this, the cost table and chart show one column over all phantoms
MAX_PLACES = 16


def _cost_frame(df):
    """Mean ``wall_s`` and ``peak_mem_mb`` of the ok cells per method label × phantom (× N when the run has
    several; one place "all phantoms" beyond :data:`MAX_PLACES`): a DataFrame with columns label, where, wall_s,
    peak_mem_mb, cells."""
    import pandas as pd

    if df.empty or not any(c in df.columns for c, _ in COST_COLUMNS):
        return pd.DataFrame(columns=["label", "where", "wall_s", "peak_mem_mb", "cells"])
    d = df[df["status"] == "ok"].copy()
    many_n = "N" in d.columns and d["N"].nunique() > 1
    d["where"] = d["phantom"].astype(str) + (", N = " + d["N"].astype(str) if many_n else "")
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


def _render_cost_chart(cf, labels: list[str], places: list[str], dpi: int = 90) -> str | None:
    """Grouped bars: time and memory, one group per phantom, one bar per method (log scale when the values
    span more than 30×)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    if cf.empty:
        return None
    fig, axes = plt.subplots(1, 2, figsize=(max(6.0, 1.2 * len(places) * max(1, len(labels)) ** 0.5 + 3.5), 3.0),
                             dpi=dpi)
    width = 0.8 / max(1, len(labels))
    x = np.arange(len(places))
    for ax, (col, name) in zip(axes, COST_COLUMNS):
        vals_all = []
        for k, lab in enumerate(labels):
            vals = [_value(cf, lab, p, col) for p in places]
            vals = [v if np.isfinite(v) else np.nan for v in vals]
            vals_all += [v for v in vals if np.isfinite(v) and v > 0]
            ax.bar(x - 0.4 + (k + 0.5) * width, np.nan_to_num(vals, nan=0.0), width, label=lab, color=method_colour(lab))
        if vals_all and max(vals_all) / min(vals_all) > 30:
            ax.set_yscale("log")
        ax.set_xticks(x, places, fontsize=7, rotation=20 if len(places) > 3 else 0)
        ax.set_title(name, fontsize=8)
        ax.tick_params(labelsize=7)
        ax.grid(axis="y", alpha=0.3)
    axes[1].legend(fontsize=6, loc="upper left", bbox_to_anchor=(1.01, 1.0), frameon=False)
    fig.tight_layout()
    return png_uri(fig)


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
    """The report's cost section: ``{"html": table, "chart": PNG data URI or None, "n_cells": int}``.

    Rows are method labels, columns phantoms (× N), each with the mean time and peak memory of its ok cells
    (over noise settings and seeds); the lowest per phantom is marked."""
    cf = _cost_frame(df)
    if cf.empty:
        return {"html": "", "chart": None, "n_cells": 0}
    labels = list(dict.fromkeys(cf["label"]))
    places = list(dict.fromkeys(cf["where"]))
    return {"html": _cost_table(cf, labels, places), "chart": _render_cost_chart(cf, labels, places),
            "n_cells": int(cf["cells"].sum())}
