"""Tests of ``phantoms.mesh.phantom``: the mesh-backed phantoms (:class:`MeshPhantom`) — normalisation,
sign, grid volume, truth, samples.  (The closest-point and winding-number primitives: test_phantoms_mesh_closest.py.)"""

import importlib.util
import time

import numpy as np
import pytest
import trimesh

from phantoms import InputError, MeshPhantom, get_phantom
from phantoms.mesh import winding_number

HAS_NILEARN = importlib.util.find_spec("nilearn") is not None


def _icosphere(subdivisions=3, radius=1.5):
    m = trimesh.creation.icosphere(subdivisions=subdivisions, radius=radius)
    return np.asarray(m.vertices), np.asarray(m.faces)


def _chord_error(v, f, radius):
    """Hausdorff distance between an inscribed polyhedron and its sphere: r − min distance to a face plane."""
    tri = v[f]
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    return radius - np.abs((n * tri[:, 0]).sum(1)).min()


@pytest.fixture(scope="module")
def bunny():
    return get_phantom("bunny")


# ------------------------------------------------------------------------------------------ kernels


# ------------------------------------------------------------------------------------------ icosphere
def test_icosphere_volume_equals_sphere_sdf_within_chord_error():
    v, f = _icosphere(3, 1.5)
    ph = MeshPhantom(v, f, name="ico")
    assert np.isclose(ph.scale, 1.0, atol=1e-9) and np.allclose(ph.centre, 0.0, atol=1e-9)
    assert ph.genus == 0 and not ph.has_creases
    eps = _chord_error(v, f, 1.5)
    assert 0 < eps < 0.01
    vol = ph.volume(n=40)
    pts = vol.grid_points().reshape(-1, 3)
    sphere = np.linalg.norm(pts, axis=1) - 1.5
    diff = vol.values.ravel() - sphere
    assert np.abs(diff).max() <= eps + 1e-9
    # inscribed polyhedron: never outside the ball, so its signed distance is never below the sphere's
    # (up to the far field's propagation, which can only overestimate)
    assert diff.min() >= -1e-9
    # exactly the certified query in the band, and the analytic-phantom contract elsewhere
    near = np.abs(vol.values.ravel()) <= 3 * vol.h
    assert np.allclose(vol.values.ravel()[near], ph.sdf(pts[near]), atol=1e-12, rtol=0)


def test_icosphere_truth_contract():
    v, f = _icosphere(4, 1.5)
    ph = MeshPhantom(v, f)
    rng = np.random.default_rng(3)
    p = rng.uniform(-2.2, 2.2, (3000, 3))
    t = ph.truth(p)
    assert np.allclose(np.linalg.norm(p - t.closest, axis=1), t.distance, atol=1e-12)
    assert np.allclose(np.abs(t.signed), t.distance)
    assert np.all(np.sign(t.signed) == np.sign(np.linalg.norm(p, axis=1) - (1.5 - 1e-3 * (t.distance < 0.01))))
    assert np.abs(ph.sdf(t.closest)).max() < 1e-12
    assert np.allclose(np.linalg.norm(t.normal, axis=1), 1.0)
    dots = ((p - t.closest) * t.normal).sum(1)
    away = t.distance > 1e-6
    assert np.all(np.sign(dots[away]) == np.sign(t.signed[away]))
    # curvature of the fine mesh by the suite's estimator: H = 1/1.5, K = 1/1.5² to a few per cent
    assert np.abs(t.H - 1 / 1.5).max() < 0.03 and np.abs(t.K - 1 / 1.5 ** 2).max() < 0.03
    assert np.isinf(t.crease_distance).all()


def test_sample_surface_is_seeded_and_area_uniform():
    v, f = _icosphere(4, 1.5)
    ph = MeshPhantom(v, f)
    p1, n1 = ph.sample_surface(50_000, seed=4)
    p2, _ = ph.sample_surface(50_000, seed=4)
    p3, _ = ph.sample_surface(50_000, seed=5)
    assert np.array_equal(p1, p2) and not np.array_equal(p1, p3)
    assert np.abs(ph.sdf(p1[:2000])).max() < 1e-12
    assert np.allclose(np.linalg.norm(n1, axis=1), 1.0) and (np.einsum("ij,ij->i", n1, p1) > 0).all()
    # uniform on a (near) sphere: E[z²] = r²/3, E[z] = 0
    assert abs((p1[:, 2] ** 2).mean() - 1.5 ** 2 / 3) < 0.02 and abs(p1[:, 2].mean()) < 0.02


