"""Checks made before an image's data is read, and ITK's own text kept off the terminal.

* :func:`check_file_kind` — only a regular file or a folder (a DICOM series) is opened: a FIFO with no writer, a
  character device (``/dev/zero``) or a socket would block the reader or feed it without end.
* :func:`check_claimed_size` and :func:`check_dicom_size` — the size the header claims (shape × bytes per voxel,
  from the header alone: nibabel's header, SimpleITK's ``ReadImageInformation``, the ``.npy`` header) is checked
  against the file (an uncompressed file that holds less data than its header claims is truncated) and against
  the available memory (:func:`phantoms.memory.available_memory`), before the data is read: a 1 KB file whose
  header claims 1500³ float32 voxels is refused at once instead of allocating 13 GB.
* A MetaImage header's ``ElementDataFile`` (``.mhd``) and an NRRD header's ``data file`` (``.nhdr``) are checked
  to exist: ITK would only say "File cannot be read" with a C++ source line.
* :func:`quiet_itk` — ITK / GDCM / MetaImage print warnings and errors on the C++ stderr (file descriptor 2);
  around a read they are switched off and captured, and :func:`itk_error_text` makes one line of an ITK error
  (no C++ source line, no object address) with what was captured.
"""

from __future__ import annotations

import contextlib
import os
import re
import stat
import sys
import tempfile
import threading
from pathlib import Path

import numpy as np

from geometry.errors import InputError

from . import memory

__all__ = ["check_file_kind", "check_claimed_size", "check_dicom_size", "quiet_itk", "itk_error_text", "one_line"]

#: bytes of float64 per voxel: every volume becomes float64 once read (phantoms.user.level_set_from_image)
_FLOAT_COPY = 8

_KINDS = ((stat.S_ISFIFO, "a FIFO (named pipe)"), (stat.S_ISCHR, "a character device"),
          (stat.S_ISBLK, "a block device"), (stat.S_ISSOCK, "a socket"))


def one_line(text) -> str:
    """``text`` on one line: runs of whitespace (newlines included) become one space."""
    return " ".join(str(text).split())


def check_file_kind(path: Path) -> None:
    """Refuse, without opening it, anything at ``path`` that is not a regular file or a folder."""
    try:
        mode = os.stat(path).st_mode
    except OSError as exc:
        raise InputError(f"{path}: cannot read the file: {exc.strerror or exc}") from None
    if stat.S_ISREG(mode) or stat.S_ISDIR(mode):
        return
    kind = next((name for test, name in _KINDS if test(mode)), "not a regular file")
    raise InputError(f"{path}: is {kind}, not an image file; give a regular file (or a folder holding a DICOM "
                     "series)")


def _gib(n: float) -> str:
    return f"{n / 2**30:.1f} GiB" if n >= 2**30 else f"{n / 2**20:.1f} MiB" if n >= 2**20 else f"{int(n)} bytes"


def _check(path: Path, shape, itemsize: int, dtype: str, *, copies: int = 1, on_disk: int | None = None) -> None:
    """The header claims ``shape`` voxels of ``itemsize`` bytes (``dtype``): refuse a file holding less than that
    (``on_disk``: the bytes the file has for its data, None when compressed) or an image that cannot fit in memory
    once read (``copies`` arrays of the data plus its float64 copy)."""
    shape = tuple(int(s) for s in shape)
    dims = "×".join(map(str, shape))
    data = float(np.prod([float(s) for s in shape])) * itemsize
    if on_disk is not None and on_disk < data:
        raise InputError(f"{path}: cannot read the file: it is truncated — its header claims a {dims} {dtype} image "
                         f"({_gib(data)} of data) but the file holds {_gib(max(on_disk, 0))} of data")
    avail = memory.available_memory()
    need = data * copies + data / max(itemsize, 1) * _FLOAT_COPY
    if avail is not None and need > avail:
        raise InputError(f"{path}: its header claims a {dims} {dtype} image ({_gib(data)} of data); reading it "
                         f"needs about {_gib(need)} but {_gib(avail)} of memory are available — a damaged header, "
                         "or an image too large for this machine (crop or downsample it first)")


# ------------------------------------------------------------------------------------------------ formats
def _check_npy(path: Path, fh, size: int | None) -> None:
    fmt = np.lib.format
    version = fmt.read_magic(fh)
    read = fmt.read_array_header_1_0 if version == (1, 0) else fmt.read_array_header_2_0
    shape, _, dtype = read(fh)
    if dtype.hasobject:           # refused by np.load itself (allow_pickle=False), with its own message
        return
    on_disk = None if size is None else size - fh.tell()
    _check(path, shape, dtype.itemsize, str(dtype), on_disk=on_disk)


