"""Tests of ``methods.cost_model``: :func:`grid_points`, :func:`crossing_cells` (the cells the zero level set
crosses: ≈ 1.5 · area / h² on a sphere; none without a surface) and the :class:`PowerLaw` model's formula."""

from __future__ import annotations

import numpy as np
import pytest

from methods.cost_model import PowerLaw, crossing_cells, grid_points
from phantoms import Volume, get_phantom


def test_grid_points():
    assert grid_points(64) == 64 ** 3 and grid_points(np.int64(8)) == 512
    assert grid_points((10, 20, 30)) == 6000


def test_crossing_cells_of_a_plane_a_sphere_and_no_surface():
    x = np.arange(10.0)[:, None, None] + np.zeros((10, 10, 10))
    assert crossing_cells(Volume(x - 4.5)) == 9 * 9                  # one layer of cells across the plane
    assert crossing_cells(Volume(np.ones((8, 8, 8)))) == 0
    vol = get_phantom("sphere").volume(n=64)
    area_cells = 4 * np.pi / vol.h ** 2
    assert 1.2 * area_cells < crossing_cells(vol) < 1.8 * area_cells
    assert crossing_cells(vol) == pytest.approx(3000, rel=0.1)        # PowerLaw's reference c0 at 64³


def test_power_law_seconds():
    law = PowerLaw(a=2.0, p=3.0, q=1.0, c0=3000.0, floor=0.5)
    assert law.seconds(64) == pytest.approx(2.5)
    assert law.seconds(128) == pytest.approx(0.5 + 2.0 * 8)           # (N/64)^p
    assert law.seconds((64, 64, 64), 6000) == pytest.approx(0.5 + 4.0)   # twice the reference surface, q = 1
    assert law.seconds(128, 4 * 3000) == pytest.approx(law.seconds(128))  # the reference surface at 128³
    assert PowerLaw(a=1.0, p=2.0).seconds(32, 10 ** 6) == pytest.approx(0.25)   # q = 0: the surface is ignored
