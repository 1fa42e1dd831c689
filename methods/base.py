"""The one small interface every reconstruction method implements, and the method registry.

A method is a subclass of :class:`Method` with

* ``name`` – the registry name (``python -m bench methods`` lists it);
* ``description`` – one line;
* ``params`` – a dict ``name -> Param(default, doc, ...)``: every tunable parameter, documented, with its default;
* ``reconstruct(volume) -> Reconstruction`` – a closed, outward-oriented triangle mesh in world coordinates.

Methods never import the benchmark (``bench``): they see a :class:`phantoms.Volume` and return a mesh.
User methods are found through the entry-point group ``levelset_bench.methods`` (see README, "Adding a
method"); each entry point names a :class:`Method` subclass.
"""

from __future__ import annotations

import importlib
from dataclasses import dataclass, field
from importlib import metadata
from typing import Any, ClassVar

import numpy as np
import trimesh

from phantoms import InputError, Volume

__all__ = [
    "Param", "Method", "Reconstruction", "ReconstructionFailed", "WrongReturnType", "as_reconstruction", "check_info", "run_reconstruct", "INFO_KEYS", "ENTRY_POINT_GROUP", "BUILTIN_METHODS",
    "available_methods", "get_method", "register_method", "method_names", "check_volume",
]

ENTRY_POINT_GROUP = "levelset_bench.methods"

#: built-in methods: name -> "module:Class" (imported lazily so one broken adapter cannot break the rest)
BUILTIN_METHODS: dict[str, str] = {
    "shape_gradient": "methods.shape_gradient:ShapeGradient",
    "marching_cubes": "methods.marching_cubes:MarchingCubes",
    "mc_taubin": "methods.mc_taubin:MCTaubin",
    "distmesh": "methods.distmesh:DistMesh",
    "poisson": "methods.poisson:ScreenedPoisson",
    "reach_for_the_spheres": "methods.reach_for_the_spheres:ReachForTheSpheres",
    "dual_contouring": "methods.dual_contouring:DualContouring",
    "flying_edges": "methods.flying_edges:FlyingEdges",
}


@dataclass(frozen=True)
class Param:
    """A documented method parameter.

    ``type`` is the Python type values are converted to (bool, int, float, str, or ``object`` for free-form
    values such as a mesh); ``choices`` restricts the value to a set; ``min``/``max`` bound numbers
    (inclusive).
    """

    default: Any
    doc: str
    type: type = float
    choices: tuple | None = None
    min: float | None = None
    max: float | None = None

    def convert(self, method: str, name: str, value: Any) -> Any:
        """Convert/validate ``value`` (strings from the command line included); InputError on failure."""
        where = f"method {method!r}, parameter {name!r}"
        t = self.type
        if self.default is None and (value is None or (isinstance(value, str)
                                                         and value.strip().lower() in ("none", "auto", ""))):
            return None  # a parameter whose default is None ("auto") accepts None/'none'/'auto' back
        try:
            if t is bool:
                if isinstance(value, str):
                    low = value.strip().lower()
                    if low in ("1", "true", "yes", "on"):
                        value = True
                    elif low in ("0", "false", "no", "off"):
                        value = False
                    else:
                        raise ValueError(value)
                elif not isinstance(value, (bool, np.bool_)):
                    raise ValueError(value)
                value = bool(value)
            elif t is int:
                if isinstance(value, bool):
                    raise ValueError(value)
                f = float(value)
                if f != int(f):
                    raise ValueError(value)
                value = int(f)
            elif t is float:
                if isinstance(value, bool):
                    raise ValueError(value)
                value = float(value)
                if not np.isfinite(value):
                    raise ValueError(value)
            elif t is str:
                if not isinstance(value, str):
                    raise ValueError(value)
        except (TypeError, ValueError):
            raise InputError(f"{where}: expected {t.__name__}, got {value!r}") from None
        if self.choices is not None and value not in self.choices:
            raise InputError(f"{where}: {value!r} is not one of {list(self.choices)}")
        if self.min is not None and value < self.min:
            raise InputError(f"{where}: {value!r} is below the minimum {self.min}")
        if self.max is not None and value > self.max:
            raise InputError(f"{where}: {value!r} is above the maximum {self.max}")
        return value


