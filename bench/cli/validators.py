"""The argparse ``type=`` validators of the command line, in one place: each parses one option's text or
raises :class:`argparse.ArgumentTypeError` with a message that quotes the text (argparse prints it after the
option's name and exits with code 2)."""

from __future__ import annotations

import argparse
import math
from collections.abc import Callable

__all__ = ["integer", "number", "int_at_least", "positive_int", "int_between", "nonneg_float", "finite_float",
           "case_timeout", "int_list"]


def integer(text: str) -> int:
    """``text`` as an int, else "not an integer"."""
    try:
        return int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not an integer: {text!r}") from None


def number(text: str) -> float:
    """``text`` as a float (nan and inf included), else "not a number"."""
    try:
        return float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None


def int_at_least(minimum: int) -> Callable[[str], int]:
    """A validator for an integer ≥ ``minimum``."""
    def parse(text: str) -> int:
        v = integer(text)
        if v < minimum:
            raise argparse.ArgumentTypeError(f"must be >= {minimum}: {text!r}")
        return v
    return parse


#: an integer ≥ 1 (worker processes, repeats, rounds)
positive_int = int_at_least(1)


def int_between(lo: int, hi: int) -> Callable[[str], int]:
    """A validator for an integer in ``[lo, hi]``."""
    def parse(text: str) -> int:
        v = integer(text)
        if not lo <= v <= hi:
            raise argparse.ArgumentTypeError(f"must be in [{lo}, {hi}]: {text!r}")
        return v
    return parse


def nonneg_float(text: str) -> float:
    """A finite number ≥ 0 (seconds, gigabytes, a tolerance)."""
    v = number(text)
    if not (v >= 0 and math.isfinite(v)):
        raise argparse.ArgumentTypeError(f"must be a finite number >= 0: {text!r}")
    return v


def finite_float(text: str) -> float:
    """Any finite number."""
    v = number(text)
    if not math.isfinite(v):
        raise argparse.ArgumentTypeError(f"must be finite: {text!r}")
    return v


def case_timeout(text: str) -> float:
    """Seconds per check-method case: 0 (no limit) up to the runner's longest time limit."""
    from ..run.limits import MAX_SECONDS

    v = number(text)
    if not 0 <= v <= MAX_SECONDS:
        raise argparse.ArgumentTypeError(f"must be between 0 (no limit) and {MAX_SECONDS:.0f}: {text!r}")
    return v


def int_list(text: str) -> list[int]:
    """Comma-separated integers (empty items ignored)."""
    try:
        return [int(t) for t in text.split(",") if t.strip()]
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected comma-separated integers: {text!r}") from None
