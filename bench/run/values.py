"""Plain values for JSON and CSV: what a cell's row and record may hold."""

from __future__ import annotations

from typing import Any

import numpy as np

__all__ = ["plain", "error_text", "cap_text", "cap_tail", "MAX_MESSAGE"]

#: characters of a message kept in results.csv, the cell's row and the page; the full text is in the traceback
MAX_MESSAGE = 2000


def plain(value: Any) -> Any:
    """JSON-able plain Python values (numpy scalars/arrays, tuples; non-finite floats kept as floats; a stage
    contract such as a :class:`~bench.run.row.ResultRow` as its ``to_dict()``).  Arrays of more than 64 elements
    become a short ``<array shape [...]>`` note."""
    if hasattr(value, "to_dict") and not isinstance(value, (dict, type)):
        return plain(value.to_dict())
    if isinstance(value, dict):
        return {str(k): plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [plain(v) for v in value]
    if isinstance(value, np.ndarray):
        if value.size > 64:
            return f"<array shape {list(value.shape)}>"
        return plain(value.tolist())
    if isinstance(value, (np.bool_, bool)):
        return bool(value)
    if isinstance(value, np.integer):
        return int(value)
    if isinstance(value, (np.floating, float)):
        return float(value)
    if value is None or isinstance(value, (int, str)):
        return value
    return repr(value)


def cap_text(text: str, limit: int = MAX_MESSAGE, where: str = "the cell's traceback") -> str:
    """``text`` when it has at most ``limit`` characters; else its first ``limit`` ones and a note giving the
    length and where the whole text is — a 5-million-character exception message must not be copied into
    every file and page that shows the error (the csv module refuses fields over 131,072 characters)."""
    text = str(text)
    if len(text) <= limit:
        return text
    return f"{text[:limit]}… ({len(text):,} characters; full text in {where})"


def cap_tail(text: str, limit: int = MAX_MESSAGE, where: str = "the cell's record") -> str:
    """A traceback of at most about ``limit`` characters: its first and last halves (the frames where it began
    and the exception line, whose message is cut by :func:`cap_text` when it alone is too long) around a note."""
    text = str(text)
    if len(text) <= limit:
        return text
    last = text.rstrip("\n").rsplit("\n", 1)[-1]
    head = text[: limit // 2]
    tail = cap_text(last, limit // 2, where) if len(last) > limit // 2 else text[-(limit // 2):]
    return f"{head}\n… ({len(text):,} characters; full text in {where}) …\n{tail}"


def error_text(exc: BaseException, limit: int = MAX_MESSAGE) -> str:
    """``Type: first line of the message``, capped at ``limit`` characters (:func:`cap_text`; the full message
    is in the traceback the cell's JSON keeps)."""
    lines = str(exc).strip().splitlines()
    return cap_text(f"{type(exc).__name__}: {lines[0]}" if lines else type(exc).__name__, limit)
