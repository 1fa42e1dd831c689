"""Degradations with exact truth (phantoms/degrade.py): known answers on the sphere and the parser's refusals."""

import numpy as np
import pytest

from phantoms import InputError, get_phantom
from phantoms.degrade import Degradation, degrade, flip_boundary, parse_degradation, thick_grid


def _ball(r=1.0):
    return 4.0 / 3.0 * np.pi * r ** 3


@pytest.mark.parametrize("n", [32, 64])
def test_the_mask_of_a_sphere_holds_its_volume_within_the_voxel_counting_error(n):
    """Counting voxels misjudges only voxels the surface cuts: those whose centre lies within half the voxel
    diagonal a = h√3/2 of the sphere, so |count·h³ − V| ≤ the shell's volume 4π/3 ((r + a)³ − (r − a)³)."""
    vol = degrade(get_phantom("sphere"), "mask", n)
    h = vol.spacing[0]
    assert vol.kind == "mask" and vol.level == 0.5 and set(np.unique(vol.raw)) == {0.0, 1.0}
    a = h * np.sqrt(3) / 2
    shell = 4.0 / 3.0 * np.pi * ((1 + a) ** 3 - (1 - a) ** 3)
    err = abs(vol.raw.sum() * h ** 3 - _ball())
    assert err <= shell
    assert err / _ball() < 0.04          # measured: 3.0 % at N = 32, 1.2 % at N = 64 (the bound is ~10× looser)
    # the level-set methods' φ is the mask's signed distance: negative exactly on the mask's voxels
    assert np.array_equal(vol.values < 0, vol.raw > 0.5)


@pytest.mark.parametrize("n", [32, 64])
def test_the_partial_volume_image_sums_to_the_exact_volume(n):
    vol = degrade(get_phantom("sphere"), "partial_volume", n)
    assert vol.kind == "intensity" and vol.raw.min() >= 0 and vol.raw.max() <= 1
    assert abs(vol.raw.sum() * np.prod(vol.spacing) / _ball() - 1) < 0.005
    assert ((vol.raw > 0) & (vol.raw < 1)).sum() > 0.5 * 4 * np.pi / vol.spacing[0] ** 2   # a band of fractions
    # φ keeps the image's 0.5 level: negative where the fraction is above one half
    assert np.array_equal(vol.values < 0, vol.raw > 0.5)


def test_the_partial_volume_of_a_mesh_phantom_sums_to_its_mesh_volume():
    ph = get_phantom("bunny")
    vol = degrade(ph, "partial_volume", 48)
    assert abs(vol.raw.sum() * np.prod(vol.spacing) / ph.solid_volume - 1) < 0.01


@pytest.mark.parametrize("k", [2, 3, 5])
def test_thick_slices_keep_the_world_box_and_the_truth(k):
    from skimage.measure import marching_cubes

    n = 64
    vol = degrade(get_phantom("sphere"), f"thick_slices@{k}+mask", n)
    h = 5.0 / (n - 1)
    assert vol.spacing[2] == pytest.approx(k * h) and vol.spacing[0] == pytest.approx(h)
    assert vol.shape[:2] == (n, n) and vol.shape[2] == (n - 1) // k + 1
    assert np.all(np.abs(vol.lower - (-2.5)) <= k * h) and np.all(np.abs(vol.upper - 2.5) <= k * h)
    v, f, _, _ = marching_cubes(vol.values, 0.0, spacing=tuple(vol.spacing))
    v += vol.origin
    lo, hi = v.min(0), v.max(0)
    # the mesh lies where the truth lies: its box within one voxel of the unit ball's on every axis
    assert np.all(np.abs(lo + 1) <= vol.spacing) and np.all(np.abs(hi - 1) <= vol.spacing)
    assert np.abs(np.linalg.norm(v, axis=1) - 1).max() <= vol.spacing.max()


def test_label_noise_at_zero_is_the_mask_and_flips_the_expected_share_seeded():
    ph = get_phantom("sphere")
    mask = degrade(ph, "mask", 48).raw > 0.5
    assert np.array_equal(degrade(ph, "label_noise@0+mask", 48).raw > 0.5, mask)
    from scipy import ndimage

    boundary = (ndimage.binary_dilation(mask) & ~mask) | (mask & ~ndimage.binary_erosion(mask, border_value=1))
    p = 0.2
    a = degrade(ph, f"label_noise@{p}+mask", 48, seed=3).raw > 0.5
    flipped = a != mask
    assert not (flipped & ~boundary).any()                     # only boundary voxels flip
    m = int(boundary.sum())
    share = flipped.sum() / m
    assert abs(share - p) < 4 * np.sqrt(p * (1 - p) / m)       # binomial: within 4 standard deviations
    assert np.array_equal(a, degrade(ph, f"label_noise@{p}+mask", 48, seed=3).raw > 0.5)     # reproducible
    assert not np.array_equal(a, degrade(ph, f"label_noise@{p}+mask", 48, seed=4).raw > 0.5)
    assert np.array_equal(flip_boundary(mask, 1.0, 0), mask ^ boundary)


