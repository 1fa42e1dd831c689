"""Running the benchmark suites: one fresh ``python -m pytest`` over ``tests/benchmarks`` (or chosen node ids),
pinned to a few CPUs with the native thread pools at one thread, its ``--benchmark-json`` turned into a
summary."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

from phantoms import InputError

from .baseline import summarise
from .timing import ENV_MODE, ENV_ROUNDS

__all__ = ["THREAD_ENV", "repo_root", "benchmarks_dir", "pinned_cpus", "run_suite"]

#: native thread pools pinned to one thread in the suite's process (unless already set): the reference is
#: single-threaded, so a benchmark's ratio must not depend on how many cores happen to be free
THREAD_ENV = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMEXPR_NUM_THREADS")


def repo_root() -> Path:
    return Path(__file__).resolve().parents[2]


def benchmarks_dir() -> Path:
    d = repo_root() / "tests" / "benchmarks"
    if not d.is_dir():
        raise InputError(f"the benchmark suites are not here ({d}): `bench perf` needs a source checkout")
    return d


def pinned_cpus(cpus: int) -> list[int] | None:
    """The CPUs the suite is pinned to: the last ``cpus`` of this process's allowed set (None: no pinning,
    ``cpus`` = 0 or no ``sched_setaffinity`` on this platform)."""
    if cpus <= 0 or not hasattr(os, "sched_getaffinity"):
        return None
    allowed = sorted(os.sched_getaffinity(0))
    return allowed[-cpus:] if cpus < len(allowed) else allowed


def _serial() -> list[str]:
    """pytest options that run the benchmarks in one process: pytest-benchmark times nothing under xdist."""
    import importlib.util

    return ["-n", "0"] if importlib.util.find_spec("xdist") is not None else []


def run_suite(*, quick: bool = False, select: list[str] | None = None, keyword: str | None = None,
              n_rounds: int | None = None, cpus: int = 1, stream=None) -> tuple[int, dict | None]:
    """Run the benchmark suites once in a fresh ``python -m pytest``; return (exit code, summary or None).

    ``select``: pytest node ids to run instead of the whole ``tests/benchmarks`` (reruns); ``keyword``: ``-k``.
    ``cpus``: pin the suite (and the worker processes it starts) to that many CPUs (default 1; 0 = no
    pinning).  On one CPU a multi-threaded benchmark runs like the single-threaded reference whatever the
    number of free cores, so its CPU-time ratio does not follow the other jobs' use of the machine.
    pytest's own output goes to ``stream`` (default: this process's stderr).
    """
    bdir = benchmarks_dir()
    root = repo_root()
    env = dict(os.environ)
    env[ENV_MODE] = "quick" if quick else "full"
    if n_rounds:
        env[ENV_ROUNDS] = str(int(n_rounds))
    for k in THREAD_ENV:
        env.setdefault(k, "1")
    for k in [k for k in env if k.startswith("PYTEST_XDIST")]:   # started from an xdist worker: time anyway
        del env[k]
    with tempfile.TemporaryDirectory(prefix="lsb-perf-") as tmp:
        out = Path(tmp) / "benchmark.json"
        cmd = [sys.executable, "-m", "pytest", *(select or [str(bdir.relative_to(root))]), "-m", "benchmark",
               "-p", "no:cacheprovider", "-q", "--benchmark-json", str(out), "--benchmark-sort=name",
               "--benchmark-columns=median,min,max,rounds", *_serial()]
        if keyword:
            cmd += ["-k", keyword]
        pin = pinned_cpus(cpus)
        pre = (lambda: os.sched_setaffinity(0, pin)) if pin else None
        target = stream if stream is not None else sys.stderr
        try:
            fd = target.fileno()
        except (AttributeError, OSError, ValueError):  # a stream without a file descriptor (tests)
            fd = None
        if fd is not None:
            proc = subprocess.run(cmd, cwd=root, env=env, stdout=fd, stderr=fd, preexec_fn=pre)
        else:
            proc = subprocess.run(cmd, cwd=root, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                                  text=True, preexec_fn=pre)
            target.write(proc.stdout)
        summary = None
        if out.exists():
            try:
                summary = summarise(json.loads(out.read_text(encoding="utf-8")))
            except (ValueError, InputError):
                summary = None
    if summary is not None:
        summary["threads"] = {k: env[k] for k in THREAD_ENV}
        summary["pinned_cpus"] = pin
    return proc.returncode, summary
