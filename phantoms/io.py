"""Reading and writing volumes.

Supported inputs (by suffix):

* ``.npz`` – keys ``values`` (3-D), optional ``origin`` and ``spacing`` (default 0 and 1);
* ``.npy`` – a bare 3-D array (unit spacing, origin 0);
* ``.nii`` / ``.nii.gz`` – NIfTI via nibabel; the affine must be axis-aligned (diagonal, positive
  spacing), giving origin and spacing;
* binary masks in any of these formats (boolean arrays, or arrays holding only 0 and 1) are turned into
  a signed distance volume, negative inside (``mask=True`` forces this, ``mask=False`` forbids it).

Writing produces ``.npz`` with ``values``, ``origin``, ``spacing``.
"""

from __future__ import annotations

import zipfile
from pathlib import Path

import numpy as np
from scipy import ndimage

from geometry.errors import InputError
from geometry.files import atomic_path, check_writable
from .volume import Volume

__all__ = ["load_volume", "save_volume", "check_volume_output", "mask_to_sdf", "is_mask"]

SUFFIXES = (".npz", ".npy", ".nii", ".nii.gz")


def _suffix(path: Path) -> str:
    name = path.name.lower()
    return ".nii.gz" if name.endswith(".nii.gz") else path.suffix.lower()


def is_mask(values: np.ndarray) -> bool:
    """True for boolean arrays and numeric arrays whose values are all 0 or 1."""
    if values.dtype == bool:
        return True
    if not np.issubdtype(values.dtype, np.number):
        return False
    with np.errstate(invalid="ignore"):
        return bool(np.isin(values, (0, 1)).all())


def mask_to_sdf(mask, origin=(0.0, 0.0, 0.0), spacing=(1.0, 1.0, 1.0)) -> Volume:
    """Signed distance volume of a binary mask (negative inside), zero half-way between voxels.

    Inside voxels get −(distance to the nearest outside voxel) + h/2, outside voxels
    (distance to the nearest inside voxel) − h/2, with anisotropic spacing honoured.
    """
    m = np.asarray(mask).astype(bool)
    if m.ndim != 3:
        raise InputError(f"a mask must be a 3-D array; got shape {m.shape}")
    if not m.any():
        raise InputError("the mask has no inside voxels (all zero): there is no surface to reconstruct")
    if m.all():
        raise InputError("the mask has no outside voxels (all one): there is no surface to reconstruct")
    spacing = np.broadcast_to(np.asarray(spacing, dtype=float), (3,))
    half = 0.5 * float(spacing.min())
    d_out = ndimage.distance_transform_edt(~m, sampling=spacing)  # outside: distance to inside
    d_in = ndimage.distance_transform_edt(m, sampling=spacing)    # inside: distance to outside
    values = np.where(m, -(d_in - half), d_out - half)
    return Volume(values, origin, spacing)


def _origin_spacing_from_affine(affine: np.ndarray, path: Path) -> tuple[np.ndarray, np.ndarray]:
    A = np.asarray(affine, dtype=float)[:3, :3]
    off = A - np.diag(np.diag(A))
    if np.abs(off).max() > 1e-6 * max(1.0, np.abs(A).max()):
        raise InputError(
            f"{path}: the NIfTI affine is not axis-aligned (it rotates or shears the grid); "
            "resample the image onto an axis-aligned grid first"
        )
    spacing = np.diag(A)
    if (spacing <= 0).any():
        raise InputError(
            f"{path}: the NIfTI affine flips an axis (spacing {spacing.tolist()}); "
            "reorient the image to RAS+ (e.g. nibabel.as_closest_canonical) first"
        )
    return np.asarray(affine, dtype=float)[:3, 3], spacing


