"""Tests of ``methods.isosurface``: marching cubes at level 0 (exact zeros nudged, no zero crossing refused), the
mesh clean-up (duplicates merged, degenerate faces dropped, faces outward) and the hand-over to VTK (axis order, no
copy, one line when VTK is missing; a label map there and back in world units: test_methods_labelmap.py)."""

from __future__ import annotations

import sys

import numpy as np
import pytest
import trimesh

from methods.isosurface import (clean_mesh, closed_mesh, marching_cubes_mesh, nudge_zeros, orient_outward, require_vtk,
                                vtk_image)
from phantoms import InputError, Volume


def test_nudge_zeros_moves_only_the_zeros_a_hair_outside_and_copies_only_then():
    values = np.array([[-2.0, 0.0], [3.0, -0.0]])
    out = nudge_zeros(values)
    assert out is not values and np.array_equal(values, [[-2.0, 0.0], [3.0, 0.0]])      # input untouched
    assert np.array_equal(out[[0, 1], [0, 0]], [-2.0, 3.0]) and np.all(out[[0, 1], [1, 1]] == 1e-9 * 3.0)
    no_zero = np.array([1.0, -1.0])
    assert nudge_zeros(no_zero) is no_zero


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


def test_closed_mesh_keeps_shared_vertices_unless_asked_and_refuses_an_empty_surface():
    ico = trimesh.creation.icosphere(subdivisions=1)
    v = np.vstack([ico.vertices, ico.vertices[:1]])            # a duplicate of vertex 0, used by one face
    f = ico.faces[:, ::-1].copy()
    f[0][f[0] == 0] = len(v) - 1
    kept = closed_mesh(v, f, "t", merge=False)
    merged = closed_mesh(v, f, "t")
    assert len(kept.vertices) == len(v) and not kept.is_watertight
    assert len(merged.vertices) == len(ico.vertices) and merged.is_watertight and merged.volume > 0
    with pytest.raises(InputError, match="method 't': no surface was extracted"):
        closed_mesh(v, np.zeros((0, 3), np.int64), "t")


def test_the_image_views_the_array_with_its_axes_reversed():
    """VTK's point (i, j, k) (x fastest) is our values[k, j, i]; spacing and origin reversed; no copy."""
    from vtkmodules.util import numpy_support

    a = np.arange(2 * 3 * 4, dtype=float).reshape(2, 3, 4)
    image = vtk_image(a, origin=(1.0, 2.0, 3.0), spacing=(0.5, 0.25, 2.0), scalars="phi")
    assert image.GetDimensions() == (4, 3, 2) and image.GetSpacing() == (2.0, 0.25, 0.5)
    assert image.GetOrigin() == (3.0, 2.0, 1.0)
    flat = numpy_support.vtk_to_numpy(image.GetPointData().GetArray("phi"))
    assert np.shares_memory(flat, a)
    assert flat[image.ComputePointId((3, 1, 0))] == a[0, 1, 3]


def test_without_vtk_one_line_naming_the_package(monkeypatch):
    # a None entry in sys.modules makes `import` raise ImportError, as if VTK were not installed
    monkeypatch.setitem(sys.modules, "vtkmodules.vtkFiltersCore", None)
    with pytest.raises(InputError) as exc:
        require_vtk("m", "vtkmodules.vtkFiltersCore")
    assert "\n" not in str(exc.value) and "method 'm' needs VTK" in str(exc.value)
    assert require_vtk("m", "vtkmodules.vtkCommonDataModel").vtkImageData is not None
