"""The curvature neighbourhood in bounded memory and time (issue 30): :func:`geometry.mesh.radius_neighbors`
(the 1-ring, then the nearest others within the radius, at most ``MAX_NEIGHBORS``) by a k-nearest query bounded
by the radius, block by block, and :func:`geometry.radius_curvature` fitting block by block — against the
all-pairs construction they replace, and the memory of scoring a dense mesh measured in a child process."""

from __future__ import annotations

import json
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest
import trimesh
from scipy.spatial import cKDTree

from geometry import MAX_NEIGHBORS, one_ring, paraboloid_curvature, radius_curvature, vertex_normals
from geometry.mesh import padded_from_pairs, radius_neighbor_blocks, radius_neighbors
from geometry.topology import edges_unique


def all_pairs_neighbors(vertices, faces, radius, max_width=MAX_NEIGHBORS):
    """The construction before issue 30: every pair within the radius (``query_pairs``), the ring edges dropped,
    ordered by distance, the 1-ring first — O(pairs in the ball) memory, the reference here."""
    vertices = np.asarray(vertices, float)
    e = edges_unique(faces).astype(np.int64)
    pairs = cKDTree(vertices).query_pairs(float(radius), output_type="ndarray").astype(np.int64)
    nv = np.int64(len(vertices))
    ekey = e[:, 0] * nv + e[:, 1]
    pkey = pairs[:, 0] * nv + pairs[:, 1]
    pairs = pairs[~np.isin(pkey, ekey)]
    pi = np.concatenate([pairs[:, 0], pairs[:, 1]])
    pj = np.concatenate([pairs[:, 1], pairs[:, 0]])
    o = np.argsort(np.linalg.norm(vertices[pi] - vertices[pj], axis=1), kind="stable")
    return padded_from_pairs(np.concatenate([e[:, 0], e[:, 1], pi[o]]), np.concatenate([e[:, 1], e[:, 0], pj[o]]),
                             len(vertices), max_width=max_width)


@pytest.fixture(scope="module")
def mc_sphere():
    """Marching cubes of the sphere at N = 64: a normal scoring mesh (~20 vertices in a 2h ball)."""
    from methods import get_method
    from phantoms import get_phantom

    vol = get_phantom("sphere").volume(n=64)
    m = get_method("marching_cubes").reconstruct(vol).mesh
    return np.asarray(m.vertices, float), np.asarray(m.faces, np.int64), 2.0 * vol.h


def _rows(nb):
    return [r[r >= 0] for r in nb]


def test_below_the_cap_the_bounded_query_equals_all_pairs(mc_sphere):
    v, f, r = mc_sphere
    ref = all_pairs_neighbors(v, f, r)
    nb = radius_neighbors(v, f, r)
    assert (ref >= 0).sum(axis=1).max() < MAX_NEIGHBORS          # the cap does not bind here
    assert nb.shape == ref.shape
    ring = _rows(one_ring(f, len(v)))
    for i, (a, b) in enumerate(zip(_rows(ref), _rows(nb))):
        assert set(a) == set(b)
        w = len(ring[i])
        assert np.array_equal(b[:w], ring[i])                     # the 1-ring first, in one_ring order
        d = np.linalg.norm(v[b[w:]] - v[i], axis=1)
        assert np.all(np.diff(d) >= 0) and np.all(d <= r)          # then the others, nearest first
    # so the fit is the same (the order of equally distant neighbours may differ: sums to rounding)
    n = vertex_normals(v, f)
    H0, K0 = paraboloid_curvature(v, n, ref)
    H1, K1 = radius_curvature(v, f, r)
    np.testing.assert_allclose(H1, H0, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(K1, K0, rtol=1e-12, atol=1e-11)


def test_a_jittered_mesh_gives_the_all_pairs_fit_bit_for_bit():
    """No two distances equal → the same rows in the same order → the same numbers exactly."""
    m = trimesh.creation.icosphere(4)
    v = m.vertices + np.random.default_rng(3).normal(0.0, 1e-3, m.vertices.shape)
    r = 0.12                                                       # ~15 vertices per ball
    ref = all_pairs_neighbors(v, m.faces, r)
    assert np.array_equal(radius_neighbors(v, m.faces, r), ref)
    H0, K0 = paraboloid_curvature(v, vertex_normals(v, m.faces), ref)
    H1, K1 = radius_curvature(v, m.faces, r, block=700, compiled=False)   # numpy vs numpy: bit for bit
    assert np.array_equal(H0, H1) and np.array_equal(K0, K1)


def test_above_the_cap_rows_keep_the_ring_and_the_nearest_others():
    m = trimesh.creation.icosphere(4)                              # 2,562 vertices
    v = m.vertices + np.random.default_rng(4).normal(0.0, 1e-4, m.vertices.shape)
    r = 0.43                                                       # 2h at N = 24: ~120 vertices per ball
    ref = all_pairs_neighbors(v, m.faces, r, max_width=10_000)
    nb = radius_neighbors(v, m.faces, r)
    assert nb.shape[1] == MAX_NEIGHBORS and (ref >= 0).sum(axis=1).min() > MAX_NEIGHBORS
    ring = _rows(one_ring(m.faces, len(v)))
    for i, (full, kept) in enumerate(zip(_rows(ref), _rows(nb))):
        assert len(kept) == MAX_NEIGHBORS
        assert np.array_equal(kept, full[:MAX_NEIGHBORS])          # the all-pairs rows cut at the cap
        assert np.array_equal(kept[:len(ring[i])], ring[i])
    # and the capped reference fits the same
    H0, K0 = paraboloid_curvature(v, vertex_normals(v, m.faces), ref[:, :MAX_NEIGHBORS])
    H1, K1 = radius_curvature(v, m.faces, r, compiled=False)
    assert np.array_equal(H0, H1) and np.array_equal(K0, K1)


def test_blocks_cover_every_vertex_once_and_the_block_size_changes_nothing(mc_sphere):
    v, f, r = mc_sphere
    spans = [(s, t) for s, t, _ in radius_neighbor_blocks(v, f, r, block=1000)]
    assert spans[0][0] == 0 and spans[-1][1] == len(v) and all(a[1] == b[0] for a, b in zip(spans, spans[1:]))
    H0, K0 = radius_curvature(v, f, r, block=len(v), compiled=False)
    H1, K1 = radius_curvature(v, f, r, block=333, compiled=False)
    assert np.array_equal(H0, H1, equal_nan=True) and np.array_equal(K0, K1, equal_nan=True)
    # and the one-shot fit over the whole neighbour array
    H2, K2 = paraboloid_curvature(v, vertex_normals(v, f), radius_neighbors(v, f, r))
    assert np.array_equal(H0, H2, equal_nan=True) and np.array_equal(K0, K2, equal_nan=True)


def test_a_mesh_smaller_than_k_and_a_ring_wider_than_the_cap():
    tet = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1.0]])
    f = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
    nb = radius_neighbors(tet, f, 10.0)                            # k = 97 > 4 vertices
    assert [sorted(r) for r in _rows(nb)] == [[1, 2, 3], [0, 2, 3], [0, 1, 3], [0, 1, 2]]
    # a fan of 120 triangles: the hub's ring (120) is cut at the cap, its first entries kept
    k = 120
    ang = np.linspace(0, 2 * np.pi, k, endpoint=False)
    v = np.vstack([[0, 0, 0], np.column_stack([np.cos(ang), np.sin(ang), np.zeros(k)])])
    faces = np.column_stack([np.zeros(k, int), 1 + np.arange(k), 1 + (np.arange(k) + 1) % k])
    nb = radius_neighbors(v, faces, 0.01)
    assert np.array_equal(nb[0], one_ring(faces, len(v))[0][:MAX_NEIGHBORS])


