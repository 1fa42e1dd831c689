"""Tests of ``bench.cli.outputs``: :func:`check_outputs` before the work, :func:`write_mesh` atomically (no
partial or temporary file left on failure), :func:`refuse_non_finite` for vertices NaN, infinite or beyond
float32."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from bench.cli.outputs import FLOAT32_MAX, check_outputs, refuse_non_finite, write_mesh
from geometry.files import WriteError
from methods import ReconstructionFailed


def test_check_outputs_creates_folders_and_refuses_a_directory_or_a_file_in_the_way(tmp_path):
    check_outputs(tmp_path / "new" / "deep" / "mesh.ply", None)
    assert (tmp_path / "new" / "deep").is_dir() and not list((tmp_path / "new" / "deep").iterdir())
    with pytest.raises(WriteError, match="it is a directory"):
        check_outputs(tmp_path / "new")
    (tmp_path / "afile").write_text("x")
    with pytest.raises(WriteError, match="is a file, not a folder"):
        check_outputs(tmp_path / "afile" / "mesh.ply")


def test_write_mesh_writes_the_mesh_and_leaves_nothing_on_failure(tmp_path):
    ico = trimesh.creation.icosphere(subdivisions=1)
    out = write_mesh(ico, tmp_path / "m.ply", "ply")
    back = trimesh.load(out, process=False)
    np.testing.assert_allclose(back.vertices, ico.vertices, atol=1e-6)
    assert len(back.faces) == len(ico.faces)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["m.ply"]
    (tmp_path / "dir.ply").mkdir()
    with pytest.raises(WriteError):
        write_mesh(ico, tmp_path / "dir.ply", "ply")
    with pytest.raises(Exception):
        write_mesh(ico, tmp_path / "bad.xyz", "no_such_format")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["dir.ply", "m.ply"]   # no temp file, no partial one


def test_refuse_non_finite_vertices():
    ico = trimesh.creation.icosphere(subdivisions=1)
    refuse_non_finite(ico, "mine")                                 # finite: nothing happens
    for bad in (np.nan, np.inf, 2 * FLOAT32_MAX):
        m = ico.copy()
        m.vertices[3, 1] = bad
        with pytest.raises(ReconstructionFailed, match=r"method 'mine' returned non-finite .*1 of 42 vertices"):
            refuse_non_finite(m, "mine")
