"""phantoms/images.py: every image format with its geometry, one world convention (RAS+), clear refusals."""

from __future__ import annotations

import gzip

import nibabel as nib
import numpy as np
import pytest
import SimpleITK as sitk

from _volumes import itk_image, sphere_mask, write_dicom_series
from phantoms import InputError
from phantoms.images import read_image

ORIGIN = (10.0, -20.0, 30.0)
SPACING = (0.5, 0.6, 0.8)


def _marked_sphere():
    m = sphere_mask().astype(np.uint8)
    m[1, 2, 3] = 1          # an asymmetric marker: a flip or a swap of axes would move it
    return m


@pytest.fixture(scope="module")
def itk_files(tmp_path_factory):
    """One marked sphere mask written by SimpleITK as NIfTI, NRRD, MetaImage (.mha, .mhd) and a DICOM series."""
    d = tmp_path_factory.mktemp("itk")
    img = itk_image(_marked_sphere(), ORIGIN, SPACING)
    paths = {}
    for suffix in (".nii.gz", ".nrrd", ".mha", ".mhd"):
        paths[suffix] = d / f"s{suffix}"
        sitk.WriteImage(img, str(paths[suffix]))
    paths["dicom"] = write_dicom_series(img, d / "dicom")
    return paths


@pytest.mark.parametrize("fmt", [".nrrd", ".mha", ".mhd", "dicom"])
def test_every_format_gives_the_same_volume_as_the_nifti(itk_files, fmt):
    ref = read_image(itk_files[".nii.gz"])
    got = read_image(itk_files[fmt])
    assert got.values.shape == ref.values.shape
    assert np.array_equal(got.values.astype(int), ref.values.astype(int))
    assert np.allclose(got.origin, ref.origin, atol=1e-5) and np.allclose(got.spacing, ref.spacing, atol=1e-6)


def test_itk_lps_becomes_ras_and_the_marker_keeps_its_world_position(itk_files):
    """ITK's physical point of voxel (1, 2, 3) is LPS; read as RAS+ (x, y negated) the same voxel is found at
    the negated point, whatever re-orientation the reader applied."""
    img = sitk.ReadImage(str(itk_files[".nrrd"]))
    lps = np.array(img.TransformIndexToPhysicalPoint((1, 2, 3)))
    got = read_image(itk_files[".nrrd"])
    ras = lps * [-1, -1, 1]
    ijk = np.round((ras - got.origin) / got.spacing).astype(int)
    assert got.values[tuple(ijk)] == 1 and got.values[tuple(ijk + [1, 0, 0])] == 0
    assert (got.spacing > 0).all()


def test_nibabel_nifti_keeps_its_ras_affine(tmp_path):
    m = _marked_sphere()
    aff = np.diag([*SPACING, 1.0])
    aff[:3, 3] = ORIGIN
    nib.save(nib.Nifti1Image(m, aff), str(tmp_path / "a.nii.gz"))
    got = read_image(tmp_path / "a.nii.gz")
    assert np.array_equal(got.values, m)
    assert np.allclose(got.origin, ORIGIN) and np.allclose(got.spacing, SPACING)


def test_flipped_and_swapped_axes_are_reoriented_not_refused(tmp_path):
    m = _marked_sphere()
    aff = np.zeros((4, 4))
    aff[0, 1], aff[1, 0], aff[2, 2], aff[3, 3] = -0.6, 0.5, 0.8, 1.0    # array axes 0/1 swapped, one flipped
    aff[:3, 3] = ORIGIN
    nib.save(nib.Nifti1Image(m, aff), str(tmp_path / "f.nii"))
    got = read_image(tmp_path / "f.nii")
    world = aff @ [1, 2, 3, 1]                         # where the file puts the marker
    ijk = np.round((world[:3] - got.origin) / got.spacing).astype(int)
    assert got.values[tuple(ijk)] == 1
    assert np.allclose(sorted(got.spacing), [0.5, 0.6, 0.8]) and got.values.sum() == m.sum()


