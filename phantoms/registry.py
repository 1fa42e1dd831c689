"""Phantom names: the analytic classes, the anatomy-like shapes (``NAME?key=value&...`` for non-default
parameters), the named real shapes, ``mesh:PATH`` for any closed mesh file and
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
from .anatomy import ANATOMY, parse_anatomy_spec
from .base import Phantom
from .field import FIELD_PREFIX, FieldPhantom, parse_field_spec
from .real import REAL_SHAPES, get_mesh_file_phantom, get_real_phantom, get_volume_phantom
from .real_tier import FINE_SHAPES, get_fine_phantom
from .user import VOLUME_PREFIX, parse_spec

__all__ = ["FIELD_PREFIX", "check_phantom_files", "PHANTOMS", "ANATOMY_PHANTOMS", "REAL_PHANTOMS", "MESH_PREFIX",
           "VOLUME_PREFIX", "phantom_names", "is_phantom_name", "get_phantom", "expand_phantoms", "is_file_phantom",
           "phantom_path", "short_name"]

#: the analytic phantom classes by name
PHANTOMS: dict[str, type[Phantom]] = {
    cls.name: cls for cls in (Sphere, Ellipsoid, FusedSpheres, Cylinder, Torus)
}

#: named real shapes (data shipped inside installed packages, loaded on first use: ``phantoms/real.py``), then the
#: real tier's fine segmentations (``phantoms/real_tier.py``); any closed mesh file is a phantom as ``mesh:PATH``.
#: PHANTOMS keeps the analytic classes only.
REAL_PHANTOMS: tuple[str, ...] = tuple(REAL_SHAPES) + tuple(FINE_SHAPES)
#: the anatomy-like shapes (``phantoms/anatomy/``): exact polyhedra, seeded and parameterised in voxels
ANATOMY_PHANTOMS: tuple[str, ...] = tuple(ANATOMY)
MESH_PREFIX = "mesh:"


def phantom_names() -> list[str]:
    """The registered phantom names: the analytic phantoms, the anatomy-like shapes, then the named real shapes.

    ``mesh:PATH`` and ``volume:PATH`` are accepted too (:func:`is_phantom_name`) but are not listed.

    Returns
    -------
    list of str
    """
    return list(PHANTOMS) + list(ANATOMY_PHANTOMS) + list(REAL_PHANTOMS)


def _is_anatomy_spec(name) -> bool:
    """An anatomy shape's name, with or without ``?key=value`` options (checked)."""
    if not isinstance(name, str) or name.partition("?")[0] not in ANATOMY:
        return False
    try:
        parse_anatomy_spec(name)
    except InputError:
        return False
    return True


def _is_mesh_name(name) -> bool:
    return isinstance(name, str) and name.startswith(MESH_PREFIX)


def is_file_phantom(name) -> bool:
    """Whether ``name`` names a file phantom: ``mesh:PATH`` or ``volume:PATH[?options]``.

    Parameters
    ----------
    name : object
        A phantom name or spec; anything that is not a string is not a file phantom.

    Returns
    -------
    bool
    """
    return isinstance(name, str) and (name.startswith(MESH_PREFIX) or name.startswith(VOLUME_PREFIX))


def phantom_path(spec: str) -> str:
    """The file (or folder, or glob) part of a ``mesh:`` / ``volume:`` spec.

    Parameters
    ----------
    spec : str
        ``mesh:PATH`` or ``volume:PATH[?key=value&...]``.

    Returns
    -------
    str
        ``PATH``, without the prefix and the options.
    """
    if spec.startswith(VOLUME_PREFIX):
        return parse_spec(spec)[0]
    return spec[len(MESH_PREFIX):]


def is_phantom_name(name: str) -> bool:
    """Whether ``name`` is a registered phantom name, ``mesh:PATH`` or ``volume:PATH``.

    Parameters
    ----------
    name : str
        The name to check; the file of a file phantom is not looked at here.

    Returns
    -------
    bool
    """
    if isinstance(name, str) and name.startswith(FIELD_PREFIX):   # its options are checked with its files
        inner = name[len(FIELD_PREFIX):].partition("?")[0]
        return not inner.startswith((FIELD_PREFIX, VOLUME_PREFIX)) and is_phantom_name(inner)
    return name in PHANTOMS or name in REAL_PHANTOMS or _is_anatomy_spec(name) or is_file_phantom(name)


