"""Phantom names: the analytic classes, the named real shapes and ``mesh:PATH`` for any closed mesh file.

Only :mod:`phantoms` (its ``__init__``) and code above the package (methods, bench) import this module;
the phantom modules themselves never do, so no phantom module depends on the list of all phantoms.
"""

from __future__ import annotations

from geometry.errors import InputError

from .analytic import Cylinder, Ellipsoid, FusedSpheres, Sphere, Torus
from .base import Phantom
from .real import REAL_SHAPES, get_mesh_file_phantom, get_real_phantom

__all__ = ["PHANTOMS", "REAL_PHANTOMS", "MESH_PREFIX", "phantom_names", "is_phantom_name", "get_phantom"]

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


def is_phantom_name(name: str) -> bool:
    """True for a registered phantom name or a ``mesh:PATH`` (the file is not checked here)."""
    return name in PHANTOMS or name in REAL_PHANTOMS or _is_mesh_name(name)


def get_phantom(name: str, **params) -> Phantom:
    """The phantom called ``name`` (optionally with non-default parameters); ``mesh:PATH`` for a mesh file."""
    if _is_mesh_name(name):
        return get_mesh_file_phantom(name, name[len(MESH_PREFIX):], **params)
    if name in REAL_PHANTOMS:
        return get_real_phantom(name, **params)
    if name not in PHANTOMS:
        raise InputError(f"unknown phantom {name!r}; valid phantoms: {', '.join(phantom_names())}, "
                         f"or {MESH_PREFIX}PATH for a closed mesh file")
    try:
        return PHANTOMS[name](**params)
    except TypeError as exc:
        raise InputError(f"bad parameters for phantom {name!r}: {exc}") from None
