"""phantoms/io.py: reading and writing volumes in every supported format, masks to signed distance."""

import gzip
import hashlib

import nibabel as nib
import numpy as np
import pytest

from phantoms import InputError, Volume, add_noise, get_phantom, load_volume, mask_to_sdf, save_volume


def test_npz_roundtrip(tmp_path):
    vol = Volume(np.random.default_rng(0).normal(size=(9, 10, 11)), origin=[1, 2, 3], spacing=[0.5, 0.25, 2])
    path = save_volume(tmp_path / "v.npz", vol)
    back = load_volume(path)
    assert np.array_equal(back.values, vol.values)
    assert np.array_equal(back.origin, vol.origin) and np.array_equal(back.spacing, vol.spacing)
    with pytest.raises(InputError, match=".npz"):
        save_volume(tmp_path / "v.npy", vol)


def test_npy_has_unit_spacing(tmp_path):
    arr = np.random.default_rng(1).normal(size=(8, 8, 8))
    np.save(tmp_path / "a.npy", arr)
    vol = load_volume(tmp_path / "a.npy")
    assert np.array_equal(vol.values, arr) and np.array_equal(vol.spacing, [1, 1, 1])
    assert np.array_equal(vol.origin, [0, 0, 0])


@pytest.mark.parametrize("suffix", [".nii", ".nii.gz"])
def test_nifti_axis_aligned(tmp_path, suffix):
    arr = get_phantom("sphere").volume(n=16).values.astype(np.float32)
    affine = np.diag([0.5, 0.75, 1.25, 1.0])
    affine[:3, 3] = [-3, -4, -5]
    path = tmp_path / f"s{suffix}"
    nib.save(nib.Nifti1Image(arr, affine), str(path))
    vol = load_volume(path)
    assert np.allclose(vol.values, arr)
    assert np.allclose(vol.spacing, [0.5, 0.75, 1.25]) and np.allclose(vol.origin, [-3, -4, -5])


def test_nifti_rotated_affine_is_rejected(tmp_path):
    th = 0.3
    affine = np.eye(4)
    affine[:2, :2] = [[np.cos(th), -np.sin(th)], [np.sin(th), np.cos(th)]]
    path = tmp_path / "rot.nii"
    nib.save(nib.Nifti1Image(np.zeros((8, 8, 8), np.float32), affine), str(path))
    with pytest.raises(InputError, match="not axis-aligned"):
        load_volume(path)


def test_mask_becomes_signed_distance(tmp_path):
    ph = get_phantom("sphere")
    ref = ph.volume(n=48)
    mask = ref.values < 0
    np.save(tmp_path / "m.npy", mask)
    sdf = load_volume(tmp_path / "m.npy")
    assert (sdf.values[mask] < 0).all() and (sdf.values[~mask] > 0).all()
    # as a distance it is within a voxel of the true distance (grid units here: spacing 1)
    assert np.abs(sdf.values - ref.values / ref.h).max() < 1.0
    # uint8 0/1 masks in NIfTI too, with the spacing honoured
    affine = np.diag([ref.h, ref.h, ref.h, 1.0])
    affine[:3, 3] = ref.origin
    nib.save(nib.Nifti1Image(mask.astype(np.uint8), affine), str(tmp_path / "m.nii.gz"))
    sdf2 = load_volume(tmp_path / "m.nii.gz")
    assert np.abs(sdf2.values - ref.values).max() < ref.h
    # forcing raw values keeps the 0/1 array
    raw = load_volume(tmp_path / "m.npy", mask=False)
    assert set(np.unique(raw.values)) == {0.0, 1.0}


def test_mask_without_inside_voxels(tmp_path):
    np.save(tmp_path / "empty.npy", np.zeros((8, 8, 8), bool))
    with pytest.raises(InputError, match="no inside voxels"):
        load_volume(tmp_path / "empty.npy")
    with pytest.raises(InputError, match="no outside voxels"):
        mask_to_sdf(np.ones((4, 4, 4)))


