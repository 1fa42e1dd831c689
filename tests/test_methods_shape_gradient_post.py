"""Tests of ``methods.shape_gradient.post``: a post-step's move that makes faces meet is halved or kept back."""

from __future__ import annotations

import numpy as np
import trimesh

from geometry.operators import MeshOperators
from methods.shape_gradient.guard import count_intersections
from methods.shape_gradient.post import keep_back


def _slab():
    """A closed slab 1 × 1 × 0.1, subdivided, and the top vertex nearest its centre."""
    m = trimesh.creation.box(extents=(1.0, 1.0, 0.1))
    for _ in range(3):
        m = m.subdivide()
    x, f = np.asarray(m.vertices, float), np.asarray(m.faces)
    top = np.flatnonzero(np.isclose(x[:, 2], 0.05))
    return x, f, top[np.argmin(np.linalg.norm(x[top, :2], axis=1))]


def test_a_move_through_the_far_side_is_kept_back_or_halved():
    x, f, i = _slab()
    ops = MeshOperators(f, len(x))
    assert count_intersections(x, f)[0] == 0
    xq = x.copy()
    xq[i, 2] -= 0.15                                             # through the bottom (z = −0.05) by 0.05
    assert count_intersections(xq, f)[0] > 0
    back, kept, ok = keep_back(ops, xq, x, local=True)            # no halving: that vertex stays where it was
    assert ok and kept >= 1 and np.array_equal(back[i], x[i])
    half, kept, ok = keep_back(ops, xq, x, local=True, halve=3)   # halved once: z = −0.025, inside the slab
    assert ok and kept == 0 and np.isclose(half[i, 2], 0.05 - 0.075)
    assert count_intersections(half, f)[0] == 0
