"""Known-answer tests of bench.metrics (METRICS.md)."""

from __future__ import annotations

import math

import numpy as np
import pymeshlab
import pytest
import trimesh

from bench.metrics import (
    METRIC_NAMES, RUNNER_NAMES, TRUTH_FREE_NAMES, evaluate, point_mesh_distance, sample_mesh_surface,
    self_intersection_pairs,
)
from phantoms import InputError, get_phantom

N = 20_000  # samples per surface in the tests (the suite's default is 100k)


def icosphere(sub: int, radius: float = 1.0) -> trimesh.Trimesh:
    return trimesh.creation.icosphere(subdivisions=sub, radius=radius)


def mean_edge(mesh) -> float:
    return float(mesh.edges_unique_length.mean())


@pytest.fixture(scope="module")
def sphere():
    return get_phantom("sphere")


@pytest.fixture(scope="module")
def fine():
    return icosphere(5)


@pytest.fixture(scope="module")
def fine_eval(fine, sphere):
    return evaluate(fine, sphere, mean_edge(fine), n_samples=N)


# ----------------------------------------------------------------------------- keys


def test_metric_names_cover_every_key(fine_eval):
    assert list(fine_eval) == [k for k in METRIC_NAMES if k not in RUNNER_NAMES]
    for k in ("hausdorff", "hausdorff_95", "mean_dist", "rms_dist"):
        assert f"{k}_h" in fine_eval
    assert len(set(METRIC_NAMES)) == len(METRIC_NAMES)
    assert {"iterations", "energy_final", "wall_s", "peak_mem_mb"} <= set(METRIC_NAMES)


def test_truth_free_subset(fine):
    out = evaluate(fine, None, mean_edge(fine), n_samples=N)
    assert list(out) == TRUTH_FREE_NAMES
    assert out["watertight"] and out["euler"] == 2 and out["components"] == 1
    assert out["self_intersections"] == 0
    assert out["H_std"] < 0.01                      # over all vertices: a sphere is constant
    assert out["n_vertices"] == 10242 and out["n_faces"] == 20480


def test_values_are_plain_python(fine_eval):
    for k, v in fine_eval.items():
        assert type(v) in (float, int, bool), (k, type(v))


def _same(a: dict, b: dict) -> bool:
    """Same keys in the same order and the same values, NaN equal to NaN (undefined metrics)."""
    return list(a) == list(b) and all(a[k] == b[k] or (a[k] != a[k] and b[k] != b[k]) for k in a)


def test_deterministic(sphere):
    m = icosphere(3, 1.05)
    a = evaluate(m, sphere, 0.1, n_samples=5000, seed=3)
    b = evaluate(m, sphere, 0.1, n_samples=5000, seed=3)
    c = evaluate(m, sphere, 0.1, n_samples=5000, seed=4)
    assert _same(a, b)
    assert a["mean_dist"] != c["mean_dist"]


def test_bad_inputs(fine, sphere):
    with pytest.raises(InputError):
        evaluate(fine, sphere, 0.0)
    with pytest.raises(InputError):
        evaluate(fine, sphere, 0.1, n_samples=0)
    with pytest.raises(InputError):
        evaluate(trimesh.Trimesh(np.zeros((0, 3)), np.zeros((0, 3), int)), sphere, 0.1)
    with pytest.raises(InputError):
        evaluate("not a mesh", sphere, 0.1)


# ----------------------------------------------------------------------------- distances


def test_offset_sphere_distances(sphere):
    """Icosphere of radius 1.1 against the unit sphere: every distance ≈ 0.1, normals agree."""
    m = icosphere(4, 1.1)
    h = 0.04
    out = evaluate(m, sphere, h, n_samples=N)
    assert out["hausdorff"] == pytest.approx(0.1, abs=1e-9)         # the vertices are exactly at 1.1
    assert out["mean_dist"] == pytest.approx(0.1, abs=2e-3)          # faces sag below 1.1 by < 2e-3
    assert out["rms_dist"] == pytest.approx(0.1, abs=2e-3)
    assert out["hausdorff_95"] == pytest.approx(0.1, abs=2e-3)
    assert out["normal_consistency"] == pytest.approx(1.0, abs=1e-3)
    assert out["hausdorff_h"] == pytest.approx(out["hausdorff"] / h)
    assert out["mean_dist_h"] == pytest.approx(out["mean_dist"] / h)
    assert out["fscore@h"] == 0.0                                     # 0.1 > h everywhere
    out2 = evaluate(m, sphere, 0.2, n_samples=N)
    assert out2["fscore@h"] == 1.0                                    # 0.1 < h everywhere


