"""The layout contract, read from the source with ``ast`` (nothing is imported):

* packages stack strictly — ``geometry`` < ``phantoms`` < ``methods`` < ``bench``: no module imports a module of
  a higher package;
* no import cycle between modules (imports inside functions count: a lazy import hides a cycle, it does not
  remove it);
* no source file over 500 lines and no function over 100 lines;
* the README at most 250 lines, and every relative link in README.md and docs/*.md names an existing file.
"""

from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parent.parent
LAYERS = ("geometry", "phantoms", "methods", "bench")
MAX_FILE_LINES = 500
MAX_FUNCTION_LINES = 100


def _module_name(path: Path) -> str:
    parts = list(path.relative_to(REPO).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def _sources() -> dict[str, Path]:
    return {_module_name(p): p for layer in LAYERS for p in sorted((REPO / layer).rglob("*.py"))}


def _resolve(module: str, is_package: bool, node: ast.ImportFrom) -> str:
    if not node.level:
        return node.module or ""
    base = module.split(".") if is_package else module.split(".")[:-1]
    base = base[: len(base) - (node.level - 1)]
    return ".".join(base + ([node.module] if node.module else []))


def import_graph(sources: dict[str, Path] | None = None) -> dict[str, set[str]]:
    """``{module: {suite modules it imports}}`` for every module of the four packages."""
    sources = sources or _sources()
    graph: dict[str, set[str]] = {}
    for module, path in sources.items():
        is_package = path.name == "__init__.py"
        targets: set[str] = set()
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom):
                base = _resolve(module, is_package, node)
                names = [f"{base}.{a.name}" if f"{base}.{a.name}" in sources else base for a in node.names]
            else:
                continue
            for name in names:
                while name and name not in sources:  # `import a.b.c` of a non-module name: its module
                    name = name.rpartition(".")[0]
                if name and name != module:
                    targets.add(name)
        graph[module] = targets
    return graph


def find_cycle(graph: dict[str, set[str]]) -> list[str] | None:
    """One import cycle as a list of modules (first = last), or None."""
    state: dict[str, int] = {}
    stack: list[str] = []

    def visit(m: str) -> list[str] | None:
        state[m] = 1
        stack.append(m)
        for t in sorted(graph.get(m, ())):
            if state.get(t) == 1:
                return stack[stack.index(t):] + [t]
            if t not in state:
                found = visit(t)
                if found:
                    return found
        stack.pop()
        state[m] = 2
        return None

    for m in sorted(graph):
        if m not in state:
            found = visit(m)
            if found:
                return found
    return None


def layer_violations(graph: dict[str, set[str]]) -> list[str]:
    rank = {name: i for i, name in enumerate(LAYERS)}
    return [f"{m} imports {t}" for m, targets in sorted(graph.items()) for t in sorted(targets)
            if rank[t.split(".")[0]] > rank[m.split(".")[0]]]


def test_lower_packages_never_import_higher_ones():
    assert layer_violations(import_graph()) == []


def test_no_import_cycle_between_modules():
    assert find_cycle(import_graph()) is None


def test_the_checks_catch_a_cycle_and_an_upward_import(tmp_path):
    """The two checks above on a made-up graph that breaks both rules (so they can fail)."""
    graph = {"phantoms.a": {"phantoms.b"}, "phantoms.b": {"phantoms.a"}, "geometry.x": {"bench.y"},
             "bench.y": set()}
    assert find_cycle(graph) in (["phantoms.a", "phantoms.b", "phantoms.a"], ["phantoms.b", "phantoms.a", "phantoms.b"])
    assert layer_violations(graph) == ["geometry.x imports bench.y"]


def test_relative_and_lazy_imports_are_resolved(tmp_path):
    """A lazy relative import inside a function is an edge of the graph."""
    pkg = tmp_path / "pkg"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("")
    (pkg / "a.py").write_text("def f():\n    from .b import g\n    return g\n")
    (pkg / "b.py").write_text("from . import a\n")
    sources = {"pkg": pkg / "__init__.py", "pkg.a": pkg / "a.py", "pkg.b": pkg / "b.py"}
    global REPO
    saved, REPO = REPO, tmp_path
    try:
        graph = import_graph(sources)
    finally:
        REPO = saved
    assert graph["pkg.a"] == {"pkg.b"} and graph["pkg.b"] == {"pkg.a"}
    assert find_cycle(graph) is not None


