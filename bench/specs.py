"""The command line's method spec ``--method [LABEL=]NAME[:key=value,...]`` (a config file's [[methods]] tables
are read by :mod:`bench.config`)."""

from __future__ import annotations

from phantoms import InputError

from .config import MethodSpec, _fmt_value
from .textspec import parse_value as _parse_value
from .textspec import split_top as _split_top

__all__ = ["parse_method_spec"]


def parse_method_spec(text: str) -> MethodSpec:
    """``[LABEL=]NAME[:key=value,key=value...]`` → :class:`MethodSpec` (values in TOML syntax or plain text).

    >>> parse_method_spec("sg0=shape_gradient:beta=0,alpha=5").params
    {'beta': 0, 'alpha': 5}
    """
    spec = text.strip()
    label = None
    head, sep, rest = spec.partition(":")
    if "=" in head:
        label, _, head = head.partition("=")
        label = label.strip()
    name = head.strip()
    if not name:
        raise InputError(f"method spec {text!r}: expected [LABEL=]NAME[:key=value,...]")
    params: dict = {}
    if sep:
        for item in _split_top(rest):
            k, eq, v = item.partition("=")
            if not eq or not k.strip():
                raise InputError(f"method spec {text!r}: expected key=value, got {item!r}")
            if k.strip() in params:
                raise InputError(f"method spec {text!r}: parameter {k.strip()!r} is given twice")
            params[k.strip()] = _parse_value(v.strip())
    if label is None:
        label = name if not params else f"{name}[{','.join(f'{k}={_fmt_value(v)}' for k, v in params.items())}]"
    return MethodSpec(name=name, label=label, params=params)
