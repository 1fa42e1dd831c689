"""Tests of ``geometry.compiled``: when the compiled kernels run, and the decorator with and without flags."""

from __future__ import annotations

import numpy as np
import pytest

from geometry import compiled


def test_the_kernels_run_from_min_size_on(monkeypatch):
    monkeypatch.setattr(compiled, "AVAILABLE", True)
    monkeypatch.setattr(compiled, "MIN_SIZE", 10_000)
    assert compiled.wanted(10_000) and not compiled.wanted(9_999)
    monkeypatch.setattr(compiled, "AVAILABLE", False)
    assert not compiled.wanted(10**6)


def test_jit_without_numba_returns_the_function_itself(monkeypatch):
    monkeypatch.setattr(compiled, "AVAILABLE", False)

    def f(x):
        return x + 1

    assert compiled.jit(f) is f and compiled.jit(fastmath=True)(f) is f


@pytest.mark.skipif(not compiled.AVAILABLE, reason="numba is not installed")
def test_jit_compiles_with_and_without_flags():
    """Both spellings give a numba dispatcher computing what the Python function computes."""
    def total(a):
        s = 0.0
        for v in a:
            s += v
        return s

    a = np.arange(10.0)
    plain, flagged = compiled.jit(total), compiled.jit(fastmath={"reassoc"})(total)
    assert plain is not total and hasattr(plain, "py_func") and hasattr(flagged, "py_func")
    assert plain(a) == flagged(a) == 45.0
