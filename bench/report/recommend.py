"""The report's first screen: which method to use, per kind of shape and kind of input — never a global winner.

Rows (:func:`shape_class`)
    The phantom's kind of shape, the results row's ``shape_kind`` (the phantom's own class attribute: ``smooth
    solid``, ``thin shell``, ``tubes``, ``cavities``, ``many parts``, ``high genus``, ``touching parts``).  A row
    without one takes it from another row of the same phantom (a cell that failed before its volume was built);
    still none: ``your data`` for a user's file (the row's ``source``), ``unclassified`` for a phantom that
    declares no kind or a run from before the column.  Rows without a ground truth get their own line,
    ``… (no truth)``: they are judged on data fidelity, not on the distance to the truth.

Columns (:func:`input_class`)
    What the method was given, from the row's degradation and noise: ``thick slices`` (any degradation with
    ``thick_slices@K``, K > 1), else ``partial volume``, else ``mask`` (label noise and blur included), else — the
    phantom's exact φ — ``noisy φ`` (noise other than ``none``) or ``clean φ``.

Margins
    ``every input`` (a kind over all the inputs it was given) and ``every shape kind`` (an input over all the kinds
    with a truth), where there is more than one to pool: a cell of two phantoms has too few inputs for a test, the
    wider scope may have enough, and its name says the scope its verdict holds for.

Cells (:func:`recommendation_table`)
    The board (:func:`bench.report.verdicts.board`) over the cell's rows on one metric — the distance to the
    truth (``hausdorff_h``), or data fidelity (``sdf_rms_h``) without a truth — and its verdict
    (:func:`bench.report.pairwise.verdict`): "use X (better than …, p …); Y is as good …" or "no method is
    clearly better".  An invalid, failed or timed-out result and a valid one that is not usable
    (:func:`bench.metrics.flags.is_usable`: in pieces, the wrong genus, a missing part, self-intersecting) is
    not dropped: on its input it loses to every usable result by more than any measured difference, and two such
    results tie; each cell says how many there were, per method.  A method that declined an input (``skipped``)
    has no result there and is compared on the inputs it took.  Each cell names what it rests on: its inputs,
    their phantoms and the number of results.
"""

from __future__ import annotations

import html
import math

from bench.metrics.flags import is_usable
from phantoms.degrade import parse_degradation

from .pairwise import TEST_NAME
from .tables import phantom_label
from .verdicts import BLOCK_KEYS, board

__all__ = ["INPUTS", "SHAPE_KINDS", "YOUR_DATA", "UNCLASSIFIED", "input_class", "shape_class",
           "recommendation_table", "recommendation_html", "recommendation_markdown", "recommendation_latex",
           "recommendation_csv", "RULE"]

#: the columns, in this order (others, e.g. a degradation this module does not know, follow)
INPUTS = ("mask", "partial volume", "thick slices", "noisy φ", "clean φ")
#: the rows, in this order (others follow alphabetically, then your data, then unclassified)
SHAPE_KINDS = ("smooth solid", "thin shell", "tubes", "cavities", "many parts", "high genus", "touching parts")
YOUR_DATA = "your data"
UNCLASSIFIED = "unclassified"
#: the pooled row (every shape kind with a truth) and column (every input of a row's kind): where a cell has too few
#: inputs for a test, the wider scope may have enough — its verdict says so by its name
ALL_SHAPES = "every shape kind"
ALL_INPUTS = "every input"
NO_TRUTH = " (no truth)"
#: at most this many phantoms are named in a cell
MAX_NAMED = 8


def _text(v) -> str | None:
    if v is None or (isinstance(v, float) and math.isnan(v)):
        return None
    t = str(v).strip()
    return None if t in ("", "nan", "None", "none") else t


def input_class(row: dict) -> str:
    """The column of a results row (see the module docstring)."""
    spec = _text(row.get("degrade")) or "none"
    try:
        d = parse_degradation(spec)
    except Exception:  # noqa: BLE001 — a degradation of another suite version: its own column
        return f"other input ({spec})"
    if d.thick_slices > 1:
        return "thick slices"
    if d.partial_volume:
        return "partial volume"
    if d.mask:
        return "mask"
    return "clean φ" if _text(row.get("noise")) is None else "noisy φ"


def _has_truth(row: dict) -> bool:
    v = row.get("has_truth")
    t = _text(v)
    return True if t is None else t.lower() in ("true", "1", "1.0", "yes")


