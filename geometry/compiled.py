"""The suite's use of numba: whether it is present, the one compile decorator, and the size from which the compiled
kernels replace their numpy references.

The kernels that have a numpy reference to fall back on (:mod:`geometry.kernels`, :mod:`geometry.broadphase`, the
shape gradient's, DistMesh's loop, the report's pictures) are compiled by :func:`jit`: on first use, cached on disk
(``cache=True``), releasing the GIL (``nogil=True``).  Without numba :func:`jit` returns the function unchanged and
:data:`AVAILABLE` is False; the callers then run their numpy references.
"""

from __future__ import annotations

try:
    import numba
    AVAILABLE = True
except ImportError:  # pragma: no cover - numba is a dependency; the numpy references still work
    numba = None
    AVAILABLE = False

#: the kernels run on arrays of at least this many vertices, faces or points (:func:`wanted`): a process
#: loads each kernel's cached machine code once (a fraction of a second; the benchmark's cells come from a fork
#: server that has loaded them); below this size numpy's per-call overhead is small enough (the paper's
#: 1,896-vertex flow is already faster compiled)
MIN_SIZE = 1000

__all__ = ["AVAILABLE", "MIN_SIZE", "jit", "wanted"]


def wanted(n: int) -> bool:
    """True when the compiled kernels should run on arrays of ``n`` elements (numba present, n ≥ MIN_SIZE)."""
    return AVAILABLE and n >= MIN_SIZE


def jit(fn=None, **flags):
    """``numba.njit(cache=True, nogil=True, **flags)`` of ``fn`` (usable as ``@jit`` or ``@jit(**flags)``);
    ``fn`` itself when numba is missing."""
    if fn is None:
        return lambda f: jit(f, **flags)
    return numba.njit(cache=True, nogil=True, **flags)(fn) if AVAILABLE else fn