def load_volume(path, mask: bool | None = None) -> Volume:
    """Read a volume from ``path`` (see the module docstring for the formats).

    ``mask=None`` (default) converts binary masks automatically; ``True`` requires a mask; ``False``
    reads the values as they are.
    """
    path = Path(path)
    if not path.exists():
        raise InputError(f"no such file: {path}")
    if path.is_dir():
        raise InputError(f"{path} is a directory, not a volume file")
    suffix = _suffix(path)
    origin, spacing = np.zeros(3), np.ones(3)
    try:
        if suffix == ".npz":
            with np.load(path, allow_pickle=False) as data:
                if "values" not in data.files:
                    raise InputError(f"{path}: an .npz volume needs a 'values' array; found {data.files}")
                values = data["values"]
                if "origin" in data.files:
                    origin = data["origin"]
                if "spacing" in data.files:
                    spacing = data["spacing"]
        elif suffix == ".npy":
            values = np.load(path, allow_pickle=False)
        elif suffix in (".nii", ".nii.gz"):
            import nibabel as nib

            img = nib.load(str(path))
            values = np.asarray(img.dataobj)
            if values.ndim == 4 and values.shape[3] == 1:
                values = values[..., 0]
            origin, spacing = _origin_spacing_from_affine(img.affine, path)
        else:
            raise InputError(f"{path}: unsupported file type {suffix!r}; supported: {', '.join(SUFFIXES)}")
    except InputError:
        raise
    except OSError as exc:
        if exc.errno is not None:  # the file cannot be read at all (permission, I/O error): not a format problem
            raise InputError(f"{path}: cannot read the file: {exc.strerror or exc}") from None
        raise InputError(f"{path}: cannot read the file (truncated or not a {suffix} volume?): {exc}") from None
    except ValueError as exc:
        if "Object arrays" in str(exc):
            raise InputError(f"{path}: the file holds Python objects (dtype object or pickled data), not "
                             "numbers; a volume must be an array of real numbers") from None
        raise InputError(f"{path}: cannot read the file (truncated or not a {suffix} volume?): {exc}") from None
    except (EOFError, zipfile.BadZipFile, KeyError) as exc:
        raise InputError(f"{path}: cannot read the file (truncated or not a {suffix} volume?): {exc}") from None
    except Exception as exc:  # nibabel raises its own types (ImageFileError, ...)
        raise InputError(f"{path}: cannot read the file: {type(exc).__name__}: {exc}") from None
    values = np.asarray(values)
    if np.issubdtype(values.dtype, np.complexfloating) or not (np.issubdtype(values.dtype, np.number)
                                                               or values.dtype == bool):
        raise InputError(f"{path}: volume values must be real numbers; got dtype {values.dtype}"
                         + (" (the imaginary part would be lost)" if values.dtype.kind == "c" else ""))
    if values.ndim != 3:
        raise InputError(f"{path}: a volume must be a 3-D array; got shape {values.shape}")
    try:
        Volume(np.zeros((2, 2, 2)), origin, spacing)  # origin/spacing: length and type, before any work
        looks_like_mask = is_mask(values)
        if mask is True and not looks_like_mask:
            raise InputError("asked to read a binary mask but the values are not all 0/1")
        if looks_like_mask and mask is not False:
            return mask_to_sdf(values, origin, spacing)
        return Volume(values, origin, spacing)
    except InputError as exc:
        raise InputError(f"{path}: {exc}") from None


def save_volume(path, volume: Volume) -> Path:
    """Write ``volume`` as ``.npz`` (keys values, origin, spacing)."""
    path = check_volume_output(path)
    with atomic_path(path) as tmp:
        np.savez_compressed(tmp, values=volume.values, origin=volume.origin, spacing=volume.spacing)
    return path


def check_volume_output(path) -> Path:
    """``path`` as a volume output: an ``.npz`` name in a writable place (checked before any work is done;
    :class:`geometry.files.WriteError` naming the cause otherwise)."""
    path = Path(path)
    if _suffix(path) != ".npz":
        raise InputError(f"volumes are written as .npz; got {path.name!r}")
    return check_writable(path)
