"""geometry.grid_derivatives: the compiled interpolation grids against numpy.gradient (bit for bit) and
against a quadratic's exact derivatives."""

import numpy as np
import pytest

from geometry.grid_derivatives import derivative_stack
from phantoms.volume import _derivative_channels


@pytest.mark.parametrize("shape,spacing", [((3, 3, 3), (1.0, 1.0, 1.0)), ((4, 5, 6), (0.1, 0.2, 0.3)),
                                           ((17, 9, 12), (0.05, 0.05, 0.07))])
@pytest.mark.parametrize("order", [0, 1, 2])
def test_equals_numpy_gradient_bit_for_bit(shape, spacing, order):
    v = np.random.default_rng(sum(shape) + order).normal(size=shape)
    a = derivative_stack(v, spacing, order)
    b = _derivative_channels(v, spacing, order)
    assert a.shape == b.shape == shape + ({0: 1, 1: 4, 2: 10}[order],)
    assert np.array_equal(a, b)


def test_exact_on_a_quadratic_border_included():
    """Central and second-order one-sided differences are exact for a quadratic: ∇φ and the Hessian at every
    grid point, the six points next to a border too."""
    h = np.array([0.1, 0.15, 0.2])
    ijk = np.stack(np.meshgrid(*[np.arange(n) for n in (7, 8, 9)], indexing="ij"), -1)
    x, y, z = np.moveaxis(ijk * h, -1, 0)
    phi = 1.0 + 2 * x - y + 0.5 * z + 3 * x * x + 0.7 * x * y - 1.1 * x * z + 0.4 * y * y + 2.5 * y * z - z * z
    out = derivative_stack(phi, h, 2)
    grad = np.stack([2 + 6 * x + 0.7 * y - 1.1 * z, -1 + 0.7 * x + 0.8 * y + 2.5 * z,
                     0.5 - 1.1 * x + 2.5 * y - 2 * z], -1)
    hess = np.array([6.0, 0.7, -1.1, 0.8, 2.5, -2.0])                      # xx, xy, xz, yy, yz, zz
    assert np.allclose(out[..., 0], phi, rtol=0, atol=0)
    assert np.allclose(out[..., 1:4], grad, rtol=0, atol=1e-10)
    assert np.allclose(out[..., 4:], hess, rtol=0, atol=1e-8)


def test_float32_is_the_float64_result_rounded():
    v = np.random.default_rng(1).normal(size=(6, 7, 8))
    a = derivative_stack(v, (0.1, 0.1, 0.1), 2, dtype=np.float32)
    assert a.dtype == np.float32
    assert np.array_equal(a, derivative_stack(v, (0.1, 0.1, 0.1), 2).astype(np.float32))


@pytest.mark.parametrize("values,order,match", [(np.zeros((4, 4)), 1, "3-D"), (np.zeros((2, 4, 4)), 1, "at least 3"),
                                                (np.zeros((4, 4, 4)), 3, "order")])
def test_bad_input_is_named(values, order, match):
    with pytest.raises(ValueError, match=match):
        derivative_stack(values, (1.0, 1.0, 1.0), order)


def test_volume_channels_use_it():
    from phantoms import Volume

    v = np.random.default_rng(2).normal(size=(9, 10, 11))
    vol = Volume(v, np.zeros(3), np.array([0.1, 0.2, 0.1]))
    assert np.array_equal(vol.channels(2), _derivative_channels(v, vol.spacing, 2))
