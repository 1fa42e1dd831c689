"""The method author's interface: :class:`Method`, the class every reconstruction method subclasses, and
:func:`check_volume`, the input check every method needs.

Required of a subclass:

* ``name`` – the registry name (``python -m bench methods`` lists it);
* ``description`` – one line;
* ``params`` – a dict ``name -> Param(default, doc, ...)`` (:class:`methods.params.Param`): every tunable
  parameter, documented, with its default; the resolved values are ``self.config``;
* ``reconstruct(volume) -> Reconstruction`` – a closed, outward-oriented triangle mesh in world coordinates
  (what it must return and how the suite checks it: :mod:`methods.contract`); abstract here.

Optional (each with a default that does nothing or asks nothing):

* ``skip_reason(volume)`` – one line when the method cannot take an input by design (the cell is ``skipped``,
  not failed);
* ``warm_up()`` – one-off costs (compiling kernels, loading a model) paid before ``reconstruct`` is timed;
* ``imports`` – modules ``reconstruct`` imports lazily, imported by the suite before the timed call;
* ``requires`` – optional packages and the command that installs each (:meth:`Method.missing`,
  :meth:`Method.require`);
* ``estimate_seconds(shape, n_crossing_cells)`` – a cost model (:class:`methods.cost_model.PowerLaw`), so a grid
  refuses a cell that cannot finish in its time limit;
* ``relative_cost`` – the run's cost relative to marching cubes, for scheduling;
* ``imports_surface`` – True for a method that reads a surface made elsewhere instead of reconstructing.

Methods never import the benchmark (``bench``): they see a :class:`phantoms.Volume` and return a mesh.  A
method is registered with :func:`methods.register_method` or installed as an entry point of group
``levelset_bench.methods`` (:mod:`methods.registry`; README, "Adding a method").
"""

from __future__ import annotations

import abc
from typing import Any, ClassVar

from phantoms import InputError, Volume

from .contract import Reconstruction
from .params import Param

__all__ = ["Method", "check_volume"]


class Method(abc.ABC):
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

    @abc.abstractmethod
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
    #: (:func:`methods.contract.run_warm_up`), so a method's time is its computation, not its imports
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
