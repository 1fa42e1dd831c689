"""The layout contract, read from the source with ``ast`` (nothing is imported):

* packages stack strictly — ``geometry`` < ``phantoms`` < ``methods`` < ``bench``: no module imports a module of
  a higher package;
* no import cycle between modules (imports inside functions count: a lazy import hides a cycle, it does not
  remove it);
* no source file over 500 lines and no function over 100 lines;
* the README at most 250 lines, and every relative link in README.md and docs/*.md names an existing file;
* every function and class of the public API has a docstring with a numpydoc ``Parameters`` section naming
  each of its parameters (the rule: :func:`test_public_api_has_numpydoc_parameters`).
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


def test_the_report_reads_tolerances_from_the_metrics_not_from_the_performance_gate():
    """The report and the gates share the metric tolerances and the value comparison (bench.metrics.tolerances);
    the report never imports bench.perf."""
    graph = import_graph()
    assert [f"{m} imports {t}" for m in sorted(graph) if m.startswith("bench.report")
            for t in sorted(graph[m]) if t.startswith("bench.perf")] == []


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


#: a face's three edges taken by column pairs: faces[:, [0, 1]] with [1, 2] and [2, 0] in one statement
_EDGES = re.compile(r"\[:, *[\[(]0, *1[\])]\].*\[:, *[\[(]1, *2[\])]\].*\[:, *[\[(]2, *0[\])]\]")
#: the Euler characteristic V − E + F from counts
_EULER = re.compile(r"\w*(?:n_?v|vert)\w*[)\]]?\s*-\s*\w*\(?\w*(?:n_?e|edge)\w*[)\]]?\s*\+\s*\w*\(?\w*(?:n_?f|face)",
                    re.IGNORECASE)


#: trilinear weights: a weight times (1 − t) and times t of one axis in one statement (``a00 * uz, a00 * tz``)
_TRILINEAR = re.compile(r"\b(\w+)\s*\*\s*u[xyz]\s*,\s*\1\s*\*\s*t[xyz]\b")
#: the compiled copies of geometry.trilinear's sum, each compared with it by the tests: the batch kernel and
#: DistMesh's per-point sample inside its jitted loop (numba's cache does not follow a call into another file)
TRILINEAR_COMPILED = ("geometry.kernels", "methods.distmesh_loop")


def primitive_copies(sources: dict[str, Path], home: str, pattern: re.Pattern = _SIGNED_VOLUME) -> list[str]:
    """Source lines outside ``home`` that compute the primitive ``pattern`` matches themselves."""
    hits = []
    for name, path in sources.items():
        if name == home:
            continue
        for i, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1):
            if pattern.search(line):
                hits.append(f"{path.relative_to(REPO)}:{i}: {line.strip()}")
    return hits


def test_signed_volume_has_one_home():
    """geometry.mesh.signed_volume is the one implementation; everyone else calls it."""
    assert primitive_copies(_sources(), "geometry.mesh") == []


def test_edges_and_euler_characteristic_have_one_home():
    """A mesh's edges (geometry.topology.face_edge_keys / edges_unique) and its Euler characteristic
    (geometry.topology.euler_characteristic) are computed in geometry/topology.py only."""
    assert primitive_copies(_sources(), "geometry.topology", _EDGES) == []
    assert primitive_copies(_sources(), "geometry.topology", _EULER) == []


def test_trilinear_sampling_has_one_reference():
    """geometry.trilinear.trilinear_channels is the one numpy trilinear gather; the only other sums of its weights
    are the compiled copies of TRILINEAR_COMPILED (tests/test_geometry_kernels.py and
    tests/test_methods_distmesh_loop.py compare them with it)."""
    sources = {k: v for k, v in _sources().items() if k not in TRILINEAR_COMPILED}
    assert primitive_copies(sources, "geometry.trilinear", _TRILINEAR) == []


#: Ericson's point–triangle region test: one of its three Voronoi products (``va = d3 * d6 - d5 * d4``, ...)
_D = r"\bd[1-6](?:\[[^\]]*\])?"
_POINT_TRIANGLE = re.compile(rf"{_D}\s*\*\s*{_D}\s*-\s*{_D}\s*\*\s*{_D}")


def test_the_closest_point_on_a_triangle_has_one_home():
    """geometry.closest.point_triangle (compiled) and its numpy reference closest_point_on_triangles, equal bit for
    bit (tests/test_geometry_closest.py), are the one point–triangle test: the metrics' distance, the mesh phantoms'
    search index and their grid signed distance call it, with one rule for degenerate triangles."""
    assert primitive_copies(_sources(), "geometry.closest", _POINT_TRIANGLE) == []


def test_the_primitive_check_finds_a_copy(tmp_path):
    p = tmp_path / "copy.py"
    p.write_text("vol = float(np.einsum('ij,ij->i', a, np.cross(b, c)).sum()) / 6.0\n")
    global REPO
    saved, REPO = REPO, tmp_path
    try:
        assert len(primitive_copies({"copy": p}, "geometry.mesh")) == 1
        p.write_text("e = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])\n"
                     "chi = len(vertices) - len(edges) + len(faces)\n"
                     "chi2 = n_vertices - n_edges + n_faces\n")
        assert len(primitive_copies({"copy": p}, "geometry.topology", _EDGES)) == 1
        assert len(primitive_copies({"copy": p}, "geometry.topology", _EULER)) == 2
        p.write_text("w = (a * uz, a * tz)\nv = (a * uz, b * tz)\n")
        assert len(primitive_copies({"copy": p}, "geometry.trilinear", _TRILINEAR)) == 1
        p.write_text("va = d3 * d6 - d5 * d4\nvb = d5[sel] * d2[sel] - d1[sel] * d6[sel]\nx = d1 * d4\n")
        assert len(primitive_copies({"copy": p}, "geometry.closest", _POINT_TRIANGLE)) == 2
    finally:
        REPO = saved


# ------------------------------------------------------------------------------------------ the public API's docstrings
#: the public API: the functions and classes these modules export (``__all__``; without it, the top-level
#: functions and classes whose names do not start with ``_``), wherever they are defined
PUBLIC_API = ("phantoms", "methods", "methods.base", "methods.contract", "methods.registry", "bench.metrics",
              "bench.run", "bench.check")
#: ``module.name`` of public definitions the check leaves out (none)
DOCSTRING_EXEMPT: set[str] = set()
_SECTION_RULE = re.compile(r"^-{3,}$")


def _exports(tree: ast.Module) -> list[str]:
    for node in tree.body:
        if isinstance(node, ast.Assign) and any(isinstance(t, ast.Name) and t.id == "__all__" for t in node.targets):
            return list(ast.literal_eval(node.value))
    return [n.name for n in tree.body
            if isinstance(n, (ast.FunctionDef, ast.ClassDef)) and not n.name.startswith("_")]


def _definition(sources: dict[str, Path], module: str, name: str):
    """``(module, node)`` of the function or class ``name`` as ``module`` exports it, followed through
    re-exports (``from .x import name``); ``(module, None)`` for a constant or a name from outside the suite."""
    path = sources[module]
    tree = ast.parse(path.read_text(encoding="utf-8"))
    for node in tree.body:
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)) and node.name == name:
            return module, node
    for node in tree.body:
        if isinstance(node, ast.ImportFrom):
            for alias in node.names:
                if (alias.asname or alias.name) == name:
                    target = _resolve(module, path.name == "__init__.py", node)
                    if target in sources:
                        return _definition(sources, target, alias.name)
    return module, None


def documented_parameters(doc: str) -> set[str] | None:
    """The names a numpydoc ``Parameters`` section lists (``a, b : type`` is two; stars dropped), or None
    without one."""
    lines = doc.splitlines()
    for i in range(len(lines) - 1):
        if lines[i].strip() == "Parameters" and _SECTION_RULE.match(lines[i + 1].strip()):
            names: set[str] = set()
            for j in range(i + 2, len(lines)):
                if j + 1 < len(lines) and _SECTION_RULE.match(lines[j + 1].strip()):
                    break                                   # the next section
                if lines[j] and not lines[j][0].isspace():  # an entry (its description is indented)
                    names.update(n.strip().lstrip("*") for n in lines[j].split(" : ")[0].split(","))
            return names
    return None


def _signature_parameters(fn: ast.FunctionDef | ast.AsyncFunctionDef) -> list[str]:
    a = fn.args
    names = [x.arg for x in a.posonlyargs + a.args + a.kwonlyargs]
    names += [x.arg for x in (a.vararg, a.kwarg) if x is not None]
    return [n for n in names if n not in ("self", "cls")]


def _is_dataclass(cls: ast.ClassDef) -> bool:
    for d in cls.decorator_list:
        d = d.func if isinstance(d, ast.Call) else d
        if (d.id if isinstance(d, ast.Name) else getattr(d, "attr", "")) == "dataclass":
            return True
    return False


def _constructor_parameters(cls: ast.ClassDef) -> tuple[list[str], str]:
    """A class's constructor parameters (its own ``__init__``'s, or a dataclass's init fields) and the
    ``__init__``'s docstring."""
    for node in cls.body:
        if isinstance(node, ast.FunctionDef) and node.name == "__init__":
            return _signature_parameters(node), ast.get_docstring(node) or ""
    if not _is_dataclass(cls):
        return [], ""
    fields = []
    for node in cls.body:
        if not (isinstance(node, ast.AnnAssign) and isinstance(node.target, ast.Name)):
            continue
        if "ClassVar" in ast.unparse(node.annotation):
            continue
        v = node.value
        if isinstance(v, ast.Call) and any(k.arg == "init" and isinstance(k.value, ast.Constant)
                                           and k.value.value is False for k in v.keywords):
            continue
        fields.append(node.target.id)
    return fields, ""


