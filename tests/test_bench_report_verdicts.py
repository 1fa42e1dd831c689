"""bench/report/verdicts.py: ranks within blocks with ties at the metric's resolution, the boards, and the
significance test that separates a consistent winner and joins methods that alternate."""

from __future__ import annotations

import numpy as np

from bench.report.verdicts import MIN_BLOCKS, block_ranks, leaderboards, significance


def _rows(values: dict[str, list[float]], metric="hausdorff_h", **extra):
    rows = []
    for label, vals in values.items():
        for i, v in enumerate(vals):
            rows.append({"phantom": f"p{i}", "variant": "sdf", "N": 48, "noise": "none", "snr_requested": None,
                         "seed": 0, "label": label, "status": "ok", "flags": "", "wall_s": 1.0, metric: v,
                         "mean_dist_h": v / 4, **extra})
    return rows


def test_a_consistent_winner_ranks_first_and_is_separated():
    rng = np.random.default_rng(0)
    base = rng.uniform(0.5, 3.0, 12)                          # shapes of very different difficulty
    rows = _rows({"B": list(base * 1.3 + 0.05), "A": list(base)})
    board = leaderboards(rows)[0]
    assert [r["label"] for r in board["rows"]] == ["A", "B"]
    a = board["rows"][0]
    assert a["hausdorff_h"] == 1.0 and (a["wins"], a["ties"], a["losses"]) == (12, 0, 0)
    sig = board["significance"]
    assert sig["n_blocks"] == 12 and sig["p"] < 0.05 and sig["cliques"] == []


def test_methods_that_alternate_are_not_told_apart():
    base = np.linspace(1.0, 2.0, 12)
    a = [v * (1.3 if i % 2 else 1.0) for i, v in enumerate(base)]
    b = [v * (1.0 if i % 2 else 1.3) for i, v in enumerate(base)]
    sig = leaderboards(_rows({"A": a, "B": b}))[0]["significance"]
    assert sig["p"] >= 0.05 and sig["cliques"] == [["A", "B"]]


def test_three_methods_friedman_nemenyi_joins_the_two_that_alternate():
    base = np.linspace(1.0, 3.0, 20)
    vals = {"A": list(base * 0.5),
            "B": [v * (1.3 if i % 2 else 1.0) for i, v in enumerate(base)],
            "C": [v * (1.0 if i % 2 else 1.3) for i, v in enumerate(base)]}
    labels, ranks = block_ranks(_rows(vals), "hausdorff_h", ["A", "B", "C"])
    sig = significance(ranks, labels)
    assert sig["p"] < 0.05 and sig["cd"] > 0
    assert sig["mean_ranks"]["A"] == 1.0 and ["B", "C"] in sig["cliques"]
    assert not any("A" in c for c in sig["cliques"])


def test_ties_at_the_metrics_resolution_and_invalid_cells_rank_last():
    rows = _rows({"A": [1.000], "B": [1.001], "C": [2.0], "D": [0.1]})
    rows[-1]["status"] = "invalid"                              # D's value is never ranked
    labels, ranks = block_ranks(rows, "hausdorff_h", ["A", "B", "C", "D"])
    assert dict(zip(labels, ranks[0])) == {"A": 1.5, "B": 1.5, "C": 3.0, "D": 4.0}
    rows = _rows({"A": [0.9], "B": [0.95]}, metric="fscore@h")  # larger is better for the F-score
    labels, ranks = block_ranks(rows, "fscore@h", ["A", "B"])
    assert list(ranks[0]) == [2.0, 1.0]


def test_few_cells_give_no_bar_and_boards_split_by_truth():
    rows = _rows({"A": [1.0, 2.0], "B": [1.5, 2.5]})
    free = _rows({"A": [0.1] * 3, "B": [0.2] * 3}, metric="sdf_rms_h", has_truth=False)
    for r in free:
        r["phantom"] = "scan_" + r["phantom"]
    boards = leaderboards(rows + free)
    assert [b["title"].split(" ")[1] for b in boards] == ["with", "without"]
    assert boards[0]["significance"]["cliques"] == [] and str(MIN_BLOCKS) in boards[0]["significance"]["note"]
    assert boards[1]["metric"] == "sdf_rms_h" and boards[1]["rows"][0]["label"] == "A"


