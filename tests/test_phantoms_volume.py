"""The volume type: index maps, trilinear interpolation of φ, ∇φ, Hessian, and bad input."""

import numpy as np
import pytest

from phantoms import InputError, Volume, get_phantom


def _vol_from(fn, n=24, lo=-1.0, h=0.1):
    axis = lo + h * np.arange(n)
    X = np.stack(np.meshgrid(axis, axis, axis, indexing="ij"), -1)
    return Volume(fn(X[..., 0], X[..., 1], X[..., 2]), origin=[lo] * 3, spacing=h)


def test_world_index_roundtrip():
    vol = Volume(np.zeros((5, 6, 7)), origin=[1.0, -2.0, 0.5], spacing=[0.5, 0.25, 2.0])
    p = np.array([[1.0, -2.0, 0.5], [2.25, -1.0, 4.5]])
    ijk = vol.world_to_index(p)
    assert np.allclose(ijk, [[0, 0, 0], [2.5, 4, 2]])
    assert np.allclose(vol.index_to_world(ijk), p)
    assert np.allclose(vol.upper, [1.0 + 4 * 0.5, -2.0 + 5 * 0.25, 0.5 + 6 * 2.0])


def test_trilinear_is_exact_for_trilinear_functions():
    f = lambda x, y, z: 1 + 2 * x - 3 * y + 0.5 * z + x * y - 2 * y * z + 0.7 * x * y * z
    vol = _vol_from(f)
    rng = np.random.default_rng(1)
    p = rng.uniform(-0.95, 1.25, (500, 3))
    assert np.allclose(vol(p), f(*p.T), atol=1e-12)


def test_gradient_and_hessian_of_quadratic():
    # central differences are exact for quadratics in the interior; trilinear interpolation of the
    # (exact, linear) gradient grids is exact too; the Hessian grids are constant.
    f = lambda x, y, z: x * x + 2 * y * y - z * z + 3 * x * y - y * z + x
    vol = _vol_from(f)
    rng = np.random.default_rng(2)
    p = rng.uniform(-0.7, 0.9, (300, 3))
    s = vol.sample(p, derivatives=2)
    x, y, z = p.T
    g = np.column_stack([2 * x + 3 * y + 1, 4 * y + 3 * x - z, -2 * z - y])
    assert np.allclose(s.phi, f(x, y, z), atol=0.02)  # trilinear error on a quadratic ~ h²
    assert np.allclose(s.grad, g, atol=1e-9)
    H = np.array([[2, 3, 0], [3, 4, -1], [0, -1, -2]], float)
    assert np.allclose(s.hess, H, atol=1e-9)
    assert np.allclose(vol.gradient(p), g, atol=1e-9)
    assert np.allclose(vol.hessian(p), H, atol=1e-9)


def test_derivative_grids_are_cached():
    vol = get_phantom("sphere").volume(n=16)
    vol.sample(np.zeros((1, 3)), derivatives=2)
    cached = vol.channels(2)
    vol.sample(np.ones((1, 3)), derivatives=2)
    assert vol.channels(2) is cached


def test_sdf_interpolation_near_surface():
    ph = get_phantom("sphere")
    vol = ph.volume(n=64)
    p, n = ph.sample_surface(2000, seed=3)
    s = vol.sample(p, derivatives=1)
    assert np.abs(s.phi).max() < vol.h ** 2  # curvature error of linear interpolation of |x| - 1
    cosang = (s.grad * n).sum(1) / np.linalg.norm(s.grad, axis=1)
    assert cosang.min() > 0.99


def test_outside_points_raise_unless_clamped():
    vol = get_phantom("sphere").volume(n=16)
    with pytest.raises(InputError, match="outside the volume"):
        vol.sample(np.array([[3.0, 0.0, 0.0]]))
    s = vol.sample(np.array([[3.0, 0.0, 0.0]]), clamp=True)
    assert np.isclose(s.phi, vol(np.array([[2.5, 0.0, 0.0]]))[0])
    # exactly on the last grid plane is inside
    vol.sample(np.array([[2.5, 2.5, 2.5]]))


