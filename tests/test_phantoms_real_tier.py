"""phantoms/real_tier.py: a fine segmentation is the truth of its coarse versions — the coarse grid is made of whole
blocks of the fine one, the coarse images hold the fine volume exactly, and the truth is the fine mask's own surface
with the fine mask's digital topology."""

import importlib.util

import numpy as np
import pytest
from scipy import ndimage
from skimage.measure import euler_number

from phantoms import InputError, get_phantom
from phantoms.degrade import degrade, parse_degradation
from phantoms.mesh import MeshPhantom
from phantoms.real_tier import MAX_FACTOR, FineReferencePhantom, block_fraction, coarse_grid

HAS_NILEARN = importlib.util.find_spec("nilearn") is not None
needs_nilearn = pytest.mark.skipif(not HAS_NILEARN, reason='needs nilearn: pip install -e ".[real]"')
JOINED = np.ones((3, 3, 3), bool)


def _digital_topology(mask: np.ndarray) -> tuple[int, int]:
    """(surface components, surface Euler characteristic) of the voxel set read with 26-connected inside and
    6-connected outside: each inside component and each enclosed outside component (cavity) is one surface, and the
    surfaces' Euler characteristic is twice the solid's."""
    parts = ndimage.label(mask, structure=JOINED)[1]
    cavities = ndimage.label(~np.pad(mask, 1))[1] - 1
    return parts + cavities, 2 * int(euler_number(np.pad(mask, 1), connectivity=3))


def _test_mask(seed: int = 3) -> np.ndarray:
    """A 34 x 32 x 30 mask with a ball, a ring (genus 1), a hollow box (a cavity), voxels touching a neighbour along
    an edge only and at a corner only (the ties), a stray voxel, and random specks: MAX_FACTOR outside voxels on
    every face."""
    shape = (34, 32, 30)
    x, y, z = np.meshgrid(*[np.arange(s) for s in shape], indexing="ij")
    m = (x - 12) ** 2 + (y - 12) ** 2 + (z - 12) ** 2 <= 16                      # ball
    r = np.hypot(x - 20, y - 19)
    m |= (np.abs(r - 4.0) <= 1.2) & (np.abs(z - 20) <= 1)                        # ring
    box = (x >= 8) & (x <= 14) & (y >= 20) & (y <= 25) & (z >= 8) & (z <= 14)
    m |= box & ~((x >= 10) & (x <= 12) & (y >= 22) & (y <= 23) & (z >= 10) & (z <= 12))   # hollow box
    m[24, 8, 8] = m[25, 9, 8] = True                                             # touch along an edge only
    m[24, 8, 12] = m[25, 9, 13] = True                                           # touch at a corner only
    rng = np.random.default_rng(seed)
    core = (slice(MAX_FACTOR, -MAX_FACTOR),) * 3
    m[core] |= rng.random(m[core].shape) < 0.01
    return m


def test_the_coarse_grid_is_made_of_whole_blocks_of_the_fine_one():
    mask = _test_mask()
    origin, spacing = np.array([-7.0, 2.5, 11.0]), np.array([0.5, 0.7, 1.1])
    for k in [(2, 2, 2), (3, 3, 3), (1, 1, 3), (2, 3, 4)]:
        frac = block_fraction(mask, k)
        shape, c_origin, c_spacing = coarse_grid(mask.shape, origin, spacing, k)
        assert frac.shape == shape and np.array_equal(c_spacing, np.array(k) * spacing)
        # brute force: each coarse voxel's fine voxels (padded with outside voxels), their centres and inside share
        pad = np.pad(mask, [(0, (-s) % f) for s, f in zip(mask.shape, k)])
        for idx in [(0, 0, 0), (3, 4, 2), tuple(s - 1 for s in shape)]:
            block = tuple(slice(i * f, (i + 1) * f) for i, f in zip(idx, k))
            centres = np.stack(np.meshgrid(*[origin[d] + spacing[d] * np.arange(block[d].start, block[d].stop)
                                             for d in range(3)], indexing="ij"), -1).reshape(-1, 3)
            assert np.allclose(c_origin + np.array(idx) * c_spacing, centres.mean(0), atol=1e-12)
            assert frac[idx] == pad[block].mean()
        # the coarse voxels hold the fine volume exactly
        assert frac.sum() * np.prod(c_spacing) == pytest.approx(mask.sum() * np.prod(spacing), rel=1e-12)


def test_the_truth_is_the_fine_masks_surface_with_its_digital_topology():
    mask = _test_mask()
    ph = FineReferencePhantom(mask, (0.0, 0.0, 0.0), 1.0, name="test")
    assert (ph.n_components, ph.euler) == _digital_topology(mask)
    # the truth is closed and bounds the voxel set to half a voxel: inside voxel centres inside, outside ones out
    centres = np.argwhere(np.ones(mask.shape, bool)).astype(float)
    near = np.abs(ndimage.distance_transform_edt(~mask) - ndimage.distance_transform_edt(mask)).ravel() <= 2
    inside = ph.inside(centres[near])
    assert np.array_equal(inside, mask.ravel()[near])
    # its vertices lie half-way between an inside and an outside voxel centre (on the voxel set's faces)
    frac = ph.vertices - np.floor(ph.vertices)
    on_half = np.abs(frac - 0.5) < 1e-5
    assert np.all(on_half.sum(axis=1) == 1)


