"""Test volumes written as the files users have: masks with a known exact surface, in NIfTI and ITK formats."""

from __future__ import annotations

from pathlib import Path

import numpy as np

#: the boxes' grid: shape, anisotropic spacing and a non-zero origin (world = origin + index * spacing)
BOX_SHAPE = (30, 28, 20)
BOX_SPACING = np.array([0.5, 0.5, 0.8])
BOX_ORIGIN = np.array([12.0, -7.5, 3.2])


def boxes_mask() -> np.ndarray:
    """Two overlapping boxes (voxel index ranges), inside = True."""
    m = np.zeros(BOX_SHAPE, bool)
    m[4:18, 5:17, 3:12] = True
    m[12:26, 10:24, 8:17] = True
    return m


def voxel_surface(mask: np.ndarray, origin, spacing) -> tuple[np.ndarray, np.ndarray]:
    """The exact boundary of a voxel set — the faces half-way between inside and outside voxel centres, where
    the mask's signed distance is zero — as a closed, outward triangle mesh in world coordinates."""
    P = np.pad(mask, 1)
    verts: dict = {}
    faces = []

    def vid(c):
        key = tuple(np.round(c * 2).astype(int))
        if key not in verts:
            verts[key] = len(verts)
        return verts[key]

    for ax in range(3):
        d = np.diff(P.astype(np.int8), axis=ax)      # +1: outside → inside along +ax (outward normal −ax)
        o = [a for a in range(3) if a != ax]
        n_ax = np.cross(np.eye(3)[o[0]], np.eye(3)[o[1]])[ax]
        for sgn in (1, -1):
            for idx in np.argwhere(d == sgn):
                base = idx.astype(float) - 1.0          # unpadded index of the voxel before the face
                base[ax] += 0.5
                corners = []
                for du, dv in ((-.5, -.5), (.5, -.5), (.5, .5), (-.5, .5)):
                    q = base.copy()
                    q[o[0]] += du
                    q[o[1]] += dv
                    corners.append(vid(q))
                if n_ax != -sgn:
                    corners = corners[::-1]
                faces += [[corners[0], corners[1], corners[2]], [corners[0], corners[2], corners[3]]]
    v = np.array(list(verts.keys()), float) / 2.0
    return v * np.asarray(spacing, float) + np.asarray(origin, float), np.array(faces)


def write_boxes(folder: Path) -> tuple[Path, Path]:
    """``boxes.nii.gz`` (uint8 0/1 mask, nibabel, RAS affine with the boxes' spacing and origin) and
    ``boxes.obj`` (its exact surface)."""
    import nibabel as nib
    import trimesh

    m = boxes_mask()
    aff = np.diag([*BOX_SPACING, 1.0])
    aff[:3, 3] = BOX_ORIGIN
    nii = Path(folder) / "boxes.nii.gz"
    nib.save(nib.Nifti1Image(m.astype(np.uint8), aff), str(nii))
    v, f = voxel_surface(m, BOX_ORIGIN, BOX_SPACING)
    obj = Path(folder) / "boxes.obj"
    trimesh.Trimesh(v, f, process=False).export(str(obj))
    return nii, obj


def sphere_mask(shape=(24, 26, 22), centre=(11.3, 12.6, 10.4), radius=7.5) -> np.ndarray:
    """A ball of ``radius`` voxels (index units) about ``centre``."""
    idx = np.stack(np.meshgrid(*[np.arange(s) for s in shape], indexing="ij"), axis=-1)
    return ((idx - np.asarray(centre)) ** 2).sum(-1) < radius ** 2


def itk_image(values: np.ndarray, origin, spacing, direction=None):
    """A SimpleITK image of an (x, y, z) array with the given LPS geometry."""
    import SimpleITK as sitk

    img = sitk.GetImageFromArray(np.ascontiguousarray(np.transpose(values, (2, 1, 0))))
    img.SetOrigin(tuple(float(x) for x in origin))
    img.SetSpacing(tuple(float(x) for x in spacing))
    if direction is not None:
        img.SetDirection(tuple(float(x) for x in np.asarray(direction, float).ravel()))
    return img


def write_dicom_series(img, folder: Path, series_uid: str = "1.2.826.0.1.3680043.2.1125.1") -> Path:
    """``img`` (3-D, integer) as a DICOM series of axial slices in ``folder`` (SimpleITK's writer).

    GDCM's writer sets the C library's locale to "C" (measured: afterwards ``locale.getencoding()`` is ASCII,
    and ``subprocess.run(..., text=True)`` in the same test process fails on any non-ASCII output), so the
    process's locale is restored after it."""
    import locale

    saved = locale.setlocale(locale.LC_ALL)
    try:
        return _write_dicom_series(img, folder, series_uid)
    finally:
        locale.setlocale(locale.LC_ALL, saved)


def _write_dicom_series(img, folder: Path, series_uid: str) -> Path:
    import SimpleITK as sitk

    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    img = sitk.Cast(img, sitk.sitkInt16)
    writer = sitk.ImageFileWriter()
    writer.KeepOriginalImageUIDOn()
    sx, sy, sz = img.GetSpacing()
    d = img.GetDirection()
    for k in range(img.GetDepth()):
        sl = img[:, :, k]
        sl.SetMetaData("0020|000e", series_uid)
        sl.SetMetaData("0020|000d", series_uid + ".0")
        sl.SetMetaData("0008|0018", f"{series_uid}.{k + 1}")
        sl.SetMetaData("0020|0032", "\\".join(f"{c:.6f}" for c in img.TransformIndexToPhysicalPoint((0, 0, k))))
        sl.SetMetaData("0020|0037", "\\".join(f"{c:.6f}" for c in (d[0], d[3], d[6], d[1], d[4], d[7])))
        sl.SetMetaData("0028|0030", f"{sy:.6f}\\{sx:.6f}")
        sl.SetMetaData("0018|0050", f"{sz:.6f}")
        sl.SetMetaData("0020|0013", str(k + 1))
        sl.SetMetaData("0008|0060", "MR")
        writer.SetFileName(str(folder / f"slice{k:03d}.dcm"))
        writer.Execute(sl)
    return folder


#: a liver label map at a CT's native resolution: voxels and spacing (mm)
LIVER_SHAPE = (438, 353, 165)
LIVER_SPACING = np.array([0.8, 0.8, 1.5])


def liver_like_mask() -> np.ndarray:
    """One smooth genus-0 organ of a liver's size (about 19 × 15 × 11 cm: a right lobe, a left lobe and a
    caudate bump, a notch between them; 1.9 M voxels) in a :data:`LIVER_SHAPE` grid."""
    ax = [(np.arange(n) - n / 2) * s for n, s in zip(LIVER_SHAPE, LIVER_SPACING)]
    x, y, z = np.meshgrid(*ax, indexing="ij", sparse=True)
    right = ((x + 25) / 95) ** 2 + (y / 75) ** 2 + (z / 55) ** 2 < 1
    left = ((x - 70) / 70) ** 2 + ((y + 10) / 45) ** 2 + ((z - 15) / 30) ** 2 < 1
    bump = ((x + 60) / 30) ** 2 + ((y - 55) / 25) ** 2 + ((z + 20) / 30) ** 2 < 1
    notch = ((x - 10) / 25) ** 2 + ((y - 60) / 30) ** 2 < 1
    return (right | left | bump) & ~notch
