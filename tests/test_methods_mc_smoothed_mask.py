"""methods/mc_smoothed_mask.py: marching cubes of the blurred mask on the unit sphere's mask at N = 48 (h = 5/47),
thick slices, a signed distance and a partial-volume intensity image."""

import numpy as np
import pytest

from methods import get_method

from _sphere_mask import closed_outward, facts, in_world_box, sphere_mask, sphere_partial_volume, sphere_sdf


@pytest.fixture(scope="module")
def mask48():
    return sphere_mask(48)


# measured: sigma 1 voxel: volume −4.8 %, max |r − 1| 0.37 h, Hausdorff 0.40 h (the blur moves the 0.5 level
# inward by about sigma² / (2 r) per curvature); sigma 0: the staircase, −1.4 %, 0.37 h
def test_a_closed_outward_sphere_shrunk_by_the_blur(mask48):
    r = get_method("mc_smoothed_mask").reconstruct(mask48)
    err, worst = facts(r.mesh, mask48.h)
    assert closed_outward(r.mesh) and worst <= 0.6, worst
    assert -0.07 <= err <= -0.03, err
    raw = get_method("mc_smoothed_mask", sigma=0.0).reconstruct(mask48).mesh
    err0, worst0 = facts(raw, mask48.h)
    assert closed_outward(raw) and abs(err0) <= 0.02 and worst0 <= 0.6
    strong = get_method("mc_smoothed_mask", sigma=2.0).reconstruct(mask48).mesh
    assert facts(strong, mask48.h)[0] < err                   # more blur, more shrinkage


def test_thick_slices_keep_the_world_box():
    vol = sphere_mask(48, z_factor=3)
    mesh = get_method("mc_smoothed_mask").reconstruct(vol).mesh
    assert closed_outward(mesh) and in_world_box(mesh, vol.spacing)


def test_a_signed_distance_is_meshed_as_its_mask_and_an_intensity_at_its_level():
    a = get_method("mc_smoothed_mask").reconstruct(sphere_sdf(48)).mesh
    b = get_method("mc_smoothed_mask").reconstruct(sphere_mask(48)).mesh
    assert closed_outward(a) and a.volume == pytest.approx(b.volume)
    pv = sphere_partial_volume(48)
    assert pv.raw.sum() * pv.h ** 3 == pytest.approx(4 / 3 * np.pi, rel=0.005)
    mesh = get_method("mc_smoothed_mask", sigma=0.0).reconstruct(pv).mesh
    err, worst = facts(mesh, pv.h)
    assert closed_outward(mesh) and abs(err) <= 0.01 and worst <= 0.2, (err, worst)     # sub-voxel boundary
