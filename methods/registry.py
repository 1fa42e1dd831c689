"""The method registry: the built-in methods, the installed plug-ins (entry points) and the classes registered in
this process, looked up by name.

* :func:`get_method` — an instance of a method by name, parameters checked;
* :func:`available_methods` / :func:`method_names` — every method: the built-ins (:data:`BUILTIN_METHODS`, imported
  lazily so one broken adapter cannot break the rest), then the entry points of group :data:`ENTRY_POINT_GROUP`,
  then the classes given to :func:`register_method`;
* :func:`register_method` — a :class:`methods.base.Method` subclass registered for the current process (a name is
  never taken over silently);
* :func:`import_plugins` — what ``--import MODULE`` does: the modules imported, a failure one line.
"""

from __future__ import annotations

import importlib
import sys
from importlib import metadata
from typing import Any

from phantoms import InputError

from .base import Method

__all__ = ["ENTRY_POINT_GROUP", "BUILTIN_METHODS", "available_methods", "get_method", "register_method",
           "method_names", "import_plugins"]

ENTRY_POINT_GROUP = "levelset_bench.methods"
#: the plug-ins' entry points per sys.path, scanned once: reading every distribution's metadata is too slow for
#: each get_method
_ENTRY_POINTS: dict[tuple, tuple] = {}

#: built-in methods: name -> "module:Class" (imported lazily so one broken adapter cannot break the rest)
BUILTIN_METHODS: dict[str, str] = {
    "shape_gradient": "methods.shape_gradient:ShapeGradient",
    "marching_cubes": "methods.marching_cubes:MarchingCubes",
    "mc_taubin": "methods.mc_taubin:MCTaubin",
    "distmesh": "methods.distmesh:DistMesh",
    "poisson": "methods.poisson:ScreenedPoisson",
    "reach_for_the_spheres": "methods.reach_for_the_spheres:ReachForTheSpheres",
    "reach_for_the_arcs": "methods.reach_for_the_arcs:ReachForTheArcs",
    "dual_contouring": "methods.dual_contouring:DualContouring",
    "dc_sdf": "methods.dc_sdf:DCSDF",
    "cgal_mesher": "methods.cgal_mesher:CGALMesher",
    "vdb": "methods.vdb:VDB",
    "flying_edges": "methods.flying_edges:FlyingEdges",
    "surface_nets": "methods.surface_nets:SurfaceNets",
    "slicer": "methods.slicer:Slicer",
    "mc_smoothed_mask": "methods.mc_smoothed_mask:MCSmoothedMask",
    "zmesh": "methods.zmesh_mc:ZMesh",
    "mesh_file": "methods.mesh_file:MeshFile",
}

_REGISTERED: dict[str, type[Method]] = {}


def register_method(cls: type[Method] | None = None, *, replace: bool = False):
    """Register a :class:`Method` subclass under ``cls.name``; usable as a decorator (``@register_method`` or
    ``@register_method(replace=True)``).

    Registered methods are listed after the built-ins and entry points (:func:`available_methods`).  A name that
    is already taken is never taken over silently: a built-in's name is refused unless ``replace=True`` says
    the replacement is meant, and a name registered earlier by another class is replaced with a warning naming
    both (the same class registered again, e.g. its module reloaded, is no change).

    Parameters
    ----------
    cls : type
        A :class:`Method` subclass with a ``name``.
    replace : bool
        Replace a built-in method of the same name (e.g. a patched marching cubes under the built-in's name).

    Returns
    -------
    type
        ``cls`` itself (or, called with ``replace`` only, the decorator).

    Raises
    ------
    InputError
        ``cls`` is not a :class:`Method` subclass with a name, or it takes a built-in's name without
        ``replace=True`` (one line naming both classes).
    """
    if cls is None:
        return lambda c: register_method(c, replace=replace)
    if not (isinstance(cls, type) and issubclass(cls, Method)) or not cls.name:
        raise InputError(f"{cls!r} is not a Method subclass with a name")
    if cls.name in BUILTIN_METHODS and not replace:
        raise InputError(f"method {cls.name!r} of {_where(cls)} would replace the built-in "
                         f"{BUILTIN_METHODS[cls.name]}: choose another name, or register_method(cls, "
                         "replace=True) to mean it")
    earlier = _REGISTERED.get(cls.name)
    if earlier is not None and _where(earlier) != _where(cls):
        import warnings

        warnings.warn(f"method {cls.name!r} of {_where(cls)} replaces the one registered by {_where(earlier)}",
                      stacklevel=2)
    _REGISTERED[cls.name] = cls
    return cls


