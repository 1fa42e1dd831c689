"""Image files a user may bring: oblique and sheared grids (cause 3), DICOM series with a gap (4), headers that
claim more than the file or the memory holds (9), files that never end or never open (12) and files ITK, GDCM or
nibabel cannot read (15).  Each is written here, small, with the library a user's scanner software would use."""

from __future__ import annotations

import locale
from pathlib import Path

import nibabel as nib
import numpy as np
import SimpleITK as sitk

from .core import Case, Ctx, exits_ok, failed_row, first, one_line

ORIGIN = (10.0, -20.0, 30.0)
SPACING = (0.5, 0.6, 0.8)
LIMIT_GB = 6.0          # address space of the commands that read a header claiming 12 GiB: enough for the suite


def mask() -> np.ndarray:
    """A ball of 5 voxels in an (18, 19, 17) grid, with an asymmetric marker voxel."""
    idx = np.stack(np.meshgrid(*[np.arange(s) for s in (18, 19, 17)], indexing="ij"), axis=-1)
    m = (((idx - np.array([8.6, 9.2, 8.1])) ** 2).sum(-1) < 25).astype(np.uint8)
    m[1, 2, 3] = 1
    return m


def rotation(degrees: float, axis: int = 2) -> np.ndarray:
    """The rotation by ``degrees`` about world axis ``axis``."""
    th = np.radians(degrees)
    c, s = np.cos(th), np.sin(th)
    i, j = [a for a in range(3) if a != axis]
    r = np.eye(3)
    r[i, i], r[i, j], r[j, i], r[j, j] = c, -s, s, c
    return r


def itk_image(values: np.ndarray, direction=None):
    """A SimpleITK image of an (x, y, z) array at ORIGIN / SPACING with an optional direction matrix."""
    img = sitk.GetImageFromArray(np.ascontiguousarray(np.transpose(values, (2, 1, 0))))
    img.SetOrigin(ORIGIN)
    img.SetSpacing(SPACING)
    if direction is not None:
        img.SetDirection(tuple(float(x) for x in np.asarray(direction, float).ravel()))
    return img


def write_nifti(path: Path, direction: np.ndarray) -> Path:
    """The marked ball as NIfTI whose affine's columns are ``direction`` scaled by SPACING."""
    aff = np.eye(4)
    aff[:3, :3] = direction * np.asarray(SPACING)[None, :]
    aff[:3, 3] = ORIGIN
    nib.save(nib.Nifti1Image(mask(), aff), str(path))
    return path


def write_itk(path: Path, direction=None) -> Path:
    """The marked ball through SimpleITK (MetaImage, NRRD, ... by suffix)."""
    sitk.WriteImage(itk_image(mask(), direction), str(path))
    return path


def write_dicom(folder: Path) -> Path:
    """The marked ball as a DICOM series of axial slices (slice000.dcm ...), the process's locale kept."""
    saved = locale.setlocale(locale.LC_ALL)
    try:
        folder.mkdir(parents=True, exist_ok=True)
        img = sitk.Cast(itk_image(mask().astype(np.int16) * 100), sitk.sitkInt16)
        writer = sitk.ImageFileWriter()
        writer.KeepOriginalImageUIDOn()
        uid = "1.2.826.0.1.3680043.2.1125.7"
        sx, sy, sz = img.GetSpacing()
        for k in range(img.GetDepth()):
            sl = img[:, :, k]
            for tag, value in (("0020|000e", uid), ("0020|000d", uid + ".0"), ("0008|0018", f"{uid}.{k + 1}"),
                               ("0020|0037", "1\\0\\0\\0\\1\\0"), ("0028|0030", f"{sy:.6f}\\{sx:.6f}"),
                               ("0018|0050", f"{sz:.6f}"), ("0020|0013", str(k + 1)), ("0008|0060", "MR"),
                               ("0020|0032", "\\".join(f"{c:.6f}" for c in
                                                        img.TransformIndexToPhysicalPoint((0, 0, k))))):
                sl.SetMetaData(tag, value)
            writer.SetFileName(str(folder / f"slice{k:03d}.dcm"))
            writer.Execute(sl)
        return folder
    finally:
        locale.setlocale(locale.LC_ALL, saved)


