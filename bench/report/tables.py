"""Summary tables: one per phantom × noise setting (× variant × N), methods as rows, metrics as columns, the
best value of each column marked.  Which value is best and how a value is shown come from the metric
registry (:data:`bench.metrics.registry.METRICS`)."""

from __future__ import annotations

import functools
import html
import math
from typing import Any

import numpy as np

from bench.metrics.registry import METRICS

__all__ = ["ci_half_width", "NO_TRUTH_NOTE", "BEST_DIRECTION", "FLAG_TITLES", "status_badges", "summary_tables",
           "complete_inputs", "phantom_label", "fmt_value", "noise_title", "input_title", "is_nan", "best_mask",
           "best_rule"]

#: how a metric's best value is chosen ("min", "max", ("target", value)); unranked metrics are absent
BEST_DIRECTION: dict[str, Any] = {k: m.best for k, m in METRICS.items() if m.best is not None}

#: columns that identify a cell or describe its outcome, never shown as metrics
_ID_COLUMNS = {"cell_id", "phantom", "variant", "N", "noise", "snr_requested", "snr_achieved", "seed", "method",
               "label", "parameters", "status", "error", "stop_reason", "source", "h", "has_truth", "degrade",
               "input_kind", "shape_kind", "topology_vs_data_detail"}

#: the note above a table whose phantom has no ground truth (a user volume without ``truth=``)
NO_TRUTH_NOTE = "no ground truth: data fidelity and mesh quality only"


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


#: a table's name for the input a method received (:attr:`phantoms.Volume.kind`)
INPUT_TITLES = {"sdf": "signed distance", "mask": "mask", "intensity": "intensity image"}


def complete_inputs(df):
    """``df`` with the input of a cell that ended before its volume was read (a user volume's timeout or failure:
    ``N`` 0, ``input_kind`` unknown) taken from a cell of the same phantom, variant, degradation and noise that
    read it — so it sits in that input's table and board instead of one of its own."""
    if not len(df) or "N" not in df.columns:
        return df
    import pandas as pd

    n = pd.to_numeric(df["N"], errors="coerce")
    unknown = ~(n > 0)
    if not unknown.any():
        return df
    keys = [k for k in ("phantom", "variant", "degrade", "noise") if k in df.columns]
    cols = [c for c in ("N", "input_kind") if c in df.columns]
    known = df[~unknown].drop_duplicates(keys).set_index(keys)[cols]
    d = df.copy()
    for i in d.index[unknown]:
        key = tuple(d.at[i, k] for k in keys)
        if key in known.index:
            for c in cols:
                v = known.loc[key, c]
                d.at[i, c] = v if not isinstance(v, pd.Series) else v.iloc[0]
    return d


def phantom_label(name: str) -> str:
    """A phantom's short name for titles, headers and charts: a file's stem (``volume:/scans/ct_01.nii.gz?label=3``
    → ``ct_01 (label=3)``); a built-in's name as it is.  The full spec goes in a legend."""
    from phantoms.registry import MESH_PREFIX, VOLUME_PREFIX

    text = str(name)
    for prefix in (VOLUME_PREFIX, MESH_PREFIX):
        if text.startswith(prefix):
            path, _, opts = text[len(prefix):].partition("?")
            stem = path.replace("\\", "/").rstrip("/").rsplit("/", 1)[-1]
            for suffix in (".nii.gz", ".tar.gz"):
                if stem.lower().endswith(suffix):
                    stem = stem[: -len(suffix)]
                    break
            else:
                stem = stem.rsplit(".", 1)[0] if "." in stem[1:] else stem
            return stem + (f" ({opts.replace('&', ', ')})" if opts else "")
    return text


def input_title(kind: str, degrade: str = "none") -> str:
    """What the methods of a table were given: ``signed distance`` or ``mask (thick_slices@3+mask)``."""
    name = INPUT_TITLES.get(str(kind), str(kind))
    return name if str(degrade) in ("none", "", "nan") else f"{name} ({degrade})"


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


#: metrics whose best is the truth's value: without a truth none is marked (χ = 2 on a skull whose reference has
#: χ = 0 would reward closing its openings)
TOPOLOGY_METRICS = ("euler", "components")


