"""Tests of ``methods.shape_gradient.field``: the noise estimate, the start smoothing that brings the noise to
its target, and the (2/3)³ variance of interpolated noise the unbias term relies on."""

from __future__ import annotations

import numpy as np
import pytest

from methods.shape_gradient import estimate_noise
from phantoms import add_noise, get_phantom


def test_noise_estimate():
    vol = get_phantom("sphere").volume(n=48)
    assert estimate_noise(vol) < 1e-3 * vol.h
    noisy, _ = add_noise(vol, "gaussian", 40.0, seed=3)
    true_sigma = np.std(noisy.values - vol.values)
    assert estimate_noise(noisy) == pytest.approx(true_sigma, rel=0.05)


def test_start_smoothing_brings_the_noise_to_its_target():
    from scipy.ndimage import gaussian_filter
    from methods.shape_gradient.field import start_smoothing
    assert start_smoothing(0.0) == 0.0 and start_smoothing(0.99) == 0.0 and start_smoothing(float("nan")) == 0.0
    sigmas = [start_smoothing(n) for n in (1.5, 3.0, 6.0)]
    assert 0 < sigmas[0] < sigmas[1] < sigmas[2]
    rng = np.random.default_rng(0)
    for noise, sigma in zip((1.5, 3.0, 6.0), sigmas):        # measured on a field of pure i.i.d. noise
        out = gaussian_filter(rng.normal(0.0, noise, (64, 64, 64)), sigma, mode="wrap")
        assert np.std(out) == pytest.approx(1.0, rel=0.05)
    assert start_smoothing(3.0, target_voxels=0.5) > sigmas[1]


def test_the_interpolated_noise_variance_is_eight_27ths():
    """The factor unbias uses: trilinear interpolation of i.i.d. unit noise at uniformly random points has mean
    variance (2/3)³ (measured on a grid of pure noise)."""
    from phantoms import Volume
    rng = np.random.default_rng(0)
    vol = Volume(rng.normal(size=(24, 24, 24)), np.zeros(3), np.ones(3))
    p = rng.uniform(2, 21, (200_000, 3))
    v = np.asarray(vol.sample(p, derivatives=0).phi)
    assert np.mean(v ** 2) == pytest.approx((2 / 3) ** 3, rel=0.03)


def test_the_flow_reads_single_precision_grids_only_above_the_size_limit(monkeypatch):
    """Large volumes: the flow's sampler reads the float32 stack (half the memory), whose φ and ∇φ agree with
    the volume's own float64 interpolation to single-precision rounding and still are the sphere's; below
    the limit it reads the float64 grids."""
    import methods.shape_gradient.field as fd

    assert fd.stack_dtype((128, 128, 128)) is np.float64 and fd.stack_dtype((160, 160, 160)) is np.float32
    vol = get_phantom("sphere").volume(n=32)
    assert fd.GridSampler(vol)._channels(2).dtype == np.float64
    monkeypatch.setattr(fd, "FLOAT32_ABOVE_BYTES", 0)
    gs = fd.GridSampler(vol)
    assert gs._channels(2).dtype == np.float32
    pts = np.random.default_rng(3).normal(size=(2000, 3))
    pts = pts / np.linalg.norm(pts, axis=1, keepdims=True) * np.random.default_rng(4).uniform(0.5, 1.5, (2000, 1))
    got, want = gs.sample(pts, derivatives=1), vol.sample(pts, derivatives=1)
    assert np.max(np.abs(got.phi - want.phi)) <= 1e-7 * np.abs(vol.values).max()
    assert np.max(np.abs(got.grad - want.grad)) <= 1e-6 and not np.array_equal(got.grad, want.grad)
    r = np.linalg.norm(pts, axis=1)
    assert np.max(np.abs(got.phi - (r - 1.0))) < 0.5 * vol.h       # the unit sphere's SDF, to interpolation error