@pytest.mark.parametrize(
    "values, match",
    [
        (np.zeros((4, 4)), "3-D"),
        (np.zeros((4, 4, 4, 2)), "3-D"),
        (np.zeros((1, 4, 4)), "at least 2"),
        (np.where(np.arange(64).reshape(4, 4, 4) == 5, np.nan, 1.0), "NaN"),
        (np.where(np.arange(64).reshape(4, 4, 4) == 5, np.inf, 1.0), "inf"),
    ],
)
def test_bad_values(values, match):
    with pytest.raises(InputError, match=match):
        Volume(values)


def test_bad_spacing_and_origin():
    with pytest.raises(InputError, match="spacing"):
        Volume(np.zeros((3, 3, 3)), spacing=0.0)
    with pytest.raises(InputError, match="origin"):
        Volume(np.zeros((3, 3, 3)), origin=[0, 0])


def test_closedness():
    vol = get_phantom("sphere").volume(n=16)
    assert vol.has_zero_crossing() and vol.is_closed()
    cut = get_phantom("sphere", radius=3.0).volume(n=16)
    assert cut.has_zero_crossing() and not cut.is_closed()
    none = vol.with_values(np.ones(vol.shape))
    assert not none.has_zero_crossing() and not none.is_closed()


def test_interpolation_matches_scipy_and_the_flow_sampler():
    """Volume.sample and the shape-gradient flow's GridSampler share one kernel; both equal scipy's
    trilinear interpolation of every cached channel grid, on an anisotropic grid, edges included."""
    from scipy.interpolate import RegularGridInterpolator

    from methods.shape_gradient import GridSampler

    rng = np.random.default_rng(3)
    vol = Volume(rng.normal(size=(9, 11, 13)), origin=[-1.0, 0.5, 2.0], spacing=[0.3, 0.2, 0.1])
    axes = [vol.origin[c] + vol.spacing[c] * np.arange(vol.shape[c]) for c in range(3)]
    p = rng.uniform(vol.lower, vol.upper, (400, 3))
    p[:3] = [vol.lower, vol.upper, [vol.upper[0], vol.lower[1], vol.upper[2]]]      # box corners
    s = vol.sample(p, derivatives=2)
    chans = vol.channels(2)
    expected = np.stack([RegularGridInterpolator(axes, chans[..., c])(p) for c in range(chans.shape[-1])], 1)
    np.testing.assert_allclose(s.phi, expected[:, 0], atol=1e-12)
    np.testing.assert_allclose(s.grad, expected[:, 1:4], atol=1e-12)
    iu = np.triu_indices(3)
    np.testing.assert_allclose(s.hess[:, iu[0], iu[1]], expected[:, 4:], atol=1e-12)
    np.testing.assert_allclose(s.hess, np.swapaxes(s.hess, 1, 2))
    g = GridSampler(vol).sample(p, derivatives=2)
    np.testing.assert_allclose(g.phi, s.phi, atol=1e-12)          # index maps differ by rounding only
    np.testing.assert_allclose(g.grad, s.grad, atol=1e-12)
    np.testing.assert_allclose(g.hess, s.hess, atol=1e-12)


def test_sampler_is_sample_with_clamp_without_the_checks():
    vol = get_phantom("ellipsoid").volume(n=20)
    p = np.random.default_rng(4).uniform(-3.0, 3.0, (400, 3))          # some outside the box: clamped
    s = vol.sampler(1)(p)
    ref = vol.sample(p, derivatives=1, clamp=True)
    assert np.allclose(s.phi, ref.phi, rtol=0, atol=1e-12) and np.allclose(s.grad, ref.grad, rtol=0, atol=1e-12)
    assert s.grad.flags.c_contiguous and vol.sampler(0)(p).grad is None
    assert vol.channels(1).shape == (20, 20, 20, 4) and vol.channels(1) is vol.channels(1)


