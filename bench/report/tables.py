"""Summary tables: one per phantom × noise setting (× variant × N), methods as rows, metrics as columns, the
best value of each column marked.  Which value is best and how a value is shown come from the metric
registry (:data:`bench.metrics.registry.METRICS`)."""

from __future__ import annotations

import html
import math
from typing import Any

import numpy as np

from bench.metrics.registry import METRICS

__all__ = ["BEST_DIRECTION", "FLAG_TITLES", "status_badges", "summary_tables", "fmt_value", "noise_title", "is_nan", "best_mask", "best_rule"]

#: how a metric's best value is chosen ("min", "max", ("target", value)); unranked metrics are absent
BEST_DIRECTION: dict[str, Any] = {k: m.best for k, m in METRICS.items() if m.best is not None}

#: columns that identify a cell or describe its outcome, never shown as metrics
_ID_COLUMNS = {"cell_id", "phantom", "variant", "N", "noise", "snr_requested", "snr_achieved", "seed", "method",
               "label", "parameters", "status", "error", "stop_reason"}


def _dtype(col: str) -> str:
    m = METRICS.get(col)
    return m.dtype if m is not None else "float"


def fmt_value(v: Any, col: str) -> str:
    """A table cell's text (HTML-escaped): yes/no for bools, integers without decimals, 4 significant digits."""
    if v is None or (isinstance(v, float) and math.isnan(v)):
        return "–"
    if isinstance(v, (bool, np.bool_)):
        return "yes" if v else "no"
    if isinstance(v, (int, np.integer)):
        return str(int(v))
    if isinstance(v, (float, np.floating)):
        v = float(v)
        if _dtype(col) == "bool":  # a mean over seeds of a yes/no metric
            return "yes" if v == 1.0 else "no" if v == 0.0 else f"{100 * v:.0f} % yes"
        if _dtype(col) == "int" and v.is_integer():
            return str(int(v))
        if math.isinf(v):
            return "∞" if v > 0 else "−∞"
        return f"{v:.4g}"
    return html.escape(str(v))


def is_nan(x) -> bool:
    try:
        return math.isnan(float(x))
    except (TypeError, ValueError):
        return False


def noise_title(noise: str, snr) -> str:
    if noise == "none":
        return "clean"
    return f"{noise} noise, SNR {float(snr):g} dB" if snr is not None and not is_nan(snr) else f"{noise} noise"


def _metric_columns(df) -> list[str]:
    from bench.metrics import METRIC_NAMES

    names = [m for m in METRIC_NAMES if m in df.columns]
    if not names:
        names = [c for c in df.columns if c not in _ID_COLUMNS]
    for extra in ("iterations", "energy_final", "wall_s", "peak_mem_mb"):
        if extra in df.columns and extra not in names:
            names.append(extra)
    return [c for c in names if c not in _ID_COLUMNS]


def best_rule(metric: str, genus: int = 0):
    """The registry's rule for ``metric``; the Euler characteristic's target is the phantom's 2 − 2·genus."""
    m = METRICS.get(metric)
    if m is None or m.best is None:
        return None
    if metric == "euler":
        return ("target", 2 - 2 * genus)
    return m.best


def _numeric(series):
    import pandas as pd

    return pd.to_numeric(series.map(lambda x: float(x) if isinstance(x, (bool, np.bool_)) else x), errors="coerce")


def best_mask(series, rule) -> np.ndarray:
    """Which entries of ``series`` are best under ``rule`` (nothing is marked with fewer than 2 values)."""
    vals = _numeric(series).to_numpy(float)
    ok = np.isfinite(vals)
    if ok.sum() < 2:
        return np.zeros(len(vals), bool)
    if rule == "min":
        best = np.nanmin(np.where(ok, vals, np.nan))
        return ok & np.isclose(vals, best, rtol=1e-9, atol=0)
    if rule == "max":
        best = np.nanmax(np.where(ok, vals, np.nan))
        return ok & np.isclose(vals, best, rtol=1e-9, atol=0)
    if isinstance(rule, tuple) and rule[0] == "target":
        d = np.abs(vals - rule[1])
        best = np.nanmin(np.where(ok, d, np.nan))
        return ok & np.isclose(d, best, rtol=1e-9, atol=1e-12)
    return np.zeros(len(vals), bool)


def _status_text(g, ok) -> str:
    statuses = g["status"].tolist()
    text = statuses[0] if len(set(statuses)) == 1 else ", ".join(f"{s}×{statuses.count(s)}"
                                                                 for s in sorted(set(statuses)))
    if len(g) > 1:
        text += f" (mean of {len(ok)}/{len(g)} seeds)"
    return text