def test_normalisation_centres_and_scales():
    v, f = _icosphere(2, 1.0)
    v2 = v * 7.0 + [10.0, -3.0, 2.0]
    ph = MeshPhantom(v2, f)
    assert np.isclose(np.linalg.norm(ph.vertices, axis=1).max(), 1.5)
    assert np.allclose(ph.centre, [10.0, -3.0, 2.0], atol=1e-6) and np.isclose(ph.scale, 1.5 / 7.0)
    # inward-oriented input is flipped: still negative inside
    ph_in = MeshPhantom(v, f[:, ::-1])
    assert ph_in.sdf(np.zeros((1, 3)))[0] < 0


# ------------------------------------------------------------------------------------------ rejection
def test_non_watertight_mesh_is_rejected(tmp_path):
    v, f = _icosphere(2, 1.0)
    with pytest.raises(InputError, match="not watertight: 3 boundary edges"):
        MeshPhantom(v, f[1:])
    path = tmp_path / "open.obj"
    trimesh.Trimesh(v, f[1:], process=False).export(path)
    with pytest.raises(InputError, match=r"open\.obj: mesh is not watertight.*fill the holes"):
        get_phantom(f"mesh:{path}")
    with pytest.raises(InputError, match="inconsistent"):
        g = f.copy()
        g[0] = g[0, ::-1]
        MeshPhantom(v, g)
    with pytest.raises(InputError, match="no such mesh file"):
        get_phantom(f"mesh:{tmp_path / 'missing.ply'}")


def test_self_intersecting_mesh_is_resolved_to_its_solid(tmp_path):
    """Two closed, outward unit spheres whose centres are one radius apart: a point inside the first just outside
    the second has the second's sheet nearest, whose outward normal points at it — the pseudonormal sign reads
    *outside* where the winding number says inside.  The phantom is the boundary of the winding-number ≥ ½ solid
    instead (phantoms/mesh/resolve.py), whose sign agrees; apart, the same spheres are one solid as they are."""
    from phantoms.mesh.index import TriangleIndex

    v, f = _icosphere(3, 1.0)
    two_v, two_f = np.vstack([v, v + [1.0, 0, 0]]), np.vstack([f, f + len(v)])
    p = np.array([[-0.2, 0.0, 0.0]])           # 0.8 inside the first sphere, 0.2 outside the second
    index = TriangleIndex(two_v, two_f)
    x, _, face, _, feat = index.closest(p)
    assert winding_number(two_v, two_f, p)[0] > 0.5 and index.sign(p, x, face, feat)[0] > 0
    resolved = MeshPhantom(two_v, two_f, normalize=False)
    assert resolved.resolution.crossing_faces > 0 and -0.83 < resolved.sdf(p)[0] < -0.77   # 0.8 from the union's
    path = tmp_path / "overlap.obj"
    trimesh.Trimesh(two_v, two_f, process=False).export(path)
    ph = get_phantom(f"mesh:{path}")
    assert ph.n_components == 1 and ph.resolution.faces_out == len(ph.faces)
    assert "winding-number ≥ ½ solid" in ph.description
    apart = MeshPhantom(np.vstack([v, v + [3.0, 0, 0]]), two_f)
    assert apart.n_components == 2 and apart.resolution is None


def test_paper_variant_does_not_exist_for_meshes():
    v, f = _icosphere(1, 1.0)
    ph = MeshPhantom(v, f)
    with pytest.raises(InputError, match="no 'paper' polynomial"):
        ph.volume(n=8, variant="paper")
    with pytest.raises(InputError, match="no 'paper' polynomial"):
        ph.paper(np.zeros((1, 3)))


# ------------------------------------------------------------------------------------------ bunny
def test_bunny_is_the_closed_genus0_pymeshlab_mesh(bunny):
    assert len(bunny.vertices) == 28088 and len(bunny.faces) == 56172
    assert bunny.genus == 0 and bunny.n_components == 1 and bunny.euler == 2
    assert np.isclose(np.linalg.norm(bunny.vertices, axis=1).max(), 1.5)
    assert bunny.paper_snr_db is None and bunny.params["source"].startswith("pymeshlab:")