# ---------------------------------------------------------------------------------------------- memory estimate
def test_a_volume_too_large_for_memory_is_refused_before_allocating_with_the_largest_n(monkeypatch):
    """With 100³ × 8 arrays × 8 bytes available, N = 100 is the largest grid that fits: an analytic answer."""
    import phantoms.memory as pv

    avail = 100 ** 3 * 8 * 8
    monkeypatch.setattr(pv, "available_memory", lambda: avail)
    pv.check_memory((100, 100, 100), 8)                       # fits exactly
    with pytest.raises(InputError, match=r"largest N³ grid that fits is N = 100$"):
        pv.check_memory((101, 101, 101), 8)
    monkeypatch.setattr(pv, "available_memory", lambda: 10 * 2 ** 20)  # 10 MiB
    with pytest.raises(InputError, match=r"N = 3000 volume on a 3000×3000×3000 grid needs about 402\.3 GiB \(2 arrays"):
        get_phantom("sphere").volume(n=3000)                   # refused at once, nothing allocated
    vol = get_phantom("sphere").volume(n=40)                  # 40³ × 8 × 8 B = 4 MB: fits
    monkeypatch.setattr(pv, "available_memory", lambda: 40 ** 3 * 8 * 3)
    with pytest.raises(InputError, match=r"interpolation grids \(order 1\)"):
        vol.channels(1)                                       # 4 channels (+ the stack) do not
    monkeypatch.setattr(pv, "available_memory", lambda: None)  # unknown: no check
    pv.check_memory((10 ** 4,) * 3, 8)


def test_derivative_channels_equal_stacking_phi_its_gradient_and_the_symmetrised_hessian_bit_for_bit():
    from phantoms.volume import _HESS_PAIRS, Volume

    rng = np.random.default_rng(3)
    values = rng.normal(size=(9, 11, 13))
    spacing = np.array([0.5, 0.7, 1.1])
    vol = Volume(values, np.zeros(3), spacing)
    grads = np.gradient(values, *spacing, edge_order=2)
    second = [np.gradient(g, *spacing, edge_order=2) for g in grads]
    hess = [0.5 * (second[a][b] + second[b][a]) if a != b else second[a][a] for a, b in _HESS_PAIRS]
    want = np.stack([values, *grads, *hess], axis=-1)
    assert np.array_equal(vol.channels(2), want)
    assert np.array_equal(Volume(values, np.zeros(3), spacing).channels(1), want[..., :4])
    assert np.array_equal(Volume(values, np.zeros(3), spacing).channels(0), want[..., :1])


def test_single_precision_grids_are_the_double_ones_rounded_and_interpolate_alike():
    """``channels(order, float32)``: the float64 grids rounded, cached apart from them; trilinear sampling of
    them (compiled and numpy) agrees with the float64 grids' to single-precision rounding."""
    from phantoms.volume import trilinear_channels

    vol = get_phantom("ellipsoid").volume(n=20)
    c64, c32 = vol.channels(2), vol.channels(2, dtype=np.float32)
    assert c32.dtype == np.float32 and vol.channels(2, dtype=np.float32) is c32 and vol.channels(2) is c64
    assert np.array_equal(c32, c64.astype(np.float32))
    idx = np.random.default_rng(4).uniform(0, 19, size=(3, 3000))
    ref = trilinear_channels(c64.reshape(-1, 10), vol.shape, idx)
    scale = np.abs(c64.reshape(-1, 10)).max(axis=0)[:, None]
    for reference in (False, True):
        got = trilinear_channels(c32.reshape(-1, 10), vol.shape, idx, reference=reference)
        assert got.dtype == np.float64
        assert np.all(np.abs(got - ref) <= 1e-7 * scale) and not np.array_equal(got, ref)
