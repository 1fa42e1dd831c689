"""User text on its way to a terminal: control characters shown, never obeyed.

A config ``name``, a method label, a phantom name, a plug-in's exception message or ``info`` warning can hold
ESC / CSI / OSC sequences (``\\x1b]0;title\\x07`` retitles the window, ``\\x1b[2J`` clears it, ``\\r`` overwrites
the line).  :func:`printable` replaces every C0 / C1 control character but newline and tab by its ``\\xNN`` /
``\\uNNNN`` escape, as ``repr`` writes it, so the text reads the same and the terminal does nothing.  The HTML
report escapes its text itself (Jinja autoescape).
"""

from __future__ import annotations

import contextlib
import faulthandler
import os
import re
import sys
import tempfile

__all__ = ["printable", "flush_std", "redirect_output", "captured_head", "capture_output", "show_captured"]

_CONTROL = re.compile(r"[\x00-\x08\x0b-\x1f\x7f-\x9f\u2028\u2029\u202a-\u202e\u2066-\u2069]")


def _escape(match: re.Match) -> str:
    c = ord(match.group())
    return f"\\x{c:02x}" if c < 0x100 else f"\\u{c:04x}"


def printable(text) -> str:
    """``str(text)`` with control characters (but ``\\n`` and ``\\t``) and bidirectional overrides escaped."""
    return _CONTROL.sub(_escape, str(text))


def flush_std() -> None:
    """Flush ``sys.stdout`` and ``sys.stderr`` (a closed or broken stream is let be)."""
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError):
            pass


def redirect_output(fd: int) -> None:
    """In a child process: file descriptors 1 and 2 (C code, subprocesses), ``sys.stdout`` / ``sys.stderr`` and
    faulthandler's crash report go to ``fd`` — what a plug-in writes never reaches the terminal raw."""
    flush_std()
    os.dup2(fd, 1)
    os.dup2(fd, 2)
    sys.stdout = open(1, "w", buffering=1, errors="backslashreplace", closefd=False)
    sys.stderr = open(2, "w", buffering=1, errors="backslashreplace", closefd=False)
    if faulthandler.is_enabled():          # its crash report went to a copy of the old stderr: captured too
        faulthandler.enable(file=sys.stderr)


def captured_head(fd: int, kept: int) -> tuple[int, str]:
    """(bytes written to the file ``fd``, its first ``kept`` bytes as text, control characters escaped)."""
    flush_std()
    size = os.fstat(fd).st_size
    return size, (printable(os.pread(fd, kept, 0).decode("utf-8", "replace")) if size else "")


@contextlib.contextmanager
def capture_output():
    """In this process: what is written on file descriptors 1 and 2 (``sys.stdout`` / ``sys.stderr``, C code)
    inside the block goes to a temporary file, restored after; yields the file's descriptor (read it with
    :func:`captured_head` before the block ends)."""
    saved = [os.dup(1), os.dup(2)]
    streams = sys.stdout, sys.stderr
    with tempfile.TemporaryFile() as out:
        try:
            redirect_output(out.fileno())
            yield out.fileno()
        finally:
            flush_std()
            os.dup2(saved[0], 1)
            os.dup2(saved[1], 2)
            for fd in saved:
                os.close(fd)
            sys.stdout, sys.stderr = streams


def show_captured(size: int, head: str, kept: int, who: str) -> None:
    """Print on stderr what ``who`` wrote (its first ``kept`` bytes, escaped; the size when there was more)."""
    if not size:
        return
    more = f", first {kept} shown" if size > kept else ""
    print(f"{who} wrote {size} bytes on stdout / stderr (control characters escaped{more}):", file=sys.stderr)
    for line in head.splitlines():
        print(f"  | {line}", file=sys.stderr)
