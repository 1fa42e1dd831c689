"""Two runs side by side (``python -m bench compare RUN_A RUN_B``): what got better or worse from A to B.

Cells are matched by what they compute, not by the code or the parameters that computed them: phantom, variant,
N, noise, requested SNR, seed and method label (:data:`MATCH_KEY`).  A changed method parameter changes every
cell id, so ids are not used; a method whose label changed too (the default label names its parameters,
``mc_taubin[iterations=30]``) is matched by its method name when it is the only unmatched label of that method
in each run.  Changed parameters are listed per label.

Each metric of the quality gate (:data:`bench.perf.quality.TOLERANCES`) is judged as the gate judges it
(:func:`bench.perf.quality.compare_value`, the same tolerances): *better*, *worse* or *same* within the
tolerance.  A cell whose status or flags changed is listed apart (``ok`` → anything else, or a gained flag, is
worse).  Time is not judged (one cell's time is noise on a shared machine: ``bench perf`` measures it); the
median ratio of ``wall_s`` is shown.
"""

from __future__ import annotations

import html
import json
import math
from dataclasses import dataclass, field
from pathlib import Path

from bench.perf.quality import TOLERANCES, cells_from_rows, compare_value, stable_cell_id

from ..run.store import read_results
from .export import phantom_genus
from .tables import best_rule

__all__ = ["MATCH_KEY", "Comparison", "compare_runs", "compare_frames", "format_comparison", "comparison_html"]

#: the columns that say what a cell computes, without the code or the method's parameters
MATCH_KEY = ("phantom", "variant", "N", "noise", "snr_requested", "seed", "label")


@dataclass
class Comparison:
    """Everything ``compare`` prints: ``values`` one dict per compared metric value ``{cell, label, metric, a,
    b, limit, verdict}`` (verdict better / worse / same), ``states`` one per cell whose status or flags changed,
    ``parameters`` one per label whose method, parameters or label changed."""

    name_a: str
    name_b: str
    n_a: int
    n_b: int
    matched: int = 0
    metrics: list[str] = field(default_factory=list)
    values: list[dict] = field(default_factory=list)
    states: list[dict] = field(default_factory=list)
    parameters: list[dict] = field(default_factory=list)
    only_a: list[str] = field(default_factory=list)
    only_b: list[str] = field(default_factory=list)
    time_ratio: float | None = None
    time_cells: int = 0

    def count(self, verdict: str) -> int:
        return sum(v["verdict"] == verdict for v in self.values)

    def cells_with(self, verdict: str) -> set[str]:
        return ({v["cell"] for v in self.values if v["verdict"] == verdict}
                | {s["cell"] for s in self.states if s["verdict"] == verdict})

    @property
    def worse(self) -> bool:
        """Something got worse: a metric beyond its tolerance, a status or a gained flag."""
        return bool(self.cells_with("worse"))

    @property
    def unchanged(self) -> bool:
        return not (self.count("worse") or self.count("better") or self.states or self.parameters or self.only_a
                    or self.only_b)

    def summary_line(self) -> str:
        if self.unchanged:
            return (f"no change: {self.matched} cells matched, every metric within the quality gate's tolerances, "
                    "same status and flags")
        worse, better = self.cells_with("worse"), self.cells_with("better") - self.cells_with("worse")
        same = self.matched - len(worse | better)
        return (f"compare: {self.matched} cells matched — {len(worse)} worse, {len(better)} better, {same} same; "
                f"{self.count('worse')} values worse, {self.count('better')} better, {self.count('same')} same "
                f"(the quality gate's tolerances); {len(self.states)} status / flag changes; "
                f"{len(self.only_a)} only in A, {len(self.only_b)} only in B")


def _key_text(col: str, v) -> str:
    if v is None or (isinstance(v, float) and math.isnan(v)):
        return ""
    if col in ("N", "seed"):
        return str(int(float(v)))
    if col == "snr_requested":
        return repr(float(v))
    return str(v)


def _keyed(rows: list[dict], key_cols) -> dict[tuple, dict]:
    """``{key: row}``; a repeated key (should not happen) gets its occurrence number appended."""
    out: dict[tuple, dict] = {}
    for r in rows:
        key = tuple(_key_text(c, r.get(c)) for c in key_cols)
        n = 0
        while (key + ((n,) if n else ())) in out:
            n += 1
        out[key + ((n,) if n else ())] = r
    return out


def _label_pairs(a: dict, b: dict) -> dict[tuple, tuple]:
    """Unmatched keys of A and B paired by method name, where a method has one unmatched label in each run."""
    only_a, only_b = [k for k in a if k not in b], [k for k in b if k not in a]

    def labels(keys, rows):
        found: dict[str, set] = {}
        for k in keys:
            found.setdefault(str(rows[k].get("method")), set()).add(k[-1] if len(k) == len(MATCH_KEY) else None)
        return found

    la, lb = labels(only_a, a), labels(only_b, b)
    free_b = set(only_b)
    pairs = {}
    for method, labs in la.items():
        if len(labs) == 1 and len(lb.get(method, ())) == 1 and None not in labs | lb[method]:
            lab_b = next(iter(lb[method]))
            for k in only_a:
                if str(a[k].get("method")) == method and (k[:-1] + (lab_b,)) in free_b:
                    pairs[k] = k[:-1] + (lab_b,)
    return pairs


