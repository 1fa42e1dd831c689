"""Tests of ``bench.report.artifacts``: :class:`Artifacts` reads a cell's ``.npz`` lazily and once, the final
mesh and the kept snapshots (fitting H when a snapshot has none), the energy history; a missing or corrupt
archive is None (with a warning), never an error."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from bench.report.artifacts import Artifacts
from bench.run.store import CELLS_DIR


@pytest.fixture()
def run(tmp_path):
    cells = tmp_path / CELLS_DIR
    cells.mkdir()
    m = trimesh.creation.icosphere(subdivisions=2, radius=1.0)
    v, f = np.asarray(m.vertices), np.asarray(m.faces)
    np.savez(cells / "full.npz", vertices=v, faces=f, H=np.ones(len(v)), energy_history=np.array([3.0, 2.0, 1.0]),
             snapshot_iterations=np.array([0, 5]), snap0_vertices=2 * v, snap5_vertices=v, snap5_H=np.zeros(len(v)),
             spacing=np.array(0.2))
    np.savez(cells / "bare.npz", energy_history=np.array([1.0]))
    (cells / "broken.npz").write_bytes(b"PK\x03\x04 truncated")
    return tmp_path, v, f


def test_the_final_mesh_snapshots_and_energy(run):
    out, v, f = run
    art = Artifacts(out)
    vv, ff, H, _ = art.mesh("full")
    np.testing.assert_array_equal(vv, v) and np.testing.assert_array_equal(ff, f)
    np.testing.assert_array_equal(H, 1.0)
    assert art.has_snapshots("full") and art.snapshot_iterations("full") == [0, 5]
    v5, _, H5, _ = art.mesh("full", 5)
    np.testing.assert_array_equal(v5, v) and np.testing.assert_array_equal(H5, 0.0)
    v0, f0, H0, _ = art.mesh("full", 0)                          # no stored H: fitted, 1/R on a sphere of R = 2
    np.testing.assert_array_equal(f0, f)
    assert np.nanmedian(H0) == pytest.approx(0.5, rel=0.05)
    assert art.mesh("full", 3) is None                           # not kept
    np.testing.assert_array_equal(art.energy("full"), [3.0, 2.0, 1.0])
    assert art.get("full") is art.get("full")                    # read once


def test_cells_without_a_mesh_missing_or_corrupt(run):
    out, _, _ = run
    warnings = []
    art = Artifacts(out, warn=warnings.append)
    assert art.mesh("bare") is None and not art.has_snapshots("bare") and art.snapshot_iterations("bare") == []
    assert art.get("missing") is None and art.energy("missing") is None and not art.has_snapshots("missing")
    assert warnings == []                                        # a cell without arrays is not a problem
    assert not art.has_snapshots("broken")
    assert art.get("broken") is None and art.mesh("broken") is None
    assert len(warnings) == 1 and "broken.npz does not load" in warnings[0]
