"""Tests of ``phantoms.base``: :func:`grid_volume` (the grid, its slabs, its checks), the argument checks, the
point and unit-vector helpers, :func:`arc_positions` and the :class:`Phantom` base's truth on a sphere."""

from __future__ import annotations

import numpy as np
import pytest

from phantoms import InputError, get_phantom
from phantoms.base import (arc_positions, as_points, check_extent, check_n, check_sample_count, grid_volume,
                           unit)


def test_grid_volume_of_a_linear_function_has_the_documented_grid():
    vol = grid_volume(lambda p: p[:, 0] + 2 * p[:, 1] - 3 * p[:, 2], n=9, extent=2.0)
    assert vol.shape == (9, 9, 9)
    np.testing.assert_allclose(vol.origin, [-2.0] * 3)
    assert vol.h == pytest.approx(0.5)
    axis = -2.0 + 0.5 * np.arange(9)
    x, y, z = np.meshgrid(axis, axis, axis, indexing="ij")
    np.testing.assert_allclose(vol.values, x + 2 * y - 3 * z)


def test_the_argument_checks():
    assert check_n(8) == 8 and check_n(96.0) == 96
    for bad in (7, 8.5, "x", None):
        with pytest.raises(InputError, match="grid size N"):
            check_n(bad)
    assert check_extent("1.5") == 1.5
    for bad in (0, -1, float("nan"), float("inf")):
        with pytest.raises(InputError, match="extent"):
            check_extent(bad)
    assert check_sample_count(3.0) == 3
    with pytest.raises(InputError, match="surface samples"):
        check_sample_count(0)
    with pytest.raises(InputError, match="grid size N"):
        grid_volume(lambda p: p[:, 0], n=4)


def test_as_points_and_unit():
    assert as_points([[1, 2, 3]]).dtype == np.float64
    with pytest.raises(InputError, match=r"\(P, 3\)"):
        as_points([1, 2, 3])
    out = unit(np.array([[3.0, 0, 4], [0, 0, 0]]), [0.0, 0.0, 1.0])
    np.testing.assert_allclose(out, [[0.6, 0, 0.8], [0, 0, 1]])


def test_arc_positions_spread_samples_evenly_over_curves_end_to_end():
    k, t = arc_positions([1.0, 3.0], 4)                       # positions 0.5, 1.5, 2.5, 3.5 of a length-4 chain
    np.testing.assert_array_equal(k, [0, 1, 1, 1])
    np.testing.assert_allclose(t, [0.5, 0.5 / 3, 1.5 / 3, 2.5 / 3])
    k, t = arc_positions([0.0, 2.0], 2)                       # a zero-length curve gets no sample
    np.testing.assert_array_equal(k, [1, 1])
    np.testing.assert_allclose(t, [0.25, 0.75])


def test_the_sphere_phantoms_truth_at_query_points():
    ph = get_phantom("sphere")
    p = np.array([[2.0, 0, 0], [0, 0.5, 0], [0, 0, -1.0]])
    t = ph.truth(p)
    np.testing.assert_allclose(t.closest, [[1, 0, 0], [0, 1, 0], [0, 0, -1]], atol=1e-12)
    np.testing.assert_allclose(t.distance, [1.0, 0.5, 0.0], atol=1e-12)
    np.testing.assert_allclose(t.signed, [1.0, -0.5, 0.0], atol=1e-12)
    np.testing.assert_allclose(t.normal, [[1, 0, 0], [0, 1, 0], [0, 0, -1]], atol=1e-12)
    np.testing.assert_allclose(t.H, 1.0) and np.testing.assert_allclose(t.K, 1.0)
    assert np.isinf(t.crease_distance).all()


def test_grid_volume_samples_in_slabs_with_the_same_values(monkeypatch):
    """grid_volume hands the function slabs of whole x-planes (at most GRID_CHUNK points, never fewer than one
    plane), so its temporaries stay bounded; the values equal one evaluation over the whole grid."""
    import phantoms.base as pb

    ph = get_phantom("ellipsoid")
    seen = []

    def fn(p):
        seen.append(len(p))
        return ph.sdf(p)

    monkeypatch.setattr(pb, "GRID_CHUNK", 5000)
    vol = pb.grid_volume(fn, n=40)
    assert max(seen) <= 5000 and min(seen) >= 40 * 40 and sum(seen) == 40 ** 3
    axis = vol.origin[0] + vol.h * np.arange(40)
    whole = np.stack(np.meshgrid(axis, axis, axis, indexing="ij"), axis=-1).reshape(-1, 3)
    assert np.array_equal(vol.values, ph.sdf(whole).reshape(40, 40, 40))
