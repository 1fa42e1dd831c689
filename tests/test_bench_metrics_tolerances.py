"""The metric tolerances (bench.metrics.tolerances): one home, read by the quality gate and the report."""

from __future__ import annotations

from bench.metrics.registry import METRICS
from bench.metrics.tolerances import TOLERANCES, Tolerance, same_within_tolerance


def test_every_tolerance_names_a_registry_column():
    assert set(TOLERANCES) <= set(METRICS)
    assert {t.better for t in TOLERANCES.values()} <= {"min", "max", "count", "target", "true"}


def test_the_quality_gate_reexports_the_same_objects():
    from bench.perf import quality

    assert quality.TOLERANCES is TOLERANCES
    assert quality.Tolerance is Tolerance
    assert quality.same_within_tolerance is same_within_tolerance


def test_same_within_tolerance_is_relative_plus_floor_and_exact_for_counts():
    assert same_within_tolerance("hausdorff_h", 1.0, 1.05)          # 5 % of 1.05 + 0.01
    assert not same_within_tolerance("hausdorff_h", 1.0, 1.07)
    assert same_within_tolerance("self_intersections", 3, 3)
    assert not same_within_tolerance("self_intersections", 3, 4)
    assert same_within_tolerance("not_a_gated_column", 1.0, 1.0 + 1e-10)
    assert not same_within_tolerance("not_a_gated_column", 1.0, 1.0 + 1e-6)


def test_finite():
    from bench.metrics.tolerances import finite

    assert finite("2.5") == 2.5 and finite(3) == 3.0
    assert finite(float("nan")) is None and finite(float("inf")) is None and finite(None) is None
    assert finite("x") is None