def shape_class(row: dict, by_phantom: dict[str, str] | None = None) -> str:
    """The row of the table a results row belongs to (see the module docstring); ``by_phantom``: the kinds other
    rows of the same phantom recorded."""
    kind = _text(row.get("shape_kind"))
    if kind is None and by_phantom:
        kind = by_phantom.get(str(row.get("phantom")))
    if kind is None:
        kind = YOUR_DATA if _text(row.get("source")) else UNCLASSIFIED
    kind = kind.replace("_", " ")
    return kind if _has_truth(row) else kind + NO_TRUTH


def _shape_order(name: str) -> tuple:
    base = name.removesuffix(NO_TRUTH)
    tier = (0, SHAPE_KINDS.index(base)) if base in SHAPE_KINDS else (
        (2, 0) if base == YOUR_DATA else (3, 0) if base == UNCLASSIFIED else (4, 0) if base == ALL_SHAPES else (1, 0))
    return (*tier, base, name.endswith(NO_TRUTH))


def _input_order(name: str) -> tuple:
    return (INPUTS.index(name), "") if name in INPUTS else (len(INPUTS) + (name == ALL_INPUTS), name)


def _names(names: list[str]) -> str:
    shown = [phantom_label(n) for n in names[:MAX_NAMED]]
    return ", ".join(shown) + (f" and {len(names) - len(shown)} more" if len(names) > len(shown) else "")


def _cell(rows: list[dict], shape: str, inp: str) -> dict:
    truth = not shape.endswith(NO_TRUTH)
    keys = [("hausdorff_h", "distance (Hausdorff)")] if truth else [("sdf_rms_h", "data fidelity (SDF)")]
    b = board(rows, keys, f"{shape} × {inp}")
    inputs = {tuple(str(r.get(k)) for k in BLOCK_KEYS) for r in rows}
    phantoms = list(dict.fromkeys(str(r.get("phantom")) for r in rows))
    bad: dict[str, int] = {}
    for r in rows:
        if not is_usable(r):
            bad[str(r.get("label"))] = bad.get(str(r.get("label")), 0) + 1
    basis = (f"{len(inputs)} input{'s' if len(inputs) != 1 else ''} ({_names(phantoms)}), {len(rows)} results"
             + ("; not usable or invalid, counted as losses: "
                + ", ".join(f"{lab} {n}" for lab, n in sorted(bad.items())) if bad else ""))
    if b is None:
        return {"text": "no method has a value here", "best": None, "basis": basis, "verdict": None}
    v = b["verdict"]
    text = v["text"]
    if sum(bad.values()) == len(rows):       # all tie as losses: say what the tie is, and what the raw values say
        text = "no method gives a usable mesh here: every result is invalid or unusable"
        raw = board(rows, keys, f"{shape} × {inp}, raw values", usable=False)
        if raw is not None and raw["verdict"]["best"]:
            text += f"; closest to the truth, usable or not: {raw['verdict']['text']}"
    return {"text": text, "best": v["best"], "as_good": v["as_good"], "basis": basis, "verdict": v,
            "metric": b["metric"], "n_inputs": len(inputs), "n_results": len(rows), "phantoms": phantoms,
            "not_usable": bad}


def recommendation_table(rows: list[dict]) -> dict:
    """The recommendation per shape kind × input over a run's result rows (dicts; see the module docstring).

    Returns ``{"shapes": [row names], "inputs": [column names], "cells": {(shape, input): {"text", "best",
    "as_good", "basis", "verdict", "metric", "n_inputs", "n_results", "phantoms", "not_usable"}}}``;
    a (shape, input) without results is absent."""
    rows = [r for r in rows if r.get("status") != "skipped"]
    by_phantom: dict[str, str] = {}
    for r in rows:
        kind = _text(r.get("shape_kind"))
        if kind is not None:
            by_phantom.setdefault(str(r.get("phantom")), kind)
    groups: dict[tuple[str, str], list[dict]] = {}
    for r in rows:
        groups.setdefault((shape_class(r, by_phantom), input_class(r)), []).append(r)
    kinds = {s for s, _ in groups}
    inputs = {i for _, i in groups}
    if len(inputs) > 1:                       # each kind over every input it was given
        for s in kinds:
            groups[(s, ALL_INPUTS)] = [r for (k, _), sub in list(groups.items()) if k == s for r in sub]
    truth_kinds = [s for s in kinds if not s.endswith(NO_TRUTH)]
    if len(truth_kinds) > 1:                  # each input over every kind with a truth
        for i in [*inputs, *([ALL_INPUTS] if len(inputs) > 1 else [])]:
            pooled = [r for (k, j), sub in list(groups.items()) if j == i and k in truth_kinds for r in sub]
            if pooled:
                groups[(ALL_SHAPES, i)] = pooled
    cells = {key: _cell(sub, *key) for key, sub in groups.items()}
    return {"shapes": sorted({s for s, _ in cells}, key=_shape_order),
            "inputs": sorted({i for _, i in cells}, key=_input_order), "cells": cells}


