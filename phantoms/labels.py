"""A label map as several phantoms: ``volume:labels.nii.gz?labels=all`` (or ``labels=1,3``) is one phantom per
label, named ``<stem>_label<L>``, each the mask of its label (docs/PHANTOMS.md, "Your own volumes")."""

from __future__ import annotations

from functools import lru_cache
from pathlib import Path

import numpy as np

from geometry.errors import InputError

from .images import read_image
from .user import format_spec, parse_spec

__all__ = ["expand_labels"]


def _present(path: str, series: str | None, spec: str) -> list[int]:
    """The non-zero labels of the label map at ``path`` (cached per file version: a run's checks and its grid
    ask several times)."""
    p = Path(path).expanduser()
    try:
        st = p.stat()
        version = (st.st_mtime_ns, st.st_size)
    except OSError:
        version = None
    return list(_present_cached(str(p), series, version, spec))


@lru_cache(maxsize=16)
def _present_cached(path: str, series: str | None, version, spec: str) -> tuple[int, ...]:
    values = read_image(path, series=series).values
    if not (values.dtype.kind in "biu" or bool(np.all(np.mod(values, 1) == 0))):
        option = "labels=" if "labels=" in spec else "label="
        raise InputError(f"{spec}: {option} needs a label map; the image holds non-integer values (range "
                         f"[{float(values.min()):g}, {float(values.max()):g}]): use threshold= or level=")
    return tuple(int(x) for x in np.unique(values) if x != 0)


def expand_labels(name: str, spec: str) -> list[tuple[str, str]]:
    """A ``labels=all`` / ``labels=1,3`` spec as one phantom per label, ``(name_label<L>, spec with label=L)``;
    a ``label=L`` spec as itself once its label is found in the image; any other spec as itself.  Reads the image
    to list its labels, so that a label that is not there is refused before any work.

    Raises
    ------
    InputError
        ``labels=`` / ``label=`` on an image that is not a label map (non-integer values, or more than 255 labels
        for ``labels=all``), or a label that does not occur (naming those present).
    """
    path, opts = parse_spec(spec)
    if "labels" not in opts and "label" not in opts:
        return [(name, spec)]
    present = _present(path, opts.get("series"), spec)
    if "label" in opts:
        wanted = [opts["label"]]
    elif opts["labels"] == "all":
        if len(present) > 255:
            raise InputError(f"{spec}: labels=all on an image with {len(present)} distinct values: not a label map")
        wanted = present
    else:
        wanted = [int(t) for t in opts["labels"].split(",")]
    missing = [x for x in wanted if x not in present]
    if missing:
        raise InputError(f"{spec}: label {', '.join(f'{x:g}' for x in missing)} does not occur in the image; "
                         f"labels present: {', '.join(map(str, present[:50]))}"
                         + (f", … ({len(present)} in all)" if len(present) > 50 else ""))
    if "label" in opts:
        return [(name, spec)]
    base = {k: v for k, v in opts.items() if k != "labels"}
    stem = name if name != spec else Path(path).name.split(".")[0]
    return [(f"{stem}_label{x}", format_spec(path, {**base, "label": x})) for x in wanted]


def label_surfaces(spec: str) -> dict[int, int]:
    """Per label of the label map a ``volume:`` spec reads: its surface size, the count of its voxels with a face
    neighbour of another value (what meshing and scoring a label cost grows with); {} for a spec without
    ``label=`` / ``labels=`` or an image that cannot be read.  Cached per file version."""
    path, opts = parse_spec(spec)
    if "labels" not in opts and "label" not in opts:
        return {}
    p = Path(path).expanduser()
    try:
        st = p.stat()
        return dict(_surfaces_cached(str(p), opts.get("series"), (st.st_mtime_ns, st.st_size)))
    except (OSError, InputError, ValueError):
        return {}


@lru_cache(maxsize=8)
def _surfaces_cached(path: str, series: str | None, version) -> tuple[tuple[int, int], ...]:
    values = read_image(path, series=series).values
    edge = np.zeros(values.shape, bool)
    for axis in range(3):
        a = np.swapaxes(values, 0, axis)
        e = np.swapaxes(edge, 0, axis)
        differs = a[1:] != a[:-1]
        e[1:] |= differs
        e[:-1] |= differs
    labels, counts = np.unique(values[edge], return_counts=True)
    return tuple((int(x), int(c)) for x, c in zip(labels, counts) if x != 0 and float(x) == int(x))
