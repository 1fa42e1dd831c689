"""Phantom names: the analytic classes, the named real shapes, ``mesh:PATH`` for any closed mesh file and
``volume:PATH[?options]`` for a user's volume (:mod:`phantoms.user`); a glob in either path is a dataset
(:func:`expand_phantoms`).

Only :mod:`phantoms` (its ``__init__``) and code above the package (methods, bench) import this module;
the phantom modules themselves never do, so no phantom module depends on the list of all phantoms.
"""

from __future__ import annotations

import glob
import re
from pathlib import Path

from geometry.errors import InputError

from .analytic import Cylinder, Ellipsoid, FusedSpheres, Sphere, Torus
from .base import Phantom
from .real import REAL_SHAPES, get_mesh_file_phantom, get_real_phantom, get_volume_phantom
from .user import VOLUME_PREFIX, parse_spec

__all__ = ["PHANTOMS", "REAL_PHANTOMS", "MESH_PREFIX", "VOLUME_PREFIX", "phantom_names", "is_phantom_name",
           "get_phantom", "expand_phantoms", "is_file_phantom", "phantom_path"]

#: the analytic phantom classes by name
PHANTOMS: dict[str, type[Phantom]] = {
    cls.name: cls for cls in (Sphere, Ellipsoid, FusedSpheres, Cylinder, Torus)
}

#: named real shapes (data shipped inside installed packages, loaded on first use: ``phantoms/real.py``);
#: any closed mesh file is a phantom as ``mesh:PATH``.  PHANTOMS keeps the analytic classes only.
REAL_PHANTOMS: tuple[str, ...] = tuple(REAL_SHAPES)
MESH_PREFIX = "mesh:"


def phantom_names() -> list[str]:
    """Analytic phantoms, then the named real shapes (``mesh:PATH`` is accepted too)."""
    return list(PHANTOMS) + list(REAL_PHANTOMS)


def _is_mesh_name(name) -> bool:
    return isinstance(name, str) and name.startswith(MESH_PREFIX)


def is_file_phantom(name) -> bool:
    """True for ``mesh:PATH`` and ``volume:PATH[?options]``."""
    return isinstance(name, str) and (name.startswith(MESH_PREFIX) or name.startswith(VOLUME_PREFIX))


def phantom_path(spec: str) -> str:
    """The file (or folder, or glob) part of a ``mesh:`` / ``volume:`` spec."""
    if spec.startswith(VOLUME_PREFIX):
        return parse_spec(spec)[0]
    return spec[len(MESH_PREFIX):]


def is_phantom_name(name: str) -> bool:
    """True for a registered phantom name, ``mesh:PATH`` or ``volume:PATH`` (the file is not checked here)."""
    return name in PHANTOMS or name in REAL_PHANTOMS or is_file_phantom(name)


_GLOB_CHARS = re.compile(r"[*?\[]")


def _stem(path: Path) -> str:
    name = path.name
    for suffix in (".nii.gz", ".tar.gz"):
        if name.lower().endswith(suffix):
            return name[: -len(suffix)]
    return path.stem if path.suffix else name


def expand_phantoms(specs) -> list[tuple[str, str]]:
    """``[(name, source), ...]``: each spec once, a ``mesh:`` / ``volume:`` spec whose path is a glob as one
    phantom per matching file (sorted; named by the file's stem, its options kept).  :class:`InputError` for an
    empty glob (naming the pattern) or two phantoms of the same name.  Files are not read here."""
    out: list[tuple[str, str]] = []
    for spec in specs:
        if not is_file_phantom(spec) or not _GLOB_CHARS.search(phantom_path(spec)):
            out.append((spec, spec))
            continue
        pattern = phantom_path(spec)
        prefix = MESH_PREFIX if spec.startswith(MESH_PREFIX) else VOLUME_PREFIX
        query = spec[len(prefix) + len(pattern):]
        matches = sorted(glob.glob(str(Path(pattern).expanduser())))
        if not matches:
            raise InputError(f"phantom {spec!r}: no file matches the pattern {pattern!r}")
        for m in matches:
            out.append((_stem(Path(m)), f"{prefix}{m}{query}"))
    seen: dict[str, str] = {}
    for name, source in out:
        if name in seen and seen[name] != source:
            raise InputError(f"two phantoms are named {name!r} ({seen[name]} and {source}); rename one of the files")
        seen[name] = source
    return list(dict.fromkeys(out))


def get_phantom(name: str, **params) -> Phantom:
    """The phantom called ``name`` (optionally with non-default parameters); ``mesh:PATH`` for a mesh file,
    ``volume:PATH[?options]`` for a user volume."""
    if name.startswith(VOLUME_PREFIX):
        return get_volume_phantom(name, **params)
    if _is_mesh_name(name):
        return get_mesh_file_phantom(name, name[len(MESH_PREFIX):], **params)
    if name in REAL_PHANTOMS:
        return get_real_phantom(name, **params)
    if name not in PHANTOMS:
        raise InputError(f"unknown phantom {name!r}; valid phantoms: {', '.join(phantom_names())}, "
                         f"or {MESH_PREFIX}PATH for a closed mesh file, {VOLUME_PREFIX}PATH for a volume file")
    try:
        return PHANTOMS[name](**params)
    except TypeError as exc:
        raise InputError(f"bad parameters for phantom {name!r}: {exc}") from None