def _parameters_text(pa, pb) -> str:
    """The keys whose value changed: ``iterations: 30 → 5`` (the whole texts when they are not JSON objects)."""
    try:
        da, db = json.loads(pa), json.loads(pb)
        if isinstance(da, dict) and isinstance(db, dict):
            keys = sorted(set(da) | set(db))
            return ", ".join(f"{k}: {json.dumps(da.get(k, '(unset)'))} → {json.dumps(db.get(k, '(unset)'))}"
                             for k in keys if da.get(k, "(unset)") != db.get(k, "(unset)"))
    except (TypeError, ValueError):
        pass
    return f"{pa} → {pb}"


def _truth_value(metric: str, row: dict) -> float | None:
    """The truth's value of a target metric (Euler characteristic 2 − 2·genus, one component)."""
    rule = best_rule(metric, phantom_genus(str(row.get("source") or row.get("phantom"))))
    return float(rule[1]) if isinstance(rule, tuple) else None


def _flag_change(fa: list[str], fb: list[str]) -> str:
    return " ".join([f"+{f}" for f in fb if f not in fa] + [f"−{f}" for f in fa if f not in fb])


def _compare_pair(cmp: Comparison, name: str, ra: dict, rb: dict) -> None:
    qa, qb = (next(iter(cells_from_rows([r], "x").values())) for r in (ra, rb))
    if qa["status"] != qb["status"] or qa["flags"] != qb["flags"]:
        gained = set(qb["flags"]) - set(qa["flags"])
        worse = (qa["status"] == "ok" and qb["status"] != "ok") or (qb["status"] == qa["status"] and gained)
        better = (qb["status"] == "ok" and qa["status"] != "ok") or (qb["status"] == qa["status"] and not gained)
        cmp.states.append({"cell": name, "label": ra.get("label"), "status": f"{qa['status']} → {qb['status']}",
                           "flags": _flag_change(qa["flags"], qb["flags"]),
                           "verdict": "worse" if worse else "better" if better else "changed"})
    for metric in cmp.metrics:
        base, cur = qa["metrics"].get(metric), qb["metrics"].get(metric)
        if base is None or cur is None:
            continue  # not comparable (a failed cell has none): its status change says it
        tol = TOLERANCES[metric]
        truth = _truth_value(metric, ra) if tol.better == "target" else None
        status, _, limit = compare_value(metric, tol, base, cur, qa["flags"], truth)
        cmp.values.append({"cell": name, "label": ra.get("label"), "metric": metric, "a": base, "b": cur,
                           "limit": limit, "verdict": "same" if status == "ok" else status})


def compare_frames(df_a, df_b, name_a: str = "A", name_b: str = "B") -> Comparison:
    """The comparison of two results tables (pure: no I/O)."""
    rows_a = df_a.astype(object).where(df_a.notna(), None).to_dict("records")
    rows_b = df_b.astype(object).where(df_b.notna(), None).to_dict("records")
    a, b = _keyed(rows_a, MATCH_KEY), _keyed(rows_b, MATCH_KEY)
    pairs = {k: k for k in a if k in b}
    pairs.update(_label_pairs(a, b))
    cmp = Comparison(name_a, name_b, len(rows_a), len(rows_b), matched=len(pairs))
    cmp.metrics = [m for m in TOLERANCES if m in df_a.columns and m in df_b.columns]
    changed: dict[tuple, dict] = {}
    ratios = []
    for ka, kb in pairs.items():
        ra, rb = a[ka], b[kb]
        name = stable_cell_id(str(ra["cell_id"]))
        sig = (ra.get("label"), rb.get("label"), ra.get("method"), rb.get("method"), ra.get("parameters"),
               rb.get("parameters"))
        if sig[0] != sig[1] or sig[2] != sig[3] or sig[4] != sig[5]:
            changed.setdefault(sig, {"label": f"{sig[0]} → {sig[1]}" if sig[0] != sig[1] else str(sig[0]),
                                     "method": f"{sig[2]} → {sig[3]}" if sig[2] != sig[3] else str(sig[2]),
                                     "change": _parameters_text(sig[4], sig[5]), "cells": 0})["cells"] += 1
        _compare_pair(cmp, name, ra, rb)
        ta, tb = ra.get("wall_s"), rb.get("wall_s")
        if ra.get("status") == rb.get("status") == "ok" and ta and tb and ta > 0:
            ratios.append(float(tb) / float(ta))
    cmp.parameters = list(changed.values())
    matched_b = set(pairs.values())
    cmp.only_a = [stable_cell_id(str(a[k]["cell_id"])) for k in a if k not in pairs]
    cmp.only_b = [stable_cell_id(str(b[k]["cell_id"])) for k in b if k not in matched_b]
    if ratios:
        import numpy as np

        cmp.time_ratio, cmp.time_cells = float(np.median(ratios)), len(ratios)
    return cmp