def best_rule(metric: str, genus: int = 0, truth: bool = True, components: int = 1):
    """The registry's rule for ``metric``; the targets of the topology columns are the truth's: ``components``
    surfaces and the Euler characteristic 2·components − 2·genus (``genus`` summed over the components).
    ``truth`` False (the cells have no ground truth): None for the topology metrics — no target to be best at."""
    m = METRICS.get(metric)
    if m is None or m.best is None or (not truth and metric in TOPOLOGY_METRICS):
        return None
    if metric == "euler":
        return ("target", 2 * components - 2 * genus)
    if metric == "components" and isinstance(m.best, tuple):
        return ("target", components)
    return m.best


def _numeric(series):
    import pandas as pd

    return pd.to_numeric(series.map(lambda x: float(x) if isinstance(x, (bool, np.bool_)) else x), errors="coerce")


def _best_index(vals: np.ndarray, rule, metric: str | None = None) -> int | None:
    """The index of the unique best of ``vals`` (float array, NaN = no value) under ``rule``; None when the best
    is shared (equal values, or with ``metric`` equal at its resolution) or there are fewer than 2 values."""
    ok = np.isfinite(vals)
    if ok.sum() < 2:
        return None
    if rule in ("min", "max"):
        score = vals if rule == "min" else -vals
    elif isinstance(rule, tuple) and rule[0] == "target":
        score = np.abs(vals - rule[1])
    else:
        return None
    score = np.where(ok, score, np.inf)
    i = int(np.argmin(score))
    others = np.flatnonzero(ok)
    others = others[others != i]
    if np.any(np.isclose(score[others], score[i], rtol=1e-9, atol=1e-12)):
        return None
    if metric is not None:
        from bench.metrics.tolerances import same_within_tolerance

        if any(same_within_tolerance(metric, float(vals[i]), float(vals[j])) for j in others):
            return None
    return i


def best_mask(series, rule, metric: str | None = None) -> np.ndarray:
    """Which entry of ``series`` is the unique best under ``rule``: one entry at most — nothing when the best is
    shared (equal values, or with ``metric`` values equal at its resolution, the quality gate's tolerance) or
    there are fewer than 2 values."""
    vals = _numeric(series).to_numpy(float)
    mask = np.zeros(len(vals), bool)
    i = _best_index(vals, rule, metric)
    if i is not None:
        mask[i] = True
    return mask


#: what each flag means (the badge's tooltip); docs/METRICS.md has the definitions
FLAG_TITLES = {
    "topology_mismatch": "Euler characteristic or number of components differs from the truth's",
    "dropped_components": "fewer components than the truth (a part was dropped)",
    "missing_parts": ("more than 0.5 % of the true surface is farther than 2 h from the mesh (coverage_pct < 99.5): "
                      "never marked best"),
    "self_intersecting": "some non-adjacent faces intersect",
    "not_converged": ("the method stopped on max_iter, line_search_floor, diverged or sign_guard (rolled back to an "
                      "earlier iterate)"),
    "inside_disagrees": ("no ground truth: more than 2 % of the grid samples with |φ| > h/2 lie on the other side of "
                         "the mesh (sign_err_pct)"),
    "topology_vs_data": ("the mesh's parts, voids or handles differ from the input's digital topology "
                         "(topology_vs_data_detail; without a ground truth the mesh is not usable)"),
}


def status_badges(status: str, flags, valid: bool, details=()) -> str:
    """The status cell: the status text (a red ``invalid`` / grey ``failed`` badge when no seed gave a valid
    result, a neutral ``skipped`` one when the method declined the input) followed by one amber badge per flag,
    named in text (the report's CSS colours ``.badge``); ``details``: the ``topology_vs_data_detail`` texts of the
    row's cells, shown after the badges (what differs from the data, in words)."""
    text = html.escape(str(status))
    if not valid and str(status).strip() == "skipped":     # the method declined this input: not a failure
        text = f'<span class="badge badge-skipped" title="the method does not take this input">{text}</span>'
    elif not valid:
        kind = "invalid" if "invalid" in str(status) else "failed"
        text = f'<span class="badge badge-{kind}" title="no valid result: never ranked best">{text}</span>'
    for f in flags or ():
        title = html.escape(FLAG_TITLES.get(f, "suspect result"))
        text += f' <span class="badge badge-flag" title="{title}">{html.escape(f)}</span>'
    if details and "topology_vs_data" in (flags or ()):
        text += "".join(f' <small class="flag-detail">{html.escape(x)}</small>' for x in details)
    return text