def test_bad_files(tmp_path):
    vol = get_phantom("sphere").volume(n=16)
    good = save_volume(tmp_path / "g.npz", vol)
    data = good.read_bytes()
    (tmp_path / "trunc.npz").write_bytes(data[: len(data) // 2])
    with pytest.raises(InputError, match="cannot read"):
        load_volume(tmp_path / "trunc.npz")
    np.save(tmp_path / "full.npy", vol.values)
    raw = (tmp_path / "full.npy").read_bytes()
    (tmp_path / "trunc.npy").write_bytes(raw[: len(raw) // 3])
    with pytest.raises(InputError, match="cannot read"):
        load_volume(tmp_path / "trunc.npy")
    (tmp_path / "junk.nii.gz").write_bytes(gzip.compress(b"not a nifti file at all"))
    with pytest.raises(InputError, match="cannot read"):
        load_volume(tmp_path / "junk.nii.gz")
    with pytest.raises(InputError, match="no such file"):
        load_volume(tmp_path / "missing.npz")
    (tmp_path / "x.vtk").write_text("x")
    with pytest.raises(InputError, match="unsupported file type"):
        load_volume(tmp_path / "x.vtk")
    np.save(tmp_path / "flat.npy", np.zeros((4, 4)))
    with pytest.raises(InputError, match="3-D"):
        load_volume(tmp_path / "flat.npy")
    bad = vol.values.copy()
    bad[3, 3, 3] = np.nan
    np.save(tmp_path / "nan.npy", bad)
    with pytest.raises(InputError, match="NaN"):
        load_volume(tmp_path / "nan.npy")
    np.savez(tmp_path / "nokey.npz", data=vol.values)
    with pytest.raises(InputError, match="'values'"):
        load_volume(tmp_path / "nokey.npz")


def test_volume_file_is_deterministic(tmp_path):
    """Same phantom, seed and SNR → the same bytes of values (hash of the array)."""
    ph = get_phantom("cylinder")
    a, _ = add_noise(ph.volume(n=32), "uniform", 42, seed=1)
    b, _ = add_noise(ph.volume(n=32), "uniform", 42, seed=1)
    assert hashlib.sha256(a.values.tobytes()).hexdigest() == hashlib.sha256(b.values.tobytes()).hexdigest()


# ---------------------------------------------------------------------------------------------- checked inputs
@pytest.mark.parametrize("origin, spacing, message", [
    (np.zeros(3), np.ones(2), "spacing must be a number or 3 numbers (x, y, z); got 2 values"),
    (np.zeros(3), np.array(["a", "b", "c"]), "spacing must be a number or 3 real numbers"),
    (np.zeros(3), np.ones(3) * (1 + 1j), "spacing must be a number or 3 real numbers"),
    (np.zeros(4), np.ones(3), "origin must be 3 numbers (x, y, z); got 4 values"),
    (np.zeros((3, 3)), np.ones(3), "origin must be 3 numbers"),
    (np.array("left"), np.ones(3), "origin must be 3 real numbers"),
])
def test_npz_origin_and_spacing_of_the_wrong_length_or_type_name_the_file(tmp_path, origin, spacing, message):
    path = tmp_path / "v.npz"
    np.savez(path, values=get_phantom("sphere").volume(n=16).values, origin=origin, spacing=spacing)
    with pytest.raises(InputError) as err:
        load_volume(path)
    assert str(err.value).startswith(f"{path}: volume ") and message in str(err.value)


def test_a_mask_with_a_bad_spacing_is_named_too(tmp_path):
    path = tmp_path / "m.npz"
    np.savez(path, values=(get_phantom("sphere").volume(n=16).values < 0), spacing=np.ones(4))
    with pytest.raises(InputError, match=f"^{path}: volume spacing .* got 4 values"):
        load_volume(path)


@pytest.mark.parametrize("values, message", [
    (np.ones((4, 4, 4)) * (1 + 2j), "real numbers; got dtype complex128 (the imaginary part would be lost)"),
    (np.full((4, 4, 4), "x"), "real numbers; got dtype <U1"),
])
def test_complex_and_text_values_are_rejected(tmp_path, values, message):
    path = tmp_path / "v.npy"
    np.save(path, values)
    with pytest.raises(InputError, match=f"^{path}: volume values must be " + message.replace("(", r"\(")
                       .replace(")", r"\)")):
        load_volume(path)
    with pytest.raises(InputError, match="real numbers"):
        Volume(values)                                         # the Volume itself refuses too


def test_object_arrays_are_named_as_such_not_as_truncated(tmp_path):
    path = tmp_path / "obj.npy"
    np.save(path, np.empty((4, 4, 4), dtype=object), allow_pickle=True)
    with pytest.raises(InputError) as err:
        load_volume(path)
    assert "Python objects" in str(err.value) and "truncated" not in str(err.value)


def test_an_unreadable_file_is_not_called_truncated(tmp_path, monkeypatch):
    import errno

    path = save_volume(tmp_path / "v.npz", get_phantom("sphere").volume(n=16))

    def denied(*a, **k):
        raise PermissionError(errno.EACCES, "Permission denied", str(path))

    monkeypatch.setattr(np, "load", denied)
    with pytest.raises(InputError) as err:
        load_volume(path)
    assert str(err.value) == f"{path}: cannot read the file: Permission denied"


def test_mask_errors_name_the_file(tmp_path):
    np.save(tmp_path / "empty.npy", np.zeros((4, 4, 4), bool))
    with pytest.raises(InputError, match=f"^{tmp_path / 'empty.npy'}: the mask has no inside voxels"):
        load_volume(tmp_path / "empty.npy")


def test_save_volume_is_atomic_and_a_write_error_names_the_path(tmp_path):
    from geometry.files import WriteError

    (tmp_path / "d.npz").mkdir()
    with pytest.raises(WriteError, match="d.npz': it is a directory"):
        save_volume(tmp_path / "d.npz", get_phantom("sphere").volume(n=16))
    save_volume(tmp_path / "ok.npz", get_phantom("sphere").volume(n=16))
    assert sorted(p.name for p in tmp_path.iterdir()) == ["d.npz", "ok.npz"]
