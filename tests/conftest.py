"""Test-session settings shared by every test folder."""

from __future__ import annotations

import pytest


def pytest_xdist_auto_num_workers(config):
    """``-n auto`` (the default addopts) means one process when benchmarks are timed: pytest-benchmark measures
    nothing under xdist, and timings beside another worker would measure the load."""
    if config.getoption("benchmark_enable", default=False):
        return 0
    return None


@pytest.fixture()
def modules_on_path(tmp_path, monkeypatch):
    """A function writing ``{module name: source}`` as module files into a folder put first on ``sys.path`` (for
    this test only); it returns the folder."""
    def write(sources: dict[str, str]):
        for name, text in sources.items():
            (tmp_path / f"{name}.py").write_text(text)
        monkeypatch.syspath_prepend(str(tmp_path))
        return tmp_path
    return write


@pytest.fixture(scope="session")
def uneven_mesh():
    """``(vertices, faces, points)``: a stretched icosphere's long slivers beside tiny triangles, two zero-area
    faces, and 500 points near and far — the hard case of the distance queries (geometry/closest.py, bvh.py)."""
    import numpy as np
    import trimesh

    m = trimesh.creation.icosphere(3)
    v = np.asarray(m.vertices) * [6.0, 1.0, 0.2]
    f = np.vstack([m.faces, [[0, 0, 1], [5, 5, 5]]])
    return v, f, np.random.default_rng(4).normal(size=(500, 3)) * [5, 1, 1]
