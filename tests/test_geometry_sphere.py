"""Tests of ``geometry.sphere``: :func:`fibonacci_points` and :func:`fibonacci_sphere` — the paper's Γ0
(1,896 vertices, 3,788 faces, radius 2), closed and outward, on the requested sphere."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from geometry.sphere import PAPER_SPHERE_RADIUS, PAPER_SPHERE_VERTICES, fibonacci_points, fibonacci_sphere


def test_fibonacci_points_are_unit_vectors_without_poles_and_evenly_spread_in_height():
    u = fibonacci_points(500)
    assert u.shape == (500, 3)
    np.testing.assert_allclose(np.linalg.norm(u, axis=1), 1.0, atol=1e-12)
    np.testing.assert_allclose(u[:, 2], 1.0 - (2.0 * np.arange(500) + 1.0) / 500)
    assert np.abs(u[:, 2]).max() < 1.0
    np.testing.assert_allclose(u.mean(axis=0), 0.0, atol=1e-2)    # area-uniform: centred
    with pytest.raises(ValueError, match="at least 4"):
        fibonacci_points(3)


def test_the_default_sphere_is_the_papers_initial_surface():
    v, f = fibonacci_sphere()
    assert (PAPER_SPHERE_VERTICES, PAPER_SPHERE_RADIUS) == (1896, 2.0)
    assert v.shape == (1896, 3) and f.shape == (3788, 3)
    np.testing.assert_allclose(np.linalg.norm(v, axis=1), 2.0)


@pytest.mark.parametrize("n, radius, center", [(24, 1.0, (0, 0, 0)), (300, 0.5, (1.0, -2.0, 3.0)),
                                               (1000, 3.0, (0.1, 0.2, 0.3))])
def test_fibonacci_sphere_is_closed_outward_genus_0_on_the_sphere(n, radius, center):
    v, f = fibonacci_sphere(n, radius, center)
    assert len(v) == n and len(f) == 2 * n - 4
    np.testing.assert_allclose(np.linalg.norm(v - np.asarray(center), axis=1), radius)
    mesh = trimesh.Trimesh(v, f, process=False)
    assert mesh.is_watertight and mesh.is_winding_consistent and mesh.euler_number == 2
    assert 0 < mesh.volume < 4 / 3 * np.pi * radius ** 3        # outward; inscribed in the sphere
    assert mesh.volume == pytest.approx(4 / 3 * np.pi * radius ** 3, rel=2.0 / n ** 0.5 + 0.01)


def test_fibonacci_sphere_refuses_a_bad_radius():
    for r in (0.0, -1.0, float("nan"), float("inf")):
        with pytest.raises(ValueError, match="radius must be positive"):
            fibonacci_sphere(100, r)
