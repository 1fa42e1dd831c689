"""Array helpers the hot paths share.

``np.unique`` of numpy ≥ 2.3 takes a hash-based path when asked for the values only; on the large integer arrays meshes
produce (edge keys, face indices) it is much slower than sorting, and the shape-gradient flow
calls it at every remesh and intersection check.
"""

from __future__ import annotations

import numpy as np

__all__ = ["unique_ints", "count_distinct"]


def unique_ints(a) -> np.ndarray:
    """The sorted distinct values of an integer array (flattened) — ``np.unique(a)``, by sorting."""
    s = np.sort(np.asarray(a).ravel())
    if len(s) == 0:
        return s
    keep = np.empty(len(s), dtype=bool)
    keep[0] = True
    np.not_equal(s[1:], s[:-1], out=keep[1:])
    return s[keep]


def count_distinct(indices, n: int) -> int:
    """How many of 0 … n−1 occur in an array of indices known to lie in [0, n)."""
    idx = np.asarray(indices).ravel()
    return int(np.count_nonzero(np.bincount(idx, minlength=n))) if len(idx) else 0
