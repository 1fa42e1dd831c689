"""Test-session settings shared by every test folder."""

from __future__ import annotations


def pytest_xdist_auto_num_workers(config):
    """``-n auto`` (the default addopts) means one process when benchmarks are timed: pytest-benchmark measures
    nothing under xdist, and timings beside another worker would measure the load."""
    if config.getoption("benchmark_enable", default=False):
        return 0
    return None
