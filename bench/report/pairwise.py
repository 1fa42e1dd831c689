"""Every method against every other on the inputs both have: the primary test of a board, and its verdict.

Pairwise comparisons (:func:`pairwise`) — the primary test
    Each pair (A, B) is compared on the inputs *both* have: per input a win, tie (equal at the metric's
    resolution, the quality gate's tolerance) or loss, and the Wilcoxon signed-rank test on the paired
    differences (two-sided; zeros split between the signs, scipy's ``zero_method="zsplit"``).  A cell that is not
    ``ok`` (or not usable, on a usable board) loses to one that is by more than any measured difference (its
    difference gets the largest magnitude); two such cells tie.  The p-values of a board are Holm-corrected
    across its pairs (Holm 1979: step-down Bonferroni, which holds the family-wise error rate at α without
    assuming independence).

    Why this test and not Friedman + Nemenyi (which :mod:`bench.report.verdicts` still computes, as a check):
    the Nemenyi critical difference compares mean ranks over the inputs *every* method has — a method run only
    on clean volumes shrinks that set to a handful — and whether A and B differ then depends on which other
    methods are on the board (adding a method moves every mean rank; Benavoli, Corani & Mangili 2016, "Should
    we really use post-hoc tests based on mean-ranks?", JMLR 17).  The signed-rank test of a pair uses only
    A and B, on every input they share, and the sizes of the differences (a sign test would not); it is chosen
    over a paired t-test because distances are skewed.  With fewer than :data:`MIN_PAIRED` shared inputs a pair
    is not tested: two-sided, five inputs all won give p = 0.0625 at best.

Verdict (:func:`verdict`)
    One statement from the Holm-corrected pairs: *use X* when X is beaten by no method and beats at least one
    significantly (of several such methods, the first in the board's order, its mean rank); the methods X is
    not told apart from are *as good*, with the shapes where they were at least as good on every input; with no
    significant difference (or only a cycle of them) *no method is clearly better*.  The diagram's bars
    (:func:`not_told_apart`: the maximal groups no two of which the test separates, each bar marking its
    members) come from the same pairs, so the sentence and the diagram cannot disagree.
"""

from __future__ import annotations

import html
import math
from itertools import combinations
from typing import Any

import numpy as np

from bench.metrics.tolerances import same_within_tolerance

__all__ = ["MIN_PAIRED", "ALPHA", "pairwise", "holm", "signed_rank_test", "median_interval", "verdict",
           "not_told_apart", "recommendation", "pairwise_html"]

MIN_PAIRED = 6
ALPHA = 0.05


def holm(ps: list[float]) -> list[float]:
    """Holm's step-down adjusted p-values (same order as ``ps``; NaN stays NaN and is not counted)."""
    idx = [i for i, p in enumerate(ps) if not math.isnan(p)]
    m = len(idx)
    out = [math.nan] * len(ps)
    running = 0.0
    for j, i in enumerate(sorted(idx, key=lambda i: ps[i])):
        running = max(running, min(1.0, (m - j) * ps[i]))
        out[i] = running
    return out


def _differences(a: dict, b: dict, metric: str) -> tuple[np.ndarray, int, int, int]:
    """Paired differences a − b (smaller is better) on the inputs both have, and a's wins / ties / losses."""
    d = paired_differences(a, b, metric)[1]
    return d, int((d < 0).sum()), int((d == 0).sum()), int((d > 0).sum())


def paired_differences(a: dict, b: dict, metric: str) -> tuple[list, np.ndarray]:
    """(the inputs both have, sorted; a − b on each): 0 where equal at the metric's resolution, a not-ok cell's
    difference the largest magnitude (see the module docstring)."""
    keys = sorted(set(a) & set(b))
    d = np.zeros(len(keys))
    bad = np.zeros(len(keys), int)     # +1: only a failed, −1: only b failed
    for i, k in enumerate(keys):
        va, vb = a[k], b[k]
        if math.isnan(va) or math.isnan(vb):
            bad[i] = (1 if math.isnan(va) else 0) - (1 if math.isnan(vb) else 0)
        elif not same_within_tolerance(metric, va, vb):
            d[i] = va - vb
    big = 1.0 + 2.0 * (np.abs(d).max() if len(d) else 0.0)
    return keys, np.where(bad != 0, bad * big, d)


def signed_rank_test(d: np.ndarray) -> tuple[float, float]:
    """(two-sided p, R− − R+): the Wilcoxon signed-rank test of d (R−: the rank sum of the negative d)."""
    import warnings

    from scipy import stats

    if not np.any(d != 0):
        return 1.0, 0.0
    nz = d[d != 0]
    r = stats.rankdata(np.abs(nz))
    # the exact null distribution without zeros or tied magnitudes (n ≤ 50), else the normal approximation with
    # the tie correction — never scipy's permutation fallback, which costs seconds a test
    exact = len(nz) == len(d) and len(np.unique(np.abs(nz))) == len(nz) and len(d) <= 50
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        p = float(stats.wilcoxon(d, zero_method="zsplit", method="exact" if exact else "approx").pvalue)
    return p, float(r[nz < 0].sum() - r[nz > 0].sum())


