"""Speed of the degraded inputs (phantoms/degrade.py): building a mask or a partial-volume image of the bunny at
N = 96 against building its signed distance volume, timed in the same test (``extra_info["sdf_ratio"]``).

The target is a degraded volume at most 2× the signed-distance volume; the assertion allows 3× for a busy
machine.  Each round starts from a fresh phantom cache: a degraded volume builds the exact volume it is made
from, so the ratio is (exact volume + degradation) / exact volume.
"""

from __future__ import annotations

import statistics
import time

import pytest

from bench.perf import rounds
from phantoms import get_phantom
from phantoms.degrade import degrade

N = 96


def _sdf(ph):
    ph._volume_cache.clear()
    return ph.volume(n=N)


def _degraded(ph, spec):
    ph._volume_cache.clear()
    return degrade(ph, spec, N)


@pytest.mark.benchmark(group="degrade")
@pytest.mark.parametrize("spec", ["mask", "partial_volume"])
def test_degraded_bunny_n96_against_its_sdf(benchmark, spec):
    ph = get_phantom("bunny")
    n_rounds = rounds(5, 2)
    _sdf(ph)                                                   # warm-up: compiled kernels, imports
    sdf_cpu = []
    for _ in range(n_rounds):
        c0 = time.process_time()
        _sdf(ph)
        sdf_cpu.append(time.process_time() - c0)
    cpu = []

    def timed():
        c0 = time.process_time()
        out = _degraded(ph, spec)
        cpu.append(time.process_time() - c0)
        return out

    vol = benchmark.pedantic(timed, rounds=n_rounds, iterations=1, warmup_rounds=1)
    ratio = statistics.median(cpu[1:] or cpu) / statistics.median(sdf_cpu)
    benchmark.extra_info["sdf_ratio"] = ratio
    benchmark.extra_info["sdf_cpu_median_s"] = statistics.median(sdf_cpu)
    assert vol.shape == (N, N, N) and vol.raw is not None
    assert ratio <= 3.0, f"degraded / sdf build = {ratio:.2f} (target 2)"
