"""The summary tables for a paper or a README (``python -m bench table RUN --format markdown|latex|csv``).

One table per group of cells (``by``: default phantom × noise, and variant / N when the run varies them):
methods as rows, the chosen metrics as columns, each value the mean over the group's ``ok`` cells (its seeds),
the ``cells`` column how many of the method's cells were ok.  The best value of a column (the registry's rule:
:func:`bench.report.tables.best_rule` / :func:`~bench.report.tables.best_mask`) is bold only where it is
unique; a method without an ok cell is never best.  Numbers have :data:`DIGITS` significant digits in markdown
and LaTeX; the CSV keeps every digit of the means.
"""

from __future__ import annotations

import html
from dataclasses import dataclass

import numpy as np

from bench.metrics.registry import METRICS
from bench.terminal import printable
from phantoms import InputError

from .tables import (best_mask, best_rule, complete_inputs, input_title, noise_title, phantom_label, phantom_topology,
                     without_truth)

__all__ = ["DEFAULT_METRICS", "GROUP_KEYS", "DIGITS", "GroupTable", "group_tables", "leaderboard_tables",
           "format_number", "to_markdown", "to_latex", "to_csv", "FORMATS"]

#: the metrics a table shows unless told otherwise (those the run has)
DEFAULT_METRICS = ("hausdorff_h", "mean_dist_h", "fscore@h", "roughness_deg", "self_intersections", "wall_s")
#: ... and for a run without ground truth: the data-fidelity metrics (and the topology against the data) in place of
#: the distances to the truth
FREE_METRICS = ("sdf_rms_h", "phi_mean_h", "sign_err_pct", "topology_diffs", "roughness_deg", "self_intersections",
                "wall_s")
#: ``--by`` names → the columns they group on
GROUP_KEYS = {"phantom": ("phantom",), "variant": ("variant",), "N": ("N",), "noise": ("noise", "snr_requested"),
              "seed": ("seed",), "input": ("input_kind", "degrade")}
#: significant digits of the numbers in markdown and LaTeX
DIGITS = 4
FORMATS = ("markdown", "latex", "csv")

@dataclass
class GroupTable:
    """One table: ``title``, the group's values (``group``), ``frame`` (columns ``method``, ``cells`` and one
    float column per metric: the means) and ``best`` (metric → boolean mask of the rows marked best)."""

    title: str
    group: dict
    frame: object
    best: dict
    #: a sentence printed under the title (a leaderboard's recommendation)
    note: str = ""


def _as_float(series):
    import pandas as pd

    return pd.to_numeric(series.map(lambda x: float(x) if isinstance(x, (bool, np.bool_)) else x), errors="coerce")


def _by_columns(df, by) -> list[str]:
    if by is None:
        by = ["phantom", *(["input"] if "degrade" in df.columns and set(df["degrade"].dropna()) - {"none"} else []),
              "noise"] + [k for k in ("variant", "N") if k in df.columns and df[k].nunique() > 1]
    unknown = [k for k in by if k not in GROUP_KEYS]
    if unknown:
        raise InputError(f"--by {','.join(unknown)}: unknown (choose from {', '.join(GROUP_KEYS)})")
    return list(dict.fromkeys(by))


def _metrics(df, metrics) -> list[str]:
    if not metrics:
        default = FREE_METRICS if without_truth(df) else DEFAULT_METRICS
        return [m for m in default if m in df.columns]
    unknown = [m for m in metrics if m not in df.columns]
    if unknown:
        shown = [c for c in df.columns if c in METRICS]
        raise InputError(f"--metric {','.join(unknown)}: not a column of this run (it has {', '.join(shown)})")
    return list(dict.fromkeys(metrics))


def _title(group: dict) -> str:
    parts = []
    for k, v in group.items():
        if k == "phantom":
            parts.append(phantom_label(v))
        elif k == "noise":
            parts.append(noise_title(v[0], v[1]))
        elif k == "input":
            parts.append(input_title(v[0], v[1]))
        elif k == "N":
            parts.append(f"N = {v}")
        elif k == "seed":
            parts.append(f"seed {v}")
        else:
            parts.append(str(v))
    return " — ".join(parts) or "all cells"


def _method_frame(sub, metrics: list[str]):
    import pandas as pd

    rows = []
    for label, g in sub.groupby("label", sort=False):
        ok = g[g["status"] == "ok"]
        rec = {"method": str(label), "cells": f"{len(ok)}/{len(g)}", "_valid": len(ok) > 0}
        for m in metrics:
            vals = _as_float(ok[m])
            rec[m] = float(vals.mean()) if vals.notna().any() else np.nan
        rows.append(rec)
    t = pd.DataFrame(rows)
    return t.sort_values("_valid", ascending=False, kind="stable").reset_index(drop=True)


