"""Tests of ``methods.marching_cubes``: the :class:`MarchingCubes` baseline (closed, outward, within half a grid
spacing of the clean phantoms at N = 96; its options), :func:`marching_cubes_mesh`, :func:`clean_mesh`,
:func:`orient_outward` (the mesh facts it reports: ``geometry.mesh.mesh_facts``, test_geometry_mesh.py)."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from _baselines import PHANTOMS, check, reconstruct, volume
from geometry.mesh import mesh_facts
from methods import get_method
from methods.marching_cubes import clean_mesh, marching_cubes_mesh, orient_outward
from phantoms import InputError, Volume, get_phantom


@pytest.mark.parametrize("phantom", PHANTOMS)
def test_marching_cubes_baseline(phantom):
    check("marching_cubes", phantom)


def test_marching_cubes_options_agree():
    vol = volume("sphere")
    a = get_method("marching_cubes", method="lorensen").reconstruct(vol).mesh
    b = reconstruct("marching_cubes", "sphere").mesh
    assert mesh_facts(a)["watertight"] and abs(a.volume - b.volume) < 1e-3
    coarse = get_method("marching_cubes", step_size=3).reconstruct(vol).mesh
    assert coarse.is_watertight and coarse.euler_number == 2 and len(coarse.vertices) < len(b.vertices) / 4


def test_marching_cubes_on_a_small_sphere_is_closed_outward_and_close():
    ph = get_phantom("sphere")
    vol = ph.volume(n=24)
    rec = get_method("marching_cubes").reconstruct(vol)
    mesh = rec.mesh
    assert mesh.is_watertight and mesh.euler_number == 2 and mesh.volume > 0
    assert np.abs(np.linalg.norm(mesh.vertices, axis=1) - 1.0).max() < 0.2 * vol.h
    assert rec.info["mesh_watertight"] and rec.info["mesh_euler"] == 2 and rec.info["stop_reason"] == "done"
    assert rec.info["mesh_vertices"] == len(mesh.vertices)


def test_exact_zeros_on_grid_points_still_give_a_manifold_mesh():
    """A sphere of radius 6 voxels whose SDF is exactly 0 at the six axis grid points."""
    idx = np.indices((17, 17, 17)).reshape(3, -1).T - 8.0
    values = (np.linalg.norm(idx, axis=1) - 6.0).reshape(17, 17, 17)
    assert (values == 0).sum() >= 6
    mesh = marching_cubes_mesh(Volume(values, np.full(3, -8.0), np.ones(3)))
    assert mesh.is_watertight and mesh.euler_number == 2 and mesh.volume > 0


def test_a_volume_without_a_zero_crossing_is_refused():
    with pytest.raises(InputError, match="no zero crossing"):
        marching_cubes_mesh(Volume(np.ones((8, 8, 8))))


def test_clean_mesh_merges_duplicates_drops_degenerate_faces_and_orients_outward():
    ico = trimesh.creation.icosphere(subdivisions=1)
    v, f = ico.vertices, ico.faces[:, ::-1]                   # inward
    soup = v[f].reshape(-1, 3)                                 # every face with its own three vertices
    faces = np.arange(len(soup)).reshape(-1, 3)
    faces = np.vstack([faces, [[0, 0, 1]], faces[:1]])         # a degenerate and a duplicate face
    mesh = clean_mesh(soup, faces)
    assert len(mesh.vertices) == len(v) and len(mesh.faces) == len(f)
    assert mesh.is_watertight and mesh.volume > 0


def test_orient_outward_flips_an_inward_mesh_in_place():
    ico = trimesh.creation.icosphere(subdivisions=1)
    inward = trimesh.Trimesh(ico.vertices, ico.faces[:, ::-1], process=False)
    assert orient_outward(inward) is inward and inward.volume > 0
    np.testing.assert_array_equal(orient_outward(inward.copy()).faces, inward.faces)   # outward: untouched
