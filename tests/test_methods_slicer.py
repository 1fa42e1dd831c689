"""methods/slicer.py: 3D Slicer's label map → closed surface on the unit sphere's mask at N = 48 (h = 5/47), its
formulas (pass band, iterations), decimation, thick slices and a signed distance."""

import pytest

from methods import get_method
from methods.slicer import iterations, passband

from _sphere_mask import closed_outward, facts, in_world_box, sphere_mask, sphere_sdf


@pytest.fixture(scope="module")
def mask48():
    return sphere_mask(48)


# measured: volume −1.7 %, max |r − 1| 0.24 h, Hausdorff 0.26 h (no smoothing: −1.4 %, 0.37 h — the staircase)
def test_a_closed_outward_sphere_that_windowed_sinc_barely_shrinks(mask48):
    r = get_method("slicer").reconstruct(mask48)
    err, worst = facts(r.mesh, mask48.h)
    assert closed_outward(r.mesh) and worst <= 0.5, worst
    assert -0.03 <= err <= 0.0, err
    assert r.info["iterations"] == 40 and r.info["passband"] == pytest.approx(0.01)


def test_smoothing_takes_the_staircase_off(mask48):
    rough = get_method("slicer", smoothing_factor=0.0).reconstruct(mask48)
    smooth = get_method("slicer").reconstruct(mask48)
    assert rough.info["iterations"] == 0 and closed_outward(rough.mesh)
    assert facts(smooth.mesh, mask48.h)[1] < facts(rough.mesh, mask48.h)[1]


def test_slicers_formulas():
    assert passband(0.0) == 1.0 and passband(0.5) == pytest.approx(0.01) and passband(1.0) == pytest.approx(1e-4)
    assert [iterations(f) for f in (0.0, 0.25, 0.5, 0.75, 1.0)] == [20, 30, 40, 50, 60]


def test_decimation_removes_the_share_of_triangles_asked(mask48):
    full = get_method("slicer").reconstruct(mask48).mesh
    half = get_method("slicer", decimation_factor=0.5).reconstruct(mask48).mesh
    assert closed_outward(half) and len(half.faces) == pytest.approx(len(full.faces) / 2, rel=0.05)


def test_thick_slices_keep_the_world_box_and_a_signed_distance_is_its_mask():
    vol = sphere_mask(48, z_factor=3)
    mesh = get_method("slicer").reconstruct(vol).mesh
    assert closed_outward(mesh) and in_world_box(mesh, vol.spacing)
    a = get_method("slicer").reconstruct(sphere_sdf(48)).mesh
    b = get_method("slicer").reconstruct(sphere_mask(48)).mesh
    assert closed_outward(a) and a.volume == pytest.approx(b.volume)
