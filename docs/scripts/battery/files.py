"""Files that lie about their size (cause 9), never end or never open (12), or that the image libraries cannot
read (15): each refused in one line naming the file and the cause, before any allocation or blocking read, with
nothing of ITK's, GDCM's or nibabel's own text on the terminal."""

from __future__ import annotations

import gzip
import io
import os
import zipfile
from pathlib import Path

import nibabel as nib
import numpy as np
import SimpleITK as sitk

from .core import Case, Ctx, exits_ok, failed_row, first, one_line
from .images import LIMIT_GB, mask, write_dicom, write_itk

HUGE = (1500, 1500, 1500)
#: what C++ libraries print that a user cannot act on
LIBRARY_TEXT = (".cxx", ".h:", "itk::", "ERROR: In ", "0x", "Description:", "MetaImage:", "gdcm")


def _dir(ctx: Ctx, name: str) -> Path:
    d = ctx.root / name
    d.mkdir(exist_ok=True)
    return d


# ------------------------------------------------------------------------------------------------ cause 9
def nifti_claiming(path: Path, shape, gz: bool = False) -> Path:
    """A tiny NIfTI (2³ float32 of data) whose header claims ``shape``."""
    nib.save(nib.Nifti1Image(np.zeros((2, 2, 2), np.float32), np.eye(4)), str(path.with_suffix(".tmp.nii")))
    img = nib.load(str(path.with_suffix(".tmp.nii")))
    header = img.header.copy()
    header.set_data_shape(shape)
    header["vox_offset"] = 352
    raw = header.binaryblock + b"\0" * (352 - len(header.binaryblock)) + np.zeros(8, np.float32).tobytes()
    path.write_bytes(gzip.compress(raw) if gz else raw)
    return path


def npy_claiming(shape) -> bytes:
    """An .npy header claiming ``shape`` float64, followed by 64 bytes."""
    buf = io.BytesIO()
    np.lib.format.write_array_header_1_0(buf, {"descr": "<f8", "fortran_order": False, "shape": tuple(shape)})
    return buf.getvalue() + b"\0" * 64


def _huge(ctx: Ctx, kind: str) -> Path:
    d = _dir(ctx, "huge")
    if kind in ("nii", "nii.gz"):
        return nifti_claiming(d / f"huge.{kind}", HUGE, gz=kind == "nii.gz")
    if kind == "mha":
        (d / "huge.mha").write_bytes(b"ObjectType = Image\nNDims = 3\nDimSize = 1500 1500 1500\n"
                                     b"ElementType = MET_FLOAT\nElementDataFile = LOCAL\n" + b"\0" * 64)
        return d / "huge.mha"
    if kind == "mhd":
        (d / "huge.raw").write_bytes(b"\0" * 64)
        (d / "huge.mhd").write_text("ObjectType = Image\nNDims = 3\nDimSize = 1500 1500 1500\n"
                                    "ElementType = MET_FLOAT\nElementDataFile = huge.raw\n")
        return d / "huge.mhd"
    if kind == "nrrd":
        (d / "huge.nrrd").write_bytes(b"NRRD0004\ntype: float\ndimension: 3\nsizes: 1500 1500 1500\n"
                                      b"encoding: raw\nendian: little\n\n" + b"\0" * 64)
        return d / "huge.nrrd"
    if kind == "npy":
        (d / "huge.npy").write_bytes(npy_claiming(HUGE))
        return d / "huge.npy"
    with zipfile.ZipFile(d / "huge.npz", "w") as z:          # npz: values claiming 1500³ inside a zip
        z.writestr("values.npy", npy_claiming(HUGE))
        z.writestr("origin.npy", _npy(np.zeros(3)))
        z.writestr("spacing.npy", _npy(np.ones(3)))
    return d / "huge.npz"


def _npy(a: np.ndarray) -> bytes:
    buf = io.BytesIO()
    np.save(buf, a)
    return buf.getvalue()