def median_interval(d: np.ndarray, level: float = 0.95) -> tuple[float, float]:
    """A distribution-free interval for the median of ``d``: the order statistics d₍ₖ₎, d₍ₙ₋ₖ₊₁₎ with the
    largest k whose binomial coverage is at least ``level`` ((min, max) when no k reaches it: n < 6)."""
    from scipy import stats

    x = np.sort(np.asarray(d, float))
    n = len(x)
    if n == 0:
        return math.nan, math.nan
    k = 0
    while k + 1 <= n // 2 and 1.0 - 2.0 * stats.binom.cdf(k, n, 0.5) >= level:
        k += 1
    return float(x[max(k - 1, 0)]), float(x[n - max(k, 1)])


def pairwise(values: dict[str, dict[tuple, float]], metric: str) -> dict[str, Any]:
    """``values``: per method label, its value per input (smaller is better; NaN: not ok / not usable).

    Returns ``{"metric", "labels", "pairs": {(a, b): {"n", "wins", "ties", "losses", "p", "p_holm",
    "better"}}, "values"}`` for every ordered pair (a's view: wins are a's), ``better`` the significantly better
    label or None; a pair with fewer than :data:`MIN_PAIRED` shared inputs has ``p`` NaN."""
    labels = list(values)
    pairs: dict[tuple[str, str], dict] = {}
    for a, b in combinations(labels, 2):
        d, w, t, l_ = _differences(values[a], values[b], metric)
        p, lead = signed_rank_test(d) if len(d) >= MIN_PAIRED else (math.nan, 0.0)
        pairs[(a, b)] = {"n": len(d), "wins": w, "ties": t, "losses": l_, "p": p, "lead": lead}
    keys = list(pairs)
    for k, ph in zip(keys, holm([pairs[k]["p"] for k in keys])):
        pairs[k]["p_holm"] = ph
        sig = not math.isnan(ph) and ph < ALPHA and pairs[k]["lead"] != 0
        pairs[k]["better"] = (k[0] if pairs[k]["lead"] > 0 else k[1]) if sig else None
    for (a, b), rec in list(pairs.items()):
        pairs[(b, a)] = {**rec, "wins": rec["losses"], "losses": rec["wins"], "lead": -rec["lead"]}
    return {"metric": metric, "labels": labels, "pairs": pairs, "values": values}


def _p(v: float) -> str:
    return "p < 0.001" if v < 0.001 else f"p = {v:.2g}"


def _join(names: list[str]) -> str:
    return names[0] if len(names) == 1 else ", ".join(names[:-1]) + " and " + names[-1]


def not_told_apart(pw: dict, order: list[str]) -> list[list[str]]:
    """The diagram's bars: every maximal group of methods no two of which the pairwise test separates (an
    untested pair is not separated) — the maximal cliques of that graph (Bron–Kerbosch with pivoting), each in
    ``order``, the groups by their first member's place in ``order``; groups of one method are left out.  Every
    pair the test leaves apart is in some group, and no group holds a separated pair."""
    pairs = pw["pairs"]
    place = {lab: i for i, lab in enumerate(order)}
    adj = {a: {b for b in order if b != a and pairs[(a, b)]["better"] is None} for a in order}
    groups: list[list[str]] = []

    def extend(clique: list[str], cand: set[str], done: set[str]) -> None:
        if not cand and not done:
            if len(clique) > 1:
                groups.append(sorted(clique, key=place.get))
            return
        pivot = max(sorted(cand | done, key=place.get), key=lambda u: len(adj[u] & cand))
        for v in sorted(cand - adj[pivot], key=place.get):
            extend(clique + [v], cand & adj[v], done & adj[v])
            cand = cand - {v}
            done = done | {v}

    extend([], set(order), set())
    return sorted(groups, key=lambda g: [place[x] for x in g])


#: at most this many shapes are named where a method is as good
MAX_WHERE = 6


def _where_as_good(pw: dict, best: str, other: str) -> list[str]:
    """The shapes (an input key's first element: its phantom) on every shared input of which ``other`` was at
    least as good as ``best`` (a tie at the metric's resolution or a win)."""
    values = pw.get("values")
    if not values:
        return []
    keys, d = paired_differences(values[other], values[best], pw["metric"])
    shapes: dict[str, bool] = {}
    for k, x in zip(keys, d):
        name = str(k[0]) if isinstance(k, tuple) and k else str(k)
        shapes[name] = shapes.get(name, True) and bool(x <= 0)
    return [name for name, ok in shapes.items() if ok]


def _names(names: list[str]) -> str:
    from .tables import phantom_label

    shown = [phantom_label(n) for n in names[:MAX_WHERE]]
    more = len(names) - len(shown)
    return ", ".join(shown) + (f" and {more} more" if more > 0 else "")


