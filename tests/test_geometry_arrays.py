"""geometry/arrays.py: the sort-based unique and the distinct count agree with numpy's definitions."""

from __future__ import annotations

import numpy as np

from geometry.arrays import count_distinct, unique_ints


def test_unique_ints_is_np_unique():
    rng = np.random.default_rng(0)
    for a in (rng.integers(0, 50, 1000), rng.integers(-10**12, 10**12, 5000), rng.integers(0, 5, (30, 3)),
              np.array([7]), np.zeros(0, dtype=np.int64)):
        np.testing.assert_array_equal(unique_ints(a), np.unique(a))


def test_count_distinct():
    f = np.array([[0, 1, 2], [2, 1, 4]])
    assert count_distinct(f, 6) == 4 and count_distinct(np.zeros(0, dtype=int), 3) == 0
    rng = np.random.default_rng(1)
    a = rng.integers(0, 100, 300)
    assert count_distinct(a, 100) == len(np.unique(a))
