"""The battery's machinery: a case, the command line run as a user would run it, and the expectations.

A case is a named check of one cause; it returns None when the suite behaved as promised, else the reason it did
not.  Commands run as ``python -m bench ...`` in their own process (own session, killed with its group when
over its time limit), from the fixture folder, with the repository and the plug-in folder on ``PYTHONPATH`` so
the checkout under test is the one that runs.
"""

from __future__ import annotations

import csv
import os
import re
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

REPO = Path(__file__).resolve().parents[3]

#: terminal controls a plug-in or a file name must never put on the terminal raw: C0 (but tab and newline),
#: DEL, C1 and the bidirectional overrides
#: ``python -c LIMITED BYTES ARGS...``: ``python ARGS...`` with its address space limited to BYTES
LIMITED = ("import os, resource, sys; n = int(sys.argv[1]); resource.setrlimit(resource.RLIMIT_AS, (n, n)); "
           "os.execv(sys.executable, [sys.executable, *sys.argv[2:]])")
CONTROLS = re.compile("[\x00-\x08\x0b-\x1f\x7f\x80-\x9f\u202a-\u202e\u2066-\u2069]")


@dataclass
class Case:
    """One check: ``cause`` (the issue's cause number, or a name), ``name`` and ``check(ctx)`` → reason or None."""

    cause: str
    name: str
    check: Callable[[Ctx], str | None]


@dataclass
class Result:
    """What one command did: exit code (None when it was killed at its time limit), both streams, seconds."""

    args: list[str]
    rc: int | None
    out: str
    err: str
    seconds: float

    @property
    def err_lines(self) -> list[str]:
        return [line for line in self.err.splitlines() if line.strip()]

    def show(self) -> str:
        """The command and what it did, short, for a failure line."""
        tail = (self.err_lines[-1] if self.err_lines else self.out.strip()[-160:]).strip()
        return f"rc={self.rc}, {len(self.err_lines)} stderr line(s), last: {tail[:200]!r}"


class Ctx:
    """The fixture folder, the plug-in folder and memoised shared work (a run folder several cases read)."""

    def __init__(self, root: Path) -> None:
        self.root = root
        self.plugins = root / "plugins"
        self.plugins.mkdir(parents=True, exist_ok=True)
        self._once: dict[str, object] = {}
        self._locks: dict[str, threading.Lock] = {}
        self._guard = threading.Lock()

    def once(self, key: str, make: Callable[[], object]) -> object:
        """``make()`` the first time ``key`` is asked for, by whichever thread asks first; its value after."""
        with self._guard:
            lock = self._locks.setdefault(key, threading.Lock())
        with lock:
            if key not in self._once:
                try:
                    self._once[key] = (True, make())
                except Exception as exc:  # noqa: BLE001 — a fixture that failed fails every case that needs it
                    self._once[key] = (False, exc)
            made, value = self._once[key]
        if not made:
            raise RuntimeError(f"fixture {key!r} failed: {value}") from value
        return value

    def bench(self, *args: str, timeout: float = 90, cwd: Path | None = None, env: dict | None = None,
              stdin: bytes | None = None, limit_gb: float | None = None) -> Result:
        """``python -m bench ARGS`` as a user runs it; killed with its process group after ``timeout`` s."""
        return self.python("-m", "bench", *args, timeout=timeout, cwd=cwd, env=env, stdin=stdin, limit_gb=limit_gb)

    def environ(self, extra: dict | None = None) -> dict:
        """The commands' environment: this one with the checkout and the plug-in folder on ``PYTHONPATH``."""
        env = dict(os.environ)
        env["PYTHONPATH"] = os.pathsep.join([str(REPO), str(self.plugins)])
        env["PYTHONIOENCODING"] = "utf-8"
        env.update(extra or {})
        return env

    def python(self, *args: str, timeout: float = 90, cwd: Path | None = None, env: dict | None = None,
               stdin: bytes | None = None, limit_gb: float | None = None) -> Result:
        """``python ARGS`` with the checkout and the plug-ins on the path (see :meth:`bench`)."""
        full_env = self.environ(env)

        cmd = [sys.executable, *args]
        if limit_gb:            # the address-space limit set in a small wrapper that then becomes the command
            cmd = [sys.executable, "-c", LIMITED, str(int(limit_gb * 2 ** 30)), *args]
        start = time.monotonic()
        proc = subprocess.Popen(cmd, cwd=cwd or self.root, env=full_env, start_new_session=True,
                                stdin=subprocess.PIPE if stdin is not None else subprocess.DEVNULL,
                                stdout=subprocess.PIPE, stderr=subprocess.PIPE)
        try:
            out, err = proc.communicate(stdin, timeout=timeout)
            rc: int | None = proc.returncode
        except subprocess.TimeoutExpired:
            kill_group(proc)
            out, err = proc.communicate()
            rc = None
        return Result(list(args), rc, out.decode("utf-8", "replace"), err.decode("utf-8", "replace"),
                      time.monotonic() - start)