def shift_slice(path: Path, dz: float) -> None:
    """Move one DICOM slice ``dz`` mm along the normal (its ImagePositionPatient rewritten)."""
    saved = locale.setlocale(locale.LC_ALL)
    try:
        sl = sitk.ReadImage(str(path))
        x, y, z = (float(t) for t in sl.GetMetaData("0020|0032").split("\\"))
        sl.SetMetaData("0020|0032", f"{x:.6f}\\{y:.6f}\\{z + dz:.6f}")
        writer = sitk.ImageFileWriter()
        writer.KeepOriginalImageUIDOn()
        writer.SetFileName(str(path))
        writer.Execute(sl)
    finally:
        locale.setlocale(locale.LC_ALL, saved)


# ------------------------------------------------------------------------------------------------ cause 3
def _oblique(ctx: Ctx, fmt: str, direction: np.ndarray, tag: str) -> Path:
    path = ctx.root / "oblique" / f"{tag}.{fmt}"
    path.parent.mkdir(exist_ok=True)
    return write_nifti(path, direction) if fmt.startswith("nii") else write_itk(path, direction)


def _shear(amount: float) -> np.ndarray:
    d = np.eye(3)
    d[:, 1] = [amount, 1.0, 0.0]
    return d / np.linalg.norm(d, axis=0)[None, :]


def oblique_cases() -> list[Case]:
    """Every tilt refused with its angle (to the nearest axis), every shear refused, axis swaps and flips read."""
    out: list[Case] = []
    for fmt in ("nii.gz", "mha"):
        for deg in (5, 10, 20, 30, 45, 60, 70):
            shown = f"{min(deg, 90 - deg):g}°"

            def check(ctx, fmt=fmt, deg=deg, shown=shown):
                p = _oblique(ctx, fmt, rotation(deg), f"z{deg}_{fmt.replace('.', '')}")
                return one_line(ctx.bench("info", str(p)), "axis-aligned", shown)
            out.append(Case("3", f"info {fmt} rotated {deg}° about z", check))
        for axis, deg in ((0, 45), (1, 20), (0, 33)):
            def check(ctx, fmt=fmt, axis=axis, deg=deg):
                p = _oblique(ctx, fmt, rotation(deg, axis), f"a{axis}_{deg}_{fmt.replace('.', '')}")
                return one_line(ctx.bench("info", str(p)), "axis-aligned")
            out.append(Case("3", f"info {fmt} rotated {deg}° about axis {axis}", check))
        for amount in (0.05, 0.3, 1.0):
            def check(ctx, fmt=fmt, amount=amount):
                p = _oblique(ctx, fmt, _shear(amount), f"shear{amount}_{fmt.replace('.', '')}")
                return one_line(ctx.bench("info", str(p)), "sheared")
            out.append(Case("3", f"info {fmt} sheared by {amount}", check))
    out.append(Case("3", "info nrrd rotated 45°", lambda ctx: one_line(
        ctx.bench("info", str(_oblique(ctx, "nrrd", rotation(45), "z45"))), "axis-aligned", "45°")))
    out.append(Case("3", "info nii.gz rotated 10° about z then 10° about x", lambda ctx: one_line(
        ctx.bench("info", str(_oblique(ctx, "nii.gz", rotation(10, 0) @ rotation(10), "zx10"))), "axis-aligned")))
    out.append(Case("3", "reconstruct nii.gz rotated 45°", lambda ctx: one_line(ctx.bench(
        "reconstruct", str(_oblique(ctx, "nii.gz", rotation(45), "r45")), "-m", "marching_cubes", "-o",
        str(ctx.root / "oblique" / "r45.ply")), "axis-aligned")))
    out.append(Case("3", "run on a volume rotated 45°: refused or a failed row", _oblique_run))
    out.append(Case("3", "truth= a label image rotated 30°", _oblique_truth))
    for name, direction in (("rotated 0.001°", rotation(0.001)), ("axes swapped and flipped",
                                                                  np.array([[0, -1.0, 0], [1, 0, 0], [0, 0, 1]])),
                            ("rotated 90°", rotation(90))):
        def check(ctx, name=name, direction=direction):
            p = _oblique(ctx, "nii.gz", direction, "ok" + str(abs(hash(name)) % 1000))
            return exits_ok(ctx.bench("info", str(p)))
        out.append(Case("3", f"control: {name} is read", check))
    return out


