"""Reading image files with their geometry: a 3-D array on an axis-aligned grid in RAS+ world coordinates.

Formats (by suffix, or a folder):

* ``.npz`` – keys ``values`` (3-D), optional ``origin`` and ``spacing`` (default 0 and 1);
* ``.npy`` – a bare 3-D array (unit spacing, origin 0);
* ``.nii`` / ``.nii.gz`` – NIfTI, read with nibabel (its affine is RAS+ by definition);
* ``.nrrd`` / ``.nhdr``, ``.mha`` / ``.mhd`` and a **folder holding one DICOM series** – read with SimpleITK.

World coordinates
    Every format ends up in one convention, RAS+ (+x towards the subject's right, +y anterior, +z superior),
    the convention of NIfTI, nibabel and FreeSurfer.
    ITK (NRRD, MetaImage, DICOM) stores LPS+ physical points; they are converted by negating x and y.  An
    ``.npz`` / ``.npy`` array is taken as already in world coordinates (no conversion).

Orientation
    An image whose direction matrix is a signed permutation (axes swapped or flipped, the usual case for DICOM
    and for NIfTI files written by ITK) is re-oriented — array axes permuted and flipped with
    :func:`nibabel.orientations.apply_orientation` — so that array axis 0 runs along +x with positive spacing.
    Nothing is resampled.  A direction matrix that rotates or shears the grid (an oblique acquisition: an axis
    more than :data:`AXIS_TOLERANCE_DEG` degrees off its nearest world axis, or two axes that far from
    perpendicular) is refused with the angle; resample such an image onto an axis-aligned grid first.
"""

from __future__ import annotations

import zipfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from geometry.errors import InputError

from .image_checks import (check_claimed_size, check_dicom_size, check_file_kind, check_nifti, itk_error_text,
                           nibabel_notes, one_line, quiet_itk)

__all__ = ["Image", "read_image", "image_suffix", "IMAGE_SUFFIXES", "ITK_SUFFIXES", "AXIS_TOLERANCE_DEG"]

ITK_SUFFIXES = (".nrrd", ".nhdr", ".mha", ".mhd")
IMAGE_SUFFIXES = (".npz", ".npy", ".nii", ".nii.gz") + ITK_SUFFIXES
#: largest angle (degrees) between a grid axis and the nearest world axis, or between two grid axes and 90°,
#: still read as axis-aligned (float32 headers round a direction cosine to ~1e-7: 0.01° is far above that)
AXIS_TOLERANCE_DEG = 0.01


@dataclass(frozen=True)
class Image:
    """A 3-D array on an axis-aligned grid: ``values[i, j, k]`` sits at ``origin + (i, j, k) * spacing`` (RAS+)."""

    values: np.ndarray
    origin: np.ndarray
    spacing: np.ndarray
    source: str


def image_suffix(path: Path) -> str:
    """The format suffix of ``path`` (``.nii.gz`` counts as one); ``"dicom"`` for a folder."""
    if path.is_dir():
        return "dicom"
    name = path.name.lower()
    return ".nii.gz" if name.endswith(".nii.gz") else path.suffix.lower()