def group_tables(df, metrics=None, by=None) -> list[GroupTable]:
    """The tables of the results frame ``df`` (:func:`bench.run.results.read_results`)."""
    if not len(df):
        raise InputError("the run has no finished cells: no table to make")
    df = complete_inputs(df)
    metrics, by = _metrics(df, metrics), _by_columns(df, by)
    cols = [c for k in by for c in GROUP_KEYS[k]]
    d = df.copy()
    for col, default in (("degrade", "none"), ("input_kind", "sdf")):      # runs from before degradations
        d[col] = d[col].fillna(default) if col in d.columns else default
    if cols:
        d["_group"] = list(zip(*(d[c].astype(object).where(d[c].notna(), None) for c in cols)))
    else:
        d["_group"] = [()] * len(d)
    tables = []
    for values, sub in d.groupby("_group", sort=False):
        it = iter(values)
        group = {k: (tuple(next(it) for _ in GROUP_KEYS[k]) if len(GROUP_KEYS[k]) > 1 else next(it)) for k in by}
        t = _method_frame(sub, metrics)
        phantoms = sub["phantom"].unique()
        components, genus = phantom_topology(str(phantoms[0])) if len(phantoms) == 1 else (1, 0)
        truth = not without_truth(sub)
        best = {}
        for m in metrics:
            rule = best_rule(m, genus, truth, components)
            mask = (best_mask(t[m].where(t["_valid"], np.nan), rule, metric=m) if rule is not None
                    else np.zeros(len(t), bool))
            best[m] = mask if mask.sum() == 1 else np.zeros(len(t), bool)    # bold only a unique best
        tables.append(GroupTable(_title(group), group, t.drop(columns="_valid"), best))
    return tables


def leaderboard_tables(df) -> list[GroupTable]:
    """The report's leaderboards (:func:`bench.report.verdicts.leaderboards`) as tables: one row per method, its
    mean rank per key metric (1 = best; the unique best in bold), wins / ties / losses on the board's first
    metric and its median time; ``cells`` = the share of its cells valid and unflagged, and usable.  Each board's
    verdict (and why other views differ) is its note; its raw twin follows, marked as not the verdict."""
    import pandas as pd

    from .verdicts import leaderboards

    if not len(df):
        raise InputError("the run has no finished cells: no leaderboard to make")
    out = []
    boards = leaderboards(complete_inputs(df).to_dict("records"))
    for board in boards:
        for b in (board, board.get("raw_board")):
            if b is None:
                continue
            recs = []
            for r in b["rows"]:
                rec = {"method": r["label"], "cells": f"{r['valid_pct']:.0f} % of {r['cells']}, "
                                                      f"{r['usable_pct']:.0f} % usable"}
                rec.update({f"rank {m}": r[m] for m, _ in b["keys"]})
                rec.update(wins=float(r["wins"]), ties=float(r["ties"]), losses=float(r["losses"]),
                           median_s=r["median_s"])
                recs.append(rec)
            frame = pd.DataFrame(recs)
            best = {c: (best_mask(frame[c], "min") if c.startswith("rank ") else np.zeros(len(frame), bool))
                    for c in frame.columns if c not in ("method", "cells")}
            title = f"{b['title']}: {b['n_inputs']} inputs, {b['n_blocks']} with every method"
            if b is board:
                note = b["recommendation"] + "".join(f" {t[0].upper()}{t[1:]}." for t in b["tests_differ"])
                note += f" Check, not the verdict: {b['significance']['note']}."
            else:
                note = "The raw values, usable or not: not the verdict (see the board above)."
            out.append(GroupTable(title, {}, frame, best, note=note))
    return out


def format_number(v, metric: str, missing: str = "–") -> str:
    """``v`` with :data:`DIGITS` significant digits (an integer metric's whole mean as an integer)."""
    if v is None or not np.isfinite(v):
        return missing if v is None or np.isnan(v) else ("inf" if v > 0 else "-inf")
    m = METRICS.get(metric)
    if m is not None and m.dtype == "int" and float(v).is_integer():
        return str(int(v))
    return f"{float(v):.{DIGITS}g}"


def _header(metric: str) -> tuple[str, str]:
    m = METRICS.get(metric)
    return metric, (m.unit if m is not None else "")