def docstring_problems(sources: dict[str, Path], modules, exempt=frozenset()) -> list[str]:
    """``"module.name: problem"`` for every exported function or class of ``modules`` whose docstring is
    missing, has no ``Parameters`` section although it takes parameters, or leaves some of them out."""
    problems, seen = [], set()
    for module in modules:
        for name in _exports(ast.parse(sources[module].read_text(encoding="utf-8"))):
            home, node = _definition(sources, module, name)
            where = f"{home}.{name}"
            if node is None or where in seen or where in exempt:
                continue
            seen.add(where)
            doc = ast.get_docstring(node) or ""
            if not doc:
                problems.append(f"{where}: no docstring")
                continue
            if isinstance(node, ast.ClassDef):
                params, init_doc = _constructor_parameters(node)
                listed = documented_parameters(doc)
                listed = listed if listed is not None else documented_parameters(init_doc)
            else:
                params, listed = _signature_parameters(node), documented_parameters(doc)
            if params and listed is None:
                problems.append(f"{where}: no Parameters section (takes {', '.join(params)})")
            elif params and set(params) - listed:
                missing = [p for p in params if p not in listed]
                problems.append(f"{where}: Parameters section leaves out {', '.join(missing)}")
    return problems


def test_public_api_has_numpydoc_parameters():
    """Every function and class of the public API (:data:`PUBLIC_API`) has a docstring, and one that takes
    parameters has a numpydoc ``Parameters`` section naming each of them.

    The rule: a function's parameters are its signature's, ``self`` / ``cls`` left out (``*args`` and
    ``**kwargs`` count, written with or without their stars); a class's are its constructor's — its own
    ``__init__``'s, or a dataclass's fields (``ClassVar`` and ``field(init=False)`` left out), documented in
    the class docstring (numpydoc's convention) or the ``__init__``'s.  A function without parameters, or a
    class that adds no constructor of its own (an exception class, an abstract base), needs the docstring
    only.  Constants are documented by their ``#:`` comments and not checked here; neither are methods.
    """
    assert docstring_problems(_sources(), PUBLIC_API, DOCSTRING_EXEMPT) == []


