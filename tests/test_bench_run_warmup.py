"""Tests of ``bench.run.warmup``: importing it warms this process (every step of a cell runs without error:
``WARM_SECONDS`` is a number, not None), and a failing step makes :func:`warm` return None, never raise."""

from __future__ import annotations

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
