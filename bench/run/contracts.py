"""The typed contracts between the run's stages: a :class:`Cell` (grid → executor → cell) and a
:class:`CellResult` (cell → executor → runner → store), whose row is a :class:`~bench.run.row.ResultRow`.

Both are frozen dataclasses, so a stage cannot change what the next one receives by accident, and a typo in a
field name is an ``AttributeError`` at once instead of a ``KeyError`` (or a silent ``.get`` default) stages
later.  Plain dicts exist only at the storage boundary: :meth:`Cell.to_dict` is exactly the dict a cell record
stores (``cells/<cell_id>.json``) and :func:`bench.run.grid.cell_id` hashes, so the ids and the run folders of
earlier runs stay valid; :meth:`Cell.from_dict` reads such a dict back (also one written by an earlier run).
Both pickle as they are, which is how executors ship them to worker processes and Dask workers.
"""

from __future__ import annotations

from dataclasses import MISSING, dataclass, field, fields, replace
from typing import Any

from .row import ResultRow

__all__ = ["Cell", "CellResult", "ResultRow"]

#: the optional keys a cell dict carries only when set, and where expand_grid puts them
_OPTIONAL = ("source", "input", "method_code", "degrade")


@dataclass(frozen=True)
class Cell:
    """Everything needed to compute one result from nothing (see :func:`bench.run.grid.expand_grid`).

    ``params`` is the method's parameter dict; it is handed to the method as it is, so do not change it in
    place (the dataclass freezes its attributes, not the dicts they hold).

    Parameters
    ----------
    phantom : str
        The phantom's name (for a file phantom, the file's stem).
    variant : str
        The phantom's volume variant (e.g. ``sdf``).
    n : int
        Grid size N (0: a user volume on its native grid).
    extent : float
        Half-width of the sampled box.
    noise : str
        The noise kind (``none``, ``gaussian``, ...).
    snr_requested : float or None
        Requested SNR in dB (None for noise ``none``).
    seed : int
        Seed of the noise and of the metric sampling.
    method : str
        The registered method name.
    label : str
        The method instance's label (unique in a grid).
    params : dict
        The method's parameters, phantom-specific ones applied.
    n_samples : int
        Surface samples the metrics use.
    imports : tuple of str
        Plug-in modules to import before the method is looked up.
    cell_id : str
        The cell's id (:func:`bench.run.grid.cell_id`; :func:`bench.run.grid.as_cell` computes it when a dict
        lacks it).
    source : str, optional
        What resolves the phantom when it is not its name (a file of a dataset glob).
    input : str, optional
        Fingerprint of a file phantom's files (part of the id).
    method_code : dict, optional
        A plug-in method's code fingerprint (:func:`bench.run.method_code.method_fingerprint`; not in the id).
    degrade : str, optional
        The degradation of the phantom's volume (:func:`phantoms.parse_degradation`, e.g. ``thick_slices@3+mask``);
        None or absent: the volume as the variant gives it.
    extra : dict
        Keys of a stored cell dict this suite does not know (kept so :meth:`to_dict` gives them back).
    """

    phantom: str
    variant: str
    n: int
    extent: float
    noise: str
    snr_requested: float | None
    seed: int
    method: str
    label: str
    params: dict
    n_samples: int
    imports: tuple[str, ...] = ()
    cell_id: str = ""
    source: str | None = None
    input: str | None = None
    method_code: dict | None = None
    degrade: str | None = None
    extra: dict = field(default_factory=dict, compare=False, repr=False)

    def to_dict(self) -> dict[str, Any]:
        """The cell as the plain dict the run folder stores and :func:`~bench.run.grid.cell_id` hashes: the keys
        in expand_grid's order, the optional ones only when set, ``imports`` a list.

        Returns
        -------
        dict
        """
        d: dict[str, Any] = {"phantom": self.phantom}
        if self.source is not None:
            d["source"] = self.source
        if self.input is not None:
            d["input"] = self.input
        if self.degrade is not None:
            d["degrade"] = self.degrade
        d.update(variant=self.variant, n=self.n, extent=self.extent, noise=self.noise,
                 snr_requested=self.snr_requested, seed=self.seed, method=self.method, label=self.label,
                 params=self.params, n_samples=self.n_samples, imports=list(self.imports))
        if self.method_code is not None:
            d["method_code"] = self.method_code
        if self.cell_id:
            d["cell_id"] = self.cell_id
        d.update({k: v for k, v in self.extra.items() if k not in d})
        return d

    @classmethod
    def from_dict(cls, d: dict) -> Cell:
        """A cell from its dict form (:meth:`to_dict`, a stored record's ``cell``, or one a user wrote).

        Parameters
        ----------
        d : dict
            The cell's keys.  ``imports``, ``cell_id`` and the optional keys may be missing; unknown keys are
            kept in ``extra``.

        Returns
        -------
        Cell

        Raises
        ------
        KeyError
            A required key (phantom, variant, n, extent, noise, snr_requested, seed, method, label, params,
            n_samples) is missing.
        """
        missing = [f.name for f in fields(cls)
                   if f.default is MISSING and f.default_factory is MISSING and f.name not in d]
        if missing:
            raise KeyError(f"a cell needs {', '.join(missing)}")
        names = {f.name for f in fields(cls)} - {"extra"}
        known = {k: v for k, v in d.items() if k in names}
        known["imports"] = tuple(known.get("imports") or ())
        return cls(**known, extra={k: v for k, v in d.items() if k not in names})


@dataclass(frozen=True)
class CellResult:
    """What computing a cell gave (:func:`bench.run.cell.run_cell`, or an executor's failed / timeout result).

    Parameters
    ----------
    row : ResultRow
        The cell's results.csv row (plus the json-only keys: ``cell_s``, ``phase_s``, ``method_info`` ...); a dict
        is converted with :meth:`ResultRow.from_dict` (``strict``: a key that is no column is an error).
    artifacts : dict
        ``{name: array}`` the report draws (written to ``cells/<cell_id>.npz``); {} when there are none.
    traceback : str or None
        The traceback of a failing cell.
    """

    row: ResultRow
    artifacts: dict = field(default_factory=dict)
    traceback: str | None = None

    def __post_init__(self) -> None:
        if isinstance(self.row, dict):
            object.__setattr__(self, "row", ResultRow.from_dict(self.row, strict=True))

    def with_row(self, values: dict | None = None, **more: Any) -> CellResult:
        """A copy whose row has ``values`` and ``more`` set (:meth:`ResultRow.updated`).

        Parameters
        ----------
        values : dict, optional
            Keys and values for the row.
        **more
            Further keys and values.

        Returns
        -------
        CellResult
        """
        return replace(self, row=self.row.updated(values, **more))

    def to_dict(self) -> dict[str, Any]:
        """``{"row", "artifacts", "traceback"}``: the result as the plain dict earlier versions passed around (the
        row's dict form: :meth:`ResultRow.to_dict`).

        Returns
        -------
        dict
        """
        return {"row": self.row.to_dict(), "artifacts": self.artifacts, "traceback": self.traceback}

    @classmethod
    def from_dict(cls, d: dict) -> CellResult:
        """A result from its dict form (:meth:`to_dict`).

        Parameters
        ----------
        d : dict
            ``row`` (required: a :class:`ResultRow` or its dict form), ``artifacts`` and ``traceback`` (optional).

        Returns
        -------
        CellResult
        """
        return cls(row=d["row"], artifacts=d.get("artifacts") or {}, traceback=d.get("traceback"))