_GLOB_CHARS = re.compile(r"[*?\[]")


def _stem(path: Path) -> str:
    name = path.name
    for suffix in (".nii.gz", ".tar.gz"):
        if name.lower().endswith(suffix):
            return name[: -len(suffix)]
    return path.stem if path.suffix else name


def short_name(name: str) -> str:
    """The name a user sees for a phantom: a ``mesh:`` / ``volume:`` spec's file stem (``volume:ct.nii.gz?level=500``
    → ``ct``), anything else as it is — a glob's or a ``labels=`` spec's phantoms are already named so
    (:func:`expand_phantoms`).  What ``{phantom}`` in a method's text parameter becomes (``mesh_file``'s
    ``path=exports/{phantom}.stl``).

    Parameters
    ----------
    name : str
        A phantom's name in a grid (:func:`expand_phantoms`' first element).

    Returns
    -------
    str
    """
    if not is_file_phantom(name):
        return name
    return _stem(Path(phantom_path(name)).expanduser())


def expand_phantoms(specs) -> list[tuple[str, str]]:
    """Expand the globs of a list of phantom specs into one phantom per matching file.

    Parameters
    ----------
    specs : iterable of str
        Phantom names and ``mesh:`` / ``volume:`` specs; a spec whose path is a glob stands for a dataset.

    Returns
    -------
    list of (str, str)
        ``[(name, source), ...]``, each spec once: a globbed spec as one phantom per matching file (sorted,
        named by the file's stem, its options kept), a ``labels=`` spec as one phantom per label (the image is
        read for its labels), any other spec as ``(spec, spec)``.  Files are not read otherwise.

    Raises
    ------
    InputError
        An empty glob (naming the pattern), a ``labels=all`` image with no label, or two phantoms of the same
        name.
    """
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
    from .labels import expand_labels

    labelled = []
    for name, source in out:
        if not (source.startswith(VOLUME_PREFIX) and "label" in source):
            labelled.append((name, source))
            continue
        pairs = expand_labels(name, source)
        if not pairs:                   # labels=all on an image of zeros: no phantom, so no cell, is no run
            raise InputError(f"phantom {source!r}: the image holds no label (every voxel is 0): no phantom to run")
        labelled += pairs
    out = labelled
    seen: dict[str, str] = {}
    for name, source in out:
        if name in seen and seen[name] != source:
            raise InputError(f"two phantoms are named {name!r} ({seen[name]} and {source}); rename one of the files")
        seen[name] = source
    return list(dict.fromkeys(out))


def get_phantom(name: str, **params) -> Phantom:
    """The phantom called ``name``.

    Parameters
    ----------
    name : str
        A registered name (:func:`phantom_names`), ``mesh:PATH`` for a closed mesh file, or
        ``volume:PATH[?options]`` for a user volume.
    **params
        Non-default parameters of the phantom (e.g. the semi-axes of an ellipsoid).

    Returns
    -------
    Phantom

    Raises
    ------
    InputError
        An unknown name (listing the valid ones) or parameters the phantom does not take; a file phantom's
        file that cannot be read.
    """
    if name.startswith(FIELD_PREFIX):
        return _field_phantom(name, **params)
    if name.startswith(VOLUME_PREFIX):
        return get_volume_phantom(name, **params)
    if _is_mesh_name(name):
        return get_mesh_file_phantom(name, name[len(MESH_PREFIX):], **params)
    if name in FINE_SHAPES:
        return get_fine_phantom(name, **params)
    if name in REAL_PHANTOMS:
        return get_real_phantom(name, **params)
    if name.partition("?")[0] in ANATOMY:
        return _anatomy_phantom(name, **params)
    if name not in PHANTOMS:
        raise InputError(f"unknown phantom {name!r}; valid phantoms: {', '.join(phantom_names())}, "
                         f"or {MESH_PREFIX}PATH for a closed mesh file, {VOLUME_PREFIX}PATH for a volume file")
    try:
        return PHANTOMS[name](**params)
    except TypeError as exc:
        raise InputError(f"bad parameters for phantom {name!r}: {exc}") from None


