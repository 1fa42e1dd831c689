"""geometry/ holds kernels that more than one user shares: a module only one method or only the report uses lives
beside its user (read from the source with ``ast``, through :func:`test_architecture.import_graph`)."""

from __future__ import annotations

from test_architecture import import_graph


def single_owner_geometry(graph: dict[str, set[str]]) -> list[str]:
    """``"module: owner"`` for every geometry module (not re-exported by the ``geometry`` package) whose users
    outside geometry — directly or through other geometry modules — all lie in one method or in the report."""
    def owner(m: str) -> str:
        parts = m.split(".")
        return ".".join(parts[:2]) if parts[0] == "methods" or parts[:2] == ["bench", "report"] else m

    users: dict[str, set[str]] = {}
    for m, targets in graph.items():
        for t in targets:
            users.setdefault(t, set()).add(m)
    found = []
    for module in sorted(m for m in graph if m.startswith("geometry.") and "geometry" not in users.get(m, ())):
        seen, todo = {module}, [module]
        while todo:                                    # the geometry modules that use it, directly or not
            inner = {u for u in users.get(todo.pop(), ()) if u.startswith("geometry.")} - seen
            seen |= inner
            todo += sorted(inner)
        outside = {owner(u) for m in seen for u in users.get(m, ()) if not u.startswith("geometry")}
        if len(outside) == 1 and next(iter(outside)).startswith(("methods.", "bench.report")):
            found.append(f"{module}: {outside.pop()}")
    return found


def test_geometry_holds_kernels_that_more_than_one_user_shares():
    """A module used only by one method or by the report lives beside it (dual contouring's manifold faces, the
    shape gradient's genus-0 start and the report's rasteriser did not); the check itself on a made-up graph."""
    assert single_owner_geometry(import_graph()) == []
    graph = {"geometry": {"geometry.a"}, "geometry.a": set(), "geometry.b": set(), "geometry.c": {"geometry.b"},
             "geometry.d": set(), "methods.m.x": {"geometry.c"}, "methods.m.y": {"geometry.b"},
             "bench.report.page": {"geometry.d"}, "methods.n": {"geometry.a", "geometry.d"}}
    assert single_owner_geometry(graph) == ["geometry.b: methods.m", "geometry.c: methods.m"]
