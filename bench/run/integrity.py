"""Checksums of the cell records: a hand-edited, corrupted or deleted cell file is found, not used.

:func:`seal` adds ``record["checksum"] = {"record": sha256, "npz": sha256 | None}`` as the record is written:
``record`` is the SHA-256 of the canonical JSON (sorted keys, no spaces) of the record without its checksum —
computed on the record as it reads back from JSON, so the value reads the same after the round trip — and
``npz`` the SHA-256 of the cell's ``.npz`` file.  :func:`record_problem` checks both.  A record without a
``checksum`` key is *unsealed*: treated as altered (deleting the key must not bypass the seal).  A run folder
written before seals existed is sealed once, explicitly, by ``python -m bench report DIR --accept-unsealed``
(:func:`bench.run.audit.seal_unsealed`).
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

from .values import plain

__all__ = ["seal", "record_problem", "file_sha256", "UNSEALED"]

#: record_problem's answer for a record without a checksum
UNSEALED = "has no seal (its checksum was removed, or it was written before seals)"


def _canonical(record: dict) -> bytes:
    body = {k: v for k, v in record.items() if k != "checksum"}
    body = json.loads(json.dumps(body, default=plain, allow_nan=True))    # as it reads back from the file
    return json.dumps(body, sort_keys=True, separators=(",", ":"), allow_nan=True).encode()


def file_sha256(path: Path) -> str | None:
    """SHA-256 of the file's bytes, None when there is no file."""
    h = hashlib.sha256()
    try:
        with open(path, "rb") as fh:
            for block in iter(lambda: fh.read(1 << 20), b""):
                h.update(block)
    except FileNotFoundError:
        return None
    return h.hexdigest()


def seal(record: dict, npz: Path | None) -> dict:
    """``record`` with its ``checksum`` (of the record and of the ``npz`` file, when it has one)."""
    sealed = dict(record)
    sealed["checksum"] = {"record": hashlib.sha256(_canonical(record)).hexdigest(),
                          "npz": file_sha256(npz) if npz is not None else None}
    return sealed


def record_problem(record: dict, npz: Path | None) -> str | None:
    """Why ``record`` (read from ``cells/<id>.json``) or its ``npz`` is not what was written — a sentence
    naming the file — :data:`UNSEALED` for a record without a checksum, None when both match (``npz`` None:
    the record alone is checked)."""
    checksum = record.get("checksum")
    if checksum is None:
        return UNSEALED
    if not isinstance(checksum, dict) or hashlib.sha256(_canonical(record)).hexdigest() != checksum.get("record"):
        return "was altered after it was written (checksum mismatch)"
    want = checksum.get("npz")
    if want is None or npz is None:
        return None
    got = file_sha256(npz)
    if got is None:
        return f"lost its arrays: {npz.name} is missing"
    return None if got == want else f"has altered arrays: {npz.name} does not match its checksum"