def _where(cls: type) -> str:
    """A class as ``module:qualname`` (how the built-ins and entry points name theirs)."""
    return f"{cls.__module__}:{cls.__qualname__}"


def import_plugins(modules) -> None:
    """Import each module named in ``modules`` (in order), e.g. ones that call :func:`register_method`.

    Parameters
    ----------
    modules : iterable of str
        Importable module names.

    Raises
    ------
    InputError
        ``cannot import module 'name': <the error>`` for any failure to import (a missing module, an exception
        the module raises, a ``sys.exit()`` at import — which would otherwise end the command silently with
        the module's exit code): it is the user's to fix.  The error is one line.
    """
    for mod in modules:
        try:
            importlib.import_module(mod)
        except SystemExit as exc:  # not a command-line exit: the plug-in's own, at import
            raise InputError(f"cannot import module {mod!r}: it called sys.exit({exc.code!r}) at import "
                             "(a plug-in module must not exit)") from None
        except Exception as exc:  # noqa: BLE001 - whatever the module raised, the user names the module
            raise InputError(f"cannot import module {mod!r}: {_one_line(exc)}") from None


def _one_line(exc: BaseException) -> str:
    """An exception's text on one line (a message with newlines joined by spaces), or its type if it has none."""
    return " ".join(str(exc).split()) or type(exc).__name__


def _load(target: str) -> type[Method]:
    module, _, attr = target.partition(":")
    return getattr(importlib.import_module(module), attr)


def available_methods() -> dict[str, type[Method]]:
    """Every method: the built-ins, then entry points of group ``levelset_bench.methods``, then registered ones.

    A built-in or plug-in that fails to import is skipped with a warning rather than breaking the others; so is
    an entry point named as a built-in (the built-in is used; ``python -m bench methods`` prints the warning).
    A method registered with ``register_method(cls, replace=True)`` replaces the built-in of its name.

    Returns
    -------
    dict of str to type
        Method name → :class:`Method` subclass.
    """
    import warnings

    out: dict[str, type[Method]] = {}
    for name, target in BUILTIN_METHODS.items():
        try:
            out[name] = _load(target)
        except (ImportError, AttributeError) as exc:
            warnings.warn(f"built-in method {name!r} unavailable: {exc}", stacklevel=2)
    key = tuple(sys.path)
    if key not in _ENTRY_POINTS:
        _ENTRY_POINTS[key] = tuple(metadata.entry_points(group=ENTRY_POINT_GROUP))
    for ep in _ENTRY_POINTS[key]:
        try:
            cls = ep.load()
        except SystemExit as exc:  # sys.exit() at import must not end the command silently either
            warnings.warn(f"plug-in method {ep.name!r} ({ep.value}) failed to load: it called "
                          f"sys.exit({exc.code!r}) at import", stacklevel=2)
            continue
        except Exception as exc:  # a broken plug-in must not take the suite down
            warnings.warn(f"plug-in method {ep.name!r} ({ep.value}) failed to load: {_one_line(exc)}",
                          stacklevel=2)
            continue
        if isinstance(cls, type) and issubclass(cls, Method):
            name = cls.name or ep.name
            if name in BUILTIN_METHODS:   # the built-in stays: a name's meaning must not depend on what is installed
                warnings.warn(f"plug-in method {ep.name!r} ({ep.value}) is not used: its name {name!r} is the "
                              f"built-in {BUILTIN_METHODS[name]}'s (rename it, or register it with "
                              "register_method(cls, replace=True) from a module given to --import)", stacklevel=2)
                continue
            out[name] = cls
        else:
            warnings.warn(f"plug-in {ep.name!r} ({ep.value}) is not a methods.Method subclass", stacklevel=2)
    out.update(_REGISTERED)
    return out


def method_names() -> list[str]:
    """The names of every available method (:func:`available_methods`), in its order.

    Returns
    -------
    list of str
    """
    return list(available_methods())


def get_method(name: str, **params: Any) -> Method:
    """An instance of the method called ``name``.

    Parameters
    ----------
    name : str
        A method name (:func:`method_names`).
    **params
        Non-default parameter values.

    Returns
    -------
    Method

    Raises
    ------
    InputError
        An unknown name (listing the valid ones), or a parameter the method refuses.
    """
    methods = available_methods()
    if name not in methods:
        raise InputError(f"unknown method {name!r}; valid methods: {', '.join(methods)}")
    return methods[name](**params)