def _rotation(degrees: float) -> np.ndarray:
    th = np.radians(degrees)
    return np.array([[np.cos(th), -np.sin(th), 0], [np.sin(th), np.cos(th), 0], [0, 0, 1]])


@pytest.mark.parametrize("degrees", [5, 20, 30, 45, 60, 70])
@pytest.mark.parametrize("fmt", ["mha", "nii.gz"])
def test_an_oblique_grid_is_refused_with_the_angle(tmp_path, degrees, fmt):
    """Every tilt is refused, with its angle to the nearest world axis (70° is 20° from the next axis): between 30°
    and 60° both direction cosines of an axis are large, which a test of the small ones alone let through."""
    path = tmp_path / f"o.{fmt}"
    d = _rotation(degrees)
    if fmt == "mha":
        sitk.WriteImage(itk_image(_marked_sphere(), ORIGIN, SPACING, direction=d.tolist()), str(path))
    else:
        aff = np.eye(4)
        aff[:3, :3] = d * np.asarray(SPACING)[None, :]
        aff[:3, 3] = ORIGIN
        nib.save(nib.Nifti1Image(_marked_sphere().astype(np.uint8), aff), str(path))
    shown = min(degrees, 90 - degrees)
    with pytest.raises(InputError, match=rf"o.{fmt.replace('.', '[.]')}: the image grid is not axis-aligned "
                                         rf"\(its direction matrix rotates an axis by {shown:g}° .*tolerance 0.01°"):
        read_image(path)


def test_a_sheared_grid_is_refused(tmp_path):
    aff = np.diag([1.0, 1.0, 1.0, 1.0])
    aff[0, 1] = 0.3                                     # the y axis leans towards x: not perpendicular
    nib.save(nib.Nifti1Image(_marked_sphere().astype(np.uint8), aff), str(tmp_path / "s.nii.gz"))
    with pytest.raises(InputError, match=r"not axis-aligned \(its axes are sheared \(16.7° from perpendicular\)"):
        read_image(tmp_path / "s.nii.gz")


def test_a_tiny_rounding_of_the_direction_is_still_axis_aligned(tmp_path):
    d = _rotation(0.001)
    sitk.WriteImage(itk_image(_marked_sphere(), ORIGIN, SPACING, direction=d.tolist()), str(tmp_path / "r.mha"))
    assert read_image(tmp_path / "r.mha").values.sum() == _marked_sphere().sum()


