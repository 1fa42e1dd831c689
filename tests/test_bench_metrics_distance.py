"""Distance statistics (bench/metrics/distance.py): hausdorff_90 against the other robust distances."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from bench.metrics import evaluate
from bench.metrics.distance import distance_metrics


def _stats(a, b, h=1.0):
    n = np.tile([0.0, 0.0, 1.0], (len(a), 1))         # normals at the mesh samples and their closest true points
    return distance_metrics(a, float(max(a.max(), b.max())), b, h, n, n)


def test_hausdorff_90_is_the_larger_90th_percentile():
    a = np.linspace(0.0, 1.0, 1001)           # 90th percentile 0.9 exactly (linear interpolation)
    b = np.linspace(0.0, 0.5, 1001)           # 0.45
    out = _stats(a, b, h=0.1)
    assert out["hausdorff_90"] == pytest.approx(0.9) and out["hausdorff_90_h"] == pytest.approx(9.0)
    assert out["hausdorff_95"] == pytest.approx(0.95) and out["hausdorff"] == 1.0


def test_hausdorff_90_never_exceeds_hausdorff_95():
    rng = np.random.default_rng(0)
    for _ in range(50):
        a, b = rng.exponential(size=rng.integers(10, 500)), rng.pareto(1.5, size=rng.integers(10, 500))
        out = _stats(a, b)
        assert out["hausdorff_90"] <= out["hausdorff_95"] <= out["hausdorff"]


def test_hausdorff_90_between_the_mean_and_hausdorff_95_on_a_bumpy_sphere():
    """A sphere with a seeded radial bump field: the robust maxima sit above the mean distance."""
    from phantoms import get_phantom

    m = trimesh.creation.icosphere(4)
    rng = np.random.default_rng(3)
    m.vertices *= (1 + 0.02 * rng.standard_normal(len(m.vertices)))[:, None]
    out = evaluate(m, get_phantom("sphere"), 0.05, n_samples=20_000)
    assert out["mean_dist"] < out["hausdorff_90"] < out["hausdorff_95"] < out["hausdorff"]
