"""Tests of ``methods.poisson``: the :class:`ScreenedPoisson` baseline (closed, outward, within 1.5 grid
spacings of the clean phantoms at N = 96) and :func:`zero_set_points`, its oriented input points."""

from __future__ import annotations

import numpy as np
import pytest

from _baselines import PHANTOMS, check, reconstruct
from methods import get_method
from methods.poisson import zero_set_points
from phantoms import get_phantom


@pytest.mark.parametrize("phantom", PHANTOMS)
def test_poisson(phantom):
    check("poisson", phantom)
    info = reconstruct("poisson", phantom).info
    assert info["kept_components"] == 1 and info["points"] > 1000


def test_poisson_on_a_small_sphere_is_closed_outward_and_close():
    vol = get_phantom("sphere").volume(n=32)
    rec = get_method("poisson").reconstruct(vol)
    mesh = rec.mesh
    assert mesh.is_watertight and mesh.euler_number == 2 and mesh.volume > 0
    assert np.abs(np.linalg.norm(mesh.vertices, axis=1) - 1.0).max() < 1.5 * vol.h
    assert rec.info["kept_components"] == 1


def test_zero_set_points_lie_on_the_sphere_with_outward_unit_normals():
    vol = get_phantom("sphere").volume(n=24)
    p, n = zero_set_points(vol)
    assert p.shape == n.shape and len(p) > 100
    r = np.linalg.norm(p, axis=1)
    assert np.abs(r - 1.0).max() < 0.2 * vol.h
    np.testing.assert_allclose(np.linalg.norm(n, axis=1), 1.0, atol=1e-9)
    assert (np.einsum("ij,ij->i", n, p / r[:, None]) > 0.95).all()   # ∇φ/|∇φ|: radial, outward