#: The ``Reconstruction.info`` keys the suite reads, and what it does with them.  Every other key is the
#: method's own fact: ``reconstruct`` prints it, a grid run keeps it in the cell's json (``row.method_info``)
#: and the report lists it; it is not a results.csv column.
INFO_KEYS: dict[str, str] = {
    "iterations": "int: iterations the method ran (results.csv column `iterations`)",
    "stop_reason": "str: why it stopped, e.g. converged | max_iter | line_search_floor | diverged "
                   "(results.csv column `stop_reason`)",
    "stop_message": "str: one line of detail on the stop (printed by `reconstruct`)",
    "energy_history": "1-D floats: the energy per iteration, entry 0 = the initial surface (the report's energy "
                      "curve; its last entry is the results.csv column `energy_final`)",
    "energy_final": "float: the final energy, when there is no energy_history",
    "warnings": "list of str: things the user must know about this result (e.g. the target's topology cannot be "
                "reached); `reconstruct` prints each as a warning line",
    "snapshots": "{iteration: vertices (V, 3) of the final mesh's faces, or (vertices, faces)}: the report's "
                 "rows of an iterative method; iteration 0 is the initial surface",
}


class ReconstructionFailed(RuntimeError):
    """A method ran but its result is not a reconstruction (collapsed, far from φ = 0, ...): the message says why.
    The command line prints it as one line (exit code 1); a grid run records it as a failed cell."""


@dataclass
class Reconstruction:
    """What a method returns: the mesh and facts about how it was made.

    ``mesh`` is a closed, outward-oriented ``trimesh.Trimesh`` in world coordinates.  ``info`` holds the
    method's facts as plain Python/numpy values; the keys the suite reads are documented in :data:`INFO_KEYS`.
    """

    mesh: trimesh.Trimesh
    info: dict = field(default_factory=dict)


class WrongReturnType(ReconstructionFailed, TypeError):
    """A method returned something other than a :class:`Reconstruction` of a ``trimesh.Trimesh`` and a dict (an
    ``info`` value of :data:`INFO_KEYS` of the wrong type, or a ``sys.exit()`` instead of a return, included)."""


def as_reconstruction(result: Any, name: str) -> Reconstruction:
    """``result`` if it is what a method must return (a :class:`Reconstruction` holding a ``trimesh.Trimesh``
    and an ``info`` dict); else :class:`WrongReturnType` naming the method and what it returned."""
    if not isinstance(result, Reconstruction):
        raise WrongReturnType(f"method {name!r} returned {type(result).__name__}, expected methods.Reconstruction "
                              "(return Reconstruction(mesh, info))")
    if not isinstance(result.mesh, trimesh.Trimesh):
        raise WrongReturnType(f"method {name!r} returned a Reconstruction whose mesh is "
                              f"{type(result.mesh).__name__}, expected trimesh.Trimesh")
    if not isinstance(result.info, dict):
        raise WrongReturnType(f"method {name!r} returned a Reconstruction whose info is "
                              f"{type(result.info).__name__}, expected dict")
    check_info(result.info, name)
    return result


def _is_int(v: Any) -> bool:
    return isinstance(v, (int, np.integer)) and not isinstance(v, (bool, np.bool_))


def _is_real(v: Any) -> bool:
    return isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(v, (bool, np.bool_))


# the INFO_KEYS the suite reads as scalars: (test, what the key must be); None is "not given"
_INFO_TYPES = {
    "iterations": (_is_int, "an int"),
    "stop_reason": (lambda v: isinstance(v, str), "a str"),
    "stop_message": (lambda v: isinstance(v, str), "a str"),
    "energy_final": (_is_real, "a real number"),
    "warnings": (lambda v: isinstance(v, (list, tuple)) and all(isinstance(w, str) for w in v), "a list of str"),
}


def check_info(info: dict, name: str) -> None:
    """:class:`WrongReturnType` naming the key when a value of :data:`INFO_KEYS` the suite reads has the wrong
    type (``warnings = "text"`` would be one warning per character, ``iterations = "many"`` a text in an integer
    column).  Keys of the method's own are not checked."""
    for key, (ok, what) in _INFO_TYPES.items():
        value = info.get(key)
        if value is not None and not ok(value):
            shown = repr(value) if len(repr(value)) <= 60 else repr(value)[:57] + "..."
            raise WrongReturnType(f"method {name!r} returned info[{key!r}] = {shown} "
                                  f"({type(value).__name__}), expected {what}")


