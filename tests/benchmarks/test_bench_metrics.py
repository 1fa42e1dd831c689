"""Speed of the full ``evaluate`` — every metric, the field's ones included (hausdorff_90, sif_pct, edge_chamfer /
edge_fscore, iou, boundary/non-manifold edges) — on a ~100k-face mesh (target: ≤ 2 s on a quiet 2-core machine;
2.05 s before the new metrics, whose cost was paid for by one edge sort for every topology count and a Newton
root find for the ellipsoid's closest points).  The ellipsoid has no creases, so a second benchmark times the
same on a ~100k-face marching-cubes cylinder, where the edge metrics run too.

Deselected by default; run with
``python -m pytest tests/benchmarks -m benchmark --benchmark-enable``.
The per-phase seconds of the last round are stored in the benchmark's ``extra_info`` (``--benchmark-json``)
and printed with ``-s``.
"""

from __future__ import annotations

import os
import time

import numpy as np
import pytest
import trimesh

from bench.metrics import METRIC_NAMES, RUNNER_NAMES, _evaluate
from phantoms import get_phantom


@pytest.fixture(scope="module")
def ellipsoid_mesh():
    """Marching cubes of the ellipsoid (paper polynomial, same zero set) on a 170³ grid over [−2.1, 2.1]³:
    101,564 faces with the sliver triangles real marching-cubes output has."""
    from skimage.measure import marching_cubes

    ph = get_phantom("ellipsoid")
    vol = ph.volume(n=170, extent=2.1, variant="paper")
    v, f, _, _ = marching_cubes(vol.values, 0.0, spacing=tuple(vol.spacing))
    mesh = trimesh.Trimesh(v + vol.origin, f)
    assert 95_000 <= len(mesh.faces) <= 110_000
    return mesh, ph, float(vol.spacing[0])


@pytest.fixture(scope="module")
def cylinder_mesh():
    """Marching cubes of the cylinder (exact sdf) on a 216³ grid over [−1.3, 1.3]³: ~100k faces."""
    from skimage.measure import marching_cubes

    ph = get_phantom("cylinder")
    vol = ph.volume(n=216, extent=1.3)
    v, f, _, _ = marching_cubes(vol.values, 0.0, spacing=tuple(vol.spacing))
    mesh = trimesh.Trimesh(v + vol.origin, f)
    assert 85_000 <= len(mesh.faces) <= 120_000
    return mesh, ph, float(vol.spacing[0])


def _timed(benchmark, mesh, ph, h):
    phases: dict = {}

    cpu: list = []

    def run():
        phases.clear()
        c0 = time.process_time()
        res = _evaluate(mesh, ph, h, n_samples=100_000, seed=0, timings=phases)
        cpu.append(time.process_time() - c0)
        return res

    out = benchmark.pedantic(run, rounds=3, iterations=1, warmup_rounds=0)
    benchmark.extra_info["n_faces"] = len(mesh.faces)
    benchmark.extra_info["phases_s"] = {k: round(v, 4) for k, v in phases.items()}
    benchmark.extra_info["cpu_s"] = [round(c, 3) for c in cpu]
    # the worker phase overlaps the others: it is not part of the wall-clock sum
    wall = sum(v for k, v in phases.items() if "(worker)" not in k)
    benchmark.extra_info["loadavg_1min_at_end"] = round(os.getloadavg()[0], 2)
    print("\nevaluate phases (s):", {k: round(v, 3) for k, v in phases.items()},
          f"wall {wall:.3f}, CPU (both threads) {cpu[-1]:.3f}, load average {os.getloadavg()[0]:.2f}")
    assert list(out) == [k for k in METRIC_NAMES if k not in RUNNER_NAMES]
    return out


@pytest.mark.benchmark(group="metrics")
def test_evaluate_100k_faces_ellipsoid(benchmark, ellipsoid_mesh):
    out = _timed(benchmark, *ellipsoid_mesh)
    assert out["watertight"] and out["euler"] == 2 and out["self_intersections"] == 0
    assert out["hausdorff_h"] < 0.1 and out["fscore@h"] == 1.0
    assert np.isnan(out["H_std"]) and np.isnan(out["edge_chamfer"])           # no creases on the ellipsoid
    assert out["iou"] > 0.99 and out["sif_pct"] == 0 and out["boundary_edges"] == out["nonmanifold_edges"] == 0


