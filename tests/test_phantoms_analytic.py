"""Phantoms: exact signed distance, closest points, normals, curvature, surface samples."""

import numpy as np
import pytest
from scipy.spatial import cKDTree

from phantoms import PHANTOMS, get_phantom

NAMES = list(PHANTOMS)


def _query_points(n=3000, seed=0):
    rng = np.random.default_rng(seed)
    return rng.uniform(-2.0, 2.0, (n, 3))


@pytest.mark.parametrize("name", NAMES)
def test_truth_distance_matches_brute_force(name):
    """Exact distance vs nearest of 400k area-uniform surface samples (KD-tree)."""
    ph = get_phantom(name)
    surf, _ = ph.sample_surface(400_000, seed=1)
    p = _query_points()
    d_brute, _ = cKDTree(surf).query(p)
    t = ph.truth(p)
    # sampling error: mean spacing of 400k points on an area-O(10) surface is ~0.006
    assert np.all(t.distance <= d_brute + 1e-12)
    assert np.abs(d_brute - t.distance).max() < 0.01
    assert np.allclose(np.abs(t.signed), t.distance)
    assert np.allclose(np.linalg.norm(p - t.closest, axis=1), t.distance, atol=1e-12)


@pytest.mark.parametrize("name", NAMES)
def test_closest_points_lie_on_the_surface_and_signs_match(name):
    ph = get_phantom(name)
    p = _query_points(seed=5)
    t = ph.truth(p)
    # the closest point has (numerically) zero signed distance
    assert np.abs(ph.sdf(t.closest)).max() < 1e-9
    # sign from the printed implicit function (same zero set, φ < 0 inside)
    away = t.distance > 1e-6
    assert np.all(np.sign(ph.paper(p[away])) == np.sign(t.signed[away]))
    # unit normals; (p - closest) is parallel to the normal wherever the surface is smooth there
    assert np.allclose(np.linalg.norm(t.normal, axis=1), 1.0)
    smooth = away & (t.crease_distance > 1e-9)
    cross = np.cross(p[smooth] - t.closest[smooth], t.normal[smooth])
    assert np.abs(cross).max() < 1e-9
    # the normal points outward: along (p - closest) outside, against it inside
    dots = ((p - t.closest) * t.normal).sum(1)[away]
    assert np.all(np.sign(dots) == np.sign(t.signed[away]))


def test_ellipsoid_closest_point_normal_condition():
    ph = get_phantom("ellipsoid")
    rng = np.random.default_rng(7)
    p = np.concatenate([
        rng.uniform(-2.5, 2.5, (20000, 3)),
        rng.uniform(-0.9, 0.9, (5000, 3)) * [1, 2, 1],         # inside
        np.column_stack([np.zeros(500), rng.uniform(-1.9, 1.9, 500), np.zeros(500)]),  # on the long axis
        np.column_stack([rng.uniform(-0.5, 0.5, 500), rng.uniform(-1.5, 1.5, 500), np.zeros(500)]),
    ])
    x = ph.closest_point(p)
    a = ph.axes
    assert np.abs((x ** 2 / a ** 2).sum(1) - 1).max() < 1e-12
    g = x / a ** 2
    g /= np.linalg.norm(g, axis=1, keepdims=True)
    r = p - x
    # (p - x) is parallel to the surface normal at x: tangential component < 1e-8
    tangential = r - (r * g).sum(1, keepdims=True) * g
    assert np.abs(tangential).max() < 1e-8
    # and it is the closest point: no better surface sample
    surf, _ = ph.sample_surface(300_000, seed=2)
    d_brute, _ = cKDTree(surf).query(p[:3000])
    assert np.all(np.linalg.norm(r[:3000], axis=1) <= d_brute + 1e-12)