def run_reconstruct(method: "Method", volume: Volume) -> Any:
    """``method.reconstruct(volume)``, with a ``sys.exit()`` inside the method turned into a
    :class:`WrongReturnType` naming it: a plug-in must not end the suite's process (``reconstruct`` exiting
    0 with no output, a grid worker gone without a row)."""
    try:
        return method.reconstruct(volume)
    except SystemExit as exc:
        raise WrongReturnType(f"method {method.name!r} called sys.exit({exc.code!r}) instead of returning "
                                   "a Reconstruction or raising an exception") from None


class Method:
    """Base class of the reconstruction methods (see the module docstring)."""

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
            value = params.get(key, spec.default)
            self.config[key] = spec.convert(self.name, key, value) if key in params else spec.default

    def reconstruct(self, volume: Volume) -> Reconstruction:  # pragma: no cover - abstract
        raise NotImplementedError

    #: rough cost of one run relative to marching cubes + scoring at the same N (the runner starts the dearest
    #: cells first, so that two workers finish together); a plug-in may set its own
    relative_cost: ClassVar[float] = 1.0

    def estimate_seconds(self, shape, n_crossing_cells: int | None = None) -> float | None:
        """The expected seconds of ``reconstruct`` on a quiet machine, for a volume of ``shape`` (a tuple, or N
        for N³) with ``n_crossing_cells`` cells crossed by the surface (None: unknown, a typical phantom assumed;
        :func:`methods.cost.crossing_cells` counts them); None (the default) when the method has no cost model.  The grid runner refuses a cell whose
        estimate exceeds its time limit (unless ``--force``), so a method that cannot scale says so before it
        runs; :class:`methods.cost.PowerLaw` is the built-in models' form."""
        return None

    def __repr__(self) -> str:
        args = ", ".join(f"{k}={v!r}" for k, v in self.config.items())
        return f"{type(self).__name__}({args})"


def check_volume(volume: Volume, method: str) -> None:
    """Raise InputError (naming ``method``) when ``volume`` has no closed zero level set inside the grid."""
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


def register_method(cls: type[Method]) -> type[Method]:
    """Register a Method subclass under ``cls.name`` (the code path entry points also take). Usable as a decorator."""
    if not (isinstance(cls, type) and issubclass(cls, Method)) or not cls.name:
        raise InputError(f"{cls!r} is not a Method subclass with a name")
    _REGISTERED[cls.name] = cls
    return cls


def import_plugins(modules) -> None:
    """Import each module named in ``modules`` (in order), e.g. ones that call :func:`register_method`.

    Any failure to import (missing module, an exception the module raises) is the user's to fix: it is
    raised as :class:`phantoms.InputError` ``cannot import module 'name': <the error>``.
    """
    for mod in modules:
        try:
            importlib.import_module(mod)
        except Exception as exc:  # noqa: BLE001 - whatever the module raised, the user names the module
            raise InputError(f"cannot import module {mod!r}: {exc}") from None


def _load(target: str) -> type[Method]:
    module, _, attr = target.partition(":")
    return getattr(importlib.import_module(module), attr)


def available_methods() -> dict[str, type[Method]]:
    """Every method: the built-ins, then entry points of group ``levelset_bench.methods``, then registered ones.

    A built-in or plug-in that fails to import is skipped with a warning rather than breaking the others.
    """
    import warnings

    out: dict[str, type[Method]] = {}
    for name, target in BUILTIN_METHODS.items():
        try:
            out[name] = _load(target)
        except (ImportError, AttributeError) as exc:
            warnings.warn(f"built-in method {name!r} unavailable: {exc}", stacklevel=2)
    for ep in metadata.entry_points(group=ENTRY_POINT_GROUP):
        try:
            cls = ep.load()
        except Exception as exc:  # a broken plug-in must not take the suite down
            warnings.warn(f"plug-in method {ep.name!r} ({ep.value}) failed to load: {exc}", stacklevel=2)
            continue
        if isinstance(cls, type) and issubclass(cls, Method):
            out[cls.name or ep.name] = cls
        else:
            warnings.warn(f"plug-in {ep.name!r} ({ep.value}) is not a methods.Method subclass", stacklevel=2)
    out.update(_REGISTERED)
    return out


def method_names() -> list[str]:
    return list(available_methods())


def get_method(name: str, **params: Any) -> Method:
    """An instance of the method called ``name`` with ``params``; InputError for unknown names/parameters."""
    methods = available_methods()
    if name not in methods:
        raise InputError(f"unknown method {name!r}; valid methods: {', '.join(methods)}")
    return methods[name](**params)
