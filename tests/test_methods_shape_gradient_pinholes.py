"""methods.shape_gradient.pinholes and methods.shape_gradient.digital.homotopic_thinning: a noise pinhole in a thin
sheet is closed (the growth then takes the whole sheet), a real hole is not, and the thinning keeps the topology and
removes every sample it may."""

from __future__ import annotations

import numpy as np
import pytest
from skimage.measure import euler_number, label

from geometry.compiled import AVAILABLE
from methods.shape_gradient.digital import homotopic_growth, homotopic_thinning
from methods.shape_gradient.pinholes import close_pinholes


def is_ball(solid):
    return (label(solid, connectivity=3).max() == 1 and euler_number(solid, connectivity=3) == 1
            and label(~solid, connectivity=1).max() == 1)


def ball_with_sheet(n=30, pinhole=0.1):
    """A ball with a sheet one sample thick sticking out along x (values: distance-like, in samples): one sample
    of the sheet, half-way out, lifted to ``pinhole`` (a noise pinhole); returns (phi, the pinhole's index)."""
    i, j, k = np.indices((n, n, n)).astype(float)
    c = n / 2.0
    ball = np.sqrt((i - 10) ** 2 + (j - c) ** 2 + (k - c) ** 2) - 5.0
    sheet = np.maximum.reduce([np.abs(k - c) - 0.4, np.abs(j - c) - 3.5, 13.0 - i, i - 25.0])
    phi = np.minimum(ball, sheet)
    hole = (19, int(c), int(c))
    phi[hole] = pinhole
    return phi, hole


def test_a_pinhole_in_a_sheet_stops_the_growth_and_is_closed():
    phi, hole = ball_with_sheet()
    solid = homotopic_growth(phi)
    left = (phi < 0) & ~solid
    assert left.sum() > 0                                  # the rim of the pinhole: the growth had to stop there
    out, facts = close_pinholes(phi, solid, 0.0, 0.25)
    assert is_ball(out)
    assert facts["left_out_before"] == left.sum() and facts["left_out"] == 0
    assert facts["pinholes"] == 1 and facts["pinhole_samples"] == 1 and out[hole]
    assert out[24, 15, 15]                                 # the sheet's far end is in the solid


def test_a_pinhole_above_the_threshold_stays_open():
    phi, hole = ball_with_sheet(pinhole=0.4)
    solid = homotopic_growth(phi)
    out, facts = close_pinholes(phi, solid, 0.0, 0.25)
    assert np.array_equal(out, solid) and facts["pinholes"] == 0 and facts["left_out"] > 0


def test_a_wide_hole_is_not_closed():
    # a sheet with a 2 × 2 hole: four samples would have to be filled, not one
    phi, _ = ball_with_sheet(pinhole=-0.5)
    phi[19:21, 15:17, 15] = 0.1
    solid = homotopic_growth(phi)
    assert ((phi < 0) & ~solid).sum() > 0
    out, facts = close_pinholes(phi, solid, 0.0, 0.25)
    assert facts["pinholes"] == 0 and np.array_equal(out, solid)


def test_nothing_left_out_or_no_threshold_changes_nothing():
    phi, _ = ball_with_sheet(pinhole=-0.5)
    solid = homotopic_growth(phi)
    assert np.array_equal(close_pinholes(phi, solid, 0.0, 0.25)[0], solid)
    phi, _ = ball_with_sheet()
    solid = homotopic_growth(phi)
    assert np.array_equal(close_pinholes(phi, solid, 0.0, 0.0)[0], solid)


@pytest.mark.parametrize("seed", range(3))
def test_thinning_keeps_the_topology_and_equals_its_reference(seed):
    from scipy import ndimage
    rng = np.random.default_rng(seed)
    phi = ndimage.gaussian_filter(rng.standard_normal((26, 26, 26)), 1.5)
    phi /= phi.std()
    solid = homotopic_growth(phi, 0.3)
    removable = solid & (phi > -0.3)
    out = homotopic_thinning(solid, phi, removable)
    assert is_ball(out) and not (out & ~solid).any() and out.sum() < solid.sum()
    if AVAILABLE:
        assert np.array_equal(out, homotopic_thinning(solid, phi, removable, reference=True))


def test_thinning_removes_a_bump_entirely_and_keeps_what_closes_a_hole():
    phi, hole = ball_with_sheet(pinhole=-0.5)
    solid = homotopic_growth(phi)
    assert is_ball(solid) and solid[hole]
    bump = np.zeros_like(solid)
    bump[5, 14:17, 14:17] = True                           # a 3 × 3 patch outside the ball, touching it
    thick = solid | bump
    assert is_ball(thick)
    assert np.array_equal(homotopic_thinning(thick, phi, bump), solid)
    # a sample in the middle of a sheet one sample thick: taking it out would open a hole, so it stays
    removable = np.zeros_like(solid)
    removable[hole] = True
    assert homotopic_thinning(solid, phi, removable)[hole]


def test_removable_samples_on_the_outer_layer_are_refused():
    solid = np.ones((5, 5, 5), bool)
    with pytest.raises(ValueError, match="outer layer"):
        homotopic_thinning(solid, np.zeros((5, 5, 5)), solid)
