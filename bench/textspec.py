"""Small text parsers of the command-line specs (``NAME:key=value,...``): values in TOML syntax, top-level
comma splitting; and a guarded TOML file reader.  No dependency on the rest of the suite but its error type."""

from __future__ import annotations

import stat
import tomllib
from pathlib import Path
from typing import Any

from geometry.errors import InputError

__all__ = ["parse_value", "split_top", "read_toml", "MAX_TOML_BYTES"]

#: the largest TOML file read (a config is a page of text)
MAX_TOML_BYTES = 4 * 2**20


def read_toml(path: Path, what: str = "config") -> dict:
    """A TOML file's tables, or one :class:`InputError` line: not a regular file (``/dev/zero``, a FIFO would never
    end), larger than :data:`MAX_TOML_BYTES`, unreadable, not UTF-8 or TOML, or nested too deeply to parse."""
    path = Path(path)
    try:
        st = path.stat()
        if not stat.S_ISREG(st.st_mode):
            raise InputError(f"{what} {str(path)!r} is not a regular file")
        if st.st_size > MAX_TOML_BYTES:
            raise InputError(f"{what} {str(path)!r} is {st.st_size / 2**20:.1f} MiB; a {what} is text of at most "
                             f"{MAX_TOML_BYTES // 2**20} MiB")
        text = path.read_bytes()
    except OSError as exc:
        raise InputError(f"cannot read {what} {str(path)!r}: {exc.strerror or exc}") from None
    try:
        return tomllib.loads(text.decode("utf-8"))
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise InputError(f"{what} {str(path)!r} is not valid TOML: {exc}") from None
    except RecursionError:
        raise InputError(f"{what} {str(path)!r} nests tables or arrays too deeply to read") from None


def parse_value(text: str) -> Any:
    """A command-line value: TOML syntax if it parses (numbers, booleans, arrays, quoted strings), else text."""
    try:
        return tomllib.loads(f"v = {text}")["v"]
    except (tomllib.TOMLDecodeError, RecursionError):
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
