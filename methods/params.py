"""A method's documented parameter (:class:`Param`): its default, what it does and the values it accepts.

A parameter has one type whether it is set or not: the type is inferred from the default when not given, and the
default goes through the same conversion as a value given on the command line or in a config, so ``Param(3,
...)`` is an int both unset and set to ``5``.
"""

from __future__ import annotations

from dataclasses import dataclass
from numbers import Integral, Real
from typing import Any

import numpy as np

from phantoms import InputError

__all__ = ["Param"]


@dataclass(frozen=True)
class Param:
    """A documented method parameter: its default, what it does, and the values it accepts.

    Parameters
    ----------
    default : object
        The value used when the parameter is not given; it is converted as a given value is (a default that does
        not convert, is not one of ``choices`` or lies outside ``[min, max]`` is a ``TypeError`` when the class
        is defined).  None reads as "auto" (then None, ``'none'`` and ``'auto'`` are accepted back).
    doc : str
        What the parameter does (``python -m bench methods`` prints it).
    type : type, optional
        The Python type values are converted to: bool, int, float, str, or ``object`` for free-form values
        such as a mesh.  Not given: the default's type (``Param(3, ...)`` is an int, ``Param(3.0, ...)`` a
        float, ``Param(True, ...)`` a bool, ``Param("a", ...)`` a str, anything else ``object``); a None default
        needs it given.
    choices : tuple, optional
        Restricts the value to a set.
    min, max : float, optional
        Inclusive bounds of a number.
    """

    default: Any
    doc: str
    type: type | None = None
    choices: tuple | None = None
    min: float | None = None
    max: float | None = None

    def __post_init__(self) -> None:
        if self.type is None:
            if self.default is None:
                raise TypeError(f"Param(None, {self.doc!r}) needs type=: the type cannot be inferred from None")
            object.__setattr__(self, "type", _type_of(self.default))
        try:
            default = self.convert("", "", self.default)
        except InputError as exc:
            raise TypeError(f"Param({self.default!r}, {self.doc!r}): the default is refused: "
                            f"{exc}") from None
        object.__setattr__(self, "default", default)

    def convert(self, method: str, name: str, value: Any) -> Any:
        """``value`` of parameter ``name`` of ``method`` converted to ``type`` (command-line strings included).

        :class:`InputError` for a value that does not convert, is not one of ``choices`` or lies outside
        ``[min, max]``.
        """
        where = f"method {method!r}, parameter {name!r}: " if method or name else ""
        t = self.type
        if self.default is None and (value is None or (isinstance(value, str)
                                                         and value.strip().lower() in ("none", "auto", ""))):
            return None  # a parameter whose default is None ("auto") accepts None/'none'/'auto' back
        try:
            if t is bool:
                if isinstance(value, str):
                    low = value.strip().lower()
                    if low in ("1", "true", "yes", "on"):
                        value = True
                    elif low in ("0", "false", "no", "off"):
                        value = False
                    else:
                        raise ValueError(value)
                elif not isinstance(value, (bool, np.bool_)):
                    raise ValueError(value)
                value = bool(value)
            elif t is int:
                if isinstance(value, bool):
                    raise ValueError(value)
                f = float(value)
                if not np.isfinite(f) or f != int(f):      # inf / nan: not an integer (no OverflowError)
                    raise ValueError(value)
                value = int(f)
            elif t is float:
                if isinstance(value, bool):
                    raise ValueError(value)
                value = float(value)
                if not np.isfinite(value):
                    raise ValueError(value)
            elif t is str:
                if not isinstance(value, str):
                    raise ValueError(value)
        except (TypeError, ValueError):
            raise InputError(f"{where}expected {t.__name__}, got {value!r}") from None
        if self.choices is not None and value not in self.choices:
            raise InputError(f"{where}{value!r} is not one of {list(self.choices)}")
        if self.min is not None and value < self.min:
            raise InputError(f"{where}{value!r} is below the minimum {self.min}")
        if self.max is not None and value > self.max:
            raise InputError(f"{where}{value!r} is above the maximum {self.max}")
        return value


def _type_of(default: Any) -> type:
    """The parameter type a default implies: bool, int, float, str, else ``object``."""
    if isinstance(default, (bool, np.bool_)):
        return bool
    if isinstance(default, Integral):
        return int
    if isinstance(default, Real):
        return float
    if isinstance(default, str):
        return str
    return object
