"""Suspect results: a valid mesh (bench.metrics.validity) can still be doubtful.  The ``flags`` column holds,
``;``-separated:

* ``topology_mismatch`` — the mesh's Euler characteristic or number of components differs from the truth's
  (a phantom knows its own: ``genus`` and ``n_components``; one component unless it says otherwise);
* ``dropped_components`` — fewer components than the truth (a method that kept only its largest part);
* ``self_intersecting`` — at least one pair of non-adjacent faces intersects;
* ``missing_parts`` — more than 0.5 % of the true surface lies farther than 2 h from the mesh (``coverage_pct``
  below 99.5): a part of the object is missing, whatever the method says (a dropped limb, an eroded thin part);
* ``not_converged`` — the method stopped on ``max_iter``, ``line_search_floor``, ``diverged`` or
  ``sign_guard`` (the shape gradient rolled back to a checkpoint: its result is an early iterate).  A run with
  no convergence test that ran its full count (``stop_reason = fixed_iterations``, the paper's presets) is not
  flagged: the count is its design.
* ``inside_disagrees`` — without a ground truth only: more than :data:`MAX_SIGN_ERR_PCT` % of the grid samples
  with |φ| > h/2 lie on the other side of the mesh (``sign_err_pct``): the mesh fills what the data says is
  outside, or leaves out what it says is inside (a closed-off cavity, a filled vault).  On the suite's
  phantoms a good mesh scores below 0.05 % and one with a missing part 0.1–1 %; with a truth, ``missing_parts``
  and ``topology_mismatch`` say it better.
* ``topology_vs_data`` — with or without a ground truth: the mesh's parts, voids or handles differ from the
  digital topology of the input's inside set beyond what its voxel contacts and speckles leave open
  (:mod:`bench.metrics.data_topology`); the row's ``topology_vs_data_detail`` names each kind (``dropped parts``,
  ``merged parts``, ``extra parts``, ``filled cavities``, ``extra cavities``, ``closed handles``, ``opened
  handles``) with its counts, e.g. ``merged parts: 28 in data, 1 in mesh``.  Without a truth such a mesh is not
  usable (the data is the only reference); with one, the truth decides (``topology_mismatch``): a degraded input
  can have another topology than the object — thick slices cut a thin tube — and a mesh that keeps the object's
  is right to differ from the data.
"""

from __future__ import annotations

import math

__all__ = ["result_flags", "FLAGS", "UNUSABLE_FLAGS", "UNUSABLE_WITHOUT_TRUTH", "is_usable"]

FLAGS = ("topology_mismatch", "dropped_components", "missing_parts", "self_intersecting", "not_converged",
         "inside_disagrees", "topology_vs_data")
#: ``inside_disagrees`` above this ``sign_err_pct`` (no truth only)
MAX_SIGN_ERR_PCT = 2.0
#: ``missing_parts`` below this ``coverage_pct``
MIN_COVERAGE_PCT = 99.5
#: a valid mesh with one of these is not *usable* (see :func:`is_usable`); ``not_converged`` alone is not a defect
#: of the mesh
UNUSABLE_FLAGS = ("topology_mismatch", "dropped_components", "missing_parts", "self_intersecting", "inside_disagrees")
#: ... and, in a row without a ground truth, these
UNUSABLE_WITHOUT_TRUTH = ("topology_vs_data",)
_NOT_CONVERGED = ("max_iter", "line_search_floor", "diverged", "sign_guard")


def _number(row: dict, key: str) -> float | None:
    v = row.get(key)
    try:
        v = float(v)
    except (TypeError, ValueError):
        return None
    return v if math.isfinite(v) else None


def result_flags(row: dict, phantom=None) -> list[str]:
    """The flags of one result row (its metrics and stop_reason) against ``phantom``'s topology (None: no truth)."""
    flags = []
    euler, comps = _number(row, "euler"), _number(row, "components")
    if phantom is not None and euler is not None and comps is not None:
        n_true = int(getattr(phantom, "n_components", 1) or 1)
        euler_true = 2 * n_true - 2 * int(getattr(phantom, "genus", 0) or 0)
        if int(euler) != euler_true or int(comps) != n_true:
            flags.append("topology_mismatch")
        if int(comps) < n_true:
            flags.append("dropped_components")
    coverage = _number(row, "coverage_pct")
    if coverage is not None and coverage < MIN_COVERAGE_PCT:
        flags.append("missing_parts")
    if (_number(row, "self_intersections") or 0) > 0:
        flags.append("self_intersecting")
    if row.get("stop_reason") in _NOT_CONVERGED:
        flags.append("not_converged")
    sign_err = _number(row, "sign_err_pct")
    if phantom is None and sign_err is not None and sign_err > MAX_SIGN_ERR_PCT:
        flags.append("inside_disagrees")
    detail = row.get("topology_vs_data_detail")
    if isinstance(detail, str) and detail.strip():
        flags.append("topology_vs_data")
    return flags


def is_usable(row: dict) -> bool:
    """A result a user who needs one closed surface can take as it is: ``ok`` (valid), the truth's number of
    components and genus where a truth exists, the data's topology where none does, no ``missing_parts``, no
    self-intersection (none of :data:`UNUSABLE_FLAGS` in the row's ``flags``, nor of
    :data:`UNUSABLE_WITHOUT_TRUTH` when the row's ``has_truth`` is false)."""
    if row.get("status") != "ok":
        return False
    flags = row.get("flags")
    text = "" if flags is None or (isinstance(flags, float) and math.isnan(flags)) else str(flags)
    bad = set(UNUSABLE_FLAGS) | (set(UNUSABLE_WITHOUT_TRUTH) if _without_truth(row) else set())
    return not {f.strip() for f in text.split(";")} & bad


def _without_truth(row: dict) -> bool:
    """The row says it had no ground truth (``has_truth`` false; a row that does not say is taken as having one)."""
    v = row.get("has_truth")
    if v is None or (isinstance(v, float) and math.isnan(v)) or str(v).strip() in ("", "nan", "None"):
        return False
    return str(v).strip().lower() not in ("true", "1", "1.0", "yes")