def size_cases() -> list[Case]:
    """A header claiming 1500³ in every format: one line, within an address-space limit far below 12 GiB."""
    out: list[Case] = []
    for kind in ("nii", "nii.gz", "mha", "mhd", "nrrd", "npy", "npz"):
        def check(ctx, kind=kind):
            return one_line(ctx.bench("info", str(_huge(ctx, kind)), limit_gb=LIMIT_GB), "huge")
        out.append(Case("9", f"info: a {kind} claiming 1500³", check))
    for kind in ("nii", "nii.gz", "mha"):
        def check(ctx, kind=kind):
            p = _huge(ctx, kind)
            return one_line(ctx.bench("reconstruct", str(p), "-m", "marching_cubes", "-o",
                                      str(p.parent / f"{kind}.ply"), limit_gb=LIMIT_GB), "huge")
        out.append(Case("9", f"reconstruct: a {kind} claiming 1500³", check))

    def run(ctx):
        p = _huge(ctx, "nii.gz")
        folder = p.parent / "run"
        res = ctx.bench("run", "--phantoms", f"volume:{p}", "--noise", "none", "--method", "marching_cubes",
                        "--out", str(folder), "--jobs", "1", "--no-report", limit_gb=LIMIT_GB)
        return one_line(res, "huge") if res.rc == 2 else first(exits_ok(res), failed_row(folder, "marching_cubes"))
    out.append(Case("9", "run: a nii.gz claiming 1500³ (refused or a failed row)", run))
    out.append(Case("9", "volume --n 3000: the largest N that fits", lambda ctx: one_line(ctx.bench(
        "volume", "sphere", "--n", "3000", "-o", str(_dir(ctx, "huge") / "big.npz"), limit_gb=LIMIT_GB), "memory")))
    return out


# ------------------------------------------------------------------------------------------------ cause 12
def _fifo(ctx: Ctx, name: str) -> Path:
    p = _dir(ctx, "fifo") / name
    if not p.exists():
        os.mkfifo(p)
    return p


def hang_cases() -> list[Case]:
    """FIFOs with no writer, endless devices, folders where a file is expected: one line within 30 s."""
    def info(target):
        return lambda ctx: one_line(ctx.bench("info", str(target(ctx)), timeout=30))

    def cfg(target):
        return lambda ctx: one_line(ctx.bench("run", "--config", str(target(ctx)), "--out",
                                              str(_dir(ctx, "fifo") / "never"), "--dry-run", timeout=30))

    def mhd_fifo(ctx):
        d = _dir(ctx, "fifo")
        (d / "v.mhd").write_text("ObjectType = Image\nNDims = 3\nDimSize = 4 4 4\nElementType = MET_FLOAT\n"
                                 "ElementDataFile = v.raw\n")
        _fifo(ctx, "v.raw")
        return d / "v.mhd"

    def symlink(ctx):
        link = _dir(ctx, "fifo") / "link.nii"
        if not link.exists():
            link.symlink_to(_fifo(ctx, "target.nii"))
        return link

    out = [Case("12", "info: a FIFO with no writer", info(lambda ctx: _fifo(ctx, "pipe.nii"))),
           Case("12", "info: volume: a FIFO named .npz", info(lambda ctx: f"volume:{_fifo(ctx, 'pipe.npz')}")),
           Case("12", "info: a symlink to a FIFO", info(symlink)),
           Case("12", "info: an .mhd whose data is a FIFO", info(mhd_fifo)),
           Case("12", "info: /dev/zero", info(lambda ctx: "/dev/zero")),
           Case("12", "info: /dev/urandom", info(lambda ctx: "/dev/urandom")),
           Case("12", "run --config /dev/zero", cfg(lambda ctx: "/dev/zero")),
           Case("12", "run --config /dev/urandom", cfg(lambda ctx: "/dev/urandom")),
           Case("12", "run --config a FIFO", cfg(lambda ctx: _fifo(ctx, "grid.toml"))),
           Case("12", "run --config a folder", cfg(lambda ctx: _dir(ctx, "fifo")))]
    out.append(Case("12", "reconstruct: a FIFO", lambda ctx: one_line(ctx.bench(
        "reconstruct", str(_fifo(ctx, "r.nii")), "-m", "marching_cubes", "-o", str(ctx.root / "fifo" / "r.ply"),
        timeout=30))))
    return out


# ------------------------------------------------------------------------------------------------ cause 15
def _no_library_text(res) -> str | None:
    for t in LIBRARY_TEXT:
        if t in res.err:
            return f"library text {t!r} on stderr: {res.err.strip()[:240]!r}"
    return None


def _write(ctx: Ctx, name: str, data: bytes) -> Path:
    p = _dir(ctx, "unreadable") / name
    p.write_bytes(data)
    return p


def _mhd_missing_raw(ctx: Ctx) -> Path:
    d = _dir(ctx, "unreadable")
    write_itk(d / "noraw.mhd")
    (d / "noraw.raw").unlink()
    return d / "noraw.mhd"


