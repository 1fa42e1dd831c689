"""The one small interface every reconstruction method implements, and the method registry.

A method is a subclass of :class:`Method` with

* ``name`` – the registry name (``python -m bench methods`` lists it);
* ``description`` – one line;
* ``params`` – a dict ``name -> Param(default, doc, ...)``: every tunable parameter, documented, with its default;
* ``reconstruct(volume) -> Reconstruction`` – a closed, outward-oriented triangle mesh in world coordinates
  (what it must return, and the checks of it: :mod:`methods.contract`, re-exported here);
* optionally ``skip_reason(volume)`` (an input the method cannot take: the cell is ``skipped``, not failed) and
  ``warm_up()`` (one-off costs such as compiling kernels, paid before ``reconstruct`` is timed).

Methods never import the benchmark (``bench``): they see a :class:`phantoms.Volume` and return a mesh.
User methods are found through the entry-point group ``levelset_bench.methods`` (see README, "Adding a
method"); each entry point names a :class:`Method` subclass.
"""

from __future__ import annotations

import importlib
import sys
from importlib import metadata
from typing import Any, ClassVar

from phantoms import InputError, Volume

from .contract import (
    INFO_KEYS,
    MethodSkipped,
    Reconstruction,
    ReconstructionFailed,
    WrongReturnType,
    as_reconstruction,
    check_info,
    check_skip,
    run_reconstruct,
    run_warm_up,
)
from .params import Param

__all__ = [
    "Param", "Method", "Reconstruction", "ReconstructionFailed", "WrongReturnType", "as_reconstruction", "check_info",
    "run_reconstruct", "INFO_KEYS",
    "MethodSkipped", "check_skip", "run_warm_up", "ENTRY_POINT_GROUP", "BUILTIN_METHODS",
    "available_methods", "get_method", "register_method", "method_names", "check_volume",
]

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