def test_pulled_vertex_hausdorff(sphere):
    """One vertex pulled out by 0.3: hausdorff ≈ 0.3, hausdorff_95 unaffected."""
    m = icosphere(4)
    base = evaluate(m, sphere, 0.05, n_samples=N)
    v = m.vertices.copy()
    v[17] *= 1.3
    spiked = trimesh.Trimesh(v, m.faces, process=False)
    out = evaluate(spiked, sphere, 0.05, n_samples=N)
    assert out["hausdorff"] == pytest.approx(0.3, abs=1e-9)
    assert base["hausdorff"] < 0.01
    assert out["hausdorff_95"] == pytest.approx(base["hausdorff_95"], rel=0.1, abs=1e-3)
    assert out["hausdorff_95"] < 0.01


def test_point_mesh_distance_is_exact():
    """The metrics' distance agrees with trimesh's exact closest point (inside, on, far outside)."""
    m = icosphere(2)
    rng = np.random.default_rng(1)
    pts = np.concatenate([rng.normal(size=(300, 3)) * 0.5, rng.normal(size=(300, 3)) * 5.0,
                          m.vertices[:20], m.triangles_center[:20]])
    d = point_mesh_distance(pts, m.vertices, m.faces)
    _, ref, _ = trimesh.proximity.closest_point(m, pts)
    np.testing.assert_allclose(d, ref, atol=1e-12, rtol=1e-9)


def test_mesh_sampler_seeded_and_area_uniform():
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [3, 0, 0], [0, 3, 0]], float) * [1, 1, 1]
    # face 0 area 0.5, face 1 (0, 3, 4) area 4.5
    f = np.array([[0, 1, 2], [0, 3, 4]])
    p1, f1 = sample_mesh_surface(v, f, 50_000, seed=7)
    p2, f2 = sample_mesh_surface(v, f, 50_000, seed=7)
    np.testing.assert_array_equal(p1, p2)
    assert np.mean(f1 == 0) == pytest.approx(0.1, abs=0.01)
    # uniform inside the triangle: mean of the samples of face 0 is its centroid
    np.testing.assert_allclose(p1[f1 == 0].mean(0), [1 / 3, 1 / 3, 0], atol=0.01)
    assert np.all(p1[f1 == 0][:, :2].sum(1) <= 1 + 1e-12)


# ----------------------------------------------------------------------------- topology and quality


def test_mesh_with_hole_not_watertight(sphere):
    m = icosphere(3)
    holed = trimesh.Trimesh(m.vertices, m.faces[1:], process=False)   # one triangular hole
    out = evaluate(holed, sphere, 0.1, n_samples=5000)
    assert out["watertight"] is False
    assert out["euler"] == 1 and out["components"] == 1
    assert evaluate(m, sphere, 0.1, n_samples=5000)["watertight"] is True


def test_torus_euler_zero():
    m = trimesh.creation.torus(major_radius=1.0, minor_radius=0.35, major_sections=64, minor_sections=32)
    torus = get_phantom("torus")
    out = evaluate(m, torus, 0.05, n_samples=N)
    assert out["euler"] == 0 and out["watertight"] and out["components"] == 1
    assert out["self_intersections"] == 0
    assert math.isnan(out["H_std"])             # no region of constant curvature on a torus
    assert out["hausdorff"] < 0.01
    assert out["H_rms_err"] < 0.1


