"""What a method must return and how the suite calls it: :class:`Reconstruction`, the ``info`` keys the suite
reads (:data:`INFO_KEYS`, type-checked by :func:`check_info`), the checks of a returned value
(:func:`as_reconstruction`), the guarded call (:func:`run_reconstruct`) and the two optional hooks the suite
calls first: :meth:`Method.skip_reason <methods.base.Method.skip_reason>` (:func:`check_skip`) and
:meth:`Method.warm_up <methods.base.Method.warm_up>` (:func:`run_warm_up`).  The suite imports its calls from
here; the package :mod:`methods` exports only what a method author uses (:class:`Reconstruction`, the exceptions a
method raises, :data:`INFO_KEYS`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
import trimesh

from phantoms import InputError, Volume

__all__ = ["INFO_KEYS", "Reconstruction", "ReconstructionFailed", "WrongReturnType", "MethodSkipped",
           "as_reconstruction", "check_info", "run_reconstruct", "check_skip", "run_warm_up"]


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
    """A method ran but its result is not a reconstruction (collapsed, far from φ = 0, ...).

    The message says why.  The command line prints it as one line (exit code 1); a grid run records it as a
    failed cell.
    """


@dataclass
class Reconstruction:
    """What a method returns: the mesh and facts about how it was made.

    Parameters
    ----------
    mesh : trimesh.Trimesh
        A closed, outward-oriented triangle mesh in world coordinates.
    info : dict
        The method's facts as plain Python/numpy values; the keys the suite reads are documented in
        :data:`INFO_KEYS` (and checked by :func:`check_info`).
    """

    mesh: trimesh.Trimesh
    info: dict = field(default_factory=dict)


class WrongReturnType(ReconstructionFailed, TypeError):
    """A method returned something other than a :class:`Reconstruction` of a ``trimesh.Trimesh`` and a dict.

    An ``info`` value of :data:`INFO_KEYS` of the wrong type, or a ``sys.exit()`` instead of a return, counts.
    """


def as_reconstruction(result: Any, name: str) -> Reconstruction:
    """Check that ``result`` is what a method must return.

    Parameters
    ----------
    result : object
        What the method's ``reconstruct`` returned.
    name : str
        The method's name, for the error message.

    Returns
    -------
    Reconstruction
        ``result`` itself: a :class:`Reconstruction` holding a ``trimesh.Trimesh`` and an ``info`` dict.

    Raises
    ------
    WrongReturnType
        Naming the method and what it returned (see :func:`check_info` for the ``info`` values).
    """
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
    """Check the types of the :data:`INFO_KEYS` values the suite reads; the method's own keys are not checked.

    A wrong type would be read wrongly downstream: ``warnings = "text"`` as one warning per character,
    ``iterations = "many"`` as a text in an integer column.

    Parameters
    ----------
    info : dict
        A :attr:`Reconstruction.info`.
    name : str
        The method's name, for the error message.

    Raises
    ------
    WrongReturnType
        Naming the key, its value and the type expected.
    """
    for key, (ok, what) in _INFO_TYPES.items():
        value = info.get(key)
        if value is not None and not ok(value):
            shown = repr(value) if len(repr(value)) <= 60 else repr(value)[:57] + "..."
            raise WrongReturnType(f"method {name!r} returned info[{key!r}] = {shown} "
                                  f"({type(value).__name__}), expected {what}")


def run_reconstruct(method, volume: Volume) -> Any:
    """Call ``method.reconstruct(volume)``, turning a ``sys.exit()`` inside the method, or a write to its
    input, into an error.

    A plug-in must not end the suite's process (``reconstruct`` exiting 0 with no output, a grid worker gone
    without a row).  Nor may it change the volume it was given: ``values`` is a read-only view, but a method
    can still turn the flag back on, write through the array's base, or rebind ``values``, ``origin`` or
    ``spacing`` — and its mesh would then be checked against the φ it made up.  A fingerprint of the volume
    (the arrays' CRC-32, the geometry, the kind and level) taken before the call is compared after it, and the
    volume's cached interpolation grids (derived, writeable) are dropped, so the suite's checks rebuild them.

    Parameters
    ----------
    method : Method
        The method instance.
    volume : Volume
        The volume to reconstruct.

    Returns
    -------
    object
        What ``reconstruct`` returned, unchecked (:func:`as_reconstruction` checks it).

    Raises
    ------
    WrongReturnType
        The method called ``sys.exit()`` or changed its input volume; any other exception of the method
        propagates unchanged.
    """
    before = _fingerprint(volume)
    try:
        out = method.reconstruct(volume)
    except SystemExit as exc:
        raise WrongReturnType(f"method {method.name!r} called sys.exit({exc.code!r}) instead of returning "
                                   "a Reconstruction or raising an exception") from None
    finally:
        if hasattr(volume, "forget_derived"):
            volume.forget_derived()         # grids the method was handed may have been written to: rebuild them
    changed = [name for name, value in _fingerprint(volume).items() if value != before[name]]
    if changed:
        raise WrongReturnType(f"method {method.name!r} changed its input volume ({', '.join(changed)}): the "
                              "volume is read-only — copy what you need to change")
    return out


_VOLUME_PARTS = ("values", "raw", "origin", "spacing", "kind", "level")


def _fingerprint(volume) -> dict[str, object]:
    """What a method must leave as it found it: per attribute of :data:`_VOLUME_PARTS`, the object's identity
    and the CRC-32 of its bytes (an array) or its value."""
    import zlib

    out: dict[str, object] = {}
    for name in _VOLUME_PARTS:
        value = getattr(volume, name, None)
        if isinstance(value, np.ndarray):
            try:
                data = value if value.flags.c_contiguous else np.ascontiguousarray(value)
                out[name] = (id(value), value.shape, value.dtype.str, zlib.crc32(data.view(np.uint8)))
            except (TypeError, ValueError):
                out[name] = (id(value), repr(value))
        else:
            out[name] = (id(value), repr(value))
    return out


class MethodSkipped(InputError):
    """The method declines its input: its :meth:`~methods.base.Method.skip_reason` gave ``reason``.

    Not a failure of the method: a grid records the cell as ``skipped`` with the reason, ``check-method`` as a
    skipped case, ``reconstruct`` as one line (exit 2, as other bad input).

    Parameters
    ----------
    method : str
        The method's name.
    reason : str
        Why it cannot take the input, one line.
    """

    def __init__(self, method: str, reason: str) -> None:
        super().__init__(f"method {method!r} skips this input: {reason}")
        self.method, self.reason = method, reason

    def __reduce__(self):          # sent between processes (a grid cell, check-method's forked cases)
        return type(self), (self.method, self.reason)


def check_skip(method, volume: Volume) -> None:
    """Ask ``method.skip_reason(volume)`` whether the method takes ``volume``; raise if it does not.

    Parameters
    ----------
    method : Method
        The method instance.
    volume : Volume
        The volume it would be given.

    Raises
    ------
    MethodSkipped
        ``skip_reason`` gave a reason (its whitespace joined into one line).
    WrongReturnType
        ``skip_reason`` returned something other than None or a non-empty str, or called ``sys.exit()``; any
        other exception of it propagates unchanged.
    """
    try:
        reason = method.skip_reason(volume)
    except SystemExit as exc:
        raise WrongReturnType(f"method {method.name!r} called sys.exit({exc.code!r}) in skip_reason") from None
    if reason is None:
        return
    if not isinstance(reason, str) or not reason.strip():
        raise WrongReturnType(f"method {method.name!r}: skip_reason returned {reason!r}, expected None (the "
                              "method takes the volume) or a non-empty str saying why not")
    raise MethodSkipped(method.name, " ".join(reason.split()))


def run_warm_up(method) -> None:
    """Import the method's libraries (:attr:`Method.imports` and :attr:`Method.requires`), then call
    ``method.warm_up()`` — its one-off costs, paid before the timed ``reconstruct``.  A module that cannot be
    imported is left to ``reconstruct``, whose :meth:`Method.require` names it.

    Parameters
    ----------
    method : Method
        The method instance.

    Raises
    ------
    WrongReturnType
        ``warm_up`` called ``sys.exit()``; any other exception of it propagates unchanged.
    """
    import importlib

    for module in (*getattr(method, "requires", {}), *getattr(method, "imports", ())):
        try:
            importlib.import_module(module)
        except ImportError:
            pass
    try:
        method.warm_up()
    except SystemExit as exc:
        raise WrongReturnType(f"method {method.name!r} called sys.exit({exc.code!r}) in warm_up") from None
