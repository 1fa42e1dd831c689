"""Tests of ``phantoms.masks``: :func:`mask_to_sdf` — the signed distance of a binary mask, zero half-way
between inside and outside voxel centres, in world units with anisotropic spacing; masks it refuses."""

from __future__ import annotations

import numpy as np
import pytest

from phantoms import InputError, mask_to_sdf


def test_a_box_mask_is_plus_minus_half_a_voxel_across_its_faces_and_the_distance_beyond():
    m = np.zeros((12, 12, 12), bool)
    m[3:9, 3:9, 3:9] = True
    vol = mask_to_sdf(m, origin=(1.0, 2.0, 3.0), spacing=0.5)
    np.testing.assert_allclose(vol.origin, [1, 2, 3]) and np.testing.assert_allclose(vol.spacing, 0.5)
    assert vol.values[3, 5, 5] == pytest.approx(-0.25) and vol.values[2, 5, 5] == pytest.approx(0.25)
    assert vol.values[0, 5, 5] == pytest.approx(3 * 0.5 - 0.25)   # three voxels out
    assert vol.values[5, 5, 5] == pytest.approx(-(3 * 0.5 - 0.25))  # the centre: three voxels in
    assert ((vol.values < 0) == m).all()


def test_mask_to_sdf_refuses_other_than_3d_and_masks_without_a_surface():
    with pytest.raises(InputError, match="3-D"):
        mask_to_sdf(np.ones((4, 4), bool))
    with pytest.raises(InputError, match="no inside voxels"):
        mask_to_sdf(np.zeros((4, 4, 4)))
    with pytest.raises(InputError, match="no outside voxels"):
        mask_to_sdf(np.ones((4, 4, 4)))


def test_mask_of_a_known_sphere_zero_level_and_distances():
    """A voxelised sphere (anisotropic spacing): the zero level set of its signed distance lies within half a
    voxel (coarsest axis) of the true sphere, and near the surface φ is the true distance within a voxel."""
    from skimage.measure import marching_cubes

    spacing = np.array([0.4, 0.5, 0.7])
    origin = np.array([-5.0, -6.0, -7.5])
    n = (30, 26, 22)
    centre, radius = np.array([0.3, -0.2, 0.1]), 4.0
    pts = origin + np.stack(np.meshgrid(*[np.arange(k) for k in n], indexing="ij"), -1) * spacing
    true = np.linalg.norm(pts - centre, axis=-1) - radius
    vol = mask_to_sdf(true < 0, origin, spacing)
    assert np.array_equal(vol.spacing, spacing) and np.array_equal(vol.origin, origin)
    assert ((vol.values < 0) == (true < 0)).all()
    v, _, _, _ = marching_cubes(vol.values, 0.0, spacing=tuple(spacing))
    err = np.abs(np.linalg.norm(v + origin - centre, axis=1) - radius)
    assert err.max() <= spacing.max() / 2 + 1e-9
    near = np.abs(true) < 2.0
    assert np.abs(vol.values[near] - true[near]).max() < spacing.max()


@pytest.mark.parametrize("spacing", [(1.0, 1.0, 1.0), (0.8, 0.8, 3.0)])
@pytest.mark.parametrize("shape", ["ball_and_speckle", "small_off_centre", "touching_a_wall"])
def test_the_distance_transforms_equal_scipys_reference(spacing, shape):
    """The compiled transforms (the fast path, the inside one cropped to the object's box) against
    :func:`scipy.ndimage.distance_transform_edt`, anisotropic too."""
    from phantoms.masks import mask_distances

    rng = np.random.default_rng(0)
    x = np.mgrid[-1:1:40j, -1:1:36j, -1:1:30j]
    m = {"ball_and_speckle": ((x ** 2).sum(0) < 0.5) | (rng.random(x.shape[1:]) < 0.01),
         "small_off_centre": ((x - np.array([0.4, -0.3, 0.2])[:, None, None, None]) ** 2).sum(0) < 0.12,
         "touching_a_wall": (np.abs(x[0] + 0.8) < 0.35) & (np.abs(x[1]) < 0.5) & (np.abs(x[2] - 0.3) < 0.9)}[shape]
    fast = mask_distances(m, np.asarray(spacing))
    ref = mask_distances(m, np.asarray(spacing), reference=True)
    for a, b in zip(fast, ref):
        np.testing.assert_allclose(a, b, rtol=1e-6, atol=1e-6 * max(spacing))


@pytest.mark.parametrize("spacing", [(1.0, 1.0, 1.0), (0.8, 0.8, 3.0)])
def test_the_signed_distance_is_the_reference_transforms_shifted_by_half_a_voxel(spacing):
    """mask_to_sdf's values against its definition on scipy's transforms: d_out − s/2 outside, s/2 − d_in inside."""
    from phantoms.masks import mask_distances

    rng = np.random.default_rng(3)
    x = np.mgrid[-1:1:31j, -1:1:27j, -1:1:22j]
    m = ((x ** 2).sum(0) < 0.4) | (rng.random(x.shape[1:]) < 0.01)
    d_out, d_in = mask_distances(m, np.asarray(spacing), reference=True)
    half = 0.5 * min(spacing)
    want = np.where(m, half - d_in, d_out - half)
    np.testing.assert_allclose(mask_to_sdf(m, spacing=spacing).values, want, rtol=1e-12, atol=1e-12)
