"""The one trilinear gather (geometry.trilinear.trilinear_channels, the numpy reference): exact on an affine
field, the grid values at the grid points, refusal of indices outside the grid.  The compiled forms are
compared with it in tests/test_geometry_kernels.py and tests/test_methods_distmesh_loop.py."""

from __future__ import annotations

import numpy as np
import pytest

from geometry.trilinear import _CHUNK, trilinear_channels


def _stack(shape):
    i, j, k = np.meshgrid(*(np.arange(n, dtype=float) for n in shape), indexing="ij")
    affine = 0.5 + 2.0 * i - 3.0 * j + 0.25 * k
    other = np.sin(i) * np.cos(j) + k * k
    return np.stack([affine, other], axis=-1).reshape(-1, 2)


def test_an_affine_field_is_reproduced_and_grid_points_give_the_grid_values():
    shape = (5, 6, 7)
    flat = _stack(shape)
    idx = np.random.default_rng(0).uniform(0, 1, size=(3, _CHUNK + 17)) * (np.array(shape)[:, None] - 1)
    got = trilinear_channels(flat, shape, idx, reference=True)
    want = 0.5 + 2.0 * idx[0] - 3.0 * idx[1] + 0.25 * idx[2]
    np.testing.assert_allclose(got[0], want, rtol=0, atol=1e-12)
    grid = np.array(np.unravel_index(np.arange(flat.shape[0]), shape), dtype=float)
    np.testing.assert_allclose(trilinear_channels(flat, shape, grid, reference=True), flat.T, rtol=0, atol=1e-12)
    assert trilinear_channels(flat, shape, idx, channels=1, reference=True).shape == (1, idx.shape[1])


@pytest.mark.parametrize("bad", [-1e-9, 4.0 + 1e-9, np.nan])
def test_indices_outside_the_grid_are_refused(bad):
    idx = np.zeros((3, 4))
    idx[0, 2] = bad
    with pytest.raises(IndexError):
        trilinear_channels(_stack((5, 6, 7)), (5, 6, 7), idx, reference=True)
