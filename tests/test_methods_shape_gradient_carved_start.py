"""Tests of ``methods.shape_gradient.carved_start`` (``carved_start``): the genus-0 start grown from the carved
hull on a grid twice as fine holds every point of the object and little else, and a limb that every sample
misses — too far from every sample for ``start_level`` — is in the start, and kept with ``hold_carved``."""

from __future__ import annotations

import numpy as np
import pytest

from methods.shape_gradient import ShapeGradient
from methods.shape_gradient.carved_start import FINE_MAX_SAMPLES, between_inside, carved_values
from phantoms import Volume

from _shape_gradient_common import far_limb_volume, one_flow

_N, _LO = 32, -2.0
_H = 4.0 / (_N - 1)


def _grid():
    g = _LO + _H * np.arange(_N)
    return np.stack(np.meshgrid(g, g, g, indexing="ij"), -1)


def test_the_carved_region_holds_the_object_and_stays_within_a_crevice_of_it():
    """An exact signed distance (a sphere of radius 1.1 off the grid's centre): every fine sample inside the
    sphere is in the carved region s < 0 (no empty ball reaches into the object) — also where trilinear φ is
    above 0 — and every fine sample in it lies within the deepest crevice between balls, about 0.6 voxel."""
    c = np.array([0.13, -0.07, 0.05])
    vol = Volume(np.linalg.norm(_grid() - c, axis=-1) - 1.1, [_LO] * 3, _H)
    fine = carved_values(vol, vol.values, 1.0)
    assert fine.shape == tuple(2 * _N - 1 for _ in range(3)) and np.allclose(fine.spacing, _H / 2)
    g = _LO + 0.5 * _H * np.arange(2 * _N - 1)
    truth = np.linalg.norm(np.stack(np.meshgrid(g, g, g, indexing="ij"), -1) - c, axis=-1) - 1.1
    carved = fine.values < 0
    # the region holds what φ₀ < 0 holds (trilinear φ₀ of the fine grid) and little else: within the deepest
    # crevice between balls; beside a convex surface inside samples lie on opposite sides (a gap's test), so
    # the crevices there are not added
    phi0 = vol.values
    assert np.array_equal(carved[::2, ::2, ::2], phi0 < 0)
    assert truth[carved].max() < 0.65 * _H
    assert (truth[carved] < 0).mean() > 0.95
    # smaller balls (a noise margin) only add to the region
    assert (carved_values(vol, vol.values, 1.0, shrink=0.2 * _H).values < 0)[carved].all()


def test_a_gap_narrower_than_a_voxel_is_not_carved_a_limb_is():
    """A ball of radius 0.9 with a slit 1.4 voxels wide cut into it, its mid-plane half-way between two rows of
    samples: the samples beside the slit read +0.2 voxel, so no ball covers the slit's mid-plane — as none covers
    a limb's axis — but the slit's banks reach past it towards the mouth: a gap, left out of the carved region."""
    p = _grid()
    y0 = _LO + 16.5 * _H
    ball = np.linalg.norm(p, axis=-1) - 0.9
    slit = np.where(p[..., 0] > 0.2, np.abs(p[..., 1] - y0) - 0.7 * _H, np.inf)
    vol = Volume(np.maximum(ball, -slit), [_LO] * 3, _H)
    g = _LO + 0.5 * _H * np.arange(2 * _N - 1)
    fp = np.stack(np.meshgrid(g, g, g, indexing="ij"), -1)
    mid = (np.abs(fp[..., 1] - y0) < 1e-9) & (fp[..., 0] > 0.3) & (np.linalg.norm(fp, axis=-1) < 0.75)
    assert mid.sum() > 20
    fine = carved_values(vol, vol.values, 1.0)
    assert (fine.values[mid] > 0).all()                                      # the slit stays open
    assert between_inside(vol, fp[mid]).all()
    far = np.array([[1.2, _LO + 16.5 * _H, _LO + 16.5 * _H]])                 # beside no inside sample
    assert not between_inside(vol, far).any()


def test_a_grid_too_large_is_not_refined():
    n = int(round(FINE_MAX_SAMPLES ** (1 / 3) / 2)) + 2
    vol = Volume(np.ones((n, n, n)), [0.0] * 3, 1.0)
    assert carved_values(vol, vol.values, 1.0) is None


@pytest.fixture(scope="module")
def far_limb():
    return far_limb_volume()


def test_a_limb_every_sample_misses_is_in_the_carved_start(far_limb):
    vol, tip = far_limb
    level = ShapeGradient().prepare(vol, start={"start_level": 0.25})
    carved = ShapeGradient().prepare(vol, start={"carved_start": True})
    assert (tip - level.state.x[:, 0].max()) / _H > 4.0                         # start_level: no limb
    assert abs(tip - carved.state.x[:, 0].max()) / _H < 1.0                      # the carved start: the limb
    facts = carved.init_facts["carved"]
    assert facts["used"] and facts["fine_pieces"] >= 1
    assert "carved" not in level.init_facts


def test_the_limb_is_kept_by_the_flow_with_hold_carved(far_limb):
    vol, tip = far_limb
    rec = one_flow(vol, {"carved_start": True, "hold_carved": True, "carve_margin": 0.1})
    assert abs(tip - rec.mesh.vertices[:, 0].max()) / _H < 1.0
    assert rec.mesh.is_watertight and rec.mesh.euler_number == 2


def test_two_balls_a_few_voxels_apart_are_not_joined_through_the_carved_region():
    """Between samples the ball depth reads less than the distance (by up to 0.87 voxel), so the gap between two
    balls 3 voxels apart would read as a shallow saddle: the fine grid joins no pieces, the start keeps one ball."""
    p = _grid()
    gap = 3.0 * _H
    c = 0.5 * gap + 0.7
    values = np.minimum(np.linalg.norm(p - [c, 0, 0], axis=-1), np.linalg.norm(p + [c, 0, 0], axis=-1)) - 0.7
    flow = ShapeGradient().prepare(Volume(values, [_LO] * 3, _H), start={"carved_start": True})
    x = flow.state.x[:, 0]
    assert flow.init_facts["carved"]["used"] and flow.init_facts["carved"]["fine_pieces"] == 2
    assert (x.min() > 0) or (x.max() < 0)                                          # one ball, no tube
