"""A label map as several phantoms: ``volume:labels.nii.gz?labels=all`` (or ``labels=1,3``) is one phantom per
label, named ``<stem>_label<L>``, each the mask of its label (docs/PHANTOMS.md, "Your own volumes")."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from geometry.errors import InputError

from .images import read_image
from .user import format_spec, parse_spec

__all__ = ["expand_labels"]


def expand_labels(name: str, spec: str) -> list[tuple[str, str]]:
    """A ``labels=all`` / ``labels=1,3`` spec as one phantom per label, ``(name_label<L>, spec with label=L)``;
    any other spec as itself.  Reads the image to list its labels.

    Raises
    ------
    InputError
        ``labels=`` on an image that is not a label map (non-integer values, or more than 255 labels), or a label
        that does not occur (naming those present).
    """
    path, opts = parse_spec(spec)
    if "labels" not in opts:
        return [(name, spec)]
    values = read_image(path, series=opts.get("series")).values
    if not (values.dtype.kind in "biu" or bool(np.all(np.mod(values, 1) == 0))):
        raise InputError(f"{spec}: labels= needs a label map; the image holds non-integer values (range "
                         f"[{float(values.min()):g}, {float(values.max()):g}]): use threshold= or level=")
    present = [int(x) for x in np.unique(values) if x != 0]
    if opts["labels"] == "all":
        if len(present) > 255:
            raise InputError(f"{spec}: labels=all on an image with {len(present)} distinct values: not a label map")
        wanted = present
    else:
        wanted = [int(t) for t in opts["labels"].split(",")]
        missing = [x for x in wanted if x not in present]
        if missing:
            raise InputError(f"{spec}: label {', '.join(map(str, missing))} does not occur in the image; labels "
                             f"present: {', '.join(map(str, present[:50]))}")
    base = {k: v for k, v in opts.items() if k != "labels"}
    stem = name if name != spec else Path(path).name.split(".")[0]
    return [(f"{stem}_label{x}", format_spec(path, {**base, "label": x})) for x in wanted]