def test_the_docstring_check_finds_a_missing_parameter(tmp_path):
    """The check above on made-up modules: a re-exported function with an undocumented parameter, a function
    and a dataclass without a Parameters section, a function without a docstring are reported; a complete one,
    a function without parameters and a constant are not."""
    pkg = tmp_path / "pkg"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("from .a import f, g, ok\n__all__ = ['f', 'g', 'ok', 'C', 'N', 'h', 'none']\n"
                                     "N = 1\ndef h(x):\n    pass\ndef none():\n    '''No parameters.'''\n"
                                     "from dataclasses import dataclass\n"
                                     "@dataclass\nclass C:\n    '''A class.'''\n    x: int\n")
    (pkg / "a.py").write_text(
        "def f(a, *, b=1):\n    '''F.\n\n    Parameters\n    ----------\n    a : int\n        A.\n\n"
        "    Returns\n    -------\n    b : int\n    '''\n"
        "def g(x):\n    '''G, with no section.'''\n"
        "def ok(x, y, **kw):\n    '''Ok.\n\n    Parameters\n    ----------\n    x, y : float\n    **kw\n"
        "        Rest.\n    '''\n")
    sources = {"pkg": pkg / "__init__.py", "pkg.a": pkg / "a.py"}
    assert docstring_problems(sources, ["pkg"]) == [
        "pkg.a.f: Parameters section leaves out b", "pkg.a.g: no Parameters section (takes x)",
        "pkg.C: no Parameters section (takes x)", "pkg.h: no docstring"]


