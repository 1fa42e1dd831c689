"""The typed results row: :class:`ResultRow`, one cell's row of results.csv plus the keys only its json keeps.

The row's schema has one home, here: the typed columns are the dataclass's fields, each marked with its group
(``id``: the leading columns of results.csv; ``input``: the volume's facts, placed in results.csv as the rows
first carry them; ``runner``: the method's own column; ``detail``: what a flag found, in words, placed as the
rows first carry them; ``tail``: flags, status, error; ``json``: kept in
``cells/<cell_id>.json`` only) and, where it is fixed, its kind in the typed table.  The metric columns are the
metrics registry's (:data:`bench.metrics.registry.METRICS`), held in ``metrics`` and not restated.  The column
lists :mod:`bench.run.store` writes by (:data:`ID_COLUMNS`, :data:`RUNNER_COLUMNS`, :data:`TAIL_COLUMNS`,
:data:`TEXT_COLUMNS`, :data:`JSON_ONLY`) derive from the fields.

A row is converted once: :func:`bench.run.cell.run_cell` fills a dict as its stages go and converts it at the
end (:meth:`ResultRow.from_dict` with ``strict=True``: a key that is neither a field nor a registered metric is
an error); a stored row (``cells/<cell_id>.json``'s ``row``) is converted as it is read
(:func:`bench.run.store.scan_cells`), leniently: the keys of another suite version (a metric since removed) are
kept in ``extra``.  :meth:`ResultRow.to_dict` gives the dict back exactly — same keys, same order, same
values: ``present`` records which keys the row has, in order (an absent key and one holding None differ in the
json: ``snr_achieved`` is None without noise, ``h`` is absent from a row that failed before its volume).
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields
from typing import Any

from bench.metrics.registry import METRICS

__all__ = ["ResultRow", "as_row", "ID_COLUMNS", "RUNNER_COLUMNS", "TAIL_COLUMNS", "TEXT_COLUMNS", "JSON_ONLY",
           "COLUMN_KINDS"]


def _column(group: str, kind: str | None = None, default: Any = None) -> Any:
    """A column field: its ``group`` (see the module docstring) and its fixed ``kind`` in the typed table
    (``"string"``, ``"int"``, ``"float"``, ``"bool"``; None: what the values are)."""
    return field(default=default, metadata={"group": group, "kind": kind})


@dataclass(frozen=True)
class ResultRow:
    """One cell's results row (see the module docstring); build it with :meth:`from_dict` or by its fields.

    Every column but ``cell_id`` may be missing (a row of a crashed cell has the identifying columns, status and
    error; a stored row of an older suite may lack more): a missing column is None, and absent from
    :meth:`to_dict` unless ``present`` names it.

    Parameters
    ----------
    cell_id : str
        The cell's id.
    phantom, variant, noise, method, label : str
        The cell's phantom, variant, noise kind, method and method label.
    N, seed : int
        Grid size (a user volume's native one for a cell with ``n`` 0) and seed.
    snr_requested, snr_achieved : float or None
        Requested and achieved SNR in dB (None without noise).
    parameters : str
        The method's parameters, canonical JSON.
    degrade, input_kind : str
        The input's degradation (``none``) and the kind of volume the method got (``sdf``, ``mask`` ...).
    source : str or None
        What resolved the phantom when it is not its name.
    phase_s : dict or None
        Seconds per phase of the cell (json only).
    h : float or None
        Grid spacing of the volume the method got.
    has_truth : bool or None
        Whether the phantom has a true surface.
    shape_kind : str or None
        The phantom's kind of shape (its ``shape_kind``: ``smooth solid``, ``thin shell`` ...), what the report's
        recommendation table groups inputs by; None for a user volume or a phantom that declares none (and in
        the rows of a suite version that did not record it).
    method_info : dict or None
        The method's info as plain values (json only; :func:`bench.run.cell.method_info`).
    phi_gradient : float or None
        Median |∇φ| of the volume as scored.
    stop_reason : str or None
        Why the method stopped (its info).
    artifact_error : str or None
        Why the cell's arrays were not drawn or sent (json only).
    topology_vs_data_detail : str or None
        The differences between the input's digital topology and the mesh's, ``; ``-joined (empty: none; the
        ``topology_vs_data`` flag, :mod:`bench.metrics.data_topology`).
    flags, status, error : str or None
        The result's flags (``;``-separated), ``ok`` / ``invalid`` / ``failed`` / ``timeout`` / ``skipped``, and
        what went wrong.
    estimate_s : float or None
        The cost estimate of a cell refused before it ran (:func:`bench.run.estimate.refusal`).
    cell_s, cpu_s : float or None
        Wall and CPU seconds of the whole cell (json only).
    method_output : dict or None
        What the method printed, ``{"bytes", "head"}`` (json only).
    metrics : dict
        ``{metric name: value}``, keys of the metrics registry only (others: ValueError).
    extra : dict
        Keys of a stored row that this suite does not know (kept so :meth:`to_dict` gives them back).
    present : tuple of str
        The row's keys in order (:meth:`to_dict`'s); () for the fields' order.  A column set to a value other
        than None is present whether named or not.
    """

    cell_id: str = field(metadata={"group": "id", "kind": "string"})
    phantom: str | None = _column("id", "string")
    variant: str | None = _column("id", "string")
    N: int | None = _column("id", "int")
    noise: str | None = _column("id", "string")
    snr_requested: float | None = _column("id", "float")
    snr_achieved: float | None = _column("id", "float")
    seed: int | None = _column("id", "int")
    method: str | None = _column("id", "string")
    label: str | None = _column("id", "string")
    parameters: str | None = _column("id", "string")
    degrade: str | None = _column("input")
    input_kind: str | None = _column("input")
    source: str | None = _column("input", "string")
    phase_s: dict | None = _column("json")
    h: float | None = _column("input", "float")
    has_truth: bool | None = _column("input", "bool")
    shape_kind: str | None = _column("input", "string")
    method_info: dict | None = _column("json")
    phi_gradient: float | None = _column("input")
    stop_reason: str | None = _column("runner", "string")     # (the metrics come before it in the fields' order)
    artifact_error: str | None = _column("json")
    topology_vs_data_detail: str | None = _column("detail")
    flags: str | None = _column("tail", "string")
    status: str | None = _column("tail", "string")
    error: str | None = _column("tail", "string")
    estimate_s: float | None = _column("input")
    cell_s: float | None = _column("json")
    cpu_s: float | None = _column("json")
    method_output: dict | None = _column("json")
    metrics: dict = field(default_factory=dict)
    extra: dict = field(default_factory=dict)
    present: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        if not isinstance(self.cell_id, str):
            raise TypeError(f"a row's cell_id is a string, not {type(self.cell_id).__name__}")
        unknown = [k for k in self.metrics if k not in METRICS]
        if unknown:
            raise ValueError(f"not a registered metric: {', '.join(map(repr, unknown))} (bench.metrics.registry)")
        clash = [k for k in self.extra if k in _FIELDS or k in METRICS]
        if clash:
            raise ValueError(f"extra keys that are columns: {', '.join(map(repr, clash))}")
        named = set(self.present)
        stray = [k for k in named if k not in _FIELDS and k not in self.metrics and k not in self.extra]
        if stray:
            raise ValueError(f"present names keys the row has no value for: {', '.join(map(repr, stray))}")
        held = tuple(k for k in self._held(ids=not self.present) if k not in named)
        if held:
            object.__setattr__(self, "present", tuple(self.present) + held)

    def _held(self, ids: bool) -> list[str]:
        """The keys this row holds a value other than None for, in the fields' order (the metrics before
        ``stop_reason``); with ``ids`` the identifying columns whatever their value, as :func:`run_cell`
        writes them (``source`` only when set)."""
        keys: list[str] = []
        for name in _FIELDS:
            if name == "stop_reason":
                keys += list(self.metrics)
            if getattr(self, name) is not None or (ids and name in ID_COLUMNS):
                keys.append(name)
        return keys + list(self.extra)

    def has(self, name: str) -> bool:
        """Whether the row has the key ``name`` (a column or metric), None-valued or not.

        Parameters
        ----------
        name : str
            A column name.
        """
        return name in self.present

    def value(self, name: str, default: Any = None) -> Any:
        """The value of column or metric ``name`` (``dict.get`` on :meth:`to_dict`); ``default`` when absent.

        Parameters
        ----------
        name : str
            A column name (a field, a metric or an extra key).
        default : Any
            What an absent key gives.
        """
        if name not in self.present:
            return default
        if name in _FIELDS:
            return getattr(self, name)
        if name in self.metrics:
            return self.metrics[name]
        return self.extra.get(name, default)

    def to_dict(self) -> dict[str, Any]:
        """The row as the plain dict the cell's json stores and results.csv is written from: the keys of
        ``present``, in its order.

        Returns
        -------
        dict
        """
        fields_, metrics, extra = self.__dict__, self.metrics, self.extra    # (written for speed: tables of 1e4 rows)
        return {k: fields_[k] if k in _FIELDS else metrics[k] if k in metrics else extra[k] for k in self.present}

    def updated(self, values: dict | None = None, **more: Any) -> ResultRow:
        """A copy with ``values`` and ``more`` set as ``dict.update`` sets them (a new key goes last).

        Parameters
        ----------
        values : dict, optional
            Keys and values (a metric name need not be an identifier).
        **more
            Further keys and values.

        Returns
        -------
        ResultRow

        Raises
        ------
        ValueError
            A new key is neither a field nor a registered metric.
        """
        d = self.to_dict()
        new = {**(values or {}), **more}
        unknown = [k for k in new if k not in d and k not in _FIELDS and k not in METRICS]
        if unknown:
            raise ValueError(f"not a column of a results row: {', '.join(map(repr, unknown))}")
        d.update(new)
        return ResultRow.from_dict(d)

    @classmethod
    def from_dict(cls, d: dict, strict: bool = False) -> ResultRow:
        """A row from its dict form (:meth:`to_dict`, a stored record's ``row``, or one built by a stage).

        Parameters
        ----------
        d : dict
            The row's keys; ``cell_id`` is required.
        strict : bool
            Refuse a key that is neither a field nor a registered metric (a stage's own row); otherwise such
            keys are kept in ``extra`` (a stored row of another suite version).

        Returns
        -------
        ResultRow

        Raises
        ------
        KeyError
            ``cell_id`` is missing.
        ValueError
            ``strict`` and an unknown key.
        """
        if "cell_id" not in d:
            raise KeyError("a results row needs cell_id")
        known = {k: v for k, v in d.items() if k in _FIELDS}
        metrics = {k: v for k, v in d.items() if k in METRICS}
        extra = {k: v for k, v in d.items() if k not in known and k not in metrics}
        if strict and extra:
            raise ValueError(f"not a column of a results row: {', '.join(map(repr, extra))} (neither a field of "
                             "ResultRow nor a metric of bench.metrics.registry)")
        return cls(**known, metrics=metrics, extra=extra, present=tuple(d))


def as_row(row: ResultRow | dict) -> ResultRow:
    """``row`` as a :class:`ResultRow` (a dict is read with :meth:`ResultRow.from_dict`).

    Parameters
    ----------
    row : ResultRow or dict
        A row or its dict form.
    """
    return row if isinstance(row, ResultRow) else ResultRow.from_dict(row)


_COLUMN_FIELDS = [f for f in fields(ResultRow) if "group" in f.metadata]
#: the row's column fields, in order (the rest: metrics, extra, present)
_FIELDS = {f.name: f for f in _COLUMN_FIELDS}
if set(_FIELDS) & set(METRICS):  # pragma: no cover — a registry edit that would make a column ambiguous
    raise ImportError(f"ResultRow fields named like registered metrics: {sorted(set(_FIELDS) & set(METRICS))}")


def _group(name: str) -> list[str]:
    return [f.name for f in _COLUMN_FIELDS if f.metadata["group"] == name]


#: the leading columns of results.csv (then every metric, then the runner's columns, then the tail)
ID_COLUMNS = _group("id")
#: columns the runner fills from the method's info and the cost measurement: the registry's runner metrics and
#: ``stop_reason`` after ``energy_final``
RUNNER_COLUMNS = [c for k, m in METRICS.items() if m.kind == "runner"
                  for c in ([k, *_group("runner")] if k == "energy_final" else [k])]
#: the last columns of results.csv
TAIL_COLUMNS = _group("tail")
#: row keys kept in the cell's json but not in results.csv
JSON_ONLY = tuple(_group("json"))
#: columns stored as text (everything else is typed by :data:`COLUMN_KINDS`, the metric registry, or by what
#: the values are)
TEXT_COLUMNS = tuple(f.name for f in _COLUMN_FIELDS if f.metadata["kind"] == "string")
#: the fixed kinds of the other typed columns
COLUMN_KINDS = {f.name: f.metadata["kind"] for f in _COLUMN_FIELDS if f.metadata["kind"] not in (None, "string")}