#: what each flag means (the badge's tooltip); docs/METRICS.md has the definitions
FLAG_TITLES = {
    "topology_mismatch": "Euler characteristic or number of components differs from the truth's",
    "dropped_components": "fewer components than the truth (a part was dropped)",
    "self_intersecting": "some non-adjacent faces intersect",
    "not_converged": "the method stopped on max_iter, line_search_floor, diverged or sign_guard (rolled back to an earlier iterate)",
}


def status_badges(status: str, flags, valid: bool) -> str:
    """The status cell: the status text (a red ``invalid`` / grey ``failed`` badge when no seed gave a valid
    result) followed by one amber badge per flag, named in text (the report's CSS colours ``.badge``)."""
    text = html.escape(str(status))
    if not valid:
        kind = "invalid" if "invalid" in str(status) else "failed"
        text = f'<span class="badge badge-{kind}" title="no valid result: never ranked best">{text}</span>'
    for f in flags or ():
        title = html.escape(FLAG_TITLES.get(f, "suspect result"))
        text += f' <span class="badge badge-flag" title="{title}">{html.escape(f)}</span>'
    return text


def _method_rows(sub, metrics: list[str]):
    """One row per method label: the mean of each metric over its ok cells (over all when none is ok: such a row
    is shown, below the valid ones, and never marked best)."""
    import pandas as pd

    rows = []
    present = [m for m in metrics if m in sub.columns]
    numbers = sub[present].apply(_numeric)                    # once for the table, not per label and metric
    for label, g in sub.groupby("label", sort=False):
        ok = g[g["status"] == "ok"]
        rec: dict[str, Any] = {"method": label}
        means = numbers.loc[(ok if len(ok) else g).index].mean()   # NaN where no value
        for m in present:
            rec[m] = float(means[m])
        flags = sorted({f for v in (ok if len(ok) else g).get("flags", pd.Series(dtype=object))
                        if isinstance(v, str) for f in v.split(";") if f})
        rec["status"] = _status_text(g, ok)
        rec["_flags"] = flags
        rec["_valid"] = len(ok) > 0
        rec["_unflagged"] = not flags
        rows.append(rec)
    t = pd.DataFrame(rows)
    # validity first: valid unflagged methods, then valid flagged ones, then those without a valid result (only
    # valid ones can be "best")
    if not len(t):
        return t
    return t.sort_values(["_valid", "_unflagged"], ascending=False, kind="stable").reset_index(drop=True)


def _genus(phantom: str) -> int:
    from phantoms import get_phantom

    try:
        return int(getattr(get_phantom(phantom), "genus", 0))
    except Exception:
        return 0


def _marked_html(t, metrics: list[str], genus: int) -> str:
    import pandas as pd

    shown = pd.DataFrame({"method": [html.escape(str(x)) for x in t["method"]]})
    for m in [c for c in metrics if c in t.columns]:
        rule = best_rule(m, genus)
        eligible = t[m].where(t["_valid"], np.nan)            # an invalid or failed result is never best
        mask = best_mask(eligible, rule) if rule is not None else np.zeros(len(t), bool)
        shown[m] = [f'<span class="best" title="best">{fmt_value(v, m)}</span>' if b else fmt_value(v, m)
                    for v, b in zip(t[m], mask)]
    shown["status"] = [status_badges(s, f, v) for s, f, v in zip(t["status"], t["_flags"], t["_valid"])]
    return shown.to_html(index=False, escape=False, classes="summary", border=0, na_rep="–")


def summary_tables(df) -> list[dict]:
    """One table per phantom × noise (× variant × N): ``[{"title", "phantom", "noise", "html", "n_methods",
    "cells"}]`` (``cells``: method label → the cell id its row's mesh viewer shows, the first seed's)."""
    metrics = _metric_columns(df)
    keys = ["phantom", "noise", "snr_requested", "variant", "N"]
    d = df.copy()
    d["snr_requested"] = d["snr_requested"].astype(object).where(d["snr_requested"].notna(), None)
    groups: dict[tuple, list[int]] = {}
    for i, r in d.iterrows():
        groups.setdefault(tuple(r[k] for k in keys), []).append(i)
    multi_variant = d["variant"].nunique() > 1 or d["N"].nunique() > 1
    tables = []
    for (phantom, noise, snr, variant, n), idx in groups.items():
        t = _method_rows(d.loc[idx], metrics)
        title = f"{phantom} — {noise_title(noise, snr)}"
        if multi_variant:
            title += f" — {variant}, N = {n}"
        sub = d.loc[idx]
        cells = {str(lab): str(g["cell_id"].iloc[0]) for lab, g in sub.groupby("label", sort=False)}
        tables.append({"title": title, "phantom": phantom, "noise": noise,
                       "html": _marked_html(t, metrics, _genus(phantom)), "n_methods": len(t),
                       "cells": cells})
    return tables
