"""Every method against every other on the inputs both have, and the sentence a board opens with.

Pairwise comparisons (:func:`pairwise`)
    A board's Friedman test (:mod:`bench.report.verdicts`) needs the inputs *every* method has; a method run
    only on clean volumes shrinks it to a handful.  Here each pair (A, B) is compared on the inputs *both* have:
    per input a win, tie (equal at the metric's resolution, the quality gate's tolerance) or loss, and the
    Wilcoxon signed-rank test on the paired differences (two-sided; zeros split between the signs, scipy's
    ``zero_method="zsplit"``).  A cell that is not ``ok`` (or not usable, on a usable board) loses to one that
    is by more than any measured difference (its difference gets the largest magnitude); two such cells tie.
    The p-values of a board are Holm-corrected across its pairs (Holm 1979: step-down Bonferroni, which holds
    the family-wise error rate at α without assuming independence).  The signed-rank test was chosen over the
    sign test because it uses the sizes of the differences, and over a paired t-test because distances are
    skewed.  With fewer than :data:`MIN_PAIRED` shared inputs a pair is not tested: two-sided, five inputs all
    won give p = 0.0625 at best.

Recommendation (:func:`recommendation`)
    One sentence generated from a board's numbers: its best method on the first key metric, whom it beats
    significantly, whom this run cannot tell it from, whom it was not tested against.
"""

from __future__ import annotations

import html
import math
from itertools import combinations
from typing import Any

import numpy as np

from bench.metrics.tolerances import same_within_tolerance

__all__ = ["MIN_PAIRED", "ALPHA", "pairwise", "holm", "signed_rank_test", "median_interval", "recommendation",
           "pairwise_html"]

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
    d = np.where(bad != 0, bad * big, d)
    return d, int((d < 0).sum()), int((d == 0).sum()), int((d > 0).sum())


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
    "better"}}}`` for every ordered pair (a's view: wins are a's), ``better`` the significantly better label or
    None; a pair with fewer than :data:`MIN_PAIRED` shared inputs has ``p`` NaN."""
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
    return {"metric": metric, "labels": labels, "pairs": pairs}


def _p(v: float) -> str:
    return "p < 0.001" if v < 0.001 else f"p = {v:.2g}"


def _join(names: list[str]) -> str:
    return names[0] if len(names) == 1 else ", ".join(names[:-1]) + " and " + names[-1]


def recommendation(board: dict) -> str:
    """The board's verdict in one sentence (see the module docstring), from its rows and pairwise tests."""
    pw, rows = board.get("pairwise"), board["rows"]
    metric = board["metric"]
    n = board.get("n_inputs", board.get("n_blocks", 0))
    where = (f"Among usable meshes on these {n} inputs (unusable ones rank last)" if board.get("usable")
             else f"On these {n} inputs")
    if not rows or pw is None:
        return f"{where}, no method has a value on {metric}."
    labels = [r["label"] for r in rows]
    if len(labels) == 1:
        return f"{where}, only {labels[0]} ran: nothing to compare."
    best = labels[0]
    beats, ties, worse, untested = [], [], [], []
    for other in labels[1:]:
        rec = pw["pairs"][(best, other)]
        if math.isnan(rec["p"]):
            untested.append((other, str(rec["n"])))
        elif rec["better"] == best:
            beats.append(f"{other} ({rec['wins']}–{rec['losses']} of {rec['n']}, {_p(rec['p_holm'])})")
        elif rec["better"] == other:
            worse.append(f"{other} ({rec['losses']}–{rec['wins']} of {rec['n']}, {_p(rec['p_holm'])})")
        else:
            ties.append(f"{other} ({_p(rec['p_holm'])})")
    parts = [f"{where}, {best} has the best mean rank on {metric}"]
    if beats:
        parts.append(f"significantly better than {_join(beats)}")
    if worse:
        parts.append(f"but significantly worse than {_join(worse)} on the inputs they share")
    if ties:
        parts.append(f"not distinguishable from {_join(ties)}")
    if untested:
        parts.append(f"not tested against {_join([u for u, _ in untested])} (only {_join([n for _, n in untested])} "
                     f"shared inputs; a test needs {MIN_PAIRED})")
    if not beats and not worse and ties:
        parts[0] = (f"No significant difference on {metric} " + ("among usable meshes " if
                    board.get("usable") else "") + f"over these {n} inputs: {best} has the best "
                    "mean rank")
    return "; ".join(parts) + f" (Wilcoxon signed-rank per pair, Holm-corrected, α = {ALPHA})."


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