_SCRIPT = textwrap.dedent("""
    import json, sys, time
    sys.path.insert(0, {root!r})

    def peak_mb():
        # VmHWM: this process's own peak (ru_maxrss keeps the parent's RSS at fork on Linux)
        with open("/proc/self/status") as fh:
            for line in fh:
                if line.startswith("VmHWM:"):
                    return int(line.split()[1]) / 1024

    import trimesh
    from phantoms import get_phantom
    from bench.metrics import evaluate
    m = trimesh.creation.icosphere(subdivisions={sub}, radius=1.0)
    t0 = time.perf_counter()
    row = evaluate(m, get_phantom("sphere"), 5.0 / ({n} - 1))
    print(json.dumps({{"faces": len(m.faces), "seconds": time.perf_counter() - t0, "peak_rss_mb": peak_mb(),
                      "H_rms_err": row["H_rms_err"], "hausdorff_h": row["hausdorff_h"]}}))
""")


def _score_in_child(sub, n):
    root = str(Path(__file__).resolve().parents[1])
    out = subprocess.run([sys.executable, "-c", _SCRIPT.format(root=root, sub=sub, n=n)], capture_output=True,
                         text=True, timeout=1200, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def test_scoring_an_82k_face_icosphere_at_n24_stays_under_1_gb():
    """~1,900 vertices in each 2h ball: before issue 30 the all-pairs list of the balls took 8.1 GB and 269 s
    (0.31 GB, 2 s after; ~4 s for this test with the child's imports on a quiet machine, so not ``heavy``)."""
    res = _score_in_child(6, 24)
    print(res)
    assert res["faces"] == 81_920
    assert res["peak_rss_mb"] < 1024
    assert res["H_rms_err"] < 0.05 and res["hausdorff_h"] < 0.01


@pytest.mark.parametrize("dense", [False, True])
def test_the_compiled_fit_equals_the_numpy_fit(mc_sphere, dense):
    from geometry import compiled

    if not compiled.AVAILABLE:
        pytest.skip("numba missing")
    if dense:
        m = trimesh.creation.icosphere(4)
        v, f, r = np.asarray(m.vertices), np.asarray(m.faces), 0.43       # the cap binds
    else:
        v, f, r = mc_sphere
    H0, K0 = radius_curvature(v, f, r, compiled=False, block=1000)
    H1, K1 = radius_curvature(v, f, r, compiled=True, block=1000)
    assert np.array_equal(np.isnan(H0), np.isnan(H1))
    np.testing.assert_allclose(H1, H0, rtol=1e-11, atol=1e-12)
    np.testing.assert_allclose(K1, K0, rtol=1e-10, atol=1e-11)
