"""Tests of ``bench.run.warmup``: importing it warms this process (every step of a cell runs without error:
``WARM_SECONDS`` is a number, not None), and a failing step makes :func:`warm` return None, never raise; the
method libraries it imports start no thread (a process forked after a thread pool started could deadlock)."""

from __future__ import annotations

import os
import subprocess
import sys

import methods


def test_importing_warmup_runs_every_step_without_error():
    from bench.run import warmup

    assert warmup.WARM_SECONDS is not None and warmup.WARM_SECONDS > 0   # None: a step failed silently


def test_a_failing_step_is_swallowed_and_reported_as_none(monkeypatch):
    from bench.run import warmup

    def broken(*args, **kwargs):
        raise RuntimeError("no methods today")

    monkeypatch.setattr(warmup, "WARM_SECONDS", warmup.WARM_SECONDS)     # put back after the test
    monkeypatch.setattr(methods, "get_method", broken)
    assert warmup.warm() is None and warmup.WARM_SECONDS is None


_COUNT_THREADS = """
import importlib, sys, threading
def native():
    return next(int(line.split()[1]) for line in open("/proc/self/status") if line.startswith("Threads:"))
before = native(), threading.active_count()
for module in sys.argv[1:]:
    importlib.import_module(module)
after = native(), threading.active_count()
print(before == after, before, after)
"""


def test_the_method_libraries_it_imports_start_no_thread():
    """In a fresh process with the executor's one-thread environment: importing the modules the fork server
    preloads for the methods leaves the process's threads (native, /proc) and Python threads as they were."""
    from bench.run.warmup import method_imports

    modules = method_imports()
    assert {"pymeshlab", "gpytoolbox", "pyamg"} <= set(modules)        # the shape gradient's lazy imports
    if not os.path.exists("/proc/self/status"):
        return
    env = {**os.environ, **{v: "1" for v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS",
                                              "NUMEXPR_NUM_THREADS")}}
    out = subprocess.run([sys.executable, "-c", _COUNT_THREADS, "numpy", "scipy.spatial", *modules], env=env,
                         capture_output=True, text=True, check=True).stdout.strip()
    assert out.startswith("True"), f"threads (native, Python) before and after the imports: {out}"
