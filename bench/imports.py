"""A user's plug-in modules (``--import MODULE``, ``run.imports``) tried in a forked child before this process
imports them.

A module that raises or calls ``sys.exit()`` at import is caught where it is imported
(:func:`methods.import_plugins`: one line naming it).  One that ends its process outright — ``os._exit(0)``, an
abort or a crash in compiled code — cannot be caught in the process that imports it: the command would end
silently, often with exit code 0, leaving no run folder and no message.  :func:`probe_imports` imports the
modules first in a forked child whose output goes nowhere; a child that dies before it has imported them all
names the module that ended it.
"""

from __future__ import annotations

import importlib
import os
import signal

from phantoms import InputError

__all__ = ["probe_imports"]


def _child(modules: list[str], fd: int) -> None:
    """In the forked child: import each module after writing its index to ``fd``; ``ok`` at the end."""
    try:
        import faulthandler

        faulthandler.disable()                  # its crash report would go to a copy of the terminal's stderr
        devnull = os.open(os.devnull, os.O_RDWR)
        for std in (0, 1, 2):
            os.dup2(devnull, std)
        for i, mod in enumerate(modules):
            os.write(fd, f"{i}\n".encode())
            try:
                importlib.import_module(mod)
            except BaseException:  # noqa: BLE001, S110 — reported by the real import, in the parent
                pass
        os.write(fd, b"ok\n")
    finally:
        os._exit(0)


def probe_imports(modules) -> None:
    """Import ``modules`` in a forked child first; InputError naming the module that ended the child's process.

    Parameters
    ----------
    modules : iterable of str
        Module names, in the order they will be imported.

    Raises
    ------
    InputError
        ``cannot import module 'name': it ended the process at import (exit code N / signal S)``.
    """
    modules = [str(m) for m in modules or ()]
    if not modules or not hasattr(os, "fork"):
        return
    read, write = os.pipe()
    pid = os.fork()
    if pid == 0:                                        # pragma: no cover - the child never returns
        os.close(read)
        _child(modules, write)
    os.close(write)
    with os.fdopen(read, "rb") as fh:
        said = fh.read().decode().split()          # to the end: the child has finished or died
    _, status = os.waitpid(pid, 0)
    if said[-1:] == ["ok"]:
        return
    mod = modules[int(said[-1])] if said else modules[0]
    if os.WIFSIGNALED(status):
        how = f"signal {signal.Signals(os.WTERMSIG(status)).name}"
    else:
        how = f"exit code {os.waitstatus_to_exitcode(status)}"
    raise InputError(f"cannot import module {mod!r}: it ended the process at import ({how}; a plug-in module must "
                     "not exit)")
