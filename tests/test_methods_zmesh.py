"""methods/zmesh_mc.py: zmesh's marching cubes of the label map on the unit sphere's mask at N = 48."""

import pytest

pytest.importorskip("zmesh")

from methods import get_method  # noqa: E402

from _sphere_mask import closed_outward, facts, in_world_box, sphere_mask, sphere_sdf  # noqa: E402


def test_the_staircase_of_the_mask_in_world_coordinates():
    vol = sphere_mask(48)
    mesh = get_method("zmesh").reconstruct(vol).mesh
    err, worst = facts(mesh, vol.h)
    assert closed_outward(mesh) and abs(err) <= 0.02 and worst <= 0.5, (err, worst)    # measured −1.4 %, 0.37 h
    same = get_method("marching_cubes").reconstruct(vol).mesh           # marching cubes of the mask's distance
    assert mesh.volume == pytest.approx(same.volume, rel=1e-3)


def test_thick_slices_a_signed_distance_and_simplification():
    vol = sphere_mask(48, z_factor=3)
    mesh = get_method("zmesh").reconstruct(vol).mesh
    assert closed_outward(mesh) and in_world_box(mesh, vol.spacing)
    assert closed_outward(get_method("zmesh").reconstruct(sphere_sdf(48)).mesh)
    full = get_method("zmesh").reconstruct(sphere_mask(48)).mesh
    small = get_method("zmesh", reduction_factor=4).reconstruct(sphere_mask(48)).mesh
    assert len(small.faces) < 0.9 * len(full.faces) and small.is_watertight   # 3308 -> 2738: max_error (auto) binds
    assert abs(small.volume / full.volume - 1) < 0.02
