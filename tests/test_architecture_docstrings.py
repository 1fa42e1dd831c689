"""Docstrings say what and why, not one machine's timings: those go to docs/NOTES.md with the command that
reproduces them (a docstring that quotes seconds goes stale on the next machine, and two docstrings quoting the
same query on two machines contradict each other).  Nor do docstrings, comments and parameter docs point to the
developers' notes or quote a measured figure (a speed-up, a before/after metric value, a date): a reason worth
keeping is said in the source or in docs/METHOD.md; the measurement stays in the notes."""

from __future__ import annotations

import ast
import io
import re
import tokenize
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


#: a pointer to the developers' notes (docs/NOTES.md)
_NOTES = re.compile(r"\bNOTES\b")

#: a measured figure: a speed ratio ("4× faster"), a relative cost ("25 % slower", "40 % less"), a number given as
#: measured ("measured 117–138"), a metric value of a run ("Hausdorff 1.49 h", "2.5 h without it"), or the date of a
#: measurement
_FIGURE = re.compile("|".join((
    r"\d+(?:[.,]\d+)?\s?(?:×|x|times)\s+(?:faster|slower)\b",
    r"\d+(?:[.,]\d+)?(?:\s?[–-]\s?\d+(?:[.,]\d+)?)?\s?%\s+(?:faster|slower|less|more)\b",
    r"\bmeasured:?\s+[~≈]?\d",
    r"\b(?:Hausdorff|mean distance)\b[^.;()]{0,24}?\d+\.\d+\s?h\b",
    r"\d+\.\d+\s?h\s+with(?:out)?\b",
    r"\b20\d\d-\d\d-\d\d\b",
)))

#: figures that are not measurements, each with why
_FIGURES_ALLOWED = {
    ("bench/perf/gate.py", "50 % slower"),                    # the gate's tolerance: a threshold, not a result
}


def documentation(path: Path):
    """``(line, text)`` of every module, class and function docstring, every comment and every parameter's doc (the
    text of a ``Param(default, doc, ...)``, which ``python -m bench methods`` prints) of the module ``path``."""
    source = path.read_text(encoding="utf-8")
    for node in ast.walk(ast.parse(source, str(path))):
        if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)):
            doc = ast.get_docstring(node)
            if doc:
                yield getattr(node, "lineno", 1), doc
        elif isinstance(node, ast.Call) and getattr(node.func, "id", getattr(node.func, "attr", None)) == "Param":
            docs = [a for a in node.args[1:2] + [k.value for k in node.keywords if k.arg == "doc"]]
            for a in docs:
                if isinstance(a, ast.Constant) and isinstance(a.value, str):
                    yield a.lineno, a.value
    for tok in tokenize.generate_tokens(io.StringIO(source).readline):
        if tok.type == tokenize.COMMENT:
            yield tok.start[0], tok.string


def documentation_hits(paths, pattern: re.Pattern, allowed=frozenset(), root: Path = REPO) -> list[str]:
    """``"file:line: match (context)"`` for every match of ``pattern`` in the documentation of ``paths`` (see
    :func:`documentation`), except the ``(file, text)`` pairs of ``allowed`` whose text is in the context."""
    hits = []
    for path in paths:
        rel = str(path.relative_to(root))
        for line, text in documentation(path):
            for m in pattern.finditer(text):
                context = text[max(0, m.start() - 20):m.end() + 12].replace("\n", " ")
                if not any(rel == f and a in context for f, a in allowed):
                    hits.append(f"{rel}:{line}: {m.group(0)} ({context})")
    return hits


def _source_paths():
    return [p for top in ("geometry", "phantoms", "methods", "bench") for p in sorted((REPO / top).rglob("*.py"))]


def test_no_docstring_or_comment_points_to_the_notes():
    assert documentation_hits(_source_paths(), _NOTES) == []


def test_no_docstring_or_comment_quotes_a_measured_figure():
    assert documentation_hits(_source_paths(), _FIGURE, _FIGURES_ALLOWED) == []


def test_the_notes_and_figure_checks_find_one(tmp_path):
    """The checks on a made-up module: a pointer to the notes in a docstring, a comment and a parameter's doc, and
    measured figures, are found; a constant with its unit, a count, a mapping and the word "notes" are not."""
    p = tmp_path / "m.py"
    p.write_text(
        '"""Faster (docs/NOTES.md); 4× faster than numpy, 30 % slower in float32."""\n'
        "# the bunny: Hausdorff 1.49 h (2026-11-23); measured 117-138 steps; 0.70 h with it\n"
        "P = {'a': Param(1.0, 'the sweep: NOTES.md', float)}\n"
        "# why: see NOTES\n\n"
        "def f():\n"
        '    """Within 3 h of the surface, the step halved 4 times; notes on the cap; 1,896 → 3,788 faces."""\n'
        "    return 0.5  # ½ voxel, 10 % of the band\n")
    notes = sorted(h.split(" (")[0] for h in documentation_hits([p], _NOTES, root=tmp_path))
    assert notes == ["m.py:1: NOTES", "m.py:3: NOTES", "m.py:4: NOTES"]
    figures = sorted(h.split(" (")[0] for h in documentation_hits([p], _FIGURE, root=tmp_path))
    assert figures == ["m.py:1: 30 % slower", "m.py:1: 4× faster", "m.py:2: 0.70 h with", "m.py:2: 2026-11-23",
                       "m.py:2: Hausdorff 1.49 h", "m.py:2: measured 1"]
    left = documentation_hits([p], _FIGURE, {("m.py", "4× faster"), ("m.py", "30 %")}, root=tmp_path)
    assert [h.split(":")[1] for h in left] == ["2", "2", "2", "2"]           # the allowed figures of line 1 are not
