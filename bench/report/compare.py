"""Two runs side by side (``python -m bench compare RUN_A RUN_B``): what got better or worse from A to B.

Cells are matched by what they compute, not by the code or the parameters that computed them: phantom, variant,
N, noise, requested SNR, seed and method label (:data:`MATCH_KEY`).  A changed method parameter changes every
cell id, so ids are not used; a method whose label changed too (the default label names its parameters,
``mc_taubin[iterations=30]``) is matched by its method name when it is the only unmatched label of that method
in each run.  Changed parameters are listed per label.

Each metric of the quality gate (:data:`bench.metrics.tolerances.TOLERANCES`) is judged as the gate judges it
(:func:`bench.metrics.tolerances.compare_value`, the quality gate's tolerances): *better*, *worse* or *same* within the
tolerance.  A cell whose status or flags changed is listed apart (``ok`` → anything else, or a gained flag, is
worse).  Time is not judged (one cell's time is noise on a shared machine: ``bench perf`` measures it); the
median ratio of ``wall_s`` is shown.

Conclusions (:func:`conclude`): per method label × key metric (:data:`KEY_METRICS`), over the inputs both runs
share (seeds, shapes), the median change B − A with a distribution-free 95 % interval for it (order statistics),
the count of inputs better / worse / the same within the gate's tolerance, and the Wilcoxon signed-rank test of
the paired changes, Holm-corrected over the tests run (a label × metric whose values did not move is "no change"
and not tested).  A change is *significant* at α = 0.05.  With fewer than
:data:`bench.report.pairwise.MIN_PAIRED` shared inputs no test is possible and the per-cell tolerances decide,
as the quality gate does.  :attr:`Comparison.worse` (``--fail-on-worse``) is a status or gained flag, a
significant worsening of a key metric, or — for a label with too few inputs to test — a value beyond its
tolerance.
"""

from __future__ import annotations

import html
import json
import math
from dataclasses import dataclass, field
from pathlib import Path

from bench.metrics.tolerances import TOLERANCES, cells_from_rows, compare_value

from ..run.results import read_results
from ..terminal import printable
from .pairwise import ALPHA, MIN_PAIRED, holm, median_interval, signed_rank_test
from .tables import best_rule, phantom_topology

__all__ = ["MATCH_KEY", "KEY_METRICS", "Comparison", "compare_runs", "compare_frames", "conclude", "format_comparison",
           "comparison_html", "short_name", "why_nothing_matched"]

