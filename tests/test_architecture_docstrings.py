"""Docstrings say what and why, not one machine's timings: those go to docs/NOTES.md with the command that
reproduces them (a docstring that quotes seconds goes stale on the next machine, and two docstrings quoting the
same query on two machines contradict each other)."""

from __future__ import annotations

import ast
import re
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]

#: a duration: a number followed by a unit of time (not part of an identifier, a power or a quote)
_DURATION = re.compile(r"(?<![\w.=])\d+(?:[.,]\d+)?\s?(?:ms|µs|s|min)\b(?![\w²³'])")

#: durations that are not measurements, each with why: a target, a default, an example of a message or a format
_ALLOWED = {
    ("geometry/kernels.py", "0.1 s target"),                  # the target the kernels were written for
    ("bench/perf/history.py", "15 min"),                      # the load averages' windows (1, 5, 15 min)
    ("bench/run/cost.py", "default 2 ms"),                    # a parameter's default
    ("bench/run/estimate.py", "47 min"),                      # an example of the refusal message
    ("bench/run/estimate.py", "10 min"),
    ("bench/run/estimate.py", "45 s"),                        # examples of the duration format
    ("bench/run/limits.py", "0.05 s"),                        # a made-up case explaining the limits
    ("bench/run/limits.py", "30 s"),
    ("bench/run/runner.py", "4 min"),                         # an example progress line
}


def docstring_durations(paths, root: Path = REPO) -> list[str]:
    """``"file: duration"`` for every duration in a module, class or function docstring of ``paths``."""
    hits = []
    for path in paths:
        tree = ast.parse(path.read_text(encoding="utf-8"), str(path))
        for node in ast.walk(tree):
            if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)):
                doc = ast.get_docstring(node) or ""
                for m in _DURATION.finditer(doc):
                    context = doc[max(0, m.start() - 20):m.end() + 8].replace("\n", " ")
                    hits.append((str(path.relative_to(root)), m.group(0), context))
    return [f"{p}: {d} ({c})" for p, d, c in hits if not any(p == f and a in c for f, a in _ALLOWED)]


def test_no_docstring_quotes_a_timing():
    paths = [p for top in ("geometry", "phantoms", "methods", "bench") for p in sorted((REPO / top).rglob("*.py"))]
    assert docstring_durations(paths) == []


def test_the_timing_check_finds_one(tmp_path):
    """The check on a made-up module: seconds and milliseconds in docstrings are found; a number of samples, a
    power and a name are not."""
    p = tmp_path / "m.py"
    p.write_text('"""Fast: 0.12 s at N = 96."""\n\ndef f():\n    """About 5 ms, 3 samples, h³, n_s=2 s_max."""\n')
    assert [h.split(" (")[0] for h in docstring_durations([p], tmp_path)] == ["m.py: 0.12 s", "m.py: 5 ms"]
