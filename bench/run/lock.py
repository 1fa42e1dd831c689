"""The run folder's owner: a lock file, so two runs never write into one folder at once.

``DIR/run.lock`` holds the owner's PID, host name, the process's start time (to tell a reused PID from the
owner) and when the run started.  It is created atomically (written under a temporary name, then hard-linked
to ``run.lock``, which fails if the file exists), so a reader never sees half a lock.

* A lock whose process is alive (same host) → :class:`LockedError` (exit 2) naming the owner.
* A *stale* lock — its PID is dead on this host, or now belongs to another process — was left by a killed run;
  it is taken over with a message on stderr.
* A lock from another host cannot be checked from here → :class:`LockedError`; remove ``run.lock`` by hand if
  that run is known to be gone.
"""

from __future__ import annotations

import datetime as _dt
import json
import os
import socket
import sys
from pathlib import Path

from phantoms import InputError

__all__ = ["RunLock", "LockedError", "LOCK_FILE", "read_lock", "lock_owner_alive"]

LOCK_FILE = "run.lock"


class LockedError(InputError):
    """The run folder is locked by another live run."""


def _proc_start(pid: int) -> str | None:
    """The start time of process ``pid`` in clock ticks since boot (Linux), None when unknown."""
    try:
        with open(f"/proc/{pid}/stat") as fh:
            stat = fh.read()
        return stat.rsplit(")", 1)[1].split()[19]
    except (OSError, IndexError):
        return None


def _pid_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # alive, owned by another user
        return True
    except (OSError, OverflowError):
        return False
    return True


def read_lock(out: str | Path) -> dict | None:
    """The lock's content (``pid``, ``host``, ``proc_start``, ``started``), {} if unreadable, None if absent."""
    path = Path(out) / LOCK_FILE
    try:
        data = json.loads(path.read_text())
    except FileNotFoundError:
        return None
    except (OSError, ValueError):
        return {}
    return data if isinstance(data, dict) else {}


def lock_owner_alive(info: dict) -> bool:
    """Whether the process that wrote the lock ``info`` still runs (a lock from another host counts as
    alive: it cannot be checked from here)."""
    if info.get("host") != socket.gethostname():
        return True
    try:
        pid = int(info["pid"])
    except (KeyError, TypeError, ValueError):
        return False
    if not _pid_alive(pid):
        return False
    start = info.get("proc_start")
    return start is None or _proc_start(pid) in (None, start)


def _describe(info: dict, path: Path) -> str:
    return (f"PID {info.get('pid', '?')} on host {info.get('host', '?')}, started {info.get('started', '?')} "
            f"(lock file {path})")


class RunLock:
    """``with RunLock(out): ...`` owns ``out`` for the block (see the module docstring)."""

    def __init__(self, out: str | Path, *, quiet: bool = False) -> None:
        self.out = Path(out)
        self.path = self.out / LOCK_FILE
        self.quiet = quiet
        self.info = {"pid": os.getpid(), "host": socket.gethostname(), "proc_start": _proc_start(os.getpid()),
                     "started": _dt.datetime.now().astimezone().isoformat(timespec="seconds")}
        self.held = False
        self.took_over: dict | None = None

    def check(self) -> None:
        """Raise :class:`LockedError` if another live run holds the folder (does not take the lock)."""
        info = read_lock(self.out)
        if info and info.get("pid") != os.getpid() and lock_owner_alive(info):
            raise LockedError(f"run folder {str(self.out)!r} is in use by another run: {_describe(info, self.path)}; "
                              "wait for it to finish or choose another --out")

    def acquire(self) -> "RunLock":
        from geometry.files import write_error

        tmp = self.out / f".{LOCK_FILE}.{os.getpid()}.tmp"
        try:
            tmp.write_text(json.dumps(self.info))
            for _ in range(3):
                try:
                    os.link(tmp, self.path)
                    self.held = True
                    return self
                except FileExistsError:
                    self._take_over_if_stale()
        except OSError as exc:
            raise write_error(self.path, exc) from None
        finally:
            tmp.unlink(missing_ok=True)
        raise LockedError(f"could not lock {str(self.out)!r}: {self.path} keeps reappearing")

    def _take_over_if_stale(self) -> None:
        info = read_lock(self.out)
        if info is None:
            return  # released meanwhile: try again
        if info and lock_owner_alive(info):
            self.check()
        if read_lock(self.out) != info:
            return  # replaced meanwhile (another run took it over first): look again
        self.took_over = info
        if not self.quiet:
            print(f"note: {self.path} was left by a run that is no longer running "
                  f"({_describe(info, self.path) if info else 'unreadable lock'}); taking it over",
                  file=sys.stderr)
        self.path.unlink(missing_ok=True)

    def release(self) -> None:
        if self.held and (read_lock(self.out) or {}).get("pid") == os.getpid():
            try:
                self.path.unlink(missing_ok=True)
            except OSError:
                pass
        self.held = False

    def __enter__(self) -> "RunLock":
        return self.acquire()

    def __exit__(self, *exc) -> None:
        self.release()
