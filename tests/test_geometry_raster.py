"""geometry/raster.py: the mesh's winding number at every grid point, against gpytoolbox's fast winding number."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh
from gpytoolbox import fast_winding_number

import geometry.raster as raster
from geometry.raster import grid_winding
from phantoms import get_phantom


def _reference(v, f, vol):
    pts = vol.grid_points().reshape(-1, 3)
    return (fast_winding_number(pts, v, f.astype(np.int32)) > 0.5).reshape(vol.shape)


@pytest.mark.parametrize("name, n", [("ellipsoid", 40), ("fused_spheres", 36), ("torus", 44)])
def test_marching_cubes_meshes_match_the_fast_winding_number(name, n):
    """Marching cubes puts vertices exactly on grid lines, the degenerate case the column offset handles."""
    from skimage.measure import marching_cubes

    vol = get_phantom(name).volume(n=n)
    v, f, _, _ = marching_cubes(vol.values, 0.0, spacing=tuple(vol.spacing))
    v += vol.origin
    w = grid_winding(v, f, vol.origin, vol.spacing, vol.shape)
    assert set(np.unique(w)) <= {0, 1}
    assert np.array_equal(w != 0, _reference(v, f, vol))
    assert np.array_equal(grid_winding(v, f[:, ::-1], vol.origin, vol.spacing, vol.shape), -w)


def test_coarse_triangles_anisotropic_grid_and_batches(monkeypatch):
    """An icosphere with triangles spanning many columns, on an anisotropic grid, in many small batches."""
    mesh = trimesh.creation.icosphere(subdivisions=1, radius=1.3)
    from phantoms import Volume

    vol = Volume(np.zeros((23, 31, 17)), origin=[-1.6, -1.7, -1.5], spacing=[0.15, 0.11, 0.2])
    v, f = np.asarray(mesh.vertices), np.asarray(mesh.faces)
    full = grid_winding(v, f, vol.origin, vol.spacing, vol.shape)
    monkeypatch.setattr(raster, "_BATCH", 7)
    assert np.array_equal(grid_winding(v, f, vol.origin, vol.spacing, vol.shape), full)
    assert np.array_equal(full != 0, _reference(v, f, vol)) and full.sum() > 1000


def test_two_nested_spheres_count_twice_and_an_empty_mesh_nothing():
    a = trimesh.creation.icosphere(subdivisions=2, radius=1.0)
    b = trimesh.creation.icosphere(subdivisions=2, radius=0.5)
    v = np.vstack([a.vertices, b.vertices])
    f = np.vstack([a.faces, b.faces + len(a.vertices)])
    from phantoms import Volume

    vol = Volume(np.zeros((21, 21, 21)), origin=[-1.2] * 3, spacing=0.12)
    w = grid_winding(v, f, vol.origin, vol.spacing, vol.shape)
    assert w[10, 10, 10] == 2 and w[10, 10, 15] == 1 and w[0, 0, 0] == 0
    assert not grid_winding(v, np.zeros((0, 3), int), vol.origin, vol.spacing, vol.shape).any()


def _random_columns(lo, hi, m, k, seed):
    rng = np.random.default_rng(seed)
    step = (hi - lo) / m
    ij = np.stack(np.meshgrid(np.arange(m), np.arange(m), indexing="ij"), axis=-1)
    cols = lo[:2] + (ij + rng.random((m, m, 2))) * step[:2]
    z = rng.uniform(lo[2], hi[2], (m, m, k))
    return cols, z, step


@pytest.mark.parametrize("name, n", [("ellipsoid", 40), ("torus", 44), ("fused_spheres", 36)])
def test_column_winding_matches_the_fast_winding_number(name, n):
    """Columns at random positions inside their cells, queries at random heights: the same inside as FWN."""
    from skimage.measure import marching_cubes

    vol = get_phantom(name).volume(n=n)
    v, f, _, _ = marching_cubes(vol.values, 0.0, spacing=tuple(vol.spacing))
    v += vol.origin
    lo, hi = v.min(0) - 0.3, v.max(0) + 0.3
    cols, z, step = _random_columns(lo, hi, 17, 23, seed=1)
    w = raster.column_winding(v, f, lo, step, cols, z)
    pts = np.concatenate([np.broadcast_to(cols[:, :, None, :], z.shape + (2,)), z[..., None]], -1).reshape(-1, 3)
    ref = fast_winding_number(pts, v, f.astype(np.int32)).reshape(z.shape)
    assert set(np.unique(w)) <= {0, 1}
    assert 0.05 < (w == 1).mean() < 0.95
    assert np.array_equal(w == 1, ref > 0.5)
    assert np.array_equal(raster.column_winding(v, f[:, ::-1], lo, step, cols, z), -w)


def test_column_winding_of_nested_spheres_and_coarse_triangles():
    """Two nested outward icospheres: 2 inside the inner, 1 between, 0 outside — by the analytic radius."""
    a = trimesh.creation.icosphere(subdivisions=3, radius=1.0)
    b = trimesh.creation.icosphere(subdivisions=1, radius=0.5)
    v = np.vstack([a.vertices, b.vertices])
    f = np.vstack([a.faces, b.faces + len(a.vertices)])
    lo, hi = np.full(3, -1.2), np.full(3, 1.2)
    cols, z, step = _random_columns(lo, hi, 5, 40, seed=2)
    w = raster.column_winding(v, f, lo, step, cols, z)
    r = np.sqrt((cols[:, :, None, :] ** 2).sum(-1) + z ** 2)
    assert np.all(w[r < 0.35] == 2) and np.all(w[(r > 0.55) & (r < 0.9)] == 1) and np.all(w[r > 1.01] == 0)
    assert not raster.column_winding(v, f[:0], lo, step, cols, z).any()