_ANATOMY_CACHE: dict = {}


def _anatomy_phantom(spec: str, **params):
    """``NAME[?key=value&...]`` of an anatomy shape (:func:`phantoms.anatomy.parse_anatomy_spec`), cached per
    process and parameters (building and checking the polyhedron takes a second or two)."""
    name, options = parse_anatomy_spec(spec)
    options.update(params)
    key = (spec, tuple(sorted(options.items())))
    if key not in _ANATOMY_CACHE:
        if len(_ANATOMY_CACHE) >= 8:
            _ANATOMY_CACHE.pop(next(iter(_ANATOMY_CACHE)))
        try:
            ph = ANATOMY[name](**options)
        except TypeError as exc:
            raise InputError(f"bad parameters for phantom {spec!r}: {exc}") from None
        ph.name = spec
        _ANATOMY_CACHE[key] = ph
    return _ANATOMY_CACHE[key]


_FIELD_CACHE: dict = {}


def _field_inner(spec: str) -> str:
    """The inner phantom's name of ``field:NAME[?scale=S]``, refused in one line unless it names a mesh phantom
    (an analytic phantom, a ``volume:`` or a nested ``field:`` is not one) — without reading any file."""
    inner_name = parse_field_spec(spec)[0]
    if inner_name.startswith((FIELD_PREFIX, VOLUME_PREFIX)) or inner_name in PHANTOMS:
        raise InputError(f"phantom {spec!r}: the field's protocol takes a mesh phantom (a real shape such as "
                         f"bunny, or {MESH_PREFIX}PATH); {inner_name!r} is not one")
    return inner_name


def _field_phantom(spec: str, **params) -> FieldPhantom:
    """``field:NAME[?scale=S]``: the mesh of phantom NAME under the field's protocol (:mod:`phantoms.field`);
    cached per process and inner phantom (whose own cache follows its file's version)."""
    from .mesh import MeshPhantom

    inner_name, scale = _field_inner(spec), parse_field_spec(spec)[1]
    inner = get_phantom(inner_name, **params)
    if not isinstance(inner, MeshPhantom):
        raise InputError(f"phantom {spec!r}: {inner_name!r} is not a mesh phantom")
    key = (spec, id(inner))
    if key not in _FIELD_CACHE:
        if len(_FIELD_CACHE) >= 8:
            _FIELD_CACHE.pop(next(iter(_FIELD_CACHE)))
        _FIELD_CACHE[key] = FieldPhantom(inner, scale, name=spec)
    return _FIELD_CACHE[key]


def check_phantom_files(source: str) -> None:
    """Refuse, before any work, a ``mesh:`` / ``volume:`` phantom whose file — or ``truth=`` file — does not
    exist (a file that exists but cannot be read is a failed row of its cells instead), and a ``field:`` phantom
    whose inner phantom is not a mesh phantom.

    Raises
    ------
    InputError
        Naming the spec and the missing path.
    """
    from pathlib import Path

    if source.startswith(FIELD_PREFIX):
        source = _field_inner(source)
    if not is_file_phantom(source):
        return
    path = Path(phantom_path(source)).expanduser()
    if not (path.is_file() or (source.startswith(VOLUME_PREFIX) and path.is_dir())):
        kind = "mesh" if source.startswith(MESH_PREFIX) else "volume"
        raise InputError(f"phantom {source!r}: no such {kind} file {str(path)!r}")
    if source.startswith(VOLUME_PREFIX):
        from .user import parse_spec

        truth = parse_spec(source)[1].get("truth")
        if truth is not None and not Path(truth).expanduser().exists():
            raise InputError(f"phantom {source!r}: no such truth file {truth!r}")
