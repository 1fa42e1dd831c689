"""Reading and writing volumes.

Reading (:func:`load_volume`): every format of :mod:`phantoms.images` (``.npz``, ``.npy``, NIfTI, NRRD,
MetaImage, a DICOM series folder) with its geometry; binary masks (boolean arrays, or arrays holding two values
such as 0/1 or 0/255) become a signed distance volume, negative inside (:func:`mask_to_sdf`; ``mask=True``
forces this, ``mask=False`` forbids it); ``threshold`` / ``label`` options turn intensity and label images into
masks (:mod:`phantoms.user`).

Writing produces ``.npz`` with ``values``, ``origin``, ``spacing``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from geometry.errors import InputError
from geometry.files import atomic_path, check_writable
from .masks import mask_to_sdf
from .volume import Volume

__all__ = ["load_volume", "save_volume", "check_volume_output", "mask_to_sdf", "is_mask"]

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


def _origin_spacing_from_affine(affine: np.ndarray, path: Path) -> tuple[np.ndarray, np.ndarray]:
    """Origin and spacing of an axis-aligned RAS+ affine with positive spacing (InputError otherwise)."""
    A = np.asarray(affine, dtype=float)[:3, :3]
    off = A - np.diag(np.diag(A))
    if np.abs(off).max() > 1e-6 * max(1.0, np.abs(A).max()) or (np.diag(A) <= 0).any():
        raise InputError(f"{path}: the affine is not axis-aligned with positive spacing; reorient the image "
                         "(nibabel.as_closest_canonical) first")
    return np.asarray(affine, dtype=float)[:3, 3], np.diag(A).copy()


def load_volume(path, mask: bool | None = None, **options) -> Volume:
    """Read a volume from ``path`` (the formats and conventions of :mod:`phantoms.images`).

    Parameters
    ----------
    path : str or Path
        A volume file, a DICOM series folder, or a ``volume:PATH[?key=value&...]`` spec.
    mask : bool, optional
        None (default): two-valued images (0/1, 0/255, boolean) are masks and become signed distances; True
        requires a mask; False reads the values as they are.
    **options
        The options of a ``volume:`` spec (:mod:`phantoms.user`): ``threshold``, ``label``, ``invert``, ``pad``,
        ``series``.

    Returns
    -------
    Volume
        World coordinates (RAS+) from the file; a mask's signed distance is negative inside.

    Raises
    ------
    InputError
        One line naming the file and the problem (missing, unreadable, truncated, not 3-D, oblique, a mask with
        no inside, a label that does not occur, ...).
    """
    from .images import read_image
    from .user import VOLUME_PREFIX, _check_options, level_set_from_image, parse_spec

    text = str(path)
    if text.startswith(VOLUME_PREFIX):
        text, opts = parse_spec(text)
        opts.update(_check_options(options, text))
    else:
        opts = _check_options(options, text)
    if mask is not None:
        opts["mask"] = "yes" if mask else "no"
    image = read_image(text, series=opts.get("series"))
    return level_set_from_image(image, opts, str(Path(text).expanduser()), require_surface=False)


def save_volume(path, volume: Volume) -> Path:
    """Write ``volume`` as ``.npz`` (keys values, origin, spacing), atomically.

    Parameters
    ----------
    path : str or Path
        The output file; must end in ``.npz`` and lie in a writable place.
    volume : Volume
        The volume to write.

    Returns
    -------
    Path
        The file written.

    Raises
    ------
    InputError
        ``path`` is not an ``.npz`` name.
    geometry.files.WriteError
        The place is not writable (naming the cause).
    """
    path = check_volume_output(path)
    with atomic_path(path) as tmp:
        np.savez_compressed(tmp, values=volume.values, origin=volume.origin, spacing=volume.spacing)
    return path


def check_volume_output(path) -> Path:
    """Check ``path`` as a volume output before any work is done: an ``.npz`` name in a writable place.

    Parameters
    ----------
    path : str or Path
        The intended output file.

    Returns
    -------
    Path
        ``path`` as a :class:`~pathlib.Path`.

    Raises
    ------
    InputError
        ``path`` is not an ``.npz`` name.
    geometry.files.WriteError
        The place is not writable (naming the cause).
    """
    path = Path(path)
    if _suffix(path) != ".npz":
        raise InputError(f"volumes are written as .npz; got {path.name!r}")
    return check_writable(path)
