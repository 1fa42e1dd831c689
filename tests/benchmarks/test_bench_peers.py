"""Flying Edges (VTK) against scikit-image marching cubes on the same volume at N = 192, in one session.

Both adapters return the same vertex set (tests/test_methods_flying_edges.py); this pair measures what the
choice costs.  The ratio of interest is ``flying_edges`` median / ``marching_cubes`` median (both also carry
their ratio to the session's reference in ``extra_info``, conftest.py).  Run with
``python -m pytest tests/benchmarks/test_bench_peers.py -m benchmark --benchmark-enable``.
"""

from __future__ import annotations

import pytest

from bench.perf import rounds
from methods import get_method
from phantoms import get_phantom

pytest.importorskip("vtkmodules.vtkFiltersCore", reason='VTK not installed: pip install "levelset-bench[vtk]"')

N = 192


@pytest.fixture(scope="module")
def ellipsoid_volume_192():
    return get_phantom("ellipsoid").volume(n=N)


def _bench(benchmark, volume, name: str):
    method = get_method(name)
    rec = benchmark.pedantic(method.reconstruct, args=(volume,), rounds=rounds(9, 5), iterations=1,
                             warmup_rounds=1)
    benchmark.extra_info["n_vertices"] = int(len(rec.mesh.vertices))
    assert rec.mesh.is_watertight and rec.mesh.euler_number == 2
    return rec


@pytest.mark.perf_slow
@pytest.mark.benchmark(group="peers-n192")
def test_marching_cubes_ellipsoid_n192(benchmark, ellipsoid_volume_192):
    _bench(benchmark, ellipsoid_volume_192, "marching_cubes")


@pytest.mark.perf_slow
@pytest.mark.benchmark(group="peers-n192")
def test_flying_edges_ellipsoid_n192(benchmark, ellipsoid_volume_192):
    _bench(benchmark, ellipsoid_volume_192, "flying_edges")
