"""User text on its way to a terminal: control characters shown, never obeyed.

A config ``name``, a method label, a phantom name, a plug-in's exception message or ``info`` warning can hold
ESC / CSI / OSC sequences (``\\x1b]0;title\\x07`` retitles the window, ``\\x1b[2J`` clears it, ``\\r`` overwrites
the line).  :func:`printable` replaces every C0 / C1 control character but newline and tab by its ``\\xNN`` /
``\\uNNNN`` escape, as ``repr`` writes it, so the text reads the same and the terminal does nothing.  The HTML
report escapes its text itself (Jinja autoescape).
"""

from __future__ import annotations

import re

__all__ = ["printable"]

_CONTROL = re.compile(r"[\x00-\x08\x0b-\x1f\x7f-\x9f\u2028\u2029\u202a-\u202e\u2066-\u2069]")


def _escape(match: re.Match) -> str:
    c = ord(match.group())
    return f"\\x{c:02x}" if c < 0x100 else f"\\u{c:04x}"


def printable(text) -> str:
    """``str(text)`` with control characters (but ``\\n`` and ``\\t``) and bidirectional overrides escaped."""
    return _CONTROL.sub(_escape, str(text))
