"""Tests of bench.run.cost: wall time and peak memory of one call (METRICS.md wall_s, peak_mem_mb)."""

from __future__ import annotations

import ctypes
import ctypes.util
import json
import mmap
import subprocess
import sys

import pytest

from bench.run.cost import measure, memory_backend

_NUMPY_MEMORY_PROBE = """
import json, time
import numpy as np
from bench.run.cost import measure, memory_backend

def work(n):
    a = np.ones(n)            # 8n bytes, touched
    time.sleep(0.05)
    return float(a.sum())

res, cost = measure(work, 25_000_000)        # 200 MB
_, small = measure(lambda: 1)
print(json.dumps({"res": res, "cost": cost, "small": small, "backend": memory_backend()}))
"""


def test_measure_wall_and_numpy_memory():
    # in a fresh interpreter, as the runner measures cells: in this long-lived test process a 200 MB
    # malloc could be served from memory freed by earlier tests without raising the RSS
    proc = subprocess.run([sys.executable, "-c", _NUMPY_MEMORY_PROBE], capture_output=True, text=True, check=True)
    out = json.loads(proc.stdout.strip().splitlines()[-1])
    cost = out["cost"]
    assert out["res"] == 25_000_000.0
    assert set(cost) == {"wall_s", "peak_mem_mb"}
    assert cost["wall_s"] >= 0.05
    if out["backend"] != "none":
        assert 150 < cost["peak_mem_mb"] < 400
        assert out["small"]["peak_mem_mb"] < 20


@pytest.mark.skipif(ctypes.util.find_library("c") is None, reason="needs libc")
def test_measure_sees_c_allocations():
    """Memory allocated by C code (invisible to tracemalloc) is counted.

    The C code maps fresh anonymous pages (libc ``mmap``) and touches them: a ``malloc`` could be served
    from memory the allocator already holds from earlier tests' frees, which raises no RSS (the caveat
    in ``bench.run.cost``) and made this test fail now and then in the full suite.
    """
    if memory_backend() == "none":
        pytest.skip("no /proc")
    libc = ctypes.CDLL(ctypes.util.find_library("c"), use_errno=True)
    libc.mmap.restype = ctypes.c_void_p
    libc.mmap.argtypes = [ctypes.c_void_p, ctypes.c_size_t, ctypes.c_int, ctypes.c_int, ctypes.c_int, ctypes.c_long]
    libc.munmap.argtypes = [ctypes.c_void_p, ctypes.c_size_t]
    libc.memset.argtypes = [ctypes.c_void_p, ctypes.c_int, ctypes.c_size_t]
    prot = mmap.PROT_READ | mmap.PROT_WRITE
    flags = mmap.MAP_PRIVATE | mmap.MAP_ANONYMOUS

    def c_work(nbytes):
        p = libc.mmap(None, nbytes, prot, flags, -1, 0)
        assert p not in (None, ctypes.c_void_p(-1).value), "mmap failed"
        libc.memset(p, 1, nbytes)
        libc.munmap(p, nbytes)

    _, cost = measure(c_work, 150 * 2 ** 20)
    assert cost["peak_mem_mb"] > 120


def test_measure_propagates_exceptions():
    def boom():
        raise RuntimeError("nope")

    with pytest.raises(RuntimeError, match="nope"):
        measure(boom)