def verdict(pw: dict, order: list[str]) -> dict[str, Any]:
    """The one verdict of the pairwise tests ``pw`` (:func:`pairwise`; see the module docstring), the methods in
    ``order`` (the board's: best mean rank first).

    Returns ``{"best": label or None, "beats": [label], "as_good": [label], "untested": [label], "groups": bars
    of the diagram, "text": "use X (better than …); Y is as good …" or "no method is clearly better …"}``."""
    pairs = pw["pairs"]
    labels = [lab for lab in order if lab in pw["labels"]]
    out: dict[str, Any] = {"best": None, "beats": [], "as_good": [], "untested": [],
                           "groups": not_told_apart(pw, labels), "text": ""}
    if len(labels) < 2:
        out["text"] = f"only {labels[0]} ran: nothing to compare" if labels else "no method ran"
        return out
    beaten = {a: [b for b in labels if b != a and pairs[(a, b)]["better"] == b] for a in labels}
    beats = {a: [b for b in labels if b != a and pairs[(a, b)]["better"] == a] for a in labels}
    winners = [a for a in labels if not beaten[a] and beats[a]]
    if not winners:
        tested = [p for (a, b), p in pairs.items() if a < b and not math.isnan(p["p"])]
        if not tested:
            why = f"no pair shares enough inputs for a test: {MIN_PAIRED} are needed"
        elif any(p["better"] for p in tested):
            why = "every method that beats another is itself beaten by a third"
        else:
            why = f"no pair differs significantly; {labels[0]} has the best mean rank"
        out["text"] = f"no method is clearly better on {pw['metric']} ({why})"
        return out
    best = winners[0]
    out["best"], out["beats"] = best, beats[best]
    rest = [b for b in labels if b != best and b not in beats[best]]
    out["untested"] = [b for b in rest if math.isnan(pairs[(best, b)]["p"])]
    out["as_good"] = [b for b in rest if b not in out["untested"]]
    won = [f"{b} ({pairs[(best, b)]['wins']}–{pairs[(best, b)]['losses']} of {pairs[(best, b)]['n']}, "
           f"{_p(pairs[(best, b)]['p_holm'])})" for b in beats[best]]
    text = f"use {best} on {pw['metric']} (better than {_join(won)})"
    for b in out["as_good"]:
        where = _where_as_good(pw, best, b)
        text += (f"; {b} is as good (not told apart, {_p(pairs[(best, b)]['p_holm'])}"
                 + (f"; at least as good on every input of {_names(where)}" if where else "") + ")")
    if out["untested"]:
        text += (f"; not tested against {_join(out['untested'])} (only "
                 f"{_join([str(pairs[(best, b)]['n']) for b in out['untested']])} shared inputs; a test needs "
                 f"{MIN_PAIRED})")
    out["text"] = text
    return out


#: how a board's verdict names its test and its rule for results that cannot be used
TEST_NAME = f"Wilcoxon signed-rank per pair, Holm-corrected, α = {ALPHA}"


def recommendation(board: dict) -> str:
    """The board's verdict in one sentence (:func:`verdict` of its pairwise tests, in the board's order)."""
    pw, rows = board.get("pairwise"), board["rows"]
    n = board.get("n_inputs", board.get("n_blocks", 0))
    where = (f"On these {n} inputs (an invalid or unusable mesh loses to a usable one)"
             if board.get("usable") else f"On these {n} inputs, ranking the raw values (usable or not)")
    if not rows or pw is None:
        return f"{where}: no method has a value on {board['metric']}."
    v = board.get("verdict") or verdict(pw, [r["label"] for r in rows])
    text = v["text"]
    return f"{where}: {text[0].upper()}{text[1:]}" + (f" ({TEST_NAME})." if len(rows) > 1 else ".")


def pairwise_html(pw: dict, order: list[str]) -> str:
    """The win / tie / loss matrix (row's view) with each pair's Holm-corrected p; significant cells marked."""
    head = "".join(f"<th>{html.escape(b)}</th>" for b in order)
    body = []
    for a in order:
        cells = []
        for b in order:
            if a == b:
                cells.append("<td>—</td>")
                continue
            rec = pw["pairs"][(a, b)]
            cls = "better" if rec["better"] == a else "worse" if rec["better"] == b else ""
            p = "not tested" if math.isnan(rec["p"]) else _p(rec["p_holm"])
            cells.append(f'<td class="{cls}" title="{html.escape(a)} vs {html.escape(b)} on {rec["n"]} shared inputs">'
                         f'{rec["wins"]} / {rec["ties"]} / {rec["losses"]}<br><small>{p}</small></td>')
        body.append(f"<tr><th>{html.escape(a)}</th>{''.join(cells)}</tr>")
    return (f'<table class="summary pairwise"><thead><tr><th>row vs column<br><small>wins / ties / losses on '
            f'{html.escape(pw["metric"])}</small></th>{head}</tr></thead><tbody>{"".join(body)}</tbody></table>')