@pytest.mark.parametrize("name", NAMES)
def test_sdf_volume_is_exact_at_grid_points(name):
    ph = get_phantom(name)
    vol = ph.volume(n=24)
    pts = vol.grid_points().reshape(-1, 3)
    t = ph.truth(pts)
    # the volume values are the distance to a point verified to lie on the surface (test above) ...
    d_geo = np.linalg.norm(pts - t.closest, axis=1)
    assert np.abs(np.abs(vol.values.ravel()) - d_geo).max() < 1e-9
    # ... agree with closed forms where they exist ...
    x, y, z = pts.T
    closed = {
        "sphere": np.sqrt(x * x + y * y + z * z) - 1,
        "torus": np.hypot(np.hypot(x, y) - 1.0, z) - 0.35,
        "fused_spheres": np.minimum(np.sqrt(x * x + y * y + (z - 0.7) ** 2),
                                    np.sqrt(x * x + y * y + (z + 0.7) ** 2)) - 0.8,
    }.get(name)
    if closed is not None:
        outside = closed > 0  # union of balls: min of distances is exact outside
        assert np.abs(vol.values.ravel()[outside] - closed[outside]).max() < 1e-9
        if name != "fused_spheres":
            assert np.abs(vol.values.ravel() - closed).max() < 1e-9
    # ... and are a true distance: never more than the brute-force nearest surface sample
    surf, _ = ph.sample_surface(200_000, seed=4)
    d_brute, _ = cKDTree(surf).query(pts)
    assert np.all(np.abs(vol.values.ravel()) <= d_brute + 1e-9)


def test_fused_spheres_interior_uses_the_crease():
    """Inside the union near the waist the nearest surface point is on the crease circle."""
    ph = get_phantom("fused_spheres")
    p = np.array([[0.3, 0.0, 0.0]])
    t = ph.truth(p)
    assert np.isclose(t.distance[0], np.sqrt(0.15) - 0.3)
    assert t.signed[0] < 0 and t.crease_distance[0] == 0 and np.isnan(t.H[0])


def test_fused_spheres_inside_is_the_sign_of_the_exact_sdf():
    """The fast inside test equals φ < 0 point for point: random points, points on both spheres (in and out of
    the other ball), on the crease, at the centres and on the axis."""
    ph = get_phantom("fused_spheres")
    rng = np.random.default_rng(7)
    u = rng.normal(size=(4000, 3))
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    t = np.linspace(0.0, 2 * np.pi, 50)
    crease = np.column_stack([ph.crease_radius * np.cos(t), ph.crease_radius * np.sin(t), np.zeros_like(t)])
    exact = np.array([[0.8, 0.0, 0.7], [0.0, 0.8, -0.7], [0.0, 0.0, 1.5], [0.0, 0.0, -1.5], [0.0, 0.0, 0.0],
                      [0.0, 0.0, 0.7], [0.0, 0.0, 0.1], [np.sqrt(0.15), 0.0, 0.0], [0.3, 0.0, 0.0]])
    pts = np.concatenate([rng.uniform(-1.6, 1.6, (20_000, 3)), ph.centres[0] + 0.8 * u[:2000],
                          ph.centres[1] + 0.8 * u[2000:], crease, exact])
    inside = ph.inside(pts)
    np.testing.assert_array_equal(inside, ph.sdf(pts) < 0)
    assert 0 < inside.sum() < len(pts)


def _implicit_curvature(f, x, h=1e-4):
    """H, K of the level set of f through x from central finite differences (outward = grad f)."""
    e = np.eye(3) * h
    g = np.stack([(f(x + e[i]) - f(x - e[i])) / (2 * h) for i in range(3)], 1)
    Hs = np.empty((len(x), 3, 3))
    for i in range(3):
        for j in range(3):
            Hs[:, i, j] = (f(x + e[i] + e[j]) - f(x + e[i] - e[j])
                           - f(x - e[i] + e[j]) + f(x - e[i] - e[j])) / (4 * h * h)
    ng = np.linalg.norm(g, axis=1)
    gHg = np.einsum("pi,pij,pj->p", g, Hs, g)
    tr = np.trace(Hs, axis1=1, axis2=2)
    H = (ng ** 2 * tr - gHg) / (2 * ng ** 3)
    adj = np.empty_like(Hs)
    for i in range(3):
        for j in range(3):
            minor = np.delete(np.delete(Hs, j, axis=1), i, axis=2)
            adj[:, i, j] = (-1) ** (i + j) * np.linalg.det(minor)
    K = np.einsum("pi,pij,pj->p", g, adj, g) / ng ** 4
    return H, K


@pytest.mark.parametrize("name", NAMES)
def test_analytic_curvature_matches_finite_differences(name):
    ph = get_phantom(name)
    x, _ = ph.sample_surface(2000, seed=9)
    t = ph.truth(x)
    ok = t.crease_distance > 0.05
    Hfd, Kfd = _implicit_curvature(ph.paper, x[ok])
    assert np.allclose(t.H[ok], Hfd, atol=2e-4, rtol=1e-4)
    assert np.allclose(t.K[ok], Kfd, atol=2e-3, rtol=1e-3)