#: the columns that say what a cell computes, without the code or the method's parameters
MATCH_KEY = ("phantom", "variant", "N", "noise", "snr_requested", "seed", "label")
#: the metrics a conclusion is drawn on (the leaderboard's key metrics with and without truth)
KEY_METRICS = ("hausdorff_h", "mean_dist_h", "sdf_rms_h", "phi_mean_h", "roughness_deg")


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
    #: one per label × key metric (:func:`conclude`)
    changes: list[dict] = field(default_factory=list)
    #: why no cell matched (:func:`why_nothing_matched`), empty when some did
    unmatched_reason: str = ""

    def count(self, verdict: str) -> int:
        return sum(v["verdict"] == verdict for v in self.values)

    def cells_with(self, verdict: str) -> set[str]:
        return ({v["cell"] for v in self.values if v["verdict"] == verdict}
                | {s["cell"] for s in self.states if s["verdict"] == verdict})

    @property
    def worse(self) -> bool:
        """Something got worse: a status or a gained flag, a significant worsening of a key metric, or a value
        beyond its tolerance for a label with too few shared inputs to test."""
        if any(s["verdict"] == "worse" for s in self.states):
            return True
        if any(c["verdict"] == "significantly worse" for c in self.changes):
            return True
        tested = {c["label"] for c in self.changes if c["n"] >= MIN_PAIRED}
        return any(v["verdict"] == "worse" and v["label"] not in tested for v in self.values)

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
        sig = {v: sum(c["verdict"] == v for c in self.changes) for v in ("significantly worse", "significantly better")}
        return (f"compare: {self.matched} cells matched — {sig['significantly worse']} method × metric significantly "
                f"worse, {sig['significantly better']} significantly better; per cell "
                f"{len(worse)} worse, {len(better)} better, {same} same; "
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
    """Unmatched keys of A and B paired by method name: where a method has one unmatched label in each run, those
    two labels; where it has several, each label of A with the one label of B whose cells ran the same parameters
    (a renamed label) when exactly one does."""
    only_a, only_b = [k for k in a if k not in b], [k for k in b if k not in a]

    def labels(keys, rows):
        found: dict[str, dict] = {}
        for k in keys:
            lab = k[-1] if len(k) == len(MATCH_KEY) else None
            found.setdefault(str(rows[k].get("method")), {}).setdefault(lab, set()).add(str(rows[k].get("parameters")))
        return found

    la, lb = labels(only_a, a), labels(only_b, b)
    free_b = set(only_b)
    pairs = {}
    for method, labs in la.items():
        other = lb.get(method, {})
        if None in labs or None in other:
            continue
        if len(labs) == 1 and len(other) == 1:
            renamed = {next(iter(labs)): next(iter(other))}
        else:
            renamed = {}
            for lab, params in labs.items():
                same = [o for o, p in other.items() if p == params]
                if len(same) == 1 and sum(p == params for p in labs.values()) == 1:
                    renamed[lab] = same[0]
        for k in only_a:
            if str(a[k].get("method")) == method and k[-1] in renamed and (k[:-1] + (renamed[k[-1]],)) in free_b:
                pairs[k] = k[:-1] + (renamed[k[-1]],)
    return pairs


def why_nothing_matched(rows_a: list[dict], rows_b: list[dict]) -> str:
    """Why two results tables share no cell, in one line with what to do: no input (phantom, variant, N, noise,
    SNR, seed) in both, or shared inputs whose method labels differ and could not be paired by method."""
    if not rows_a or not rows_b:
        return f"run {'A' if not rows_a else 'B'} has no cells"
    inputs_a = {tuple(_key_text(c, r.get(c)) for c in MATCH_KEY[:-1]) for r in rows_a}
    inputs_b = {tuple(_key_text(c, r.get(c)) for c in MATCH_KEY[:-1]) for r in rows_b}
    if not inputs_a & inputs_b:
        ph_a = sorted({str(r.get("phantom")) for r in rows_a})
        ph_b = sorted({str(r.get("phantom")) for r in rows_b})
        return (f"no input (phantom, variant, N, noise, SNR, seed) is in both runs (phantoms of A: "
                f"{', '.join(ph_a[:6])}; of B: {', '.join(ph_b[:6])}): compare runs of the same grid")
    lab_a = list(dict.fromkeys(str(r.get("label")) for r in rows_a))
    lab_b = list(dict.fromkeys(str(r.get("label")) for r in rows_b))
    return (f"the runs share {len(inputs_a & inputs_b)} input(s) but no method label (A: {', '.join(lab_a[:6])}; "
            f"B: {', '.join(lab_b[:6])}), and no label could be paired by its method (one label of a method in each "
            "run, or labels of the same parameters): give the methods the same labels, e.g. --method LABEL=NAME:...")


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
    """The truth's value of a target metric (its components; Euler characteristic 2·components − 2·genus)."""
    components, genus = phantom_topology(str(row.get("source") or row.get("phantom")))
    rule = best_rule(metric, genus, True, components)
    return float(rule[1]) if isinstance(rule, tuple) else None


def _flag_change(fa: list[str], fb: list[str]) -> str:
    return " ".join([f"+{f}" for f in fb if f not in fa] + [f"−{f}" for f in fa if f not in fb])


def _pair_label(ra: dict, rb: dict) -> str:
    la, lb = str(ra.get("label")), str(rb.get("label"))
    return la if la == lb else f"{la} → {lb}"


def short_name(r: dict) -> str:
    """A cell's readable name: phantom/N/noise[@SNR]/seed/label (the variant, degradation when not plain)."""
    parts = [str(r.get("phantom"))]
    if r.get("variant") not in (None, "", "sdf"):
        parts.append(str(r.get("variant")))
    parts.append(f"N{_key_text('N', r.get('N'))}")
    if r.get("degrade") not in (None, "", "none"):
        parts.append(str(r.get("degrade")))
    snr = _key_text("snr_requested", r.get("snr_requested"))
    parts.append(str(r.get("noise")) + (f"@{float(snr):g}dB" if snr else ""))
    parts.append(f"s{_key_text('seed', r.get('seed'))}")
    return "/".join(parts + [str(r.get("label"))]).replace(" ", "_")


def conclude(cmp: Comparison) -> list[dict]:
    """Per label × key metric: the paired changes over the shared inputs, their median and interval, the test
    (see the module docstring).  Sorted: significant worsening first."""
    import numpy as np

    groups: dict[tuple[str, str], list[dict]] = {}
    for v in cmp.values:
        if v["metric"] in KEY_METRICS and isinstance(v["a"], (int, float)) and isinstance(v["b"], (int, float)):
            groups.setdefault((v["label"], v["metric"]), []).append(v)
    out = []
    for (label, metric), vals in groups.items():
        sign = -1.0 if TOLERANCES[metric].better == "max" else 1.0
        d = np.array([sign * (float(v["b"]) - float(v["a"])) for v in vals])
        moved = np.array([v["verdict"] != "same" for v in vals])
        rec = {"label": label, "metric": metric, "n": len(d), "worse_n": int(((d > 0) & moved).sum()),
               "better_n": int(((d < 0) & moved).sum()), "median": float(sign * np.median(d)),
               "interval": tuple(sign * x for x in median_interval(d)), "p": math.nan, "p_holm": math.nan,
               "lead": 0.0}
        rec["same_n"] = rec["n"] - rec["worse_n"] - rec["better_n"]
        if len(d) >= MIN_PAIRED and moved.any():
            rec["p"], rec["lead"] = signed_rank_test(np.where(moved, d, 0.0))
        out.append(rec)
    for rec, ph in zip(out, holm([r["p"] for r in out])):
        rec["p_holm"] = ph
        if rec["n"] < MIN_PAIRED:
            rec["verdict"] = "not tested"
        elif not (rec["worse_n"] or rec["better_n"]):
            rec["verdict"] = "no change"
        elif ph < ALPHA and rec["lead"] != 0:
            rec["verdict"] = "significantly worse" if rec["lead"] < 0 else "significantly better"
        else:
            rec["verdict"] = "no significant change"
    order = {"significantly worse": 0, "significantly better": 1, "no significant change": 2, "not tested": 3,
             "no change": 4}
    return sorted(out, key=lambda r: (order[r["verdict"]], r["label"], KEY_METRICS.index(r["metric"])))


def change_line(c: dict) -> str:
    """One conclusion in words: ``label: metric significantly worse — worse on 9, better on 1, the same on 0
    of 10 inputs; median change +0.31 (95 % interval +0.12 … +0.5); p = 0.004``."""
    unit = " h" if c["metric"].endswith("_h") else "°" if c["metric"].endswith("_deg") else ""
    lo, hi = sorted(c["interval"])
    head = f"{c['label']}: {c['metric']} {c['verdict']}"
    if c["verdict"] == "no change":
        return f"{head} on {c['n']} inputs (every value within the gate's tolerance)"
    counts = f"worse on {c['worse_n']}, better on {c['better_n']}, the same on {c['same_n']} of {c['n']} inputs"
    med = f"median change {c['median']:+.3g}{unit} (95 % interval {lo:+.3g} … {hi:+.3g}{unit})"
    test = (f"too few inputs to test (fewer than {MIN_PAIRED}): judged per cell" if c["verdict"] == "not tested"
            else f"p = {c['p_holm']:.2g}" if c["p_holm"] >= 0.001 else "p < 0.001")
    return f"{head} — {counts}; {med}; {test}"


def _compare_pair(cmp: Comparison, name: str, ra: dict, rb: dict) -> None:
    qa, qb = (next(iter(cells_from_rows([r], "x").values())) for r in (ra, rb))
    if qa["status"] != qb["status"] or qa["flags"] != qb["flags"]:
        gained = set(qb["flags"]) - set(qa["flags"])
        declined = "skipped" in (qa["status"], qb["status"])   # a method that declines an input: not comparable
        worse = not declined and ((qa["status"] == "ok" and qb["status"] != "ok") or (qb["status"] == qa["status"]
                                                                                       and gained))
        better = not declined and ((qb["status"] == "ok" and qa["status"] != "ok") or (qb["status"] == qa["status"]
                                                                                        and not gained))
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
        cmp.values.append({"cell": name, "label": _pair_label(ra, rb), "metric": metric, "a": base, "b": cur,
                           "limit": limit, "verdict": "same" if status == "ok" else status})


def compare_frames(df_a, df_b, name_a: str = "A", name_b: str = "B") -> Comparison:
    """The comparison of two results tables (pure: no I/O)."""
    rows_a = df_a.astype(object).where(df_a.notna(), None).to_dict("records")
    rows_b = df_b.astype(object).where(df_b.notna(), None).to_dict("records")
    a, b = _keyed(rows_a, MATCH_KEY), _keyed(rows_b, MATCH_KEY)
    pairs = {k: k for k in a if k in b}
    pairs.update(_label_pairs(a, b))
    cmp = Comparison(name_a, name_b, len(rows_a), len(rows_b), matched=len(pairs))
    if not pairs:
        cmp.unmatched_reason = why_nothing_matched(rows_a, rows_b)
    cmp.metrics = [m for m in TOLERANCES if m in df_a.columns and m in df_b.columns]
    changed: dict[tuple, dict] = {}
    ratios = []
    for ka, kb in pairs.items():
        ra, rb = a[ka], b[kb]
        name = short_name(rb)
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
    cmp.only_a = [short_name(a[k]) for k in a if k not in pairs]
    cmp.only_b = [short_name(b[k]) for k in b if k not in matched_b]
    if ratios:
        import numpy as np

        cmp.time_ratio, cmp.time_cells = float(np.median(ratios)), len(ratios)
    cmp.changes = conclude(cmp)
    return cmp


def compare_runs(run_a: str | Path, run_b: str | Path) -> Comparison:
    """Read two run folders (:func:`bench.run.results.read_results`) and compare them."""
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
    if cmp.changes:
        lines.append(f"verdicts per method and key metric (paired over the inputs both runs share; Wilcoxon "
                     f"signed-rank, Holm-corrected over the {sum(not math.isnan(c['p']) for c in cmp.changes)} "
                     f"tests, α = {ALPHA}):")
        lines += ["  " + change_line(c) for c in cmp.changes]
        lines.append("per cell (the quality gate's tolerances):")
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


def _verdict_class(verdict: str) -> str:
    """The CSS class of a change's list item: ``worse`` or ``better`` when its verdict says so, else none."""
    return "worse" if "worse" in verdict else "better" if "better" in verdict else ""


def comparison_html(cmp: Comparison) -> str:
    """A self-contained page with the content of :func:`format_comparison` (every text escaped, its control
    characters shown as ``\\xNN``: :func:`bench.terminal.printable`)."""
    e = html.escape
    parts = [f"<!doctype html><html><head><meta charset='utf-8'><title>compare {e(cmp.name_a)} → {e(cmp.name_b)}"
             f"</title><style>{_STYLE}</style></head><body><h1>levelset-bench compare</h1>",
             f"<p>A: <code>{e(cmp.name_a)}</code> ({cmp.n_a} cells)<br>B: <code>{e(cmp.name_b)}</code> "
             f"({cmp.n_b} cells)</p>", f"<p class='summary'>{e(cmp.summary_line())}</p>",
             "<h2>Changed methods</h2>", _table(cmp.parameters, ["label", "method", "change", "cells"]),
             f"<h2>Verdicts per method and key metric</h2><p>Paired over the inputs both runs share; Wilcoxon "
             f"signed-rank, Holm-corrected, α = {ALPHA}.</p><ul>"
             + "".join(f"<li class='{_verdict_class(c['verdict'])}'>{e(change_line(c))}</li>" for c in cmp.changes)
             + "</ul>",
             "<h2>Per cell</h2>"]
    for verdict in ("worse", "better"):
        vals = [v for v in cmp.values if v["verdict"] == verdict]
        parts += [f"<details><summary class='{verdict}'>{verdict.capitalize()} ({len(vals)} values)</summary>",
                  _table(vals, ["cell", "metric", "a", "b", "limit"]), "</details>"]
    parts += ["<h2>Status / flags changed</h2>", _table(cmp.states, ["cell", "verdict", "status", "flags"])]
    for side, cells in (("A", cmp.only_a), ("B", cmp.only_b)):
        parts += [f"<h2>Only in {side}</h2>", _table([{"cell": c} for c in cells], ["cell"])]
    if cmp.time_ratio is not None:
        parts.append(f"<p>time: median wall_s B / A = {cmp.time_ratio:.3g} over {cmp.time_cells} cells (not "
                     "judged)</p>")
    parts.append(f"<p>Metrics judged with the quality gate's tolerances: {e(', '.join(cmp.metrics))}.</p>"
                 "</body></html>")
    return printable("\n".join(parts))
