"""Small text parsers of the command-line specs (``NAME:key=value,...``): values in TOML syntax, top-level
comma splitting.  No dependency on the rest of the suite."""

from __future__ import annotations

import tomllib
from typing import Any

__all__ = ["parse_value", "split_top"]


def parse_value(text: str) -> Any:
    """A command-line value: TOML syntax if it parses (numbers, booleans, arrays, quoted strings), else text."""
    try:
        return tomllib.loads(f"v = {text}")["v"]
    except tomllib.TOMLDecodeError:
        return text


def split_top(text: str) -> list[str]:
    """Split on commas not inside brackets (so ``snapshots=[1,50]`` stays one item)."""
    out, depth, cur = [], 0, ""
    for ch in text:
        if ch in "[{":
            depth += 1
        elif ch in "]}":
            depth -= 1
        if ch == "," and depth == 0:
            out.append(cur)
            cur = ""
        else:
            cur += ch
    if cur.strip():
        out.append(cur)
    return [s.strip() for s in out if s.strip()]
