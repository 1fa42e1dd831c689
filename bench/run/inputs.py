"""Checks of a run's inputs made before any executor starts, each failure an :class:`InputError` of one line."""

from __future__ import annotations

import importlib.util

from phantoms import InputError

__all__ = ["require_dask", "parse_scheduler_address"]

DASK_INSTALL_HINT = 'pip install -e ".[dask]"'


def require_dask() -> None:
    """Raise :class:`InputError` naming the extra to install when Dask's ``distributed`` is missing."""
    if importlib.util.find_spec("distributed") is None:
        raise InputError("--executor dask needs Dask's distributed scheduler, which is not installed; install it "
                         f"with: {DASK_INSTALL_HINT}")


def parse_scheduler_address(text: str) -> str:
    """``text`` as distributed reads a scheduler address (``host:port`` is ``tcp://host:port``).

    Raises :class:`InputError` with distributed's reason (unknown scheme, no port) or for a port out of range.
    """
    from distributed.comm.addressing import get_address_host_port, normalize_address

    try:
        address = normalize_address(text.strip())
        port = get_address_host_port(address)[1]
    except ValueError as exc:
        raise InputError(f"--scheduler: not a scheduler address: {text!r} ({exc})") from None
    if not 0 < port < 65536:
        raise InputError(f"--scheduler: port out of range in {text!r}")
    return address
