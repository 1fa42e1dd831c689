"""Tests of ``phantoms.mesh.grid_kernels``, the compiled kernels of the grid signed distance, one by one:
:func:`tri_eval` against :func:`geometry.closest.closest_point_on_triangles`, :func:`mark_band` against the
distance to the vertices, the neighbour table against three nested loops.  (The whole grid:
test_phantoms_mesh_grid_sdf.py.)"""

from __future__ import annotations

import numpy as np
import trimesh

from geometry.closest import closest_point_on_triangles
from phantoms.mesh import grid_kernels as gk
from phantoms.mesh.index import TriangleIndex


def _mesh():
    m = trimesh.creation.icosphere(subdivisions=2, radius=1.0)
    return np.asarray(m.vertices), np.asarray(m.faces)


def test_tri_eval_is_the_suites_point_triangle_kernel_bit_for_bit():
    """tri_eval calls geometry.closest's kernel from another file, which numba's cache does not track: equal to
    the numpy reference bit for bit (a stale cache after a change of the kernel fails here), degenerate faces too."""
    v, f = _mesh()
    f = np.vstack([f, [[0, 0, 1], [5, 5, 5]]])                  # a segment and a point
    idx = TriangleIndex(v, f)
    rng = np.random.default_rng(0)
    p = rng.normal(size=(400, 3)) * 1.5
    faces = np.concatenate([rng.integers(0, len(f), 300), np.repeat([len(f) - 2, len(f) - 1], 50)])
    a, b, c = (v[f[faces, k]] for k in range(3))
    d2, feat, _, _ = closest_point_on_triangles(p, a, b, c)
    got = [gk.tri_eval(q[0], q[1], q[2], idx.tri, int(t)) for q, t in zip(p, faces)]
    np.testing.assert_array_equal([g[0] for g in got], np.sqrt(d2))
    np.testing.assert_array_equal([g[1] for g in got], feat)


def test_mark_band_marks_the_grid_points_within_the_radius_of_a_vertex():
    v, _ = _mesh()
    axis = np.linspace(-1.5, 1.5, 16)
    state = np.zeros((16, 16, 16), np.int8)
    gk.mark_band(v, axis, 0.3, state, 7)
    g = np.stack(np.meshgrid(axis, axis, axis, indexing="ij"), -1).reshape(-1, 3)
    d = np.linalg.norm(g[:, None] - v[None], axis=2).min(1).reshape(16, 16, 16)
    np.testing.assert_array_equal(state == 7, d <= 0.3)
    assert set(np.unique(state)) == {0, 7}


def test_the_neighbour_table_is_the_26_offsets_in_nested_loop_order():
    """The propagation's visiting order (ties go to the first neighbour) is that of three nested loops."""
    loops = [(di, dj, dk) for di in (-1, 0, 1) for dj in (-1, 0, 1) for dk in (-1, 0, 1) if (di, dj, dk) != (0, 0, 0)]
    assert gk.NEIGHBOURS.tolist() == [list(t) for t in loops]
    n = 5
    np.testing.assert_array_equal(gk.neighbour_offsets(n), [(di * n + dj) * n + dk for di, dj, dk in loops])
    grid = np.arange(n ** 3).reshape(n, n, n)
    for i, j, k in [(0, 0, 0), (2, 2, 2), (4, 1, 0), (2, 4, 3)]:
        r = int(grid[i, j, k])
        want = [int(grid[i + di, j + dj, k + dk]) if 0 <= i + di < n and 0 <= j + dj < n and 0 <= k + dk < n else -1
                for di, dj, dk in loops]
        got = [gk._neighbour(r, m, n, gk.neighbour_offsets(n)) for m in range(26)]
        assert got == want
        assert gk._interior(r, n) == (-1 not in want)
