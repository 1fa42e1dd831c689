"""Plain values for JSON and CSV: what a cell's row and record may hold."""

from __future__ import annotations

from typing import Any

import numpy as np

__all__ = ["plain", "error_text"]


def plain(value: Any) -> Any:
    """JSON-able plain Python values (numpy scalars/arrays, tuples; non-finite floats kept as floats).
    Arrays of more than 64 elements become a short ``<array shape [...]>`` note."""
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


def error_text(exc: BaseException) -> str:
    """``Type: first line of the message`` (the full traceback goes to the cell's JSON)."""
    lines = str(exc).strip().splitlines()
    return f"{type(exc).__name__}: {lines[0]}" if lines else type(exc).__name__