def test_quality_angles():
    # one equilateral triangle and one with a 5° angle, not connected
    s = np.sin(np.radians(5.0))
    v = np.array([[0, 0, 0], [1, 0, 0], [0.5, np.sqrt(3) / 2, 0],
                  [0, 0, 5], [1, 0, 5], [np.cos(np.radians(5.0)), s, 5]])
    m = trimesh.Trimesh(v, [[0, 1, 2], [3, 4, 5]], process=False)
    out = evaluate(m, None, 0.1, n_samples=1000)
    assert out["min_angle_deg"] == pytest.approx(5.0, abs=1e-9)
    assert out["pct_angle_lt_10"] == pytest.approx(50.0)
    assert out["components"] == 2


# ----------------------------------------------------------------------------- self-intersections


def test_interpenetrating_spheres_self_intersect():
    a = icosphere(3)
    b = icosphere(3)
    b.apply_translation([1.0, 0.2, 0.1])
    both = trimesh.util.concatenate([a, b])
    out = evaluate(both, None, 0.1, n_samples=1000)
    assert out["self_intersections"] > 0
    assert out["components"] == 2 and out["euler"] == 4
    # the faces in our pairs are exactly the faces MeshLab selects as self-intersecting
    pairs = self_intersection_pairs(both.vertices, both.faces)
    ms = pymeshlab.MeshSet()
    ms.add_mesh(pymeshlab.Mesh(vertex_matrix=np.asarray(both.vertices), face_matrix=np.asarray(both.faces)))
    ms.compute_selection_by_self_intersections_per_face()
    sel = np.flatnonzero(ms.current_mesh().face_selection_array())
    np.testing.assert_array_equal(np.unique(pairs), sel)
    # a single closed sphere: none
    assert evaluate(a, None, 0.1, n_samples=1000)["self_intersections"] == 0


def test_rotated_marching_cubes_mesh_has_no_self_intersections():
    mesh, _, _ = _mc_mesh("cylinder", 40)
    rot = trimesh.transformations.random_rotation_matrix(np.random.default_rng(2).random(3))[:3, :3]
    assert len(self_intersection_pairs(mesh.vertices @ rot.T, mesh.faces)) == 0


def test_adjacent_faces_are_not_counted(fine):
    assert len(self_intersection_pairs(fine.vertices, fine.faces)) == 0



# ----------------------------------------------------------------------------- curvature and smoothness


def test_fine_icosphere_curvature(fine_eval):
    assert fine_eval["H_rms_err"] < 0.01                 # H within 1 % of 1
    assert fine_eval["H_max_err"] < 0.01
    assert fine_eval["K_rms_err"] < 0.02
    assert fine_eval["H_std"] < 0.01
    assert fine_eval["roughness_deg"] < 3.0


def test_noisy_icosphere_is_rougher(fine, fine_eval, sphere):
    rng = np.random.default_rng(0)
    h = mean_edge(fine)
    v = fine.vertices + rng.normal(scale=0.1 * h, size=fine.vertices.shape)
    noisy = trimesh.Trimesh(v, fine.faces, process=False)
    out = evaluate(noisy, sphere, h, n_samples=N)
    assert out["H_std"] > 5 * fine_eval["H_std"] and out["H_std"] > 0.05
    assert out["roughness_deg"] > 2 * fine_eval["roughness_deg"]
    assert out["hausdorff"] < 0.05                        # still close to the surface


def test_inward_winding_gives_the_same_curvature(fine, fine_eval, sphere):
    flipped = trimesh.Trimesh(fine.vertices, fine.faces[:, ::-1], process=False)
    out = evaluate(flipped, sphere, mean_edge(fine), n_samples=N)
    assert out["H_rms_err"] == pytest.approx(fine_eval["H_rms_err"], rel=1e-9)
    assert out["H_std"] == pytest.approx(fine_eval["H_std"], rel=1e-9)


def _mc_mesh(name, n=56):
    from skimage.measure import marching_cubes

    ph = get_phantom(name)
    vol = ph.volume(n=n, extent=2.3 if name == "ellipsoid" else 1.6, variant="paper")
    v, f, _, _ = marching_cubes(vol.values, 0.0, spacing=tuple(vol.spacing))
    return trimesh.Trimesh(v + vol.origin, f), ph, float(vol.spacing[0])


@pytest.mark.parametrize("name, has_region", [("cylinder", True), ("fused_spheres", True),
                                              ("ellipsoid", False)])
