"""Tests of ``methods.marching_cubes``: the :class:`MarchingCubes` baseline (closed, outward, within half a grid
spacing of the clean phantoms at N = 96; its options; the mesh facts it reports: ``geometry.mesh.mesh_facts``,
test_geometry_mesh.py).  Its mesh function and clean-up: test_methods_isosurface.py."""

from __future__ import annotations

import numpy as np
import pytest

from _baselines import PHANTOMS, check, reconstruct, volume
from geometry.mesh import mesh_facts
from methods import get_method
from phantoms import get_phantom


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
