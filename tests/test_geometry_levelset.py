"""geometry/levelset.py: Newton projection onto φ = 0, against the analytic sphere SDF."""

from __future__ import annotations

import numpy as np

from geometry.levelset import newton_project

R = 0.8


def _sphere(p):
    r = np.linalg.norm(p, axis=1)
    return r - R, p / r[:, None]


def _sphere_t(xt):
    phi, g = _sphere(np.ascontiguousarray(xt.T))
    return phi, np.ascontiguousarray(g.T)


def test_points_project_to_the_radius():
    x = np.random.default_rng(0).uniform(-2, 2, (500, 3))
    p, counts = newton_project(_sphere, x, 1)
    assert np.allclose(np.linalg.norm(p, axis=1), R, atol=1e-12)
    assert counts == {"flat": 0, "capped": 0}
    assert not np.shares_memory(p, x)


def test_both_layouts_agree():
    x = np.random.default_rng(1).uniform(-2, 2, (300, 3))
    p, c = newton_project(_sphere, x, 2, max_step=0.1)
    pt, ct = newton_project(_sphere_t, np.ascontiguousarray(x.T), 2, max_step=0.1, coords_first=True)
    assert np.allclose(p, pt.T, atol=1e-15, rtol=0) and c == ct


def test_step_cap_counts_and_limits_the_move():
    x = np.array([[2.0, 0, 0], [R + 0.05, 0, 0]])
    p, counts = newton_project(_sphere, x, 1, max_step=0.5)
    assert np.allclose(p, [[1.5, 0, 0], [R, 0, 0]])
    assert counts["capped"] == 1
    p3, _ = newton_project(_sphere, x, 3, max_step=0.5)
    assert np.allclose(np.linalg.norm(p3, axis=1), R)


def test_flat_gradient_points_stay_and_box_clamps():
    def flat_at_first(p):
        phi, g = _sphere(p)
        g[0] = 0.0
        return phi, g

    x = np.array([[1.5, 0, 0], [0.0, 1.5, 0]])
    p, counts = newton_project(flat_at_first, x, 1, flat_g2=1e-12)
    assert np.array_equal(p[0], x[0]) and counts["flat"] == 1
    p, _ = newton_project(_sphere, np.array([[0.0, 0.1, 0]]), 1, box=([-1, -1, -1], [1, 0.5, 1]))
    assert p[0, 1] == 0.5