def test_known_curvature_values():
    assert np.allclose(get_phantom("sphere").truth(np.array([[0, 0, 3.0]])).H, 1.0)
    e = get_phantom("ellipsoid").truth(np.array([[0.0, 3.0, 0.0], [3.0, 0.0, 0.0]]))
    assert np.allclose(e.K, [4.0, 0.25])      # ends of the long axis: K = 4; equator: K = 1/4
    c = get_phantom("cylinder").truth(np.array([[1.0, 0, 0.2], [0.1, 0, 2.0], [1.0, 0, 2.0]]))
    assert np.allclose(c.H[:2], [1.25, 0.0]) and np.isnan(c.H[2]) and c.crease_distance[2] == 0
    assert np.isinf(get_phantom("torus").truth(np.array([[0, 0, 3.0]])).crease_distance).all()


@pytest.mark.parametrize("name", NAMES)
def test_surface_samples_are_seeded_and_area_uniform(name):
    ph = get_phantom(name)
    p1, n1 = ph.sample_surface(100_000, seed=11)
    p2, _ = ph.sample_surface(100_000, seed=11)
    p3, _ = ph.sample_surface(100_000, seed=12)
    assert p1.shape == (100_000, 3) and np.array_equal(p1, p2) and not np.array_equal(p1, p3)
    assert np.abs(ph.sdf(p1)).max() < 1e-9
    assert np.allclose(np.linalg.norm(n1, axis=1), 1.0)
    # area uniformity: sample means of smooth functions equal their area-weighted means over a fine
    # marching-cubes mesh projected onto the true surface (independent of the sampler)
    from skimage.measure import marching_cubes
    vol = ph.volume(n=96)
    v, f, _, _ = marching_cubes(vol.values, 0.0, spacing=tuple(vol.spacing))
    v = ph.truth(v + vol.origin).closest
    tri = v[f]
    area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    c = tri.mean(1)
    for fn in (lambda q: q[:, 2] ** 2, lambda q: q[:, 1] ** 2, lambda q: np.exp(q[:, 0] + 0.5 * q[:, 2])):
        assert abs(fn(p1).mean() - (area * fn(c)).sum() / area.sum()) < 0.01


def test_ellipsoid_curvature_range():
    ph = get_phantom("ellipsoid")
    x, _ = ph.sample_surface(50_000, seed=0)
    t = ph.truth(x)
    assert t.K.min() >= 0.25 - 1e-12 and t.K.max() <= 4 + 1e-12


def test_paper_variant_has_the_same_zero_set():
    for name in NAMES:
        ph = get_phantom(name)
        v_sdf, v_pap = ph.volume(n=32), ph.volume(n=32, variant="paper")
        assert np.array_equal(v_sdf.values < 0, v_pap.values < 0)


def test_ellipsoid_compiled_root_matches_the_numpy_reference():
    """The closest-point root find runs compiled; its numpy form (``Ellipsoid._root``) is the reference: the same
    roots to a few ulp on random points, on the planes of the axes and at the centre."""
    from phantoms.analytic import Ellipsoid, _root_compiled

    rng = np.random.default_rng(3)
    p = rng.normal(size=(20000, 3)) * 1.5
    p[:50, 0] = 0.0
    p[50:100, 2] = 0.0
    p[100:110] = 0.0
    ph = Ellipsoid((1.0, 2.0, 1.0))
    y = np.abs(p)
    e2 = ph.axes ** 2
    m = e2.min()
    ey = ph.axes * y
    lo = np.full(len(p), -m)
    hi = np.maximum(np.maximum(ph.axes.max() * np.linalg.norm(y, axis=1) - m, 0.0), lo + 1e-12)
    ref = Ellipsoid._root(ey, e2, lo.copy(), hi.copy())
    got = _root_compiled(np.ascontiguousarray(ey), e2, lo.copy(), hi.copy(), 200)
    assert np.allclose(got, ref, rtol=1e-13, atol=1e-13)
    x = ph.closest_point(p)
    assert np.abs((x ** 2 / e2).sum(1) - 1.0).max() < 1e-12