def compare_runs(run_a: str | Path, run_b: str | Path) -> Comparison:
    """Read two run folders (:func:`bench.run.store.read_results`) and compare them."""
    return compare_frames(read_results(run_a), read_results(run_b), str(run_a), str(run_b))


def _num(v) -> str:
    if v is None:
        return "–"
    if isinstance(v, bool):
        return "yes" if v else "no"
    return f"{v:.4g}" if isinstance(v, float) else str(v)


def _value_line(v: dict) -> str:
    rel = ""
    if isinstance(v["a"], (int, float)) and not isinstance(v["a"], bool) and v["a"]:
        rel = f"{100 * (v['b'] - v['a']) / abs(v['a']):+.1f} %"
    limit = f"limit {_num(v['limit'])}" if v["limit"] is not None and v["verdict"] == "worse" else ""
    note = "; ".join(x for x in (rel, limit) if x)
    return f"  {v['cell']}  {v['metric']}: {_num(v['a'])} → {_num(v['b'])}" + (f"  ({note})" if note else "")


def format_comparison(cmp: Comparison) -> str:
    """The comparison as text: changed parameters, worse and better values, status / flag changes, unmatched
    cells, time, and the summary line last."""
    lines = [f"A: {cmp.name_a} ({cmp.n_a} cells)", f"B: {cmp.name_b} ({cmp.n_b} cells)"]
    for p in cmp.parameters:
        lines.append(f"changed: {p['label']} ({p['method']}, {p['cells']} cells): {p['change'] or 'same parameters'}")
    for verdict in ("worse", "better"):
        vals = [v for v in cmp.values if v["verdict"] == verdict]
        if vals:
            lines.append(f"{verdict} ({len(vals)} values in {len({v['cell'] for v in vals})} cells):")
            lines += [_value_line(v) for v in vals]
    if cmp.states:
        lines.append(f"status / flags changed ({len(cmp.states)} cells):")
        lines += [f"  {s['verdict']:<7} {s['cell']}  status {s['status']}" + (f"; flags {s['flags']}" if s["flags"]
                                                                              else "") for s in cmp.states]
    for side, cells in (("A", cmp.only_a), ("B", cmp.only_b)):
        if cells:
            lines.append(f"only in {side} ({len(cells)} cells):")
            lines += [f"  {c}" for c in cells]
    if cmp.time_ratio is not None:
        lines.append(f"time: median wall_s B / A = {cmp.time_ratio:.3g} over {cmp.time_cells} cells (not judged: "
                     "one cell's time is noise; `bench perf` measures speed)")
    lines.append(cmp.summary_line())
    return "\n".join(lines)


_STYLE = ("body{font:14px/1.4 system-ui,sans-serif;margin:2em;max-width:1200px}table{border-collapse:collapse;"
          "margin:.5em 0 1.5em}td,th{border:1px solid #ccc;padding:2px 8px;text-align:left}"
          ".worse{color:#b00}.better{color:#070}.summary{font-weight:bold}")


def _table(rows: list[dict], cols: list[str]) -> str:
    import pandas as pd

    if not rows:
        return "<p>none</p>"
    frame = pd.DataFrame([{c: (_num(r[c]) if c in ("a", "b", "limit") else r[c]) for c in cols} for r in rows])
    return frame.to_html(index=False, escape=True, border=0, na_rep="–")


def comparison_html(cmp: Comparison) -> str:
    """A self-contained page with the content of :func:`format_comparison` (every text escaped)."""
    e = html.escape
    parts = [f"<!doctype html><html><head><meta charset='utf-8'><title>compare {e(cmp.name_a)} → {e(cmp.name_b)}"
             f"</title><style>{_STYLE}</style></head><body><h1>levelset-bench compare</h1>",
             f"<p>A: <code>{e(cmp.name_a)}</code> ({cmp.n_a} cells)<br>B: <code>{e(cmp.name_b)}</code> "
             f"({cmp.n_b} cells)</p>", f"<p class='summary'>{e(cmp.summary_line())}</p>",
             "<h2>Changed methods</h2>", _table(cmp.parameters, ["label", "method", "change", "cells"])]
    for verdict in ("worse", "better"):
        vals = [v for v in cmp.values if v["verdict"] == verdict]
        parts += [f"<h2 class='{verdict}'>{verdict.capitalize()} ({len(vals)} values)</h2>",
                  _table(vals, ["cell", "metric", "a", "b", "limit"])]
    parts += ["<h2>Status / flags changed</h2>", _table(cmp.states, ["cell", "verdict", "status", "flags"])]
    for side, cells in (("A", cmp.only_a), ("B", cmp.only_b)):
        parts += [f"<h2>Only in {side}</h2>", _table([{"cell": c} for c in cells], ["cell"])]
    if cmp.time_ratio is not None:
        parts.append(f"<p>time: median wall_s B / A = {cmp.time_ratio:.3g} over {cmp.time_cells} cells (not "
                     "judged)</p>")
    parts.append(f"<p>Metrics judged with the quality gate's tolerances: {e(', '.join(cmp.metrics))}.</p>"
                 "</body></html>")
    return "\n".join(parts)