def _nrrd_cut(ctx: Ctx) -> Path:
    d = _dir(ctx, "unreadable")
    good = write_itk(d / "good.nrrd")
    return _write(ctx, "cut.nrrd", good.read_bytes()[: good.stat().st_size // 2])


def _bad_sizeof(ctx: Ctx) -> Path:
    d = _dir(ctx, "unreadable")
    nib.save(nib.Nifti1Image(mask(), np.eye(4)), str(d / "ok.nii"))
    data = bytearray((d / "ok.nii").read_bytes())
    data[0:4] = (999).to_bytes(4, "little")
    return _write(ctx, "badsize.nii", bytes(data))


def _junk_dicom(ctx: Ctx) -> Path:
    d = _dir(ctx, "unreadable") / "junkdicom"
    d.mkdir(exist_ok=True)
    for k in range(3):
        (d / f"x{k}.dcm").write_bytes(b"DICM" * 50)
    return d


def _dicom_and_junk(ctx: Ctx) -> Path:
    folder = write_dicom(_dir(ctx, "unreadable") / "dicomjunk")
    (folder / "notes.dcm").write_bytes(b"not a dicom file at all")
    return folder


UNREADABLE = {
    "an .mhd whose raw file is missing (names the raw file)": (_mhd_missing_raw, ("noraw.raw",)),
    "an .mha with ElementType MET_BOGUS": (lambda ctx: _write(ctx, "bogus.mha", (
        b"ObjectType = Image\nNDims = 3\nDimSize = 4 4 4\nElementType = MET_BOGUS\nElementDataFile = LOCAL\n"
        + b"\0" * 64)), ("bogus.mha",)),
    "an .mha with DimSize of letters": (lambda ctx: _write(ctx, "dims.mha", (
        b"ObjectType = Image\nNDims = 3\nDimSize = a b c\nElementType = MET_FLOAT\nElementDataFile = LOCAL\n"
        + b"\0" * 64)), ("dims.mha",)),
    "an .nrrd with two sizes for three dimensions": (lambda ctx: _write(ctx, "bad.nrrd", (
        b"NRRD0004\ntype: float\ndimension: 3\nsizes: 4 4\nencoding: raw\n\nxxxx")), ("bad.nrrd",)),
    "an .nrrd of type bogus": (lambda ctx: _write(ctx, "type.nrrd", (
        b"NRRD0004\ntype: bogus\ndimension: 3\nsizes: 4 4 4\nencoding: raw\n\n" + b"\0" * 64)), ("type.nrrd",)),
    "an .nrrd cut in half": (_nrrd_cut, ("cut.nrrd",)),
    "an empty .mha": (lambda ctx: _write(ctx, "empty.mha", b""), ("empty.mha",)),
    "a .nii.gz of junk": (lambda ctx: _write(ctx, "junk.nii.gz", gzip.compress(b"not an image" * 40)),
                          ("junk.nii.gz",)),
    "a .nii of 400 random bytes": (lambda ctx: _write(ctx, "rand.nii", np.random.default_rng(0).bytes(400)),
                                   ("rand.nii",)),
    "a folder of junk .dcm files": (_junk_dicom, ("junkdicom",)),
    "a .nii.gz that is not gzip": (lambda ctx: _write(ctx, "plain.nii.gz", b"\x1f\x8b" + b"x" * 300),
                                   ("plain.nii.gz",)),
}


def unreadable_cases() -> list[Case]:
    """Files the libraries cannot read: one line naming the file, no library text, a series with junk read."""
    out = []
    for name, (make, words) in UNREADABLE.items():
        def check(ctx, make=make, words=words):
            res = ctx.bench("info", str(make(ctx)), timeout=60)
            return first(one_line(res, *words), _no_library_text(res))
        out.append(Case("15", f"info: {name}", check))

    def repaired(ctx):
        res = ctx.bench("info", str(_bad_sizeof(ctx)))
        if res.rc != 0:
            return first(one_line(res, "badsize.nii"), _no_library_text(res))
        bad = [ln for ln in res.err_lines if not (ln.startswith("warning: ") and "badsize.nii" in ln)]
        return f"stderr lines that are not warnings naming the file: {bad[:2]}" if bad else None
    out.append(Case("15", "info: a .nii with sizeof_hdr 999 (refused, or read with a warning naming it)", repaired))

    def series_with_junk(ctx):
        res = ctx.bench("info", str(_dicom_and_junk(ctx)))
        return first(exits_ok(res) if res.rc == 0 else one_line(res, "notes.dcm"), _no_library_text(res))
    out.append(Case("15", "info: a DICOM series beside a junk .dcm (read, or one line naming it)", series_with_junk))

    def reconstruct_missing_raw(ctx):
        res = ctx.bench("reconstruct", str(_mhd_missing_raw(ctx)), "-m", "marching_cubes", "-o",
                        str(ctx.root / "unreadable" / "x.ply"))
        return first(one_line(res, "noraw.raw"), _no_library_text(res))
    out.append(Case("15", "reconstruct: an .mhd whose raw file is missing", reconstruct_missing_raw))
    sitk.ProcessObject.SetGlobalWarningDisplay(False)
    return out
