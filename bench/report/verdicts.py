"""Who wins: a leaderboard over the run's cells and whether the differences are significant.

Ranking (:func:`block_ranks`)
    A *block* is one input — (phantom, variant, N, noise, SNR, seed) — on which every method was run. Within a
    block the methods are ranked on one key metric: values the same at the metric's resolution (the quality
    gate's tolerance, :func:`bench.metrics.tolerances.same_within_tolerance`) share the average of their ranks; a
    cell that is not ``ok`` (invalid, failed, timeout) or has no value ranks last.  Ranks, never raw values,
    are then averaged over blocks, so a shape with large distances does not outweigh one with small ones.

Boards (:func:`leaderboards`)
    One board per degradation of the input (a mask, a partial-volume image ...: Hausdorff and mean distance,
    |volume error|, roughness), then one for the undegraded cells with ground truth (key metrics: Hausdorff
    and mean distance, SDF agreement, roughness) and one for truth-free cells (SDF agreement, |φ| on the mesh,
    roughness).  A method's row: its mean rank per key metric, wins / ties / losses against the best on the
    board's first metric (win: alone at the best value; tie: the best value shared), the share of its cells that
    are valid and unflagged, and usable, its median time.  Mean ranks use only the blocks every method has.

The verdict (:func:`bench.report.pairwise.verdict`)
    A board answers "which method gives a mesh I can use, closest to the truth?": it ranks an invalid or unusable
    result (:func:`bench.metrics.flags.is_usable`) last, and its verdict comes from one test, the Wilcoxon
    signed-rank test of every pair on the inputs both have, Holm-corrected (:mod:`bench.report.pairwise` says
    why this test).  The board's sentence, the order of its rows (the recommended method first, then the methods
    no other beats, then the rest, each by mean rank) and the bars of its diagram (methods the pairwise test
    cannot tell apart) all come from it.  Its twin ``raw_board`` ranks the raw values, usable or not ("which is
    closest to the truth?"); where its leader differs, the sentence says so and why.

A check (:func:`significance`)
    On the board's first metric: with three or more methods the Friedman test over methods × blocks and the
    Nemenyi post-hoc critical difference CD = q_α √(k(k + 1) / 6N) (Demšar 2006; q_α from the studentized range
    distribution, scipy.stats), with two methods the Wilcoxon signed-rank test; α = 0.05; fewer than
    :data:`MIN_BLOCKS` blocks: no test.  It is not the verdict: where it separates a pair the pairwise test does
    not (or the reverse), the board says so in words (``tests_differ``), naming both numbers.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from bench.metrics.flags import is_usable
from bench.metrics.registry import METRICS
from bench.metrics.tolerances import same_within_tolerance

from .pairwise import not_told_apart, pairwise, recommendation, signed_rank_test, verdict

__all__ = ["BLOCK_KEYS", "TRUTH_KEYS", "DEGRADED_KEYS", "FREE_KEYS", "MIN_BLOCKS", "ALPHA", "block_ranks",
           "leaderboards", "board", "significance", "tests_differ", "cd_figure", "board_html"]

BLOCK_KEYS = ("phantom", "variant", "N", "degrade", "noise", "snr_requested", "seed")
#: key metrics of the board with ground truth: (column, what it measures)
TRUTH_KEYS = (("hausdorff_h", "distance (Hausdorff)"), ("mean_dist_h", "distance (mean)"),
              ("sdf_rms_h", "data fidelity"), ("roughness_deg", "smoothness"))
#: key metrics of a degraded input's board (a mask, a partial-volume image): the distances, the volume error
#: (smoothing shrinks, dilation grows), roughness; SDF agreement is left out (φ is the mask's distance, not the truth)
DEGRADED_KEYS = (("hausdorff_h", "distance (Hausdorff)"), ("mean_dist_h", "distance (mean)"),
                 ("volume_err_pct", "volume error (|%|)"), ("roughness_deg", "smoothness"))
#: key metrics of the truth-free board
FREE_KEYS = (("sdf_rms_h", "data fidelity (SDF)"), ("phi_mean_h", "data fidelity (|φ|)"),
             ("roughness_deg", "smoothness"))
MIN_BLOCKS = 10
ALPHA = 0.05


def _num(v) -> float:
    try:
        x = float(v)
    except (TypeError, ValueError):
        return math.nan
    return x if math.isfinite(x) else math.nan


def _sign(metric: str) -> float:
    """+1 when smaller is better, −1 when larger is (the registry's ``best``)."""
    best = METRICS[metric].best if metric in METRICS else "min"
    return -1.0 if best == "max" else 1.0


def _rank_one(values: dict[str, float], metric: str) -> dict[str, float]:
    """Ranks (1 = best) of one block's values; equal at the metric's resolution → the average rank; NaN last."""
    s = _sign(metric)
    ok = sorted((s * v, m) for m, v in values.items() if not math.isnan(v))
    ranks: dict[str, float] = {}
    i = 0
    while i < len(ok):
        j = i
        while j + 1 < len(ok) and same_within_tolerance(metric, s * ok[i][0], s * ok[j + 1][0]):
            j += 1
        for k in range(i, j + 1):
            ranks[ok[k][1]] = (i + j) / 2 + 1
        i = j + 1
    bad = [m for m, v in values.items() if math.isnan(v)]
    for m in bad:
        ranks[m] = len(ok) + (len(bad) + 1) / 2
    return ranks


def _flagged(r: dict) -> bool:
    flags = str(r.get("flags") if r.get("flags") is not None else "").strip(" ;")
    return flags not in ("", "nan", "None")


def _is_true(v) -> bool:
    return str(v).strip().lower() in ("true", "1", "1.0", "yes")


def _blocks(rows: list[dict], labels: list[str]) -> dict[tuple, dict[str, dict]]:
    """``{block key: {label: row}}`` for the blocks holding every label (the first row of a label wins)."""
    blocks: dict[tuple, dict[str, dict]] = {}
    for r in rows:
        key = tuple(str(r.get(k)) for k in BLOCK_KEYS)
        blocks.setdefault(key, {}).setdefault(str(r.get("label")), r)
    return {k: v for k, v in blocks.items() if all(lab in v for lab in labels)}


def _value(r: dict, metric: str) -> float:
    """The cell's value on ``metric`` (NaN unless ok); a ``("target", t)`` metric as its distance to t."""
    if r.get("status") != "ok":
        return math.nan
    best = METRICS[metric].best if metric in METRICS else "min"
    return abs(_num(r.get(metric)) - best[1]) if isinstance(best, tuple) else _num(r.get(metric))


def block_ranks(rows: list[dict], metric: str, labels: list[str] | None = None) -> tuple[list[str], np.ndarray]:
    """(labels, ranks array of shape (blocks, methods)) on ``metric`` over the blocks every label has."""
    labels = labels or sorted({str(r.get("label")) for r in rows})
    blocks = _blocks(rows, labels)
    out = [[_rank_one({lab: _value(b[lab], metric) for lab in labels}, metric)[lab] for lab in labels]
           for _, b in sorted(blocks.items())]
    return labels, np.asarray(out, float).reshape(len(out), len(labels))


def significance(ranks: np.ndarray, labels: list[str], values: np.ndarray | None = None) -> dict[str, Any]:
    """The test on a (blocks × methods) rank matrix (see the module docstring): ``{"test", "n_blocks", "p",
    "cd", "mean_ranks", "cliques", "note"}``; ``cliques``: groups of methods not told apart (lists of labels)."""
    from scipy import stats

    n, k = ranks.shape if ranks.ndim == 2 else (0, len(labels))
    mean = {lab: float(ranks[:, i].mean()) if n else math.nan for i, lab in enumerate(labels)}
    out: dict[str, Any] = {"test": None, "n_blocks": int(n), "p": None, "cd": None, "mean_ranks": mean,
                           "cliques": [], "note": ""}
    if k < 2:
        out["note"] = "one method: nothing to compare"
        return out
    if n < MIN_BLOCKS:
        out["note"] = (f"{n} shared cells: too few for a significance test (at least {MIN_BLOCKS} are needed); "
                       "the ranks above are descriptive only")
        return out
    if k == 2:
        d = (values[:, 0] - values[:, 1]) if values is not None else (ranks[:, 0] - ranks[:, 1])
        d = d[np.isfinite(d)]
        p = signed_rank_test(d)[0]
        out.update(test="Wilcoxon signed-rank (two methods)", p=p)
        out["cliques"] = [list(labels)] if p >= ALPHA else []
    else:
        p = float(stats.friedmanchisquare(*[ranks[:, i] for i in range(k)]).pvalue) if np.ptp(ranks) > 0 else 1.0
        q = float(stats.studentized_range.ppf(1 - ALPHA, k, np.inf)) / math.sqrt(2.0)
        cd = q * math.sqrt(k * (k + 1) / (6.0 * n))
        out.update(test="Friedman + Nemenyi (critical difference)", p=p, cd=cd)
        order = sorted(labels, key=lambda lab: mean[lab])
        if p >= ALPHA:
            out["cliques"] = [order]
        else:
            cliques = []
            for i, a in enumerate(order):
                group = [b for b in order[i:] if mean[b] - mean[a] < cd]
                if len(group) > 1 and not any(set(group) <= set(c) for c in cliques):
                    cliques.append(group)
            out["cliques"] = cliques
    out["note"] = (f"{out['test']} on {n} shared cells, α = {ALPHA}: p = {out['p']:.3g}"
                   + (f", CD = {out['cd']:.2f} ranks" if out["cd"] else "")
                   + ("; it cannot tell apart " + "; ".join(" ~ ".join(c) for c in out["cliques"])
                      if out["cliques"] else "; every difference is significant"))
    return out


def _wtl(ranks: np.ndarray, i: int) -> tuple[int, int, int]:
    best = ranks.min(axis=1)
    shared = (ranks == best[:, None]).sum(axis=1)
    at_best = ranks[:, i] == best
    return int((at_best & (shared == 1)).sum()), int((at_best & (shared > 1)).sum()), int((~at_best).sum())


def _input(r: dict) -> tuple:
    return tuple(str(r.get(k)) for k in BLOCK_KEYS)


def _per_label(rows: list[dict], metric: str, labels: list[str]) -> dict[str, dict[tuple, float]]:
    """Each label's value per input (smaller is better, NaN unless ok; the first row of an input wins)."""
    out: dict[str, dict[tuple, float]] = {lab: {} for lab in labels}
    for r in rows:
        lab = str(r.get("label"))
        if lab in out:
            out[lab].setdefault(_input(r), _sign(metric) * _value(r, metric))
    return out


def board(rows: list[dict], keys, title: str, usable: bool = True) -> dict | None:
    """One board over ``rows`` on the key metrics ``keys`` ((column, title) pairs; the first decides the verdict);
    ``usable``: an invalid or unusable cell (:func:`bench.metrics.flags.is_usable`) ranks last and loses every
    pair to a usable one (the board's verdict); False: the raw values of every valid cell."""
    keys = [(m, t) for m, t in keys if any(np.isfinite(_num(r.get(m))) for r in rows)]
    labels = list(dict.fromkeys(str(r.get("label")) for r in rows))
    if not keys or len(labels) < 1:
        return None
    n_usable = {lab: sum(1 for r in rows if str(r.get("label")) == lab and is_usable(r)) for lab in labels}
    if usable:
        rows = [r if is_usable(r) else {**r, "status": "unusable"} for r in rows]
    first = keys[0][0]
    per_label = _per_label(rows, first, labels)
    n_inputs = len({_input(r) for r in rows})
    _, ranks0 = block_ranks(rows, first, labels)
    mean_ranks = {}
    for m, _ in keys:
        _, rk = block_ranks(rows, m, labels)
        mean_ranks[m] = rk.mean(axis=0) if len(rk) else np.full(len(labels), math.nan)
    table = []
    for i, lab in enumerate(labels):
        mine = [r for r in rows if str(r.get("label")) == lab]
        good = [r for r in mine if r.get("status") == "ok" and not _flagged(r)]
        times = [_num(r.get("wall_s")) for r in mine if np.isfinite(_num(r.get("wall_s")))]
        rec = {"label": lab, "cells": len(mine), "valid_pct": 100.0 * len(good) / len(mine) if mine else math.nan,
               "usable_pct": 100.0 * n_usable[lab] / len(mine) if mine else math.nan,
               "median_s": float(np.median(times)) if times else math.nan}
        for m, _ in keys:
            rec[m] = float(mean_ranks[m][i])
        rec["wins"], rec["ties"], rec["losses"] = _wtl(ranks0, i) if len(ranks0) else (0, 0, 0)
        table.append(rec)
    pw = pairwise(per_label, first)
    # by mean rank; with no input every method has, by the share of pairwise comparisons won
    score = {lab: sum(pw["pairs"][(lab, o)]["wins"] - pw["pairs"][(lab, o)]["losses"] for o in labels if o != lab)
             for lab in labels}
    table.sort(key=lambda r: (r[first] if len(ranks0) else 0.0, -score[r["label"]], r["label"]))
    by_rank = [r["label"] for r in table]
    v = verdict(pw, by_rank)
    beaten = {a for a in labels for b in labels if b != a and pw["pairs"][(a, b)]["better"] == b}
    table.sort(key=lambda r: (r["label"] != v["best"], r["label"] in beaten, by_rank.index(r["label"])))
    v = verdict(pw, [r["label"] for r in table])
    v["groups"] = not_told_apart(pw, by_rank)      # the diagram's bars, in the order of its axis
    values = None
    if len(labels) == 2:
        blocks = _blocks(rows, labels)
        values = np.array([[_sign(first) * _value(b[lab], first) for lab in labels] for _, b in sorted(blocks.items())])
    out = {"title": title, "keys": keys, "rows": table, "n_blocks": int(len(ranks0)), "n_inputs": n_inputs,
           "significance": significance(ranks0, labels, values), "metric": first, "usable": usable,
           "pairwise": pw, "verdict": v}
    out["recommendation"] = recommendation(out)
    out["tests_differ"] = tests_differ(out)
    return out


def tests_differ(board: dict) -> list[str]:
    """Sentences naming each pair the Friedman + Nemenyi check (:func:`significance`) separates and the pairwise
    test does not, or the reverse — with both numbers and why the verdict follows the pairwise test."""
    sig, pairs = board["significance"], board["pairwise"]["pairs"]
    if sig["test"] is None or not sig["test"].startswith("Friedman"):
        return []
    mean, cd = sig["mean_ranks"], sig["cd"]
    labels = sorted(mean, key=lambda lab: mean[lab])
    only_nemenyi, only_pairwise = [], []
    for i, a in enumerate(labels):
        for b in labels[i + 1:]:
            gap = mean[b] - mean[a]
            nem = sig["p"] < ALPHA and gap >= cd
            rec = pairs[(a, b)]
            pw_ = rec["better"] is not None
            p = "not tested" if math.isnan(rec["p"]) else f"p = {rec['p_holm']:.2g}"
            if nem and not pw_:
                only_nemenyi.append(f"{a} from {b} (rank gap {gap:.2f} ≥ CD {cd:.2f}; pairwise {p})")
            elif pw_ and not nem:
                only_pairwise.append(f"{rec['better']} from {b if rec['better'] == a else a} ({p}; rank gap "
                                     f"{gap:.2f}" + (f" < CD {cd:.2f})" if sig["p"] < ALPHA else
                                                      f", Friedman p = {sig['p']:.2g} ≥ {ALPHA})"))
    out = []
    n = sig["n_blocks"]
    if only_nemenyi:
        out.append(f"Friedman + Nemenyi over the {n} inputs every method has would separate "
                   + "; ".join(only_nemenyi) + " — the pairwise test does not")
    if only_pairwise:
        out.append("The pairwise test separates " + "; ".join(only_pairwise)
                   + f" — Friedman + Nemenyi over the {n} inputs every method has does not")
    if out:
        out.append("the verdict follows the pairwise test: it compares each pair on every input the two share, "
                   "weighs the size of each difference, and its answer for A and B does not depend on the other "
                   "methods on the board, as a mean-rank difference does")
    return out


def _degrade(r: dict) -> str:
    d = r.get("degrade")
    return "none" if d is None or str(d) in ("", "nan", "None") else str(d)


#: how a board names a degraded input's kind
KIND_TITLES = {"mask": "a mask", "intensity": "an intensity image", "sdf": "a signed distance"}


def leaderboards(rows: list[dict]) -> list[dict]:
    """The boards of a run (see the module docstring), each with its raw twin: with ground truth, and truth-free
    (cells without).

    A run with degraded inputs (``degrade``) gets one board per degradation first, each answering "from this
    input, which method?" on :data:`DEGRADED_KEYS`; the undegraded cells follow as usual.  A cell a method
    declined (status ``skipped``: it does not take that input) is left out: the method does not have that input."""
    rows = [r for r in rows if r.get("status") != "skipped"]
    boards = []
    degrades = list(dict.fromkeys(_degrade(r) for r in rows))
    for d in [d for d in degrades if d != "none"]:
        sub = [r for r in rows if _degrade(r) == d and not _no_truth(r)]
        kinds = sorted({str(r.get("input_kind")) for r in sub if r.get("input_kind") not in (None, "")})
        kind = " / ".join(KIND_TITLES.get(k, k) for k in kinds) or "a degraded volume"
        b = _with_raw(sub, DEGRADED_KEYS, f"From {kind}: {d}") if sub else None
        if b is not None:
            b["degrade"] = d
            boards.append(b)
    plain = [r for r in rows if _degrade(r) == "none"]
    truth = [r for r in plain if not _no_truth(r)]
    free = [r for r in rows if _no_truth(r)]
    truth_title = "Cells with ground truth" + (" (undegraded inputs)" if len(degrades) > 1 else "")
    for sub, keys, title in ((truth, TRUTH_KEYS, truth_title),
                             (free, FREE_KEYS, "Cells without ground truth (data fidelity only)")):
        if sub:
            b = _with_raw(sub, keys, title)
            if b is not None:
                boards.append(b)
    return boards


def _with_raw(rows: list[dict], keys, title: str) -> dict | None:
    """The board (usable meshes first) with its twin over the raw values (``raw_board``); where the twin's leader
    differs, a sentence in ``tests_differ`` says which and how many of its meshes were usable."""
    b = board(rows, keys, title)
    if b is None:
        return None
    raw = board(rows, keys, f"{title}: closest to the truth, usable or not", usable=False)
    b["raw_board"] = raw
    if raw is not None and raw["rows"] and b["rows"] and raw["rows"][0]["label"] != b["rows"][0]["label"]:
        top = raw["rows"][0]
        b["tests_differ"] = [f"Ranking the raw values, usable or not, {top['label']} would come first "
                             f"({top['usable_pct']:.0f} % of its {top['cells']} meshes usable): the verdict "
                             "counts a mesh that cannot be used as a loss", *b["tests_differ"]]
    return b


def _no_truth(r: dict) -> bool:
    v = r.get("has_truth")
    if v is not None and str(v) not in ("", "nan", "None"):
        return not _is_true(v)
    return False


def cd_figure(board: dict, colours: dict[str, str]) -> dict | None:
    """A plotly figure of the board's diagram: each method's mean rank on the board's first metric (over the
    inputs every method has) on an axis, and bars joining the methods the board's verdict — the pairwise test —
    cannot tell apart (``board["verdict"]["groups"]``); None without a mean rank or a tested pair."""
    if not board["n_blocks"] or not any(not math.isnan(p["p"]) for p in board["pairwise"]["pairs"].values()):
        return None
    mean = {r["label"]: r[board["metric"]] for r in board["rows"]}
    order = sorted(mean, key=lambda lab: mean[lab])
    groups = board["verdict"]["groups"]
    k = len(order)
    data = [{"type": "scatter", "mode": "markers", "x": [mean[lab]], "y": [0], "name": lab,
             "hovertemplate": f"{lab}: mean rank %{{x:.2f}}<extra></extra>",
             "marker": {"size": 11, "color": colours.get(lab, "#444")}, "showlegend": False} for lab in order]
    # labels on leader lines at four staggered heights: methods with close mean ranks do not overprint
    labels = [{"x": mean[lab], "y": 0, "text": lab, "showarrow": True, "arrowhead": 0, "arrowwidth": 1,
               "arrowcolor": "#999", "ax": 0, "ay": -(18 + 18 * (i % 4)), "font": {"size": 11},
               "bgcolor": "rgba(255,255,255,0.85)"} for i, lab in enumerate(order)]
    # a bar per group, its members marked on it: a method inside the bar's span without a mark is not in it
    for j, group in enumerate(groups):
        xs = sorted(mean[lab] for lab in group)
        data.append({"type": "scatter", "mode": "lines+markers", "x": xs, "y": [-0.3 - 0.25 * j] * len(xs),
                     "line": {"width": 3, "color": "#555"}, "marker": {"size": 9, "symbol": "line-ns-open",
                                                                        "line": {"width": 3, "color": "#222"}},
                     "hoverinfo": "text", "showlegend": False, "text": "not told apart: " + ", ".join(group)})
    best = board["verdict"]["best"]
    title = (f"{board['title']}: mean rank on {board['metric']} over the {board['n_blocks']} inputs every method "
             f"has; bars: not told apart by the pairwise test"
             + (f"; use {best}" if best else "; no method clearly better"))
    return {"data": data, "layout": {
        "title": {"text": title, "font": {"size": 12}},
        "xaxis": {"title": "mean rank (1 = best)", "range": [0.5, k + 0.5], "dtick": 1},
        "yaxis": {"visible": False, "range": [-0.4 - 0.25 * max(1, len(groups)), 1.0]},
        "height": 280 + 20 * len(groups), "margin": {"t": 60, "b": 40}, "annotations": labels}}


def _fmt(v, digits: str = ".2f") -> str:
    return "–" if v is None or (isinstance(v, float) and math.isnan(v)) else format(v, digits)


def board_html(board: dict, colours: dict[str, str]) -> str:
    """A board as an HTML table (escaped): method, mean rank per key metric, W/T/L, valid %, usable %, median time."""
    import html

    head = ["method", *[f"{t}<br><small>mean rank on {html.escape(m)}</small>" for m, t in board["keys"]],
            f"wins / ties / losses<br><small>on {html.escape(board['metric'])}</small>",
            "valid &amp; unflagged", "usable<br><small>the truth's parts and genus (without a truth: the data's), no "
            "missing part or self-intersection</small>", "median time"]
    body = []
    for r in board["rows"]:
        colour = html.escape(colours.get(r["label"], "#444"))
        cells = [f'<span class="swatch" style="background:{colour}"></span>{html.escape(r["label"])}',
                 *[_fmt(r[m]) for m, _ in board["keys"]], f"{r['wins']} / {r['ties']} / {r['losses']}",
                 f"{_fmt(r['valid_pct'], '.0f')} % of {r['cells']}", f"{_fmt(r['usable_pct'], '.0f')} %",
                 f"{_fmt(r['median_s'], '.3g')} s"]
        body.append("<tr>" + "".join(f"<td>{c}</td>" for c in cells) + "</tr>")
    return ('<table class="summary leaderboard"><thead><tr>' + "".join(f"<th>{h}</th>" for h in head)
            + "</tr></thead><tbody>" + "".join(body) + "</tbody></table>")
