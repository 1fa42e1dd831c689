"""The metric registry (bench.metrics.registry): one entry per reported metric, well-formed facts."""

from __future__ import annotations

import dataclasses

import pytest

from bench.metrics import METRIC_NAMES
from bench.metrics.registry import METRICS, Metric


def test_every_metric_column_has_an_entry_in_the_same_order():
    assert list(METRICS) == list(METRIC_NAMES)
    assert all(m.name == k for k, m in METRICS.items())


def test_facts_are_well_formed():
    for m in METRICS.values():
        assert m.dtype in ("float", "int", "bool"), m
        assert m.best in ("min", "max", None) or (isinstance(m.best, tuple) and m.best[0] == "target"), m
        assert m.meaning and "\n" not in m.meaning, m
        assert isinstance(m.unit, str), m


def test_facts_the_report_relies_on():
    assert METRICS["watertight"].dtype == "bool"
    assert {k for k, m in METRICS.items() if m.dtype == "int"} == {
        "euler", "components", "self_intersections", "n_vertices", "n_faces", "iterations"}
    assert all(METRICS[f"{k}_h"].best == "min" for k in ("hausdorff", "hausdorff_95", "mean_dist", "rms_dist"))
    assert METRICS["euler"].best == ("target", 2) and METRICS["components"].best == ("target", 1)
    assert METRICS["n_vertices"].best is None and METRICS["wall_s"].best == "min"


def test_entries_are_frozen():
    with pytest.raises(dataclasses.FrozenInstanceError):
        METRICS["hausdorff"].best = "max"  # type: ignore[misc]
    assert [f.name for f in dataclasses.fields(Metric)] == ["name", "best", "dtype", "meaning", "unit"]