def test_a_fine_mask_without_its_outside_margin_is_refused():
    mask = _test_mask()
    mask[2, 15, 15] = True
    with pytest.raises(InputError, match=f"{MAX_FACTOR} outside voxels on every face"):
        FineReferencePhantom(mask, (0.0, 0.0, 0.0), 1.0)


def test_the_marching_cubes_of_the_fine_input_is_the_truth_but_at_ties():
    from methods import get_method

    mask = _test_mask()
    ph = FineReferencePhantom(mask, (-3.0, 4.0, 1.5), 0.8, name="test")
    vol = ph.volume()
    assert vol.kind == "mask" and np.array_equal(vol.raw > 0.5, mask)
    mesh = get_method("marching_cubes").reconstruct(vol).mesh
    # both ways: the method's vertices to the truth, the truth's samples to the method's mesh (exact distances)
    d_mesh = ph.closest(np.asarray(mesh.vertices))[1]
    other = MeshPhantom(mesh.vertices, mesh.faces, normalize=False)
    d_truth = other.closest(ph.sample_surface(5000, seed=0)[0])[1]
    # the same surface up to the tie break (both cross every grid edge at the same point), except in the cells
    # where voxels touch along an edge or at a corner only: there the method's marching cubes cuts what the truth
    # joins, within that cell — well under a voxel apart
    h = 0.8
    for d in (d_mesh, d_truth):
        assert np.mean(d < 1e-5 * h) > 0.95 and d.max() < 0.75 * h


@pytest.mark.parametrize("text, k", [("downsample@2+partial_volume", (2, 2, 2)), ("downsample@3+mask", (3, 3, 3)),
                                     ("thick_slices@3+partial_volume", (1, 1, 3)),
                                     ("downsample@2+thick_slices@2+mask", (2, 2, 4))])
def test_the_coarse_inputs_keep_the_fine_volume_and_the_block_centres(text, k):
    mask = _test_mask()
    origin, spacing = np.array([10.0, -4.0, 2.0]), 1.0
    ph = FineReferencePhantom(mask, origin, spacing, name="test")
    assert ph.block_factors(text) == k
    vol = degrade(ph, text, 0)                           # the phantom's own grid: N does not apply
    frac = block_fraction(mask, k)
    assert np.array_equal(vol.spacing, np.array(k, float))
    assert np.allclose(vol.origin, origin + 0.5 * (np.array(k) - 1))
    assert vol.is_closed() and vol.level == 0.5
    if parse_degradation(text).partial_volume:
        assert vol.kind == "intensity" and np.array_equal(vol.raw, frac)
        assert vol.raw.sum() * np.prod(vol.spacing) == pytest.approx(ph.fine_volume, rel=1e-12)
    else:
        assert vol.kind == "mask" and np.array_equal(vol.raw, (frac > 0.5).astype(float))
    # the level set methods read is negative exactly on the inside voxels
    assert np.array_equal(vol.values < 0, vol.raw > 0.5)


def test_coarsening_beyond_the_margin_or_without_a_fine_segmentation_is_refused():
    ph = FineReferencePhantom(_test_mask(), (0.0, 0.0, 0.0), 1.0, name="test")
    with pytest.raises(InputError, match="at most 6 along an axis"):
        degrade(ph, "downsample@3+thick_slices@3+mask", 0)
    with pytest.raises(InputError, match="add \\+mask or \\+partial_volume"):
        degrade(ph, "thick_slices@3", 0)
    with pytest.raises(InputError, match="downsample coarsens a segmentation"):
        parse_degradation("downsample@2")
    with pytest.raises(InputError, match="K must be an integer >= 1"):
        parse_degradation("downsample@1.5+mask")
    with pytest.raises(InputError, match="coarsens a fine segmentation.*'sphere' is not one"):
        degrade(get_phantom("sphere"), "downsample@2+mask", 32)
    assert str(parse_degradation("mask+thick_slices@2+downsample@3")) == "downsample@3+thick_slices@2+mask"


@needs_nilearn
@pytest.mark.parametrize("name, kind", [("mni_wm", "tubes"), ("mni_gm", "thin shell")])
def test_the_mni_segmentations_load_on_the_template_grid(name, kind):
    ph = get_phantom(name)
    assert ph.shape_kind == kind and ph.fine_mask.shape == (72, 72, 72) and ph.native_n() == 72
    assert np.array_equal(ph.fine_spacing, [1.0, 1.0, 1.0])
    # the 60 mm cube about MNI (-30, -40, 20) mm, 6 outside voxels around it: template voxel centres are integers
    assert np.array_equal(ph.fine_origin, np.array([-30.0, -40.0, 20.0]) - 30 - MAX_FACTOR)
    assert (ph.n_components, ph.euler) == _digital_topology(ph.fine_mask)
    assert ph.genus == type(ph).genus
    for text in ("downsample@2+partial_volume", "downsample@3+mask", "thick_slices@3+partial_volume"):
        vol = degrade(ph, text, 0)
        assert vol.is_closed()
        if vol.kind == "intensity":
            assert vol.raw.sum() * np.prod(vol.spacing) == pytest.approx(ph.fine_volume, rel=1e-12)
