"""Performance and quality history: one JSON line per ``bench perf`` run, and a self-contained interactive plot.

``python -m bench perf --history FILE`` appends a line (:func:`history_entry`)::

    {"format": "levelset-bench-history/1", "date": ..., "commit": "<sha>", "dirty": false,
     "machine": {...}, "load": [1, 5, 15 min], "mode": "quick",
     "ratios": {benchmark: gated ratio}, "wall_ratios": {...},
     "quality": {cell: {metric: value}},
     "gate": {"timing": true|false|null, "quality": true|false|null, "failures": [names]}}

``python -m bench perf --plot FILE -o history.html`` draws every benchmark's ratio and every quality metric
across the runs of FILE (x: run number with commit and date; plotly, its JavaScript embedded once — the page
needs no network), a red ✕ on every point of a run whose gate failed.
"""

from __future__ import annotations

import datetime as _dt
import json
import os
import platform
from pathlib import Path

from phantoms import InputError

__all__ = ["HISTORY_FORMAT", "history_entry", "append_history", "read_history", "plot_history"]

HISTORY_FORMAT = "levelset-bench-history/1"


def _load() -> list[float] | None:
    try:
        return [round(x, 2) for x in os.getloadavg()]
    except (AttributeError, OSError):
        return None


def history_entry(timing: dict | None, quality: dict | None, *, timing_passed: bool | None = None,
                  quality_passed: bool | None = None, failures: list[str] | None = None,
                  commit: dict | None = None) -> dict:
    """One history line from a perf summary (``timing``) and/or a quality summary (``quality``)."""
    ratios, wall = {}, {}
    for name, b in ((timing or {}).get("benchmarks") or {}).items():
        r = b.get("cpu_ratio") if b.get("cpu_ratio") is not None else b.get("ratio")
        if r is not None:
            ratios[name] = r
        if b.get("ratio") is not None:
            wall[name] = b["ratio"]
    q = {k: {m: v for m, v in c.get("metrics", {}).items() if v is not None} | {"status": c.get("status")}
         for k, c in ((quality or {}).get("cells") or {}).items()}
    commit = commit if commit is not None else ((quality or {}).get("commit") or {})
    if not commit and timing:
        commit = {"commit": (timing.get("commit") or {}).get("id"), "dirty": (timing.get("commit") or {}).get("dirty")}
    return {"format": HISTORY_FORMAT, "date": _dt.datetime.now().astimezone().isoformat(timespec="seconds"),
            "commit": commit.get("commit"), "dirty": commit.get("dirty"),
            "machine": {"node": platform.node(), "platform": platform.platform(), "cpu_count": os.cpu_count()},
            "load": _load(), "mode": (timing or {}).get("mode"), "ratios": ratios, "wall_ratios": wall,
            "quality": q, "gate": {"timing": timing_passed, "quality": quality_passed, "failures": failures or []}}


def append_history(path: str | Path, entry: dict) -> Path:
    """Append one line to the history file (created with its folder if needed)."""
    p = Path(path)
    try:
        p.parent.mkdir(parents=True, exist_ok=True)
        with open(p, "a", encoding="utf-8") as fh:
            fh.write(json.dumps(entry, separators=(",", ":")) + "\n")
            fh.flush()
            os.fsync(fh.fileno())
    except OSError as exc:
        raise InputError(f"cannot append to the history file {str(p)!r}: {exc.strerror or exc}") from None
    return p


def read_history(path: str | Path) -> list[dict]:
    """The entries of a history file, in order.  A line that is not a history entry → :class:`InputError`
    naming the line (a truncated last line, e.g. after a crash, is skipped with its number in ``skipped``)."""
    p = Path(path)
    try:
        lines = p.read_text(encoding="utf-8").splitlines()
    except OSError as exc:
        raise InputError(f"cannot read the history file {str(p)!r}: {exc.strerror or exc}") from None
    out = []
    for i, line in enumerate(lines, 1):
        if not line.strip():
            continue
        try:
            e = json.loads(line)
        except ValueError:
            if i == len(lines):      # an interrupted append: the last line only
                continue
            raise InputError(f"{str(p)!r} line {i}: not JSON") from None
        if not isinstance(e, dict) or e.get("format") != HISTORY_FORMAT:
            raise InputError(f"{str(p)!r} line {i}: not a history entry (format {HISTORY_FORMAT})")
        out.append(e)
    if not out:
        raise InputError(f"{str(p)!r}: no history entries")
    return out