def test_constant_curvature_regions(name, has_region):
    mesh, ph, h = _mc_mesh(name)
    out = evaluate(mesh, ph, h, n_samples=N)
    assert out["watertight"] and out["euler"] == 2
    assert out["self_intersections"] == 0               # flat, axis-aligned facets: no false positives
    assert math.isfinite(out["H_rms_err"]) and out["H_rms_err"] < 0.5
    if has_region:
        assert math.isfinite(out["H_std"]) and out["H_std"] < 0.3
    else:
        assert math.isnan(out["H_std"])
    assert out["hausdorff_h"] < 1.0                      # marching cubes stays within a voxel


def test_crease_band_excludes_rim_vertices():
    mesh, ph, h = _mc_mesh("cylinder")
    wide = evaluate(mesh, ph, h, n_samples=2000, crease_band=0.1)
    none = evaluate(mesh, ph, h, n_samples=2000, crease_band=0.0)
    assert none["H_max_err"] > wide["H_max_err"]         # rim vertices carry the largest errors


def test_worker_thread_same_result_and_errors_propagate(sphere, monkeypatch):
    import bench.metrics as bm

    m = icosphere(3, 1.02)
    par = evaluate(m, sphere, 0.1, n_samples=5000)
    monkeypatch.setattr(bm, "PARALLEL_DISTANCE", False)
    assert _same(evaluate(m, sphere, 0.1, n_samples=5000), par)
    monkeypatch.setattr(bm, "PARALLEL_DISTANCE", True)

    def broken(*args):
        raise RuntimeError("distance backend failed")

    monkeypatch.setattr(bm, "point_mesh_distance", broken)
    with pytest.raises(RuntimeError, match="distance backend failed"):
        evaluate(m, sphere, 0.1, n_samples=5000)


@pytest.mark.parametrize("with_truth", [True, False])
def test_evaluate_derives_each_mesh_quantity_once(monkeypatch, sphere, with_truth):
    """One ScoredMesh per evaluation: the face cross products (→ normals, areas), the signed volume, the edge
    grouping (→ edges, counts, adjacency) and the vertex normals are computed once and shared by every metric."""
    import geometry.mesh as gm
    import geometry.topology as gt

    calls: dict[str, int] = {}

    def counted(module, name):
        real = getattr(module, name)

        def wrapper(*a, **k):
            calls[name] = calls.get(name, 0) + 1
            return real(*a, **k)
        monkeypatch.setattr(module, name, wrapper)

    for module, name in ((gm, "_face_cross"), (gm, "signed_volume"), (gm, "_vertex_normals"),
                         (gt, "face_edge_keys"), (gt, "edges_unique"), (gm, "edges_unique")):
        counted(module, name)
    mesh = icosphere(3)
    vol = sphere.volume(24)
    evaluate(mesh, sphere if with_truth else None, 0.05, volume=vol, n_samples=2000)
    assert calls == {"_face_cross": 1, "signed_volume": 1, "_vertex_normals": 1, "face_edge_keys": 1}, calls


def test_volume_error_is_the_signed_relative_volume_against_the_exact_ball(fine, fine_eval):
    """The icosphere is inscribed in the unit ball: its volume is short by exactly its polyhedral volume's
    deficit; a shrunk copy reads the shrink (0.9³ − 1 = −27.1 %)."""
    exact = 100 * (abs(fine.volume) / (4 / 3 * np.pi) - 1)
    assert fine_eval["volume_err_pct"] == pytest.approx(exact, abs=1e-9) and -0.1 < exact < 0
    small = icosphere(3, radius=0.9)
    out = evaluate(small, get_phantom("sphere"), mean_edge(small), n_samples=5000)
    assert out["volume_err_pct"] == pytest.approx(100 * (abs(small.volume) / (4 / 3 * np.pi) - 1), abs=1e-9)
    assert -28.5 < out["volume_err_pct"] < -27.1      # the shrink plus the coarser polyhedron's deficit
    assert np.isnan(evaluate(small, None, 0.1, n_samples=5000).get("volume_err_pct", np.nan))