def test_blur_spreads_the_boundary_and_keeps_the_amount():
    ph = get_phantom("sphere")
    sharp = degrade(ph, "partial_volume", 48)
    blurred = degrade(ph, "blur@1.5+partial_volume", 48)
    part = lambda v: ((v.raw > 0.01) & (v.raw < 0.99)).sum()      # noqa: E731
    assert part(blurred) > 2 * part(sharp)
    assert blurred.raw.sum() == pytest.approx(sharp.raw.sum(), rel=1e-3)


def test_parse_names_and_canonical_text():
    d = parse_degradation("mask + thick_slices@3")
    assert d == Degradation(mask=True, thick_slices=3) and str(d) == "thick_slices@3+mask"
    assert parse_degradation("none").is_none and str(parse_degradation("")) == "none"
    assert parse_degradation("blur@1+partial_volume").kind == "intensity"
    assert thick_grid(64, 2.5, 3)[0] == (64, 64, 22)


@pytest.mark.parametrize("text, value, shown", [
    ("blur@1e6+partial_volume", 1e6, "blur@1000000+partial_volume"),
    ("blur@1e+06+partial_volume", 1e6, "blur@1000000+partial_volume"),     # an exponent's + is not a step's
    ("blur@1.23456789+mask", 1.23456789, "blur@1.23456789+mask"),
    ("blur@2.5e16+mask", 2.5e16, "blur@2.5e16+mask"), ("blur@1E-7+mask", 1e-7, "blur@1e-07+mask"),
])
def test_a_value_is_written_in_full_and_reads_back_as_given(text, value, shown):
    d = parse_degradation(text)
    assert d.blur == value and str(d) == shown and parse_degradation(str(d)) == d
    noisy = parse_degradation("label_noise@0.123456789+mask")
    assert noisy.label_noise == 0.123456789 and parse_degradation(str(noisy)) == noisy


@pytest.mark.parametrize("text, words", [
    ("thick_slices@0+mask", "integer >= 1"), ("thick_slices@2.5+mask", "integer >= 1"),
    ("label_noise@1.5+mask", "in [0, 1]"), ("label_noise@-0.1+mask", "in [0, 1]"),
    ("blur@-1+mask", "sigma must be >= 0"), ("blur@nan+mask", "finite"), ("mask+partial_volume", "exclude"),
    ("label_noise@0.1", "add +mask"), ("blur@1", "add +mask or +partial_volume"), ("masks", "unknown step"),
    ("mask+mask", "twice"), ("thick_slices+mask", "needs a value"), ("mask@2", "takes no value"),
])
def test_bad_degradations_are_one_line_naming_the_problem(text, words):
    with pytest.raises(InputError, match=None) as err:
        parse_degradation(text)
    assert words in str(err.value) and "\n" not in str(err.value)


def test_a_user_volume_has_no_subvoxel_truth(tmp_path):
    from phantoms import get_phantom as resolve

    m = np.zeros((20, 20, 20), np.uint8)
    m[5:15, 5:15, 5:15] = 1
    path = tmp_path / "seg.npy"
    np.save(path, m)
    ph = resolve(f"volume:{path}")
    with pytest.raises(InputError, match="no sub-voxel truth"):
        degrade(ph, "partial_volume", 0)
    vol = degrade(ph, "mask", 0)
    assert vol.kind == "mask" and int(vol.raw.sum()) == 1000


@pytest.mark.parametrize("name, k", [("bunny", 1), ("fused_spheres", 1), ("bunny", 3), ("torus", 2)])
def test_the_partial_volume_shortcut_equals_the_inside_test_of_every_sub_sample(name, k):
    """Sub-samples inside the distance ball of their voxel's centre or of a face / edge neighbour take its side
    without the inside test: the fractions equal those of testing all 4³ sub-samples of every boundary voxel,
    on thick slices (every k-th z-plane) too."""
    from phantoms.degrade import PV_SAMPLES, partial_volume_fraction

    ph = get_phantom(name)
    n, extent = 40, 2.5
    vol = ph.volume(n=n, extent=extent)
    phi, origin = np.ascontiguousarray(np.asarray(vol.values)[:, :, ::k]), np.asarray(vol.origin)
    spacing = np.asarray(vol.spacing, float) * np.array([1.0, 1.0, k])
    fast = partial_volume_fraction(ph, phi, origin, spacing)
    band = np.argwhere(np.abs(phi) < 0.5 * np.linalg.norm(spacing))
    offs = (np.arange(PV_SAMPLES) + 0.5) / PV_SAMPLES - 0.5
    sub = np.stack(np.meshgrid(offs, offs, offs, indexing="ij"), axis=-1).reshape(-1, 3) * spacing
    pts = (origin + band * spacing)[:, None, :] + sub[None]
    brute = np.asarray(ph.inside(pts.reshape(-1, 3)), bool).reshape(len(band), -1).mean(axis=1)
    np.testing.assert_array_equal(fast[tuple(band.T)], brute)
    np.testing.assert_array_equal(fast, partial_volume_fraction(ph, phi, origin, spacing, reference=True))
    assert 0 < ((brute > 0) & (brute < 1)).sum()                      # there are partial voxels to get right