class Method:
    """Base class of the reconstruction methods (see the module docstring).

    A subclass sets ``name``, ``description`` and ``params`` and implements :meth:`reconstruct`; the resolved
    parameter values are in ``self.config``.

    Parameters
    ----------
    **params
        Non-default parameter values, converted and checked by their :class:`Param`.

    Raises
    ------
    InputError
        An unknown parameter name (listing the valid ones) or a value its :class:`Param` refuses.
    """

    name: ClassVar[str] = ""
    description: ClassVar[str] = ""
    params: ClassVar[dict[str, Param]] = {}

    def __init__(self, **params: Any) -> None:
        unknown = sorted(set(params) - set(self.params))
        if unknown:
            valid = ", ".join(self.params) or "(none)"
            raise InputError(f"method {self.name!r} has no parameter {unknown[0]!r}; valid parameters: {valid}")
        self.config: dict[str, Any] = {}
        for key, spec in self.params.items():
            self.config[key] = spec.convert(self.name, key, params[key]) if key in params else spec.default

    def reconstruct(self, volume: Volume) -> Reconstruction:  # pragma: no cover - abstract
        """Reconstruct the zero level set of ``volume``.

        Parameters
        ----------
        volume : Volume
            φ < 0 inside, in world coordinates.

        Returns
        -------
        Reconstruction
            A closed, outward-oriented mesh in world coordinates and the method's facts.

        Raises
        ------
        InputError
            A volume the method cannot work on (e.g. no closed zero level set: :func:`check_volume`).
        ReconstructionFailed
            The method ran but its result is not a reconstruction.
        """
        raise NotImplementedError

    def skip_reason(self, volume: Volume) -> str | None:
        """None when the method takes ``volume``, else one line saying why not.

        For an input the method cannot take by design — e.g. a mask-native method given a kind it cannot read —
        rather than a failure: the suite asks before :meth:`warm_up` and :meth:`reconstruct`, a grid records the
        cell as ``skipped`` with the reason (a row that does not count against the method) and
        ``check-method`` reports the case as skipped.  Keep it cheap (read ``volume.kind``, ``shape``, ...):
        it is not timed.  The default takes every volume.

        Parameters
        ----------
        volume : Volume
            The volume :meth:`reconstruct` would be given.

        Returns
        -------
        str or None
        """
        return None

    def warm_up(self) -> None:
        """Pay the method's one-off costs — compiling numba kernels on a tiny input, loading a model — so that
        they do not count in the timed :meth:`reconstruct` (``wall_s``).

        The suite calls it after :meth:`skip_reason` and before every timed :meth:`reconstruct`, in the same
        process (a grid cell's own process); a second call in a process should cost nothing (numba keeps what
        it compiled; ``cache=True`` keeps it on disk for the next process).  The modules of :attr:`imports` and
        :attr:`requires` are imported before it.  Its seconds are the row's
        ``phase_s["warm_up"]`` and count in the cell's time limit, not the method's.  An exception fails the
        cell as one in :meth:`reconstruct` would.  The default does nothing.
        """

    #: optional packages the method needs: {top-level module: the command that installs it}.  While one is
    #: missing the method is listed as unavailable with that command (``python -m bench methods``) and
    #: :meth:`require` — called first by ``reconstruct`` — fails in one line instead of an import traceback
    requires: ClassVar[dict[str, str]] = {}

    @classmethod
    def missing(cls) -> str | None:
        """None when every module of :attr:`requires` is installed, else one line naming the first missing
        one and the command that installs it (nothing is imported: listing the methods stays cheap)."""
        import importlib.util

        for module, command in cls.requires.items():
            if importlib.util.find_spec(module) is None:
                return f"method {cls.name!r} needs {module}, which is not installed: {command}"
        return None

    @classmethod
    def require(cls) -> None:
        """Raise :class:`InputError` with :meth:`missing`'s line when a required module is not installed."""
        message = cls.missing()
        if message:
            raise InputError(message)

    #: True for a method that reads a surface made elsewhere (``mesh_file``) instead of reconstructing the volume
    #: it is given: a grid scores its surface like any other, but ``check-method``'s cases (volumes to reconstruct)
    #: cannot judge it
    imports_surface: ClassVar[bool] = False

    #: modules :meth:`reconstruct` imports lazily (a library such as VTK takes seconds to import): the suite
    #: imports them, with those of :attr:`requires`, before the timed :meth:`reconstruct`
    #: (:func:`methods.run_warm_up`), so a method's time is its computation, not its imports
    imports: ClassVar[tuple[str, ...]] = ()

    #: rough cost of one run relative to marching cubes + scoring at the same N (the runner starts the dearest
    #: cells first, so that two workers finish together); a plug-in may set its own
    relative_cost: ClassVar[float] = 1.0

    def estimate_seconds(self, shape, n_crossing_cells: int | None = None) -> float | None:
        """The expected seconds of ``reconstruct`` on a quiet machine, for a volume of ``shape`` (a tuple, or N
        for N³) with ``n_crossing_cells`` cells crossed by the surface (None: unknown, a typical phantom assumed;
        :func:`methods.cost_model.crossing_cells` counts them); None (the default) when the method has no cost model.
        The grid runner refuses a cell whose estimate exceeds its time limit (unless ``--force``), so a method that
        cannot scale says so before it runs; :class:`methods.cost_model.PowerLaw` is the built-in models' form."""
        return None

    def __repr__(self) -> str:
        args = ", ".join(f"{k}={v!r}" for k, v in self.config.items())
        return f"{type(self).__name__}({args})"


def check_volume(volume: Volume, method: str) -> None:
    """Check that ``volume`` has a closed zero level set inside its grid, the input every method needs.

    Parameters
    ----------
    volume : Volume
        The volume to check.
    method : str
        The method's name, for the error message.

    Raises
    ------
    InputError
        Not a :class:`phantoms.Volume`, no zero crossing, or a zero level set that reaches the grid's boundary.
    """
    if not isinstance(volume, Volume):
        raise InputError(f"method {method!r}: expected a phantoms.Volume, got {type(volume).__name__}")
    if not volume.has_zero_crossing():
        raise InputError(
            f"method {method!r}: the volume has no zero crossing (values in "
            f"[{volume.values.min():.4g}, {volume.values.max():.4g}]), so there is no surface to reconstruct"
        )
    if not volume.is_closed():
        raise InputError(
            f"method {method!r}: the zero level set is open — it reaches the boundary of the grid "
            "(values <= 0 on a boundary face); enlarge the grid so the surface is closed inside it"
        )


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