#: what the table's heading says about its rule
RULE = (f"Each cell: one verdict from the pairwise tests ({TEST_NAME}) on the distance to the truth "
        "(hausdorff_h; without a truth: sdf_rms_h) over that kind of shape and input only; an invalid or unusable "
        "mesh counts as a loss. It holds for the inputs it names, not beyond them; the last row and column pool "
        "every kind of shape and every input, for a verdict with a wider scope where a cell has too few inputs.")


def recommendation_html(table: dict) -> str:
    """The table as HTML (escaped): shape kinds as rows, inputs as columns, the verdict and its basis per cell."""
    esc = html.escape
    head = "".join(f"<th>{esc(i)}</th>" for i in table["inputs"])
    body = []
    for s in table["shapes"]:
        tds = []
        for i in table["inputs"]:
            c = table["cells"].get((s, i))
            if c is None:
                tds.append('<td class="none">not run</td>')
                continue
            cls = "use" if c["best"] else "tie"
            tds.append(f'<td class="{cls}"><b>{esc(c["text"])}</b><br><small>rests on {esc(c["basis"])}</small></td>')
        body.append(f"<tr><th>{esc(s)}</th>{''.join(tds)}</tr>")
    return (f'<table class="recommend"><thead><tr><th>shape kind \\ input</th>{head}</tr></thead>'
            f'<tbody>{"".join(body)}</tbody></table>')


def _md(text: str) -> str:
    return str(text).replace("\\", "\\\\").replace("|", "\\|").replace("*", "\\*").replace("\n", " ")


def recommendation_markdown(table: dict) -> str:
    """The table as a GitHub pipe table under a heading, the rule first."""
    lines = ["### Which method, for which shape and input", "", _md(RULE), "",
             "| shape kind \\ input | " + " | ".join(_md(i) for i in table["inputs"]) + " |",
             "|:---|" + "|".join(":---" for _ in table["inputs"]) + "|"]
    for s in table["shapes"]:
        cells = []
        for i in table["inputs"]:
            c = table["cells"].get((s, i))
            cells.append("not run" if c is None else f"**{_md(c['text'])}** — rests on {_md(c['basis'])}")
        lines.append(f"| {_md(s)} | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def recommendation_latex(table: dict) -> str:
    """The table as one LaTeX ``table`` float (booktabs rules, wrapped text columns), the rule in its caption."""
    from .export import latex_text

    width = f"{0.85 / max(1, len(table['inputs'])):.2f}"
    cols = "p{0.12\\linewidth}" + "".join(f"p{{{width}\\linewidth}}" for _ in table["inputs"])
    lines = ["\\begin{table}[htbp]", "\\centering", "\\footnotesize", f"\\begin{{tabular}}{{{cols}}}", "\\toprule",
             " & ".join(["shape kind / input", *map(latex_text, table["inputs"])]) + " \\\\", "\\midrule"]
    for s in table["shapes"]:
        cells = []
        for i in table["inputs"]:
            c = table["cells"].get((s, i))
            cells.append("not run" if c is None else
                         f"\\textbf{{{latex_text(c['text'])}}} (rests on {latex_text(c['basis'])})")
        lines.append(" & ".join([latex_text(s), *cells]) + " \\\\")
    lines += ["\\bottomrule", "\\end{tabular}", f"\\caption{{{latex_text(RULE)}}}",
              "\\label{tab:levelset-bench-recommend}", "\\end{table}"]
    return "\n".join(lines) + "\n"


def recommendation_csv(table: dict) -> str:
    """The table in long form: one line per (shape kind, input) with its verdict, best method and basis."""
    import pandas as pd

    recs = [{"shape_kind": s, "input": i, "verdict": c["text"], "best": c["best"] or "",
             "as_good": ";".join(c.get("as_good") or []), "n_inputs": c.get("n_inputs"),
             "n_results": c.get("n_results"), "phantoms": ";".join(c.get("phantoms") or []),
             "not_usable": ";".join(f"{k}={v}" for k, v in sorted((c.get("not_usable") or {}).items()))}
            for s in table["shapes"] for i in table["inputs"] if (c := table["cells"].get((s, i))) is not None]
    return pd.DataFrame(recs).to_csv(index=False)
