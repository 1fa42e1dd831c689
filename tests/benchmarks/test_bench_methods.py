"""Speed of the volume → mesh methods on the ellipsoid at N = 96 (the reference's own volume).

Deselected by default; run with ``python -m pytest tests/benchmarks -m benchmark`` or ``python -m bench perf``.
Each benchmark's ratio to the same-session reference (marching cubes on this volume) is written into
``extra_info`` by ``conftest.py``; ``test_marching_cubes_ellipsoid_n96`` measures the reference itself, so its
ratio should be ≈ 1 (a check on the ratio machinery and on the noise of the machine).
"""

from __future__ import annotations

import pytest

from bench.perf import rounds
from methods import get_method


def _bench(benchmark, ellipsoid_volume_96, name: str, n_rounds: int, warmup: int = 0):
    method = get_method(name)
    rec = benchmark.pedantic(method.reconstruct, args=(ellipsoid_volume_96,), rounds=n_rounds, iterations=1,
                             warmup_rounds=warmup)
    mesh = rec.mesh
    benchmark.extra_info["n_vertices"] = int(len(mesh.vertices))
    benchmark.extra_info["n_faces"] = int(len(mesh.faces))
    assert mesh.is_watertight
    assert mesh.euler_number == 2
    # the ellipsoid's semi-axes are (1, 2, 1) (sdf variant): the mesh spans about 2 × 4 × 2
    ext = mesh.bounds[1] - mesh.bounds[0]
    assert ext == pytest.approx([2.0, 4.0, 2.0], abs=0.15)
    return rec


@pytest.mark.benchmark(group="methods")
def test_marching_cubes_ellipsoid_n96(benchmark, ellipsoid_volume_96):
    _bench(benchmark, ellipsoid_volume_96, "marching_cubes", rounds(15, 7), warmup=1)


@pytest.mark.benchmark(group="methods")
def test_poisson_ellipsoid_n96(benchmark, ellipsoid_volume_96):
    _bench(benchmark, ellipsoid_volume_96, "poisson", rounds(5, 3))


@pytest.mark.benchmark(group="methods")
def test_distmesh_ellipsoid_n96(benchmark, ellipsoid_volume_96):
    _bench(benchmark, ellipsoid_volume_96, "distmesh", rounds(3, 2))
