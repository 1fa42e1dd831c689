"""The box-restricted exact distance transform (phantoms/mask_edt.py) against scipy's exact one."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import ndimage

from phantoms.mask_edt import outside_distance


def _masks():
    rng = np.random.default_rng(7)
    x = np.mgrid[-1:1:23j, -1:1:17j, -1:1:29j]
    flat = np.zeros((23, 17, 29), bool)
    flat[4:20, 3:14, 14] = True                                     # one plane: a box one voxel thick
    single = np.zeros((23, 17, 29), bool)
    single[0, 16, 28] = True                                        # one voxel in a corner
    return {
        "ball": (x ** 2).sum(0) < 0.3,
        "off_centre_ball": ((x - np.array([0.5, -0.4, 0.3])[:, None, None, None]) ** 2).sum(0) < 0.1,
        "speckle": rng.random(x.shape[1:]) < 0.02,
        "dense": rng.random(x.shape[1:]) < 0.6,
        "slab_touching_a_wall": (x[0] < -0.6) & (np.abs(x[2]) < 0.3),
        "flat": flat,
        "single_voxel": single,
        "two_far_apart": (((x - 0.8) ** 2).sum(0) < 0.05) | (((x + 0.8) ** 2).sum(0) < 0.05),
    }


@pytest.mark.parametrize("spacing", [(1.0, 1.0, 1.0), (0.8, 0.8, 3.0), (2.0, 0.5, 1.3)])
@pytest.mark.parametrize("name", list(_masks()))
def test_equals_scipys_exact_transform(name, spacing):
    m = _masks()[name]
    got = outside_distance(m, spacing)
    want = ndimage.distance_transform_edt(~m, sampling=spacing)
    assert got.dtype == np.float64 and got.flags.c_contiguous and got.shape == m.shape
    np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-12)
    assert (got[m] == 0).all()


def test_the_axis_order_does_not_change_the_answer():
    """The passes run in the order of the box's extents; a transposed mask gives the transposed distances."""
    m = _masks()["off_centre_ball"] | _masks()["speckle"]
    spacing = np.array([0.7, 1.1, 2.0])
    base = outside_distance(m, spacing)
    for order in [(2, 0, 1), (1, 2, 0), (2, 1, 0)]:
        moved = outside_distance(np.ascontiguousarray(m.transpose(order)), spacing[list(order)])
        np.testing.assert_allclose(moved, base.transpose(order), rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("shape", [(1, 5, 5), (3, 1, 1), (1, 1, 1), (2, 7, 1), (6, 4, 3)])
def test_thin_grids_and_fortran_order(shape):
    """Axes of one or two voxels, and a mask not in C order, against scipy on random masks and spacings."""
    rng = np.random.default_rng(sum(shape))
    for _ in range(5):
        m = rng.random(shape) < 0.3
        m.flat[rng.integers(m.size)] = True
        spacing = rng.uniform(0.5, 2.0, 3)
        want = ndimage.distance_transform_edt(~m, sampling=spacing)
        np.testing.assert_allclose(outside_distance(m, spacing), want, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(outside_distance(np.asfortranarray(m), spacing), want, rtol=1e-12, atol=1e-12)
