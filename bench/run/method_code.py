"""A plug-in method's code, fingerprinted: what the suite's own code identity does not cover.

:func:`method_fingerprint` hashes the source files of the modules that define a method's class and its bases
outside the suite's packages (:data:`SUITE_PACKAGES`), together with the class's parameters and their defaults.
:func:`bench.run.grid.expand_grid` stores it in each cell of a plug-in (``method_code``);
:func:`bench.run.identity.changed_methods` compares it on ``--resume``.  Only those module files count: helpers
a plug-in imports from other modules of its own are not hashed.  The files are read when the grid is expanded
(in a fresh ``python -m bench`` process, the code that runs).
"""

from __future__ import annotations

import hashlib
import inspect
import json
from pathlib import Path

from methods.base import Method

from .provenance import SUITE_ROOT

__all__ = ["SUITE_PACKAGES", "method_fingerprint"]

#: the suite's own packages: their code is in :func:`bench.run.identity.code_identity` (git commit and
#: uncommitted changes)
SUITE_PACKAGES = ("geometry", "phantoms", "methods", "bench")


#: the interface's own classes (:class:`methods.base.Method` and its bases: ``abc.ABC``, ``object``): not a plug-in's
#: code wherever their files are
_INTERFACE = frozenset(Method.__mro__)


def _in_suite(path: Path) -> bool:
    """True for a file of the suite's own packages (under the suite's root)."""
    root = Path(SUITE_ROOT).resolve()
    return any(path.is_relative_to(root / pkg) for pkg in SUITE_PACKAGES)


def _class_file(klass: type) -> Path | None:
    try:
        return Path(inspect.getsourcefile(klass) or inspect.getfile(klass)).resolve()
    except (TypeError, OSError):  # a class of a module without a file (__main__ in an interpreter, ...)
        return None


def method_fingerprint(cls: type) -> dict | None:
    """``{"hash": sha256 (16 hex), "files": [...]}`` of a plug-in method class, or None for a built-in one.

    The hash covers the bytes of the source file of every class in ``cls``'s MRO defined outside the suite's
    packages (:data:`SUITE_PACKAGES`: the suite's own code, in its code identity), in MRO order, and
    the class's parameters (``Param`` with default, type and bounds).  ``files`` names those files (for
    messages; moving the plug-in does not change the hash).  A class whose module has no file (defined in an
    interactive session) is hashed by its module and class name.
    """
    h = hashlib.sha256()
    files: list[str] = []
    seen: set[str] = set()
    for klass in getattr(cls, "__mro__", (cls,)):
        if klass in _INTERFACE:
            continue
        path = _class_file(klass)
        if path is not None and _in_suite(path):
            continue
        key = str(path) if path is not None else f"<{klass.__module__}.{klass.__qualname__}>"
        if key in seen:
            continue
        seen.add(key)
        files.append(key)
        try:
            data = path.read_bytes() if path is not None else key.encode()
        except OSError:
            data = f"unreadable {key}".encode()
        h.update(hashlib.sha256(data).digest())
    if not files:
        return None
    params = getattr(cls, "params", {}) or {}
    h.update(json.dumps({k: repr(v) for k, v in params.items()}, sort_keys=True).encode())
    return {"hash": h.hexdigest()[:16], "files": files}