def test_bunny_signs_in_concavities(bunny):
    x, n = bunny.sample_surface(20_000, seed=7)
    t = bunny.truth(x)
    assert np.allclose(t.distance, 0.0, atol=1e-12)
    concave = np.flatnonzero(t.H < -0.5)                          # saddle/concave regions (H < 0)
    assert len(concave) > 200
    rng = np.random.default_rng(0)
    idx = np.concatenate([rng.choice(concave, 1500, replace=False), rng.choice(len(x), 1500, replace=False)])
    for eps in (1e-4, 2e-3):
        out = bunny.sdf(x[idx] + eps * n[idx])
        inn = bunny.sdf(x[idx] - eps * n[idx])
        assert np.all(out > 0) and np.all(inn < 0)
        assert out.max() <= eps * (1 + 1e-9) and inn.min() >= -eps * (1 + 1e-9)
    # deeper into the concavities (up to a grid step): the pseudonormal sign equals the exact winding number
    deep = x[concave[:120]] + np.repeat([[0.02], [-0.02], [0.05], [-0.05]], 30, axis=0) * n[concave[:120]]
    w = winding_number(bunny.vertices, bunny.faces, deep)
    assert np.all(np.abs(w - np.round(w)) < 1e-6)
    assert np.array_equal(bunny.sdf(deep) < 0, w > 0.5)


def test_bunny_grid_volume_exact_band_and_far_field(bunny):
    vol = bunny.volume(n=48)
    assert vol.is_closed()
    g = vol.values.ravel()
    pts = vol.grid_points().reshape(-1, 3)
    rng = np.random.default_rng(2)
    band = np.flatnonzero(np.abs(g) <= 3 * vol.h)
    far = np.flatnonzero(np.abs(g) > 3 * vol.h)
    ib = rng.choice(band, 800, replace=False)
    assert np.allclose(g[ib], bunny.sdf(pts[ib]), atol=1e-12, rtol=0)
    jf = rng.choice(far, 800, replace=False)
    exact = bunny.sdf(pts[jf])
    assert np.array_equal(np.sign(exact), np.sign(g[jf]))
    err = np.abs(g[jf]) - np.abs(exact)
    assert err.min() >= -1e-12 and err.max() < 0.05 * vol.h
    # signs of grid points near the surface against the exact winding number
    k = rng.choice(band, 150, replace=False)
    w = winding_number(bunny.vertices, bunny.faces, pts[k])
    assert np.array_equal(g[k] < 0, w > 0.5)
    # enclosed volume matches the mesh's
    assert abs((g < 0).sum() * vol.h ** 3 - trimesh.Trimesh(bunny.vertices, bunny.faces).volume) < 0.05


def test_bunny_truth_contract(bunny):
    rng = np.random.default_rng(5)
    p = rng.uniform(-1.8, 1.8, (2000, 3))
    t = bunny.truth(p)
    assert np.allclose(np.linalg.norm(p - t.closest, axis=1), t.distance, atol=1e-12)
    assert np.allclose(np.linalg.norm(t.normal, axis=1), 1.0)
    away = t.distance > 1e-6
    dots = ((p - t.closest) * t.normal).sum(1)
    assert np.all(np.sign(dots[away]) == np.sign(t.signed[away]))
    # no mesh vertex is closer than the closest point (point-to-triangle, not point-to-vertex)
    from scipy.spatial import cKDTree

    dv, _ = cKDTree(bunny.vertices).query(p)
    assert np.all(t.distance <= dv + 1e-12)
    assert bunny.has_creases and np.isfinite(t.crease_distance).all()
    # H, K are NaN exactly where the closest point lies on a crease edge
    on = t.crease_distance <= 1e-12
    assert np.array_equal(np.isnan(t.H), on) and np.array_equal(np.isnan(t.K), on)
    x, _ = bunny.sample_surface(5000, seed=1)
    assert np.isfinite(bunny.truth(x).H).mean() > 0.999


# ------------------------------------------------------------------------------------------ cortex / MRI


# ------------------------------------------------------------------------------------------ timing (slow)
@pytest.mark.slow
@pytest.mark.parametrize("name,limit", [("bunny", 30.0), ("cortex", 30.0)])
def test_grid_sdf_at_n96_is_fast(name, limit):
    if name == "cortex" and not HAS_NILEARN:
        pytest.skip("needs nilearn")
    ph = get_phantom(name)
    t0 = time.process_time()                 # CPU time: the machine's other jobs do not count
    stats = {}
    g = ph.signed_distance_grid(96, 2.5, stats)
    assert time.process_time() - t0 < limit
    assert (g < 0).any() and (g > 0).any()