def ci_half_width(values: np.ndarray) -> float | None:
    """Half-width of the 95 % confidence interval of the mean of ``values`` (Student t; None below 2 values or
    when they are all equal)."""
    if len(values) < 2 or np.ptp(values) == 0:
        return None
    return float(_t975(len(values) - 1) * values.std(ddof=1) / np.sqrt(len(values)))


@functools.lru_cache(maxsize=None)
def _t975(dof: int) -> float:
    from scipy import stats

    return float(stats.t.ppf(0.975, dof))


def _method_rows(d, idx: np.ndarray, num: dict[str, np.ndarray], metrics: list[str]) -> list[dict]:
    """One row per method label of the table's rows ``idx``: the mean of each metric over its ok cells (over
    all when none is ok: such a row is shown, below the valid ones, and never marked best); ``num``: the numeric
    metric columns of the whole frame (converted once)."""
    labels = d["label"].to_numpy()[idx]
    status = d["status"].to_numpy()[idx]
    flags_col = d["flags"].to_numpy()[idx] if "flags" in d.columns else np.array([""] * len(idx), object)
    detail_col = (d["topology_vs_data_detail"].to_numpy()
                  if "topology_vs_data_detail" in d.columns else np.array([""] * len(d), object))
    rows = []
    for label in dict.fromkeys(labels):
        mine = labels == label
        ok = mine & (status == "ok")
        use = idx[ok] if ok.any() else idx[mine]
        rec: dict[str, Any] = {"method": label, "_ci": {}}
        for m in metrics:
            if m not in num:
                continue
            vals = num[m][use]
            vals = vals[np.isfinite(vals)]
            rec[m] = float(vals.mean()) if len(vals) else np.nan
            if _dtype(m) != "bool":                     # a mean of yes/no is a share, shown as such
                rec["_ci"][m] = ci_half_width(vals)
        chosen = flags_col[ok] if ok.any() else flags_col[mine]
        flags = sorted({f for v in chosen if isinstance(v, str) for f in v.split(";") if f})
        told = detail_col[use]
        details = list(dict.fromkeys(v for v in told if isinstance(v, str) and v.strip()))
        statuses = list(status[mine])
        text = statuses[0] if len(set(statuses)) == 1 else ", ".join(f"{x}×{statuses.count(x)}"
                                                                     for x in sorted(set(statuses)))
        if mine.sum() > 1:
            text += f" (mean of {int(ok.sum())}/{int(mine.sum())} seeds)"
        rec.update(status=text, _flags=flags, _details=details, _valid=bool(ok.any()), _unflagged=not flags)
        rows.append(rec)
    # validity first: valid unflagged methods, then valid flagged ones, then those without a valid result (only
    # valid ones can be "best")
    return sorted(rows, key=lambda r: (not r["_valid"], not r["_unflagged"]))


@functools.lru_cache(maxsize=256)
def phantom_topology(phantom: str) -> tuple[int, int]:
    """The truth's number of surfaces and summed genus for the phantom named ``phantom`` — the targets of the
    components and Euler characteristic columns; (1, 0) when the name does not resolve (a file that moved)."""
    from phantoms import get_phantom

    try:
        ph = get_phantom(phantom)
    except Exception:  # noqa: BLE001 — a file phantom that moved, an unreadable volume: the report still renders
        return 1, 0
    return int(getattr(ph, "n_components", 1) or 1), int(getattr(ph, "genus", 0) or 0)


def _source(sub) -> str:
    """What resolves a table's phantom: the rows' ``source`` (a dataset file) or the phantom name."""
    if "source" in sub.columns:
        vals = [str(x) for x in sub["source"] if isinstance(x, str) and x]
        if vals:
            return vals[0]
    return str(sub["phantom"].iloc[0])


def without_truth(sub) -> bool:
    """True when no row of the table had a ground truth (``has_truth`` false, or no truth metric at all)."""
    from bench.metrics.registry import METRICS

    if "has_truth" in sub.columns:
        flags = sub["has_truth"].map(lambda x: str(x).strip().lower() in ("true", "1", "1.0", "yes"))
        if sub["has_truth"].notna().any():
            return not bool(flags.any())
    truth_cols = [k for k, m in METRICS.items() if m.kind in ("distance", "distance_h", "truth") and k in sub.columns]
    return bool(truth_cols) and bool(sub[truth_cols].isna().all().all()) and bool((sub["status"] == "ok").any())


