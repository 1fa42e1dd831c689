"""bench.run.lock: one run per folder — a live owner is named (exit 2), a stale lock is taken over."""

from __future__ import annotations

import json
import os
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest

from bench.run.lock import LOCK_FILE, LockedError, RunLock, lock_owner_alive, read_lock

REPO = Path(__file__).resolve().parent.parent
TESTS = Path(__file__).resolve().parent


def _dead_pid() -> int:
    """The PID of a process that has exited (and been reaped)."""
    proc = subprocess.Popen([sys.executable, "-c", "pass"])
    proc.wait()
    return proc.pid


def test_the_lock_names_its_owner_and_is_released(tmp_path):
    with RunLock(tmp_path) as lock:
        info = read_lock(tmp_path)
        assert info["pid"] == os.getpid() and info["host"] == socket.gethostname() and info["started"]
        assert lock.held
    assert read_lock(tmp_path) is None
    assert sorted(p.name for p in tmp_path.iterdir()) == []          # no temp file either


def test_a_live_lock_refuses_naming_pid_and_host(tmp_path):
    sleeper = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])
    try:
        (tmp_path / LOCK_FILE).write_text(json.dumps({"pid": sleeper.pid, "host": socket.gethostname(),
                                                       "started": "2026-01-01T00:00:00"}))
        with pytest.raises(LockedError, match=f"PID {sleeper.pid} on host {socket.gethostname()}"):
            RunLock(tmp_path).acquire()
        assert read_lock(tmp_path)["pid"] == sleeper.pid             # the owner's lock is untouched
    finally:
        sleeper.kill()
        sleeper.wait()


def test_a_stale_lock_is_taken_over_with_a_message(tmp_path, capsys):
    pid = _dead_pid()
    (tmp_path / LOCK_FILE).write_text(json.dumps({"pid": pid, "host": socket.gethostname(), "started": "x"}))
    with RunLock(tmp_path) as lock:
        assert lock.took_over["pid"] == pid and read_lock(tmp_path)["pid"] == os.getpid()
    err = capsys.readouterr().err
    assert f"PID {pid}" in err and "no longer running" in err and "taking it over" in err


def test_a_reused_pid_is_not_the_owner(tmp_path):
    """The lock keeps the owner's process start time: a live process with the same PID but another start time
    (the PID was reused after the owner died) does not hold the folder."""
    me = {"pid": os.getpid(), "host": socket.gethostname(), "started": "x"}
    assert lock_owner_alive({**me, "proc_start": RunLock(tmp_path).info["proc_start"]})
    assert not lock_owner_alive({**me, "proc_start": "1"})
    assert not lock_owner_alive({**me, "pid": _dead_pid()})


def test_a_lock_from_another_host_is_respected(tmp_path):
    (tmp_path / LOCK_FILE).write_text(json.dumps({"pid": 1, "host": "elsewhere.example", "started": "x"}))
    with pytest.raises(LockedError, match="elsewhere.example"):
        RunLock(tmp_path).acquire()


def _env() -> dict:
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(TESTS), str(REPO)] + [p for p in [env.get("PYTHONPATH")] if p])
    env["PYTHONWARNINGS"] = "ignore"
    return env


@pytest.mark.heavy
def test_two_runs_into_one_folder_the_second_exits_2_naming_the_owner(tmp_path):
    """A slow grid (a method that sleeps) holds the folder; a second run into it, with or without --resume and
    even with another config, exits 2 naming the first run's PID; the first run finishes normally."""
    out = tmp_path / "run"
    base = ["--quick", "--phantoms", "sphere", "--noise", "none", "--n", "16", "--n-samples", "2000",
            "--import", "runner_plugins", "--no-report", "--jobs", "1", "--out", str(out)]
    first = subprocess.Popen([sys.executable, "-m", "bench", "run", *base, "--method", "sleepy:seconds=4"],
                             cwd=REPO, env=_env(), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 60
        while not (out / LOCK_FILE).exists() and time.monotonic() < deadline and first.poll() is None:
            time.sleep(0.05)
        assert (out / LOCK_FILE).exists(), "the first run never locked its folder"
        for extra in (["--method", "marching_cubes"], ["--method", "sleepy:seconds=4", "--resume"]):
            second = subprocess.run([sys.executable, "-m", "bench", "run", *base, *extra], cwd=REPO, env=_env(),
                                    capture_output=True, text=True, timeout=120)
            assert second.returncode == 2, second.stderr
            last = second.stderr.strip().splitlines()[-1]
            assert f"in use by another run: PID {first.pid}" in last and "Traceback" not in second.stderr
        stdout, stderr = first.communicate(timeout=120)
    finally:
        if first.poll() is None:
            first.kill()
    assert first.returncode == 0, stderr
    assert "1 cells:" in stdout and not (out / LOCK_FILE).exists()  # (sleepy fails by design)