def test_each_degradation_gets_its_own_board_first_and_volume_error_ranks_by_its_size():
    base = np.linspace(0.5, 2.0, 12)
    plain = _rows({"A": list(base), "B": list(base * 1.5)})
    # from a mask B is the better one; A shrinks the volume by 8 %, B grows it by 2 %: |2| < |−8|
    mask = _rows({"A": list(base * 2), "B": list(base)}, degrade="mask", input_kind="mask")
    for r in mask:
        r["volume_err_pct"] = -8.0 if r["label"] == "A" else 2.0
    boards = leaderboards(plain + mask)
    assert [b["title"] for b in boards] == ["From a mask: mask", "Cells with ground truth (undegraded inputs)"]
    first = boards[0]
    assert [r["label"] for r in first["rows"]] == ["B", "A"] and first["n_blocks"] == 12
    assert dict(first["keys"])["volume_err_pct"] and first["rows"][0]["volume_err_pct"] == 1.0
    assert [r["label"] for r in boards[1]["rows"]] == ["A", "B"]      # the undegraded cells are not mixed in


def _disagreeing_board() -> dict:
    """Six methods on 16 inputs: B < C < D < E by a constant factor everywhere; A is the best on 12 inputs by a
    little and the worst on 4 by a lot, F the reverse.  Mean ranks put A 2.5 ahead of F (CD 1.88: Nemenyi
    separates them); the signed-rank test weighs the four large differences and does not."""
    n = 16
    base = np.linspace(1.0, 2.0, n)
    odd = {1, 6, 10, 13}
    vals = {"A": [b * (3.0 if i in odd else 1.0) for i, b in enumerate(base)],
            **{lab: list(base * f) for lab, f in zip("BCDE", (1.1, 1.2, 1.3, 1.4))},
            "F": [b * (0.5 if i in odd else 1.5) for i, b in enumerate(base)]}
    return leaderboards(_rows(vals))[0]


def test_where_nemenyi_and_the_pairwise_test_disagree_the_board_renders_one_verdict():
    from jinja2 import Environment, FileSystemLoader, select_autoescape

    from bench.report.page import TEMPLATE_DIR
    from bench.report.pairwise import pairwise_html
    from bench.report.verdicts import board_html, cd_figure

    b = _disagreeing_board()
    sig, pairs, v = b["significance"], b["pairwise"]["pairs"], b["verdict"]
    # the construction: Nemenyi separates A from F, the pairwise test does not
    assert sig["p"] < 0.05 and sig["mean_ranks"]["F"] - sig["mean_ranks"]["A"] >= sig["cd"]
    assert pairs[("A", "F")]["better"] is None and not any({"A", "F"} <= set(c) for c in sig["cliques"])
    # one verdict: the sentence, the rows' order and the diagram's bars all from the pairwise test
    assert v["best"] == "B" and b["rows"][0]["label"] == "B"
    assert set(v["beats"]) == {"C", "D", "E"} and set(v["as_good"]) == {"A", "F"}
    text = b["recommendation"]
    assert "Use B on hausdorff_h (better than " in text
    for lab in v["beats"]:
        assert f"{lab} (16–0 of 16" in text and f"{lab} is as good" not in text
    for lab in v["as_good"]:
        assert f"{lab} is as good (not told apart" in text
    fig = cd_figure(b, {})
    bars = [set(t["text"].removeprefix("not told apart: ").split(", ")) for t in fig["data"] if t["mode"] != "markers"]
    labels = [r["label"] for r in b["rows"]]
    for i, x in enumerate(labels):
        for y in labels[i + 1:]:
            joined = any({x, y} <= bar for bar in bars)
            assert joined == (pairs[(x, y)]["better"] is None), (x, y)
    assert "use B" in fig["layout"]["title"]["text"]
    # the check that disagrees is named, with both numbers, and the verdict says which test it follows
    why = "; ".join(b["tests_differ"])
    assert "Friedman + Nemenyi over the 16 inputs every method has would separate" in why
    assert "A from F (rank gap 2.50 ≥ CD 1.88; pairwise p = 1)" in why
    assert "the verdict follows the pairwise test" in why
    # rendered: one verdict sentence, the why, the raw board marked as not the verdict
    b["html"], b["pairwise_html"] = board_html(b, {}), pairwise_html(b["pairwise"], labels)
    b["raw_board"]["html"], b["chart"] = board_html(b["raw_board"], {}), 1
    env = Environment(loader=FileSystemLoader(str(TEMPLATE_DIR)), autoescape=select_autoescape(["html"]))
    page = env.get_template("board.html").render(b=b, verdict_charts=[fig])
    assert page.count('class="verdict"') == 1 and page.count("Use B") == 1 and "clearly better" not in page
    assert "Why other views differ: Friedman + Nemenyi" in page and "not the verdict" in page
    assert b["raw_board"]["recommendation"] not in page