# ------------------------------------------------------------------------------------ settings resolved in one place
#: a name holds settings when it contains one of these (``cfg``, ``self.config``, ``settings``, ``stage``, ...)
_SETTINGS_NAMES = ("cfg", "config", "setting", "param", "stage", "option")


def _holds_settings(node: ast.expr) -> bool:
    name = node.id if isinstance(node, ast.Name) else getattr(node, "attr", "")
    return any(word in name.lower() for word in _SETTINGS_NAMES)


def settings_defaults(paths) -> list[str]:
    """``"file:line: call"`` for every read of a setting with a fallback of its own: ``<settings>.get(key,
    default)`` (a default given positionally or by keyword) or ``getattr(<settings>, name, default)``, where
    ``<settings>`` is a name or attribute that holds settings (:data:`_SETTINGS_NAMES`)."""
    hits = []
    for path in paths:
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"), str(path))):
            if not isinstance(node, ast.Call):
                continue
            f = node.func
            by_get = (isinstance(f, ast.Attribute) and f.attr == "get" and _holds_settings(f.value)
                      and len(node.args) + len(node.keywords) >= 2)
            by_getattr = (isinstance(f, ast.Name) and f.id == "getattr" and len(node.args) == 3
                          and _holds_settings(node.args[0]))
            if by_get or by_getattr:
                hits.append((str(path.relative_to(REPO)), node.lineno, ast.unparse(node)))
    return [f"{p}:{line}: {call}" for p, line, call in sorted(hits)]


#: reads with a fallback that restate no declared default, each with why it is not one
_SETTINGS_DEFAULTS_ALLOWED = {
    # a phantom without phantom-specific parameters has none: the empty dict is the absence, not a default
    "bench/config.py: self.phantom_params.get(phantom, {})",
    # the stored config of a run folder, possibly written before the name and description were stored
    "bench/report/page.py: config.get('name', 'run')",
    "bench/report/page.py: config.get('description', '')",
}


def test_settings_are_read_without_defaults_of_their_own():
    """bench/ and methods/ resolve settings once (a method's Params, the shape gradient's FlowSettings, the
    dataclasses of bench.config and bench.run.options): no module reads a setting with a default of its own,
    which could contradict the documented default — apart from the reviewed reads of
    :data:`_SETTINGS_DEFAULTS_ALLOWED`."""
    paths = sorted((REPO / "bench").rglob("*.py")) + sorted((REPO / "methods").rglob("*.py"))
    hits = [h for h in settings_defaults(paths) if h.split(":")[0] + ":" + h.split(":", 2)[2]
            not in _SETTINGS_DEFAULTS_ALLOWED]
    assert hits == []


def test_the_settings_check_finds_a_default(tmp_path):
    """The check above on a made-up module: defaults read from cfg, self.config, a stage and by getattr are
    reported; a lookup without a default, a dict that holds no settings and a plain attribute are not."""
    p = tmp_path / "flow.py"
    p.write_text("a = cfg.get('guard', False)\nb = self.config.get('x', default=1)\nc = stage.get('beta', 1.0)\n"
                 "d = getattr(settings, 'tol', 0.0)\ne = cfg.get('x')\nf = topology.get('compatible', True)\n"
                 "g = settings.tol\n")
    global REPO
    saved, REPO = REPO, tmp_path
    try:
        hits = settings_defaults([p])
    finally:
        REPO = saved
    assert [h.split(": ")[0] for h in hits] == ["flow.py:1", "flow.py:2", "flow.py:3", "flow.py:4"]
