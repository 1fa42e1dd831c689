"""The gate (:func:`gate`, a pure function) and the table ``bench perf`` prints.

``change = ratio / baseline_ratio − 1``; a benchmark **fails** when ``change > tolerance`` (default 0.5: more
than 50 % slower relative to the reference).  Benchmarks only in the run are ``new`` and benchmarks only in the
baseline are ``missing`` (or ``skipped`` when the run said so, e.g. ``--quick``); neither fails unless
``fail_on_missing``.  A benchmark without a ratio (e.g. run with ``--benchmark-disable``) is ``no ratio``.
Faster than the baseline by the same factor (``ratio < baseline / (1 + tolerance)``) is ``faster`` — time to
refresh the baseline so the gate keeps its sensitivity.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from ..metrics.tolerances import finite

__all__ = ["DEFAULT_TOLERANCE", "OK", "FASTER", "REGRESSION", "NEW", "MISSING", "SKIPPED", "NO_RATIO",
           "GateResult", "gate", "format_seconds", "format_table"]

DEFAULT_TOLERANCE = 0.5

#: statuses of :func:`gate` rows
OK, FASTER, REGRESSION, NEW, MISSING, SKIPPED, NO_RATIO = ("ok", "faster", "REGRESSION", "new", "missing",
                                                          "skipped", "no ratio")


@dataclass
class GateResult:
    """Rows (one per benchmark, sorted by name) and the verdict of :func:`gate`."""

    rows: list[dict] = field(default_factory=list)
    tolerance: float = DEFAULT_TOLERANCE
    compared: bool = True

    @property
    def failures(self) -> list[str]:
        return [r["name"] for r in self.rows if r["failed"]]

    @property
    def passed(self) -> bool:
        return not self.failures


def _bench_map(summary: dict | None) -> dict[str, dict]:
    if summary is None:
        return {}
    b = summary.get("benchmarks", summary)
    # allow the plain form {name: ratio}
    return {k: (v if isinstance(v, dict) else {"ratio": v}) for k, v in b.items()}


def gate(baseline: dict | None, current: dict, tolerance: float = DEFAULT_TOLERANCE, *,
         fail_on_missing: bool = False, metric: str = "cpu") -> GateResult:
    """Compare the ratios of ``current`` with those of ``baseline`` (summaries, or plain ``{name: ratio}``).

    ``metric``: ``"cpu"`` compares the CPU-time ratios (``cpu_ratio``) of the benchmarks that have one on both
    sides and the wall-clock ratios of the others; ``"wall"`` always the wall-clock ratios (``ratio``).
    Pure: no I/O.  ``baseline=None`` gives the rows without a verdict (every row passes).  See the module
    docstring for the statuses.
    """
    if not (tolerance >= 0 and math.isfinite(tolerance)):
        raise ValueError(f"tolerance must be a finite number >= 0, got {tolerance!r}")
    if metric not in ("cpu", "wall"):
        raise ValueError(f"metric must be 'cpu' or 'wall', got {metric!r}")
    base, cur = _bench_map(baseline), _bench_map(current)
    skipped = set((current or {}).get("skipped") or []) if isinstance(current, dict) else set()
    rows = []
    for name in sorted(set(base) | set(cur)):
        b, c = base.get(name), cur.get(name)
        key = "ratio"
        if metric == "cpu" and (c is None or finite(c.get("cpu_ratio")) is not None) \
                and (b is None or finite(b.get("cpu_ratio")) is not None):
            key = "cpu_ratio"
        row = {"name": name, "median_s": (c or {}).get("median_s"), "wall_ratio": finite((c or {}).get("ratio")),
               "cpu_ratio": finite((c or {}).get("cpu_ratio")), "metric": "cpu" if key == "cpu_ratio" else "wall",
               "ratio": finite((c or {}).get(key)), "baseline_ratio": finite((b or {}).get(key)),
               "baseline_median_s": (b or {}).get("median_s"), "change": None, "failed": False}
        if c is None:
            row["status"] = SKIPPED if name in skipped else MISSING
            row["failed"] = fail_on_missing and baseline is not None and name not in skipped
        elif baseline is None:
            row["status"] = OK if row["ratio"] is not None else NO_RATIO
        elif b is None:
            row["status"] = NEW
        elif row["ratio"] is None or row["baseline_ratio"] is None or row["baseline_ratio"] <= 0:
            row["status"] = NO_RATIO
        else:
            change = row["ratio"] / row["baseline_ratio"] - 1.0
            row["change"] = change
            if change > tolerance:
                row["status"], row["failed"] = REGRESSION, True
            elif row["ratio"] * (1.0 + tolerance) < row["baseline_ratio"]:
                row["status"] = FASTER
            else:
                row["status"] = OK
        rows.append(row)
    return GateResult(rows=rows, tolerance=tolerance, compared=baseline is not None)


def format_seconds(v) -> str:
    if v is None:
        return "–"
    return f"{v * 1e3:.1f} ms" if v < 1 else f"{v:.2f} s"


def format_table(result: GateResult) -> str:
    """The perf table: benchmark, median time, ratio, baseline ratio, change, status."""
    head = ["benchmark", "median", "ratio", "cpu ratio"] + (["baseline", "change", "status"] if result.compared
                                                            else [])
    body = []
    for r in result.rows:
        wall, cpu = r.get("wall_ratio", r["ratio"]), r.get("cpu_ratio")
        line = [r["name"], format_seconds(r["median_s"]), "–" if wall is None else f"{wall:.3f}",
                "–" if cpu is None else f"{cpu:.3f}"]
        if result.compared:
            # the baseline of the ratio the gate compared (marked * for the wall-clock ratio)
            line += ["–" if r["baseline_ratio"] is None else f"{r['baseline_ratio']:.3f}"
                     + ("*" if r.get("metric") == "wall" else ""),
                     "–" if r["change"] is None else f"{100 * r['change']:+.0f} %", r["status"]]
        body.append(line)
    widths = [max(len(str(x)) for x in col) for col in zip(head, *body)] if body else [len(h) for h in head]
    fmt = lambda cells: "  ".join(str(c).ljust(w) if i == 0 else str(c).rjust(w)  # noqa: E731
                                  for i, (c, w) in enumerate(zip(cells, widths)))
    lines = [fmt(head), "  ".join("-" * w for w in widths)] + [fmt(b) for b in body]
    return "\n".join(lines)
