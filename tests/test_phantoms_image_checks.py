"""phantoms/image_checks.py (issue 40, items 9, 12, 15): what is refused before an image's data is read — a
header claiming more than the file holds (truncated) or than the memory holds, a FIFO or a device, an .mhd whose
raw file is missing — each in one line naming the cause, exit 2 on the command line, and nothing of ITK's own
text on the terminal."""

from __future__ import annotations

import os
import subprocess
import sys

import nibabel as nib
import numpy as np
import pytest
import SimpleITK as sitk

from _volumes import itk_image, sphere_mask, write_dicom_series
from bench.cli import main
from phantoms import InputError
from phantoms import memory as pm
from phantoms.image_checks import itk_error_text, quiet_itk
from phantoms.images import read_image


def _nifti_claiming(path, shape, gz=False):
    """A tiny NIfTI (2³ float32 of data) whose header claims ``shape``."""
    nib.save(nib.Nifti1Image(np.zeros((2, 2, 2), np.float32), np.eye(4)), path)
    img = nib.load(path)
    header = img.header.copy()
    header.set_data_shape(shape)
    header["vox_offset"] = 352
    data = np.asarray(img.dataobj).tobytes()
    raw = header.binaryblock + b"\0" * (352 - len(header.binaryblock)) + data
    if gz:
        import gzip
        raw = gzip.compress(raw)
    path.write_bytes(raw)
    return path


def _one_error_line(capsys):
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("error: ") and "Traceback" not in err, err
    return err


# ---------------------------------------------------------------------------------------- item 9: sizes
def test_a_tiny_nifti_claiming_1500_cubed_is_a_truncated_file_before_any_allocation(tmp_path, capsys):
    path = _nifti_claiming(tmp_path / "huge.nii", (1500, 1500, 1500))
    assert path.stat().st_size < 2000
    assert main(["info", str(path)]) == 2
    err = _one_error_line(capsys)
    assert "truncated" in err and "1500×1500×1500 float32" in err and "12.6 GiB" in err


def test_a_compressed_nifti_claiming_more_than_the_memory_is_refused_with_both_sizes(tmp_path, capsys, monkeypatch):
    path = _nifti_claiming(tmp_path / "huge.nii.gz", (1500, 1500, 1500), gz=True)
    monkeypatch.setattr(pm, "available_memory", lambda: 8 * 2 ** 30)
    assert main(["info", str(path)]) == 2
    err = _one_error_line(capsys)
    assert "claims a 1500×1500×1500 float32 image (12.6 GiB of data)" in err
    assert "8.0 GiB of memory are available" in err


def test_reconstruct_refuses_the_claimed_size_before_reading(tmp_path, capsys, monkeypatch):
    path = _nifti_claiming(tmp_path / "huge.nii.gz", (1500, 1500, 1500), gz=True)
    monkeypatch.setattr(pm, "available_memory", lambda: 2 ** 30)
    code = main(["reconstruct", str(path), "--method", "marching_cubes", "-o", str(tmp_path / "m.ply")])
    assert code == 2 and "of memory are available" in _one_error_line(capsys)


@pytest.mark.parametrize("suffix", [".mha", ".nrrd", ".npy", ".npz", ".nii.gz"])
def test_each_format_is_checked_against_the_memory_from_its_header(tmp_path, monkeypatch, suffix):
    values = np.zeros((20, 20, 20), np.float32)
    path = tmp_path / f"v{suffix}"
    if suffix == ".npy":
        np.save(path, values)
    elif suffix == ".npz":
        np.savez_compressed(path, values=values)
    elif suffix == ".nii.gz":
        nib.save(nib.Nifti1Image(values, np.eye(4)), path)
    else:
        sitk.WriteImage(sitk.GetImageFromArray(values), str(path))
    assert read_image(path).values.shape == (20, 20, 20)
    monkeypatch.setattr(pm, "available_memory", lambda: 20 ** 3 * 8)      # the float64 copy alone
    with pytest.raises(InputError, match=r"20×20×20 .*of memory are available"):
        read_image(path)


def test_a_dicom_series_is_checked_against_the_memory(tmp_path, monkeypatch):
    folder = write_dicom_series(itk_image(sphere_mask().astype(np.int16), (0, 0, 0), (1, 1, 1)), tmp_path / "d")
    monkeypatch.setattr(pm, "available_memory", lambda: 1000)
    with pytest.raises(InputError, match=r"claims a 24×26×22 .*of memory are available"):
        read_image(folder)


@pytest.mark.parametrize("suffix", [".mha", ".nrrd", ".npy", ".nii"])
def test_an_uncompressed_file_shorter_than_its_header_claims_is_truncated(tmp_path, suffix):
    values = np.zeros((10, 10, 10), np.float32)
    path = tmp_path / f"v{suffix}"
    if suffix == ".npy":
        np.save(path, values)
    elif suffix == ".nii":
        nib.save(nib.Nifti1Image(values, np.eye(4)), path)
    else:
        sitk.WriteImage(sitk.GetImageFromArray(values), str(path))
    path.write_bytes(path.read_bytes()[:-100])
    with pytest.raises(InputError, match=r"cannot read the file: it is truncated — .*10×10×10 .*\(4000 bytes of "
                                         r"data\) but the file holds 3900 bytes"):
        read_image(path)


