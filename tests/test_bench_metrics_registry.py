"""The metric registry (bench.metrics.registry): one entry per reported metric, well-formed facts."""

from __future__ import annotations

import dataclasses

import pytest

from bench.metrics import METRIC_NAMES
from bench.metrics.registry import METRICS, Metric


def test_every_metric_column_has_an_entry_in_the_same_order():
    assert list(METRICS) == list(METRIC_NAMES)
    assert all(m.name == k for k, m in METRICS.items())
    assert {m.kind for m in METRICS.values()} <= {"distance", "distance_h", "truth", "truth_free", "fidelity", "runner"}
    assert [k for k, m in METRICS.items() if m.kind == "distance_h"] == [
        f"{k}_h" for k, m in METRICS.items() if m.kind == "distance"]


def test_evaluate_returns_exactly_the_registered_metrics_it_owns():
    """The registry is the schema: with truth every non-runner metric, without truth the truth-free ones."""
    import trimesh

    from bench.metrics import evaluate
    from phantoms import get_phantom

    mesh = trimesh.creation.icosphere(subdivisions=2, radius=1.0)
    with_truth = evaluate(mesh, get_phantom("sphere"), 0.1, n_samples=2000)
    assert list(with_truth) == [k for k, m in METRICS.items() if m.kind != "runner"]
    without = evaluate(mesh, None, 0.1, n_samples=2000)
    assert list(without) == [k for k, m in METRICS.items() if m.kind in ("truth_free", "fidelity")]


def test_facts_are_well_formed():
    for m in METRICS.values():
        assert m.dtype in ("float", "int", "bool"), m
        assert m.best in ("min", "max", None) or (isinstance(m.best, tuple) and m.best[0] == "target"), m
        assert m.meaning and "\n" not in m.meaning, m
        assert isinstance(m.unit, str), m


def test_facts_the_report_relies_on():
    assert METRICS["watertight"].dtype == "bool"
    assert {k for k, m in METRICS.items() if m.dtype == "int"} == {
        "euler", "components", "self_intersections", "n_vertices", "n_faces", "iterations", "boundary_edges",
        "nonmanifold_edges", "data_parts", "data_cavities", "data_handles", "mesh_voids", "mesh_genus",
        "topology_diffs"}
    assert all(METRICS[f"{k}_h"].best == "min" for k in ("hausdorff", "hausdorff_95", "mean_dist", "rms_dist"))
    assert METRICS["euler"].best == ("target", 2) and METRICS["components"].best == ("target", 1)
    assert METRICS["n_vertices"].best is None and METRICS["wall_s"].best == "min"


def test_entries_are_frozen():
    with pytest.raises(dataclasses.FrozenInstanceError):
        METRICS["hausdorff"].best = "max"  # type: ignore[misc]
    assert [f.name for f in dataclasses.fields(Metric)] == ["name", "best", "dtype", "meaning", "unit", "kind"]


def test_every_metric_is_defined_in_the_repository_docs():
    """docs/METRICS.md holds the definition of every column the suite reports (a `name` in backticks)."""
    from pathlib import Path

    doc = (Path(__file__).resolve().parents[1] / "docs" / "METRICS.md").read_text()
    missing = [k for k in METRICS if f"`{k}`" not in doc and not (k.endswith("_h") and f"`{k[:-2]}`" in doc)]
    assert not missing, missing
    for col in ("status", "error", "flags"):
        assert f"`{col}`" in doc