def _check_numpy(path: Path, suffix: str) -> None:
    if suffix == ".npy":
        with open(path, "rb") as fh:
            _check_npy(path, fh, os.path.getsize(path))
        return
    import zipfile

    with zipfile.ZipFile(path) as z:
        if "values.npy" in z.namelist():
            info = z.getinfo("values.npy")
            with z.open(info) as fh:
                _check_npy(path, fh, info.file_size if info.compress_type == zipfile.ZIP_STORED else None)


def check_nifti(path: Path, img) -> None:
    """The shape and data type of a NIfTI header (nibabel, nothing read yet) against the file and the memory."""
    header = img.header
    dtype = np.dtype(header.get_data_dtype())
    compressed = str(path).lower().endswith(".gz")
    offset = getattr(img.dataobj, "offset", None)        # where the proxy will read (the header's vox_offset
    offset = int(header.get_data_offset() if offset is None else offset)   # may say 0 for a single file)
    on_disk = None if compressed else os.path.getsize(path) - offset
    _check(path, header.get_data_shape(), dtype.itemsize, str(dtype), on_disk=on_disk)


def _header_keys(path: Path, sep: str, limit: int = 1 << 16) -> tuple[dict[str, str], int]:
    """``key<sep>value`` lines of a text header (lower-case keys) and the byte where the header ends (after the
    MetaImage ``ElementDataFile`` line or the NRRD blank line)."""
    keys, pos = {}, 0
    with open(path, "rb") as fh:
        for raw in iter(lambda: fh.readline(limit), b""):
            pos += len(raw)
            line = raw.decode("latin-1").strip()
            if not line and sep == ":":
                break
            key, found, value = line.partition(sep)
            if found:
                keys[key.strip().lower()] = value.strip()
            if sep == "=" and key.strip().lower() == "elementdatafile" or pos >= limit:
                break
    return keys, pos


def _data_file(path: Path, name: str, what: str) -> Path | None:
    """The data file a header names (relative to the header's folder); None for a list or a pattern of files."""
    if not name or name.split()[0].upper() == "LIST" or "%" in name or len(name.split()) > 1:
        return None
    data = Path(name) if Path(name).is_absolute() else path.parent / name
    if not data.exists():
        raise InputError(f"{path}: the data file its header names ({what} = {name}) does not exist: {data}")
    check_file_kind(data)
    return data


def _itk_on_disk(path: Path) -> int | None:
    """Bytes a MetaImage / NRRD file has for its data (None when compressed or unknown); the data file the header
    names must exist."""
    if path.suffix.lower() in (".mha", ".mhd"):
        keys, end = _header_keys(path, "=")
        name = keys.get("elementdatafile", "")
        compressed = keys.get("compresseddata", "false").lower() == "true"
        if name.upper() == "LOCAL":
            return None if compressed else os.path.getsize(path) - end
        data = _data_file(path, name, "ElementDataFile")
    else:
        keys, end = _header_keys(path, ":")
        name = keys.get("data file", keys.get("datafile", ""))
        compressed = keys.get("encoding", "raw").lower() not in ("raw",)
        if not name:
            return None if compressed else os.path.getsize(path) - end
        data = _data_file(path, name, "data file")
    return None if compressed or data is None else os.path.getsize(data)


def _itk_pixel(reader) -> tuple[int, str]:
    """(bytes per voxel, type name) of the image a SimpleITK reader has read the information of."""
    import SimpleITK as sitk

    name = sitk.GetPixelIDValueAsString(reader.GetPixelID())
    bits = re.search(r"(\d+)-bit", name)
    size = int(bits.group(1)) // 8 if bits else 8
    if "complex" in name:
        size *= 2
    return size * max(int(reader.GetNumberOfComponents()), 1), name


def _itk_information(path: Path, file) -> object:
    """A SimpleITK reader that has read the header of ``file`` (ITK's stderr captured; its error in one line)."""
    import SimpleITK as sitk

    reader = sitk.ImageFileReader()
    reader.SetFileName(str(file))
    said: list[str] = []
    try:
        with quiet_itk() as said:
            reader.ReadImageInformation()
    except RuntimeError as exc:
        raise InputError(f"{path}: cannot read the image header ({itk_error_text(exc, ''.join(said))})") from None
    return reader