@pytest.mark.parametrize("layer", LAYERS)
def test_no_source_file_over_500_lines(layer):
    long = {str(p.relative_to(REPO)): n for p in (REPO / layer).rglob("*.py")
            for n in [len(p.read_text().splitlines())] if n > MAX_FILE_LINES}
    assert long == {}


@pytest.mark.parametrize("layer", LAYERS)
def test_no_function_over_100_lines(layer):
    long = {}
    for p in (REPO / layer).rglob("*.py"):
        for node in ast.walk(ast.parse(p.read_text())):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                n = node.end_lineno - node.lineno + 1
                if n > MAX_FUNCTION_LINES:
                    long[f"{p.relative_to(REPO)}:{node.lineno} {node.name}"] = n
    assert long == {}


# ------------------------------------------------------------------------------------------------ the documentation
README_MAX_LINES = 250
LINK = re.compile(r"\]\(([^)\s]+)\)")


def broken_links(docs: list[Path]) -> list[str]:
    """``"file: target"`` for every relative markdown link whose file does not exist (anchors and URLs skipped)."""
    broken = []
    for doc in docs:
        for target in LINK.findall(doc.read_text(encoding="utf-8")):
            path = target.split("#", 1)[0]
            if not path or re.match(r"[a-z][a-z0-9+.-]*:", path):  # an anchor in the same page, or a URL
                continue
            if not (doc.parent / path).exists():
                broken.append(f"{doc.name}: {target}")
    return broken


def test_readme_is_at_most_250_lines():
    """The README is for users; the reference and the measurements live in docs/."""
    n = len((REPO / "README.md").read_text(encoding="utf-8").splitlines())
    assert n <= README_MAX_LINES, f"README.md has {n} lines (at most {README_MAX_LINES}; move detail to docs/)"


def test_relative_markdown_links_point_to_existing_files():
    """Every relative link (``](docs/...)``, ``](....md)``) in README.md and docs/*.md names an existing file."""
    assert broken_links([REPO / "README.md", *sorted((REPO / "docs").glob("*.md"))]) == []


def test_the_link_check_finds_a_broken_link(tmp_path):
    """The check above on a made-up page: a missing file is reported; anchors, URLs and existing files are not."""
    (tmp_path / "docs").mkdir()
    (tmp_path / "docs" / "GUIDE.md").write_text("# Guide\n")
    page = tmp_path / "README.md"
    page.write_text("[a](docs/NOPE.md) [b](#x) [c](https://example.org/a.md) [d](docs/GUIDE.md#guide)\n")
    assert broken_links([page]) == ["README.md: docs/NOPE.md"]


# ---------------------------------------------------------------------------------------------- one home per primitive
#: the signed-volume formula Σ v0 · (v1 × v2) / 6: a cross product and a division by 6 in one statement
_SIGNED_VOLUME = re.compile(r"np\.cross\([^\n]*\)[^\n]*/\s*6(\.0)?\b|/\s*6(\.0)?\b[^\n]*np\.cross\(")


def primitive_copies(sources: dict[str, Path], home: str) -> list[str]:
    """Source lines outside ``home`` that compute a signed volume themselves."""
    hits = []
    for name, path in sources.items():
        if name == home:
            continue
        for i, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1):
            if _SIGNED_VOLUME.search(line):
                hits.append(f"{path.relative_to(REPO)}:{i}: {line.strip()}")
    return hits


def test_signed_volume_has_one_home():
    """geometry.mesh.signed_volume is the one implementation; everyone else calls it."""
    assert primitive_copies(_sources(), "geometry.mesh") == []


def test_the_primitive_check_finds_a_copy(tmp_path):
    p = tmp_path / "copy.py"
    p.write_text("vol = float(np.einsum('ij,ij->i', a, np.cross(b, c)).sum()) / 6.0\n")
    global REPO
    saved, REPO = REPO, tmp_path
    try:
        assert len(primitive_copies({"copy": p}, "geometry.mesh")) == 1
    finally:
        REPO = saved
