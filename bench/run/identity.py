"""A run folder's identity: which grid it holds (the config fingerprint) and which code computed each cell.

* :func:`config_fingerprint` hashes the parts of a config that decide the cells and their results (grid,
  methods, metrics, run settings — not the name, description or report layout); ``--resume`` with a config
  whose fingerprint differs from the folder's ``config.json`` is refused, naming the keys that differ
  (:func:`config_differences`), so an earlier user's finished cells are never dropped or mixed.
* :func:`code_identity` is the suite's version and git commit (plus a hash of uncommitted changes), stored in
  every cell record; :func:`mixed_code` lists the identities found in a folder, so a resume with other code is
  refused unless ``--allow-mixed-code`` (then run.json and the report say so).
* :func:`changed_methods` covers what the suite's identity does not: a plug-in method's own code.  Each cell of a
  plug-in carries ``method_code`` (:func:`bench.run.method_code.method_fingerprint`: its module files and
  parameters, hashed); ``--resume`` reruns, and overwrites, the finished cells whose plug-in changed since.
"""

from __future__ import annotations

import hashlib
import subprocess
from functools import lru_cache
from importlib import metadata

from phantoms import InputError

from .contracts import Cell
from .grid import canonical_json
from .method_code import SUITE_PACKAGES, method_fingerprint
from .provenance import SUITE_ROOT, git_commit

__all__ = ["config_fingerprint", "config_differences", "check_same_config", "code_identity", "code_label",
           "mixed_code", "MixedCodeError", "method_fingerprint", "changed_methods", "SUITE_PACKAGES"]

#: top-level config keys that do not change any cell (labels and page layout)
_COSMETIC = ("name", "description", "report")


class MixedCodeError(InputError):
    """The folder's cells were computed by other code than the one running now."""


def _essential(cfg_dict: dict) -> dict:
    return {k: v for k, v in cfg_dict.items() if k not in _COSMETIC}


def config_fingerprint(cfg_dict: dict) -> str:
    """sha256 (hex, 16 characters) of the cell-deciding parts of a config dict (``RunConfig.to_dict()``)."""
    return hashlib.sha256(canonical_json(_essential(cfg_dict)).encode()).hexdigest()[:16]


def _flatten(obj, prefix: str = "") -> dict[str, str]:
    """``{"grid.phantoms": '["sphere"]', "methods": '[...]'}``: tables split into dotted keys, lists kept."""
    if isinstance(obj, dict):
        out: dict[str, str] = {}
        for k, v in obj.items():
            out.update(_flatten(v, f"{prefix}{k}."))
        return out
    return {prefix.rstrip("."): canonical_json(obj)}


def config_differences(old: dict, new: dict) -> list[str]:
    """The dotted keys whose values differ between two config dicts (cosmetic keys ignored), sorted."""
    a, b = _flatten(_essential(old)), _flatten(_essential(new))
    return sorted(k for k in set(a) | set(b) if a.get(k) != b.get(k))


def check_same_config(folder_cfg: dict, new_cfg: dict, where: str) -> None:
    """Raise :class:`InputError` naming the differing keys unless the two configs give the same grid."""
    diff = config_differences(folder_cfg, new_cfg)
    if diff:
        raise InputError(f"--resume: the config differs from the run in {where!r} ({', '.join(diff)}); resume "
                         "without grid options (the folder's own config is used) or choose another --out")


def _diff_hash() -> str | None:
    try:
        res = subprocess.run(["git", "-C", str(SUITE_ROOT), "diff", "HEAD", "--no-ext-diff", "--binary"],
                             capture_output=True, timeout=20)
    except (OSError, subprocess.SubprocessError):
        return None
    return hashlib.sha1(res.stdout).hexdigest()[:10] if res.returncode == 0 else None


@lru_cache(maxsize=1)
def code_identity() -> dict:
    """``{"version", "commit", "dirty", "diff"}`` of the running suite (``diff``: a hash of the uncommitted
    changes to tracked files, so two different dirty trees on one commit differ)."""
    try:
        version = metadata.version("levelset-bench")
    except metadata.PackageNotFoundError:
        version = None
    git = git_commit() or {}
    dirty = bool(git.get("dirty"))
    return {"version": version, "commit": git.get("commit"), "dirty": dirty,
            "diff": _diff_hash() if dirty else None}


def code_label(code: dict | None) -> str:
    """A short readable form: ``0.1.0 @ 60da513`` (``+dirty:<hash>``), or ``unknown``."""
    if not code:
        return "unknown (recorded before code versions were kept)"
    commit = (code.get("commit") or "no git")[:7]
    dirty = f"+dirty:{code.get('diff') or '?'}" if code.get("dirty") else ""
    return f"{code.get('version') or '?'} @ {commit}{dirty}"


def mixed_code(records: dict[str, dict], current: dict | None) -> dict[str, int]:
    """``{code_label: number of cells}`` over the records and the ``current`` code (None: it will compute no
    cell), when more than one code computed (or would compute) the folder's cells; {} when they agree."""
    counts: dict[str, int] = {}
    for rec in records.values():
        label = code_label(rec.get("code"))
        counts[label] = counts.get(label, 0) + 1
    if current is not None:
        counts.setdefault(code_label(current), 0)
    return counts if len(counts) > 1 else {}


def _code_hash(code) -> str | None:
    return code.get("hash") if isinstance(code, dict) else None


def changed_methods(records: dict[str, dict], cells: list[Cell]) -> dict[str, dict]:
    """The finished cells whose plug-in method code differs from the code that would compute them now:
    ``{method: {"cells": [cell_id, ...], "files": [...], "unknown": bool}}`` (``unknown``: a record written
    before plug-in code was recorded).  Built-in methods (no ``method_code`` on either side) never differ here:
    the suite's own code is checked by :func:`mixed_code`.  ``records`` are the stored dicts (their ``cell`` in
    its dict form), ``cells`` the grid's :class:`~bench.run.contracts.Cell` objects."""
    current = {c.cell_id: c for c in cells}
    out: dict[str, dict] = {}
    for cid, rec in records.items():
        cell = current.get(cid)
        if cell is None:
            continue
        old = (rec.get("cell") or {}).get("method_code")
        new = cell.method_code
        if _code_hash(old) == _code_hash(new):
            continue
        entry = out.setdefault(cell.method, {"cells": [], "files": (new or old or {}).get("files", []),
                                                "unknown": False})
        entry["cells"].append(cid)
        entry["unknown"] = entry["unknown"] or old is None
    return out