def _marked_html(t: list[dict], metrics: list[str], topology: tuple[int, int], truth: bool = True) -> str:
    cols = [c for c in metrics if any(c in r for r in t)]
    marks = {}
    components, genus = topology
    for m in cols:
        rule = best_rule(m, genus, truth, components)
        # an invalid or failed result is never best
        vals = np.array([r.get(m, np.nan) if r["_valid"] and "missing_parts" not in r["_flags"] else np.nan
                         for r in t], float)
        marks[m] = _best_index(vals, rule, metric=m) if rule is not None else None
    head = "".join(f"<th>{html.escape(c)}</th>" for c in ["method", "status", *cols])
    body = []
    for i, r in enumerate(t):
        cells = [html.escape(str(r["method"])),
                 status_badges(r["status"], r["_flags"], r["_valid"], r.get("_details", ()))]
        for m in cols:
            x = fmt_value(r.get(m, np.nan), m)
            ci = r["_ci"].get(m)
            if ci:
                x += f' <span class="ci" title="95 % interval of the mean over seeds">± {fmt_value(ci, m)}</span>'
            cells.append(f'<span class="best" title="best">{x}</span>' if marks[m] == i else x)
        body.append("<tr>" + "".join(f"<td>{c}</td>" for c in cells) + "</tr>")
    # method, then status with its flag badges: the columns that say what a row is come first (sticky)
    return ('<table class="dataframe summary">\n<thead>\n<tr style="text-align: right;">' + head
            + "</tr>\n</thead>\n<tbody>\n" + "\n".join(body) + "\n</tbody>\n</table>")


def summary_tables(df) -> list[dict]:
    """One table per phantom × noise (× variant × N): ``[{"title", "phantom", "noise", "html", "n_methods",
    "cells", "note"}]`` (``cells``: method label → the cell id its row's mesh viewer shows, the first seed's;
    ``note``: :data:`NO_TRUTH_NOTE` for a phantom without ground truth — its truth columns are left out)."""
    from bench.metrics.registry import METRICS

    metrics = _metric_columns(df)
    keys = ["phantom", "degrade", "input_kind", "noise", "snr_requested", "variant", "N"]
    d = complete_inputs(df.reset_index(drop=True))
    for col, default in (("degrade", "none"), ("input_kind", "sdf")):      # runs from before degradations
        d[col] = d[col].fillna(default).astype(str) if col in d.columns else default
    d["snr_requested"] = d["snr_requested"].astype(object).where(d["snr_requested"].notna(), None)
    num = {m: _numeric(d[m]).to_numpy(float) for m in metrics if m in d.columns}
    groups: dict[tuple, list[int]] = {}
    for i, key in enumerate(zip(*(d[k].tolist() for k in keys))):
        groups.setdefault(key, []).append(i)
    multi_variant = d["variant"].nunique() > 1 or d["N"].nunique() > 1
    truth_kinds = ("distance", "distance_h", "truth")
    tables = []
    for (phantom, degrade, kind, noise, snr, variant, n), idx in groups.items():
        idx = np.asarray(idx)
        sub = d.iloc[idx]
        no_truth = without_truth(sub)
        shown = [m for m in metrics if not (no_truth and m in METRICS and METRICS[m].kind in truth_kinds)]
        t = _method_rows(d, idx, num, shown)
        title = f"{phantom_label(phantom)} — {input_title(kind, degrade)}, {noise_title(noise, snr)}"
        if multi_variant:
            title += f" — {variant}, N = {n}"
        cells = {}
        for lab, cid in zip(sub["label"], sub["cell_id"]):
            cells.setdefault(str(lab), str(cid))
        topology = (1, 0) if no_truth else phantom_topology(_source(sub))
        tables.append({"title": title, "phantom": phantom, "short": phantom_label(phantom), "noise": noise,
                       "html": _marked_html(t, shown, topology, not no_truth),
                       "n_methods": len(t), "cells": cells, "note": NO_TRUTH_NOTE if no_truth else ""})
    return tables