def _x_labels(entries: list[dict]) -> list[str]:
    return [f"#{i + 1} {(e.get('commit') or '?')[:8]}{'+' if e.get('dirty') else ''} {(e.get('date') or '')[:10]}"
            for i, e in enumerate(entries)]


def _figures(entries: list[dict]):
    import plotly.graph_objects as go

    x = _x_labels(entries)
    failed = [not ((e["gate"].get("timing") is not False) and (e["gate"].get("quality") is not False))
              for e in entries]
    figs = []

    def one(title: str, ytitle: str, series: dict[str, list]):
        fig = go.Figure()
        for name, ys in sorted(series.items()):
            fig.add_trace(go.Scatter(x=x, y=ys, mode="lines+markers", name=name))
            bad = [(xi, y) for xi, y, f in zip(x, ys, failed) if f and y is not None]
            if bad:
                fig.add_trace(go.Scatter(x=[b[0] for b in bad], y=[b[1] for b in bad], mode="markers",
                                         marker={"symbol": "x", "size": 11, "color": "red"},
                                         name=f"{name}: gate failed", showlegend=False))
        fig.update_layout(title=title, yaxis_title=ytitle, xaxis_title="run (commit, date)", height=420,
                          margin={"l": 60, "r": 20, "t": 50, "b": 80}, legend={"font": {"size": 10}})
        figs.append(fig)

    names = sorted({n for e in entries for n in e.get("ratios", {})})
    if names:
        one("Benchmark ratios to the same-session reference (lower is faster)", "ratio",
            {n: [e.get("ratios", {}).get(n) for e in entries] for n in names})
    cells = sorted({c for e in entries for c in e.get("quality", {})})
    metrics = sorted({m for e in entries for c in e.get("quality", {}).values() for m in c if m != "status"})
    for m in metrics:
        series = {c: [_num(e.get("quality", {}).get(c, {}).get(m)) for e in entries] for c in cells}
        series = {c: ys for c, ys in series.items() if any(y is not None for y in ys)}
        if series:
            one(f"Quality: {m} per cell", m, series)
    return figs


def _num(v):
    if isinstance(v, bool):
        return float(v)
    return v if isinstance(v, (int, float)) else None


def plot_history(path: str | Path, out: str | Path) -> Path:
    """Write the self-contained HTML page of the history file ``path`` to ``out``."""
    import plotly.io as pio

    entries = read_history(path)
    figs = _figures(entries)
    parts = [pio.to_html(f, full_html=False, include_plotlyjs=(i == 0), default_height="420px")
             for i, f in enumerate(figs)]
    fails = sum(1 for e in entries if e["gate"].get("timing") is False or e["gate"].get("quality") is False)
    html = ("<!DOCTYPE html><html><head><meta charset='utf-8'><title>levelset-bench perf history</title></head>"
            "<body style='font-family:sans-serif'><h1>Performance and quality history</h1>"
            f"<p>{len(entries)} runs from {str(path)!r}; {fails} with a failed gate (red ✕).</p>"
            + "\n".join(f"<div class='figure'>{p}</div>" for p in parts) + "</body></html>")
    o = Path(out)
    try:
        o.parent.mkdir(parents=True, exist_ok=True)
        tmp = o.with_name(o.name + ".tmp")
        tmp.write_text(html, encoding="utf-8")
        tmp.replace(o)
    except OSError as exc:
        raise InputError(f"cannot write {str(o)!r}: {exc.strerror or exc}") from None
    return o