def test_bad_images_are_one_line_naming_the_file(tmp_path):
    sitk.WriteImage(sitk.GetImageFromArray(np.zeros((5, 6), np.uint8)), str(tmp_path / "flat.nrrd"))
    with pytest.raises(InputError, match="flat.nrrd: a volume must be a 3-D image; got a 2-D image"):
        read_image(tmp_path / "flat.nrrd")
    nib.save(nib.Nifti1Image(np.zeros((4, 4, 4, 3), np.float32), np.eye(4)), str(tmp_path / "t.nii.gz"))
    with pytest.raises(InputError, match="t.nii.gz: a 4-D image .*3 volumes"):
        read_image(tmp_path / "t.nii.gz")
    good = tmp_path / "g.nrrd"
    sitk.WriteImage(itk_image(_marked_sphere(), ORIGIN, SPACING), str(good))
    data = good.read_bytes()
    (tmp_path / "cut.nrrd").write_bytes(data[: len(data) // 2])
    (tmp_path / "empty.mha").write_bytes(b"")
    (tmp_path / "junk.nii.gz").write_bytes(gzip.compress(b"not an image"))
    for name in ("cut.nrrd", "empty.mha", "junk.nii.gz"):
        with pytest.raises(InputError) as err:
            read_image(tmp_path / name)
        msg = str(err.value)
        assert msg.startswith(str(tmp_path / name)) and "cannot read" in msg and "\n" not in msg
    (tmp_path / "nodicom").mkdir()
    with pytest.raises(InputError, match="nodicom: the folder holds no DICOM series"):
        read_image(tmp_path / "nodicom")


def test_a_dicom_folder_with_two_series_names_them_and_series_picks_one(tmp_path):
    img = itk_image(_marked_sphere(), ORIGIN, SPACING)
    folder = tmp_path / "two"
    write_dicom_series(img, folder, series_uid="1.2.3.4.1")
    write_dicom_series(sitk.Flip(img, (True, False, False)), folder / "_", series_uid="1.2.3.4.2")
    for p in (folder / "_").iterdir():
        p.rename(folder / f"b_{p.name}")
    with pytest.raises(InputError, match=r"two: the folder holds 2 DICOM series \(1.2.3.4.1, 1.2.3.4.2\); choose one"):
        read_image(folder)
    a = read_image(folder, series="1.2.3.4.1")
    assert a.values.sum() == _marked_sphere().sum()
    with pytest.raises(InputError, match="no DICOM series '9.9'"):
        read_image(folder, series="9.9")


@pytest.mark.parametrize("how", ["missing", "truncated"])
def test_a_dicom_series_with_a_gap_is_refused_naming_the_slice(tmp_path, how):
    folder = write_dicom_series(itk_image(_marked_sphere().astype(np.int16), ORIGIN, SPACING), tmp_path / "dcm")
    assert read_image(folder).values.shape == _marked_sphere().shape       # whole: read
    victim = folder / "slice010.dcm"
    if how == "missing":
        victim.unlink()
    else:
        victim.write_bytes(victim.read_bytes()[:200])
    with pytest.raises(InputError) as err:
        read_image(folder)
    msg = str(err.value)
    assert "\n" not in msg
    # GDCM leaves a truncated file out of the series: the same gap either way
    assert "not evenly spaced: 1.6 mm between slice 10 (slice009.dcm" in msg and "against 0.8 mm" in msg, msg


def test_a_sheared_mha_is_refused_too(tmp_path):
    d = np.eye(3)
    d[:, 1] = [0.3, 1.0, 0.0]                            # ITK stores any direction matrix: y leans towards x
    d[:, 1] /= np.linalg.norm(d[:, 1])
    sitk.WriteImage(itk_image(_marked_sphere(), ORIGIN, SPACING, direction=d.tolist()), str(tmp_path / "s.mha"))
    with pytest.raises(InputError, match=r"s.mha: .*not axis-aligned \(its axes are sheared \(16.7° from perp"):
        read_image(tmp_path / "s.mha")


def test_a_dicom_series_with_one_slice_out_of_place_is_refused_naming_it(tmp_path):
    """No slice missing, but slice011.dcm 0.3 mm off its place along the normal (0020|0032 rewritten)."""
    import locale

    folder = write_dicom_series(itk_image(_marked_sphere().astype(np.int16), ORIGIN, SPACING), tmp_path / "dcm")
    victim = str(folder / "slice011.dcm")
    sl = sitk.ReadImage(victim)
    x, y, z = (float(t) for t in sl.GetMetaData("0020|0032").split("\\"))
    sl.SetMetaData("0020|0032", f"{x:.6f}\\{y:.6f}\\{z + 0.3:.6f}")
    saved = locale.setlocale(locale.LC_ALL)
    try:
        writer = sitk.ImageFileWriter()
        writer.KeepOriginalImageUIDOn()
        writer.SetFileName(victim)
        writer.Execute(sl)
    finally:
        locale.setlocale(locale.LC_ALL, saved)
    with pytest.raises(InputError) as err:
        read_image(folder)
    msg = str(err.value)
    assert "\n" not in msg and "not evenly spaced: 1.1 mm between slice 11 (slice010.dcm" in msg, msg
    assert "slice 12 (slice011.dcm)" in msg and "against 0.8 mm" in msg, msg