# ---------------------------------------------------------------------------------------------- markdown
def _md(text: str) -> str:
    """``text`` safe in a pipe table or a heading: control characters escaped (:func:`bench.terminal.printable`),
    ``<``, ``>`` and ``&`` as HTML entities (a viewer that renders inline HTML shows them as text, never as a
    tag), the table's and emphasis's own characters backslash-escaped."""
    text = html.escape(printable(text), quote=False)
    return text.replace("\\", "\\\\").replace("|", "\\|").replace("*", "\\*").replace("\n", " ")


def to_markdown(tables: list[GroupTable]) -> str:
    """GitHub pipe tables, one under a ``###`` heading per group; the unique best in bold."""
    out = []
    for t in tables:
        metrics = [c for c in t.frame.columns if c not in ("method", "cells")]
        head = ["method", "cells"] + [f"{n} ({u})" if u else n for n, u in map(_header, metrics)]
        lines = [f"### {_md(t.title)}", "", *([_md(t.note), ""] if t.note else []),
                 "| " + " | ".join(_md(h) for h in head) + " |",
                 "|" + "|".join([":---", "---:"] + ["---:"] * len(metrics)) + "|"]
        for i, r in t.frame.iterrows():
            cells = [_md(r["method"]), r["cells"]]
            for m in metrics:
                text = format_number(r[m], m)
                cells.append(f"**{text}**" if t.best[m][i] else text)
            lines.append("| " + " | ".join(cells) + " |")
        out.append("\n".join(lines))
    return "\n\n".join(out) + "\n"


# ---------------------------------------------------------------------------------------------- LaTeX
_LATEX = {"\\": r"\textbackslash{}", "&": r"\&", "%": r"\%", "$": r"\$", "#": r"\#", "_": r"\_", "{": r"\{",
          "}": r"\}", "~": r"\textasciitilde{}", "^": r"\textasciicircum{}", "°": r"$^\circ$", "²": r"$^2$",
          "³": r"$^3$", "α": r"$\alpha$", "φ": r"$\varphi$", "−": "-", "–": "--", "—": "---", "×": r"$\times$",
          "<": r"\textless{}", ">": r"\textgreater{}", "|": r"\textbar{}"}


def latex_text(text: str) -> str:
    """``text`` safe in LaTeX body text (control characters shown as ``\\xNN``: :func:`bench.terminal.printable`;
    the special characters escaped, a few Unicode signs spelled out)."""
    return "".join(_LATEX.get(ch, ch) for ch in printable(text))


def to_latex(tables: list[GroupTable]) -> str:
    """One ``table`` float per group, booktabs rules, units in the header, the unique best in bold (pandas'
    Styler; needs ``\\usepackage{booktabs}``)."""
    import pandas as pd

    out = []
    for k, t in enumerate(tables):
        metrics = [c for c in t.frame.columns if c not in ("method", "cells")]
        head = ["method", "cells"] + [latex_text(n) + (f" ({latex_text(u)})" if u else "")
                                      for n, u in map(_header, metrics)]
        shown = pd.DataFrame({"method": [latex_text(x) for x in t.frame["method"]],
                              "cells": [latex_text(x) for x in t.frame["cells"]],
                              **{h: [format_number(v, m, "--") for v in t.frame[m]]
                                 for h, m in zip(head[2:], metrics)}})
        shown.columns = head
        bold = pd.DataFrame("", index=shown.index, columns=shown.columns)
        for h, m in zip(head[2:], metrics):
            bold.loc[t.best[m], h] = "textbf:--rwrap;"
        sty = shown.style.hide(axis="index").apply(lambda _: bold, axis=None)
        out.append(sty.to_latex(hrules=True, column_format="lr" + "r" * len(metrics), environment="table",
                                position="htbp", position_float="centering",
                                caption=latex_text(t.title + (f". {t.note}" if t.note else "")),
                                label=f"tab:levelset-bench-{k + 1}"))
    return "\n".join(out)


# ---------------------------------------------------------------------------------------------- CSV
def to_csv(tables: list[GroupTable]) -> str:
    """One CSV of every table: the group's columns, method, cells, then each metric's mean at full precision."""
    import pandas as pd

    frames = []
    for t in tables:
        f = t.frame.copy()
        pos = 0
        for k, v in t.group.items():
            for col, value in zip(GROUP_KEYS[k], v if len(GROUP_KEYS[k]) > 1 else (v,)):
                f.insert(pos, col, value)
                pos += 1
        frames.append(f)
    return pd.concat(frames, ignore_index=True).to_csv(index=False)