def check_claimed_size(path: Path, suffix: str) -> None:
    """Refuse, before its data is read, a ``.npy`` / ``.npz`` / MetaImage / NRRD file that is truncated, names a
    data file that does not exist, or claims more voxels than the memory holds (NIfTI: :func:`check_nifti`,
    DICOM: :func:`check_dicom_size`)."""
    if suffix in (".npy", ".npz"):
        _check_numpy(path, suffix)
    elif suffix in (".mha", ".mhd", ".nrrd", ".nhdr"):
        on_disk = _itk_on_disk(path)
        reader = _itk_information(path, path)
        size, name = _itk_pixel(reader)
        # the ITK image, the numpy copy of it, the float64 volume
        _check(path, reader.GetSize(), size, name, copies=2, on_disk=on_disk)


def check_dicom_size(path: Path, files) -> None:
    """A DICOM series: the first slice's size and pixel type × the number of slices, against the memory."""
    reader = _itk_information(path, files[0])
    size, name = _itk_pixel(reader)
    _check(path, (*reader.GetSize()[:2], len(files)), size, name, copies=2)


# ------------------------------------------------------------------------------------------ ITK's stderr
_ITK_LOCK = threading.RLock()       # re-entrant: a DICOM read checks its slices inside its own quiet block
#: how much of ITK's captured stderr is kept for an error message
_KEEP = 4096


@contextlib.contextmanager
def quiet_itk():
    """ITK's warnings off and the C++ stderr (fd 2) captured while the block runs; yields a list that holds the
    captured text (one string) once the block has ended."""
    import SimpleITK as sitk

    captured: list[str] = []
    with _ITK_LOCK:
        shown = sitk.ProcessObject.GetGlobalWarningDisplay()
        sitk.ProcessObject.SetGlobalWarningDisplay(False)
        try:
            sys.stderr.flush()
            saved = os.dup(2)
        except (OSError, ValueError):             # no fd 2 to capture: warnings off is all we can do
            saved = None
        try:
            with tempfile.TemporaryFile() as tmp:
                if saved is not None:
                    os.dup2(tmp.fileno(), 2)
                try:
                    yield captured
                finally:
                    if saved is not None:
                        os.dup2(saved, 2)
                        os.close(saved)
                    tmp.seek(0)
                    captured.append(tmp.read(_KEEP).decode("utf-8", "replace"))
        finally:
            sitk.ProcessObject.SetGlobalWarningDisplay(shown)


def itk_error_text(exc: BaseException, captured: str = "") -> str:
    """One line from a SimpleITK exception: the ITK message without the "Exception thrown in SimpleITK ..."
    preamble, the C++ source line and the object address, with the first line ITK printed on stderr."""
    lines = []
    for line in str(exc).splitlines():
        line = re.sub(r"^Exception thrown in SimpleITK \w+:\s*", "", line.strip())
        line = re.sub(r"\S+\.(?:cxx|cpp|h|hxx|txx):\d+:?", "", line)
        line = re.sub(r"^(?:ITK ERROR|itk::ERROR|sitk::ERROR):\s*", "", line.strip())
        line = re.sub(r"\(0x[0-9a-fA-F]+\)", "", line).strip()
        if line:
            lines.append(line)
    said = one_line(next((ln for ln in captured.splitlines() if ln.strip()), ""))
    if said:   # ITK's "Reason:" is a stale errno ("No such file or directory" for a file that exists)
        lines = [ln for ln in lines if not ln.startswith("Reason:")]
    text = one_line(" ".join(lines)) or type(exc).__name__
    if said and said not in text:
        text += f" (ITK: {said[:200]})"
    return text[:400]


# ------------------------------------------------------------------------------------------ nibabel's notes
@contextlib.contextmanager
def nibabel_notes(path: Path):
    """nibabel's own log lines while the block reads ``path`` (it prints header repairs such as "sizeof_hdr
    should be 348; set sizeof_hdr to 348" raw on stderr, without the file's name) become one ``warning:`` line
    each, naming the file, control characters escaped."""
    import logging

    logger = logging.getLogger("nibabel.global")
    said: list[str] = []

    class _Collect(logging.Handler):
        def emit(self, record: logging.LogRecord) -> None:
            said.append(record.getMessage())

    handlers, propagate = logger.handlers[:], logger.propagate
    logger.handlers, logger.propagate = [_Collect()], False
    try:
        yield
    finally:
        logger.handlers, logger.propagate = handlers, propagate
        for text in said:
            text = "".join(c if c.isprintable() else repr(c)[1:-1] for c in one_line(text))
            print(f"warning: {path}: nibabel: {text[:400]}", file=sys.stderr)