# ------------------------------------------------------------------------------------ item 12: not a file
def test_info_on_a_fifo_with_no_writer_is_refused_without_blocking(tmp_path):
    fifo = tmp_path / "pipe.nii"
    os.mkfifo(fifo)
    for arg in (str(fifo), f"volume:{fifo}?threshold=0.5"):
        r = subprocess.run([sys.executable, "-m", "bench", "info", arg], capture_output=True, text=True, timeout=60)
        assert r.returncode == 2, r.stderr
        assert r.stderr.count("\n") == 1 and "is a FIFO (named pipe), not an image file" in r.stderr, r.stderr


def test_a_character_device_is_refused(capsys):
    assert main(["info", "/dev/zero"]) == 2
    assert "is a character device, not an image file" in _one_error_line(capsys)


def test_an_mhd_naming_a_fifo_as_its_data_is_refused(tmp_path):
    sitk.WriteImage(sitk.GetImageFromArray(np.zeros((4, 4, 4), np.float32)), str(tmp_path / "v.mhd"))
    (tmp_path / "v.raw").unlink()
    os.mkfifo(tmp_path / "v.raw")
    with pytest.raises(InputError, match="is a FIFO"):
        read_image(tmp_path / "v.mhd")


# ---------------------------------------------------------------------------- item 15: ITK's own text
def test_an_mhd_whose_raw_file_is_missing_names_the_raw_file(tmp_path, capfd):
    sitk.WriteImage(sitk.GetImageFromArray(np.zeros((4, 4, 4), np.float32)), str(tmp_path / "v.mhd"))
    (tmp_path / "v.raw").unlink()
    assert main(["info", str(tmp_path / "v.mhd")]) == 2
    out, err = capfd.readouterr()
    assert err.count("\n") == 1 and "ElementDataFile = v.raw" in err and "does not exist" in err, err
    assert ".cxx" not in err


@pytest.mark.parametrize("name, header", [
    ("bad.mha", "ObjectType = Image\nNDims = 3\nDimSize = 4 4\nElementType = MET_BOGUS\nElementDataFile = LOCAL\n"),
    ("bad.nrrd", "NRRD0004\ntype: float\ndimension: 3\nsizes: 4 4\nencoding: raw\n\n"),
])
def test_a_bad_itk_header_is_one_line_without_a_source_line_and_nothing_leaks(tmp_path, capfd, name, header):
    (tmp_path / name).write_text(header + "xxxx")
    assert main(["info", str(tmp_path / name)]) == 2
    out, err = capfd.readouterr()
    assert err.count("\n") == 1 and err.startswith("error: "), err      # MetaImage's own lines are captured
    assert ".cxx" not in err and "0x" not in err and "No such file or directory" not in err, err


def test_quiet_itk_captures_the_cpp_stderr_and_itk_error_text_uses_it(capfd):
    with quiet_itk() as said:
        os.write(2, b"MetaImage: M_Read: the cause\nmore\n")
    assert capfd.readouterr().err == ""
    exc = RuntimeError("Exception thrown in SimpleITK ImageFileReader_Execute: /x/itkMetaImageIO.cxx:490:\n"
                       "ITK ERROR: MetaImageIO(0x55fd): File cannot be read: a.mha for reading.\n"
                       "Reason: No such file or directory")
    text = itk_error_text(exc, "".join(said))
    assert text == "MetaImageIO: File cannot be read: a.mha for reading. (ITK: MetaImage: M_Read: the cause)"


def test_a_nibabel_message_over_two_lines_is_joined(tmp_path, monkeypatch):
    path = tmp_path / "v.nii"
    nib.save(nib.Nifti1Image(np.zeros((10, 10, 10), np.float32), np.eye(4)), path)

    def two_lines(*args, **kwargs):
        raise OSError("Expected 4000 bytes, got 3900 bytes from v.nii\n - could the file be damaged?")

    monkeypatch.setattr(nib.arrayproxy.ArrayProxy, "__array__", two_lines)
    with pytest.raises(InputError) as info:
        read_image(path)
    assert "\n" not in str(info.value) and "v.nii - could the file be damaged?" in str(info.value)


def test_itks_warnings_during_a_series_read_do_not_reach_the_terminal(tmp_path, capfd, monkeypatch):
    """ImageSeriesReader warns on the C++ stderr ("WARNING: In .../itkImageSeriesReader.hxx, line 502 ... missing
    slices detected"); with the gap check switched off so that the read gets that far, nothing reaches fd 2."""
    import phantoms.images as pi

    folder = write_dicom_series(itk_image(sphere_mask().astype(np.uint8), (0, 0, 0), (1, 1, 1)), tmp_path / "d")
    sorted(folder.iterdir())[5].unlink()
    monkeypatch.setattr(pi, "_check_slice_spacing", lambda path, files: None)
    read_image(folder)
    assert capfd.readouterr().err == ""


def test_nibabels_header_repair_is_one_warning_line_naming_the_file(tmp_path, capfd):
    """nibabel repairs a wrong sizeof_hdr and logs it raw on stderr, without the file's name: it becomes one
    ``warning:`` line naming the file, and the image is read."""
    nib.save(nib.Nifti1Image(sphere_mask().astype(np.uint8), np.eye(4)), str(tmp_path / "ok.nii"))
    data = bytearray((tmp_path / "ok.nii").read_bytes())
    data[0:4] = (999).to_bytes(4, "little")
    (tmp_path / "bad.nii").write_bytes(bytes(data))
    assert read_image(tmp_path / "bad.nii").values.sum() == sphere_mask().sum()
    err = capfd.readouterr().err
    assert err == f"warning: {tmp_path / 'bad.nii'}: nibabel: sizeof_hdr should be 348; set sizeof_hdr to 348\n"