def kill_group(proc: subprocess.Popen, sig: int = signal.SIGKILL) -> None:
    """Send ``sig`` to the process group ``proc`` leads (each command runs in its own session)."""
    try:
        os.killpg(proc.pid, sig)
    except ProcessLookupError:
        pass


# ---------------------------------------------------------------------------------------------- expectations
def one_line(res: Result, *words: str, rc: int = 2) -> str | None:
    """Exit ``rc``, exactly one line on stderr holding every one of ``words`` (case-insensitive), no traceback,
    no raw terminal control."""
    if res.rc is None:
        return f"still running after {res.seconds:.0f} s (killed)"
    if res.rc != rc:
        return f"exit {res.rc}, expected {rc}: {res.show()}"
    if "Traceback" in res.err or "Traceback" in res.out:
        return f"a traceback: {res.show()}"
    if len(res.err_lines) != 1:
        return f"{len(res.err_lines)} lines on stderr, expected 1: {res.err.strip()[:300]!r}"
    line = res.err_lines[0].lower()
    missing = [w for w in words if w.lower() not in line]
    if missing:
        return f"the line does not name {missing}: {res.err_lines[0][:300]!r}"
    return raw_controls(res)


def exits_ok(res: Result, rc: int = 0) -> str | None:
    """Exit ``rc`` (default 0) with no traceback."""
    if res.rc != rc:
        return f"exit {res.rc}, expected {rc}: {res.show()}"
    if "Traceback" in res.err:
        return f"a traceback: {res.show()}"
    return None


def raw_controls(res: Result) -> str | None:
    """A raw terminal control (ESC, BEL, C1, a bidi override) in either stream, or None."""
    for name, text in (("stdout", res.out), ("stderr", res.err)):
        m = CONTROLS.search(text)
        if m:
            at = m.start()
            return f"raw control U+{ord(m.group()):04X} on {name}: {text[max(0, at - 40):at + 20]!r}"
    return None


def no_traceback(res: Result) -> str | None:
    """No Python traceback in either stream and not killed at the time limit."""
    if res.rc is None:
        return f"still running after {res.seconds:.0f} s (killed)"
    if "Traceback" in res.err or "Traceback" in res.out:
        return f"a traceback: {res.show()}"
    return None


def rows(folder: Path) -> list[dict]:
    """The rows of ``folder/results.csv`` (empty when there is none)."""
    path = folder / "results.csv"
    if not path.exists():
        return []
    with path.open(newline="") as fh:
        return list(csv.DictReader(fh))


def failed_row(folder: Path, label: str, *words: str, statuses=("failed",)) -> str | None:
    """The row of method label ``label`` has one of ``statuses`` and an error naming every one of ``words``."""
    found = [r for r in rows(folder) if r.get("label") == label or r.get("method") == label]
    if not found:
        return f"no row for {label!r} in {folder.name}/results.csv"
    for r in found:
        if r.get("status") not in statuses:
            return f"{label}: status {r.get('status')!r}, expected {'/'.join(statuses)} ({r.get('error', '')[:160]!r})"
        missing = [w for w in words if w.lower() not in (r.get("error") or "").lower()]
        if missing:
            return f"{label}: the error does not name {missing}: {(r.get('error') or '')[:240]!r}"
        if CONTROLS.search(r.get("error") or ""):
            return f"{label}: a raw control in the row's error: {r['error'][:120]!r}"
    return None


def first(*reasons: str | None) -> str | None:
    """The first reason that is not None (checks in order)."""
    for r in reasons:
        if r:
            return r
    return None