@pytest.mark.benchmark(group="metrics")
def test_evaluate_100k_faces_cylinder(benchmark, cylinder_mesh):
    out = _timed(benchmark, *cylinder_mesh)
    assert out["watertight"] and out["iou"] > 0.99
    assert np.isfinite(out["edge_chamfer"]) and out["edge_fscore"] > 0.5    # its rims are found


@pytest.fixture(scope="module")
def cell_n96():
    """A cell's scoring at the paper's N = 96: marching cubes of the ellipsoid and the volume it came from."""
    from methods import get_method

    ph = get_phantom("ellipsoid")
    vol = ph.volume(n=96)
    return get_method("marching_cubes").reconstruct(vol).mesh, ph, vol


@pytest.mark.benchmark(group="metrics")
def test_evaluate_fidelity_cost_n96(benchmark, cell_n96):
    """What the data-fidelity metrics add to a cell's scoring at N = 96: ``evaluate`` with the volume (the
    benchmark) against the same call without it, in CPU time, the two interleaved round by round
    (``extra_info["fidelity_cpu_ratio"]``).  The volume's path holds the fidelity block and the
    topology-against-the-data columns; the bound catches them becoming a large share of scoring, with room for a
    busy CI machine (docs/NOTES.md, "The fidelity benchmark's bound")."""
    mesh, ph, vol = cell_n96
    without: list = []
    with_vol: list = []

    def run():
        c0 = time.process_time()
        _evaluate(mesh, ph, vol.h, n_samples=100_000, seed=0)
        without.append(time.process_time() - c0)
        c0 = time.process_time()
        res = _evaluate(mesh, ph, vol.h, volume=vol, n_samples=100_000, seed=0)
        with_vol.append(time.process_time() - c0)
        return res

    run()                                                   # warm caches (numba kernels, truth structures)
    without.clear()
    with_vol.clear()
    out = benchmark.pedantic(run, rounds=7, iterations=1, warmup_rounds=0)
    ratio = float(min(with_vol) / min(without))
    benchmark.extra_info["fidelity_cpu_ratio"] = round(ratio, 3)
    benchmark.extra_info["cpu_s_without"] = [round(c, 3) for c in without]
    benchmark.extra_info["cpu_s_with"] = [round(c, 3) for c in with_vol]
    print(f"\nfidelity metrics: CPU {np.median(with_vol):.3f} s with, {np.median(without):.3f} s without, "
          f"ratio {ratio:.3f}, load average {os.getloadavg()[0]:.2f}")
    assert np.isfinite(out["sdf_rms_h"]) and out["sign_err_pct"] == 0.0
    assert ratio <= 1.4


@pytest.fixture(scope="module")
def icosphere_82k():
    """An icosphere of 81,920 faces: far denser than its grid at N = 24 (~1,900 vertices in a 2h ball) and
    N = 96 (~110) — the meshes of issue 30 (before: 269 s and 8.1 GB at N = 24, 24 s at N = 96)."""
    return trimesh.creation.icosphere(subdivisions=6, radius=1.0), get_phantom("sphere")


@pytest.mark.perf_slow
@pytest.mark.benchmark(group="metrics")
@pytest.mark.parametrize("n", [24, 96])
def test_evaluate_dense_icosphere(benchmark, icosphere_82k, n):
    """``evaluate`` on the 82k-face icosphere with h = 5/(N − 1): the curvature neighbourhood capped at
    ``geometry.MAX_NEIGHBORS`` and queried and fitted block by block (issue 30 target: within 4× the 100k-face
    time)."""
    mesh, ph = icosphere_82k
    out = _timed(benchmark, mesh, ph, 5.0 / (n - 1))
    assert out["watertight"] and out["self_intersections"] == 0 and out["H_rms_err"] < 0.05