def _reorient(values: np.ndarray, affine: np.ndarray, path: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(values, origin, spacing) with array axes along +x, +y, +z, from a RAS+ voxel-to-world ``affine``."""
    from nibabel.orientations import apply_orientation, inv_ornt_aff, io_orientation

    A = np.asarray(affine, dtype=float)
    R = A[:3, :3]
    norms = np.linalg.norm(R, axis=0)
    if not (np.isfinite(A).all() and (norms > 0).all()):
        raise InputError(f"{path}: the image geometry is degenerate (voxel-to-world matrix {R.round(6).tolist()})")
    cosines = R / norms
    # each grid axis's angle to the world axis nearest it, and the grid axes' angles to each other (a shear)
    tilt = np.degrees(np.arccos(np.clip(np.abs(cosines).max(axis=0), 0.0, 1.0)))
    gram = np.clip(np.abs(cosines.T @ cosines) - np.eye(3), 0.0, 1.0)
    shear = 90.0 - np.degrees(np.arccos(gram.max()))
    if max(tilt.max(), shear) > AXIS_TOLERANCE_DEG:
        what = (f"its axes are sheared ({shear:.3g}° from perpendicular)" if shear > AXIS_TOLERANCE_DEG else
                f"its direction matrix rotates an axis by {tilt.max():.3g}° from the nearest world axis")
        raise InputError(f"{path}: the image grid is not axis-aligned ({what}; tolerance {AXIS_TOLERANCE_DEG:g}°); "
                         "levelset-bench reads axis-aligned grids only — resample it onto an axis-aligned grid first "
                         "(e.g. SimpleITK.Resample with an identity direction)")
    ornt = io_orientation(A)
    A2 = A @ inv_ornt_aff(ornt, values.shape)
    values = apply_orientation(values, ornt)
    spacing = np.abs(np.diag(A2[:3, :3]))
    return np.ascontiguousarray(values), A2[:3, 3].copy(), spacing


def _read_numpy(path: Path, suffix: str):
    origin, spacing = np.zeros(3), np.ones(3)
    if suffix == ".npz":
        with np.load(path, allow_pickle=False) as data:
            if "values" not in data.files:
                raise InputError(f"{path}: an .npz volume needs a 'values' array; found {data.files}")
            values = data["values"]
            if "origin" in data.files:
                origin = data["origin"]
            if "spacing" in data.files:
                spacing = data["spacing"]
    else:
        values = np.load(path, allow_pickle=False)
    return values, origin, spacing


def _read_nifti(path: Path):
    import nibabel as nib

    with nibabel_notes(path):                   # its header repairs: one warning line naming the file
        img = nib.load(str(path))
        check_nifti(path, img)                  # header only: nothing of the data is read before this
        values = np.asarray(img.dataobj)
    values = _drop_singleton_4d(values, path)
    if values.ndim != 3:
        raise InputError(f"{path}: a volume must be a 3-D image; got a {values.ndim}-D image of shape {values.shape}")
    return _reorient(values, img.affine, path)


def _drop_singleton_4d(values: np.ndarray, path: Path) -> np.ndarray:
    if values.ndim == 4:
        if values.shape[3] == 1:
            return values[..., 0]
        raise InputError(f"{path}: a 4-D image (shape {values.shape}: {values.shape[3]} volumes); "
                         "levelset-bench reads one 3-D volume — extract the one you want first")
    return values


#: how far (relative) a gap between two slices may differ from the series' median slice spacing
SLICE_GAP_TOLERANCE = 0.01


def _check_slice_spacing(path: Path, files) -> None:
    """Refuse a DICOM series whose slices are not evenly spaced along their normal (a slice missing, a truncated
    file GDCM left out, a mixed acquisition): ITK would stack them at one spacing and put every slice after the
    gap at the wrong place.  Each file's ImagePositionPatient (0020|0032) is projected on the slice normal from its
    ImageOrientationPatient (0020|0037)."""
    import SimpleITK as sitk

    if len(files) < 3:
        return
    positions, normal = [], None
    reader = sitk.ImageFileReader()
    for f in files:
        reader.SetFileName(f)
        try:
            reader.ReadImageInformation()
            pos = np.array([float(t) for t in reader.GetMetaData("0020|0032").split("\\")])
            if normal is None:
                o = np.array([float(t) for t in reader.GetMetaData("0020|0037").split("\\")])
                normal = np.cross(o[:3], o[3:])
        except (RuntimeError, ValueError, IndexError):
            raise InputError(f"{path}: slice file {Path(f).name} has no readable position (0020|0032) or "
                             "orientation (0020|0037); the slices cannot be checked for gaps") from None
        positions.append(float(pos @ normal))
    z = np.asarray(positions)
    gaps = np.abs(np.diff(z))
    step = float(np.median(gaps))
    bad = np.flatnonzero(np.abs(gaps - step) > SLICE_GAP_TOLERANCE * step)
    if step <= 0 or len(bad):
        i = int(bad[0]) if len(bad) else 0
        raise InputError(f"{path}: the DICOM slices are not evenly spaced: {gaps[i]:.4g} mm between slice {i + 1} "
                         f"({Path(files[i]).name}, at {z[i]:.4g} mm) and slice {i + 2} ({Path(files[i + 1]).name}) "
                         f"against {step:.4g} mm elsewhere — a slice missing or unreadable?")


def _itk_image(path: Path, series: str | None):
    import SimpleITK as sitk

    if path.is_dir():
        ids = list(sitk.ImageSeriesReader.GetGDCMSeriesIDs(str(path)) or ())
        if not ids:
            raise InputError(f"{path}: the folder holds no DICOM series")
        if series is None:
            if len(ids) > 1:
                raise InputError(f"{path}: the folder holds {len(ids)} DICOM series ({', '.join(ids)}); choose one "
                                 f"with ?series=UID")
            series = ids[0]
        elif series not in ids:
            raise InputError(f"{path}: no DICOM series {series!r} in the folder; series: {', '.join(ids)}")
        files = sitk.ImageSeriesReader.GetGDCMSeriesFileNames(str(path), series)
        _check_slice_spacing(path, files)
        check_dicom_size(path, files)
        reader = sitk.ImageSeriesReader()
        reader.SetFileNames(files)
        return reader.Execute()
    return sitk.ReadImage(str(path))


def _read_itk(path: Path, series: str | None):
    import SimpleITK as sitk

    said: list[str] = []
    try:
        with quiet_itk() as said:                 # ITK / GDCM print on the C++ stderr: captured, not shown
            img = _itk_image(path, series)
    except RuntimeError as exc:
        raise InputError(f"{path}: cannot read the image ({itk_error_text(exc, ''.join(said))})") from None
    if img.GetNumberOfComponentsPerPixel() != 1:
        raise InputError(f"{path}: a vector image ({img.GetNumberOfComponentsPerPixel()} components per voxel); "
                         "a volume needs one value per voxel")
    dim = img.GetDimension()
    arr = sitk.GetArrayFromImage(img)          # numpy axes are ITK's reversed: (z, y, x) or (t, z, y, x)
    values = np.transpose(arr, tuple(range(arr.ndim))[::-1])
    if dim == 4:
        values = _drop_singleton_4d(values, path)
    if values.ndim != 3:
        raise InputError(f"{path}: a volume must be a 3-D image; got a {dim}-D image of shape {values.shape}")
    D = np.asarray(img.GetDirection(), float).reshape(dim, dim)[:3, :3]
    lps = np.eye(4)
    lps[:3, :3] = D * np.asarray(img.GetSpacing(), float)[None, :3]
    lps[:3, 3] = img.GetOrigin()[:3]
    ras = np.diag([-1.0, -1.0, 1.0, 1.0]) @ lps              # ITK's LPS+ → RAS+
    return _reorient(values, ras, path)


def read_image(path, *, series: str | None = None) -> Image:
    """The image at ``path`` as an :class:`Image` (see the module docstring); :class:`InputError` naming the file
    and the problem for a missing, unreadable, truncated, empty, 2-D / 4-D or oblique image."""
    path = Path(path).expanduser()
    if not path.exists():
        raise InputError(f"no such file: {path}")
    check_file_kind(path)          # a FIFO or a device would block the reader or never end: refused unopened
    suffix = image_suffix(path)
    try:
        check_claimed_size(path, suffix)
        if suffix in (".npz", ".npy"):
            values, origin, spacing = _read_numpy(path, suffix)
        elif suffix in (".nii", ".nii.gz"):
            values, origin, spacing = _read_nifti(path)
        elif suffix in ITK_SUFFIXES or suffix == "dicom":
            values, origin, spacing = _read_itk(path, series)
        else:
            raise InputError(f"{path}: unsupported file type {suffix!r}; supported: {', '.join(IMAGE_SUFFIXES)} "
                             "or a folder holding a DICOM series")
    except InputError:
        raise
    except MemoryError:
        raise InputError(f"{path}: not enough memory to read the image") from None
    except OSError as exc:
        if exc.errno is not None:  # the file cannot be read at all (permission, I/O error): not a format problem
            raise InputError(f"{path}: cannot read the file: {one_line(exc.strerror or exc)}") from None
        raise InputError(f"{path}: cannot read the file (truncated or not a {suffix} image?): "
                         f"{one_line(exc)}") from None
    except ValueError as exc:
        if "Object arrays" in str(exc):
            raise InputError(f"{path}: the file holds Python objects (dtype object or pickled data), not "
                             "numbers; a volume must be an array of real numbers") from None
        raise InputError(f"{path}: cannot read the file (truncated or not a {suffix} image?): "
                         f"{one_line(exc)}") from None
    except (EOFError, zipfile.BadZipFile, KeyError) as exc:
        raise InputError(f"{path}: cannot read the file (truncated or not a {suffix} image?): "
                         f"{one_line(exc)}") from None
    except Exception as exc:  # nibabel and SimpleITK raise their own types (ImageFileError, RuntimeError, ...)
        text = itk_error_text(exc) if "SimpleITK" in str(exc) else one_line(exc)[:300]
        raise InputError(f"{path}: cannot read the image ({type(exc).__name__}: {text})") from None
    values = np.asarray(values)
    if np.issubdtype(values.dtype, np.complexfloating) or not (np.issubdtype(values.dtype, np.number)
                                                               or values.dtype == bool):
        raise InputError(f"{path}: volume values must be real numbers; got dtype {values.dtype}"
                         + (" (the imaginary part would be lost)" if values.dtype.kind == "c" else ""))
    if values.ndim != 3:
        raise InputError(f"{path}: a volume must be a 3-D array; got shape {values.shape}")
    if values.size == 0:
        raise InputError(f"{path}: the image is empty (shape {values.shape})")
    return Image(values, np.asarray(origin), np.asarray(spacing), str(path))