def _oblique_run(ctx: Ctx) -> str | None:
    p = _oblique(ctx, "nii.gz", rotation(45), "run45")
    out = ctx.root / "oblique" / "run45"
    res = ctx.bench("run", "--phantoms", f"volume:{p}", "--noise", "none", "--method", "marching_cubes",
                    "--out", str(out), "--jobs", "1", "--no-report")
    if res.rc == 2:
        return one_line(res, "axis-aligned")
    return first(exits_ok(res), failed_row(out, "marching_cubes", "axis-aligned"))


def _oblique_truth(ctx: Ctx) -> str | None:
    vol = write_itk(ctx.root / "oblique" / "straight.nii.gz")
    truth = _oblique(ctx, "nii.gz", rotation(30), "truth30")
    return one_line(ctx.bench("info", f"volume:{vol}?truth={truth}"), "axis-aligned")


# ------------------------------------------------------------------------------------------------ cause 4
def _series(ctx: Ctx, tag: str) -> Path:
    return write_dicom(ctx.root / "dicom" / tag)


def dicom_cases() -> list[Case]:
    """A series with a slice missing, truncated, moved or doubled is refused naming the slice; a whole one read."""
    out = [Case("4", "control: a whole series is read", lambda ctx: exits_ok(ctx.bench(
        "info", str(_series(ctx, "whole")))))]
    for k in (1, 8, 15):
        def check(ctx, k=k):
            folder = _series(ctx, f"missing{k}")
            (folder / f"slice{k:03d}.dcm").unlink()
            return one_line(ctx.bench("info", str(folder)), "slice", "spaced")
        out.append(Case("4", f"info: slice {k} of 17 missing", check))

    def truncated(ctx):
        folder = _series(ctx, "truncated")
        victim = folder / "slice009.dcm"
        victim.write_bytes(victim.read_bytes()[:300])
        return one_line(ctx.bench("info", str(folder)), "slice")

    def moved(ctx):
        folder = _series(ctx, "moved")
        shift_slice(folder / "slice011.dcm", 0.3)
        return one_line(ctx.bench("info", str(folder)), "slice", "spaced")

    def doubled(ctx):
        folder = _series(ctx, "doubled")
        shift_slice(folder / "slice011.dcm", -0.8)        # on top of slice 10
        return one_line(ctx.bench("info", str(folder)), "slice")

    def via(command):
        def check(ctx):
            folder = _series(ctx, f"gap_{command}")
            (folder / "slice006.dcm").unlink()
            if command == "reconstruct":
                return one_line(ctx.bench("reconstruct", str(folder), "-m", "marching_cubes", "-o",
                                          str(folder.parent / "gap.ply")), "slice")
            run = folder.parent / "gap_run"
            res = ctx.bench("run", "--phantoms", f"volume:{folder}", "--noise", "none", "--method",
                            "marching_cubes", "--out", str(run), "--jobs", "1", "--no-report")
            return one_line(res, "slice") if res.rc == 2 else first(exits_ok(res),
                                                                    failed_row(run, "marching_cubes", "slice"))
        return check
    out += [Case("4", "info: slice 9 truncated to 300 bytes", truncated),
            Case("4", "info: slice 11 moved 0.3 mm", moved),
            Case("4", "info: slice 11 moved onto slice 10", doubled),
            Case("4", "reconstruct: slice 6 missing", via("reconstruct")),
            Case("4", "run: slice 6 missing (refused or a failed row)", via("run"))]
    return out
