"""Anatomy phantoms (phantoms/anatomy/): known answers — closed-form volume and area of the ideal shapes within the
tessellation error and exactly for the mesh, the designed components and genus, the certified distance against an
exhaustive point-triangle search, the inside test against the exact winding number — and every degradation keeps
the exact truth."""

import math

import numpy as np
import pytest
import trimesh

from geometry.closest import closest_point_on_triangles
from geometry.topology import euler_characteristic
from phantoms import InputError, add_noise, get_phantom, is_phantom_name, phantom_names
from phantoms.anatomy import ANATOMY, parse_anatomy_spec
from phantoms.base import SHAPE_KINDS
from phantoms.degrade import degrade, thick_grid
from phantoms.mesh import winding_number

NAMES = list(ANATOMY)
#: the designed (components, genus) of each default phantom
DESIGNED = {"vault_shell": (1, 3), "vessel_tree": (1, 0), "cavity_solid": (4, 0), "spine_parts": (5, 0),
            "lattice": (1, 81), "touching_pair": (2, 0)}
#: the grid the degradations are tested on (small: fast)
N_TEST = 40


@pytest.fixture(scope="module", params=NAMES)
def ph(request):
    return get_phantom(request.param)


def _brute_distance(points, v, f):
    """Exhaustive point-triangle distance: every point against every face."""
    out = np.empty(len(points))
    a, b, c = v[f[:, 0]], v[f[:, 1]], v[f[:, 2]]
    for i, p in enumerate(points):
        d2 = closest_point_on_triangles(np.broadcast_to(p, a.shape), a, b, c)[0]
        out[i] = np.sqrt(d2.min())
    return out


def _near_surface_points(ph, n, seed):
    """Surface samples pushed off along their normals by up to ±3 voxels, and uniform points in the box."""
    rng = np.random.default_rng(seed)
    pts, nrm = ph.sample_surface(n, seed=seed)
    near = pts + nrm * rng.uniform(-3, 3, (n, 1)) * ph.h
    box = rng.uniform(-2.0, 2.0, (n // 2, 3))
    return np.concatenate([near, box])


def test_the_names_are_registered_with_their_shape_kind():
    for name in NAMES:
        assert name in phantom_names() and is_phantom_name(name)
        assert ANATOMY[name].shape_kind in SHAPE_KINDS
    kinds = {ANATOMY[n].shape_kind for n in NAMES}
    assert kinds == set(SHAPE_KINDS) - {"smooth solid"}          # one anatomy shape per non-smooth kind
    for name in ("sphere", "ellipsoid", "fused_spheres", "cylinder", "torus"):
        assert get_phantom(name).shape_kind == "smooth solid"
    from phantoms.real import REAL_SHAPES

    assert {cls.shape_kind for cls in REAL_SHAPES.values()} == {"smooth solid"}


def test_the_built_surface_has_the_designed_components_and_genus(ph):
    comps, genus = DESIGNED[ph.name]
    assert (ph.n_components, ph.genus) == (comps, genus) == (ph.expected_components, ph.expected_genus)
    assert type(ph).genus == genus                                # the class fact listings show
    # independently: trimesh's split and Euler number; χ = 2C − 2g summed over the components
    tm = trimesh.Trimesh(ph.vertices, ph.faces, process=False)
    assert len(tm.split(only_watertight=False)) == comps
    assert tm.euler_number == euler_characteristic(ph.faces, len(ph.vertices)) == 2 * comps - 2 * genus
    assert tm.is_watertight and tm.is_winding_consistent and tm.volume > 0
    assert ph.face_areas.min() > 1e-14                            # no zero-area sliver (coplanar booleans make them)


def test_the_mesh_volume_and_area_are_exact_and_the_ideal_shapes_within_the_tessellation_error(ph):
    tm = trimesh.Trimesh(ph.vertices, ph.faces, process=False)
    assert ph.solid_volume == pytest.approx(tm.volume, rel=1e-12)
    assert ph.surface_area == pytest.approx(tm.area, rel=1e-12)
    v_ideal, a_ideal = ph.ideal_volume(), ph.ideal_area()
    if v_ideal is None:                                           # the vessel tree: capsules overlap at the joints
        assert ph.name == "vessel_tree" and a_ideal is None
        return
    delta = ph.tessellation_error
    # the polyhedron lies within δ of the ideal surface: the volumes differ by at most area · δ, the areas by a
    # relative 4δ (radii of curvature ≥ 1 world unit on the bodies; measured 0.05-0.6 of these bounds)
    assert abs(ph.solid_volume - v_ideal) <= a_ideal * delta + 1e-12 * v_ideal
    assert abs(ph.surface_area - a_ideal) <= 4 * delta * a_ideal + 1e-12 * a_ideal
    if ph.name == "spine_parts":                                  # regular prisms: their volume in closed form
        assert ph.solid_volume == pytest.approx(ph.prism_volume(), rel=1e-12)


def test_the_closed_forms_hold_for_other_parameters():
    """A second parameter set of the closed-form shapes (thickness, holes, cavities, gap, cells) — the formulas
    are not tuned to the defaults."""
    for spec in ("vault_shell?thickness=3&foramina=5&foramen_radius=2&seed=4", "cavity_solid?count=5&seed=2",
                 "touching_pair?gap=1&socket=2&seed=3", "lattice?cells=2&strut=4&seed=5",
                 "spine_parts?count=3&gap_min=1&gap_max=1.5&seed=6"):
        ph = get_phantom(spec)
        assert ph.name == spec
        assert abs(ph.solid_volume - ph.ideal_volume()) <= ph.ideal_area() * ph.tessellation_error + 1e-12
        assert abs(ph.surface_area - ph.ideal_area()) <= 4 * ph.tessellation_error * ph.ideal_area() + 1e-12
    assert get_phantom("lattice?cells=2&strut=4&seed=5").genus == 3 * 9 * 2 - 27 + 1          # k = 3 nodes: 28
    assert get_phantom("vault_shell?thickness=3&foramina=5&foramen_radius=2&seed=4").genus == 5
    assert get_phantom("cavity_solid?count=5&seed=2").n_components == 6


def test_the_distance_matches_an_exhaustive_point_triangle_search(ph):
    pts = _near_surface_points(ph, 60, seed=1)
    d_brute = _brute_distance(pts, ph.vertices, ph.faces)
    sdf = ph.sdf(pts)
    np.testing.assert_allclose(np.abs(sdf), d_brute, rtol=0, atol=1e-12)
    # the sign: inside ⇔ the exact winding number is 1 (0 outside, also in a cavity or between the parts)
    w = winding_number(ph.vertices, ph.faces, pts)
    assert np.all(np.abs(w - np.round(w)) < 1e-6) and set(np.round(w).astype(int)) <= {0, 1}
    np.testing.assert_array_equal(sdf < 0, w > 0.5)
    np.testing.assert_array_equal(ph.inside(pts), w > 0.5)


def test_the_mesh_and_the_ideal_shape_agree_off_the_tessellation_band(ph):
    """Where the ideal shape's CSG bound says a point is farther than the tessellation error from its surface,
    the mesh puts it on the same side — the polyhedron is the shape it claims to be, cavities and gaps included."""
    pts = _near_surface_points(ph, 4000, seed=2)
    ideal = ph.ideal_sdf(pts)
    sure = np.abs(ideal) > ph.tessellation_error + 1e-9
    assert sure.mean() > 0.9
    np.testing.assert_array_equal(ph.inside(pts[sure]), ideal[sure] < 0)
    # the surface samples are on the ideal surface within the tessellation error
    s, _ = ph.sample_surface(2000, seed=3)
    assert np.abs(ph.ideal_sdf(s)).max() <= ph.tessellation_error + 1e-9


def test_the_surface_samples_are_seeded_and_on_the_mesh(ph):
    a, na = ph.sample_surface(500, seed=7)
    b, _ = ph.sample_surface(500, seed=7)
    assert np.array_equal(a, b) and not np.array_equal(a, ph.sample_surface(500, seed=8)[0])
    assert np.abs(ph.sdf(a)).max() < 1e-12
    np.testing.assert_allclose(np.linalg.norm(na, axis=1), 1.0)


def test_the_seed_draws_the_shape_and_the_same_seed_the_same_shape():
    for name in ("vault_shell", "vessel_tree", "cavity_solid", "spine_parts"):
        a, b = ANATOMY[name](seed=3), ANATOMY[name](seed=3)
        assert np.array_equal(a.vertices, b.vertices)
        c = get_phantom(f"{name}?seed=4")
        assert a.vertices.shape != c.vertices.shape or not np.array_equal(a.vertices, c.vertices)


def test_sizes_are_in_voxels_of_the_given_grid():
    thin = ANATOMY["vault_shell"](n=64, thickness=1.0)
    coarse = ANATOMY["vault_shell"](n=32, thickness=1.0)
    assert thin.r_out - thin.r_in == pytest.approx(5.0 / 63)
    assert coarse.r_out - coarse.r_in == pytest.approx(5.0 / 31)
    tree = get_phantom("vessel_tree")
    assert tree.radii.max() / tree.h == pytest.approx(3.0) and tree.radii.min() / tree.h < 1.0
    pair = get_phantom("touching_pair")
    assert pair.r1 - pair.r_ball == pytest.approx(0.25 * pair.h)
    # the gap as built: the two parts' closest vertices are a quarter voxel apart (within the tessellation)
    tm = trimesh.Trimesh(pair.vertices, pair.faces, process=False)
    ball, cup = sorted(tm.split(only_watertight=False), key=lambda m: m.volume)[::-1][:2]
    gap = trimesh.proximity.closest_point(cup, ball.vertices)[1].min()
    assert 0.25 * pair.h - pair.tessellation_error <= gap <= 0.25 * pair.h + 1e-9
    spine = get_phantom("spine_parts")
    assert np.all((spine.gaps >= 0.5 * spine.h) & (spine.gaps <= 2 * spine.h))


@pytest.mark.parametrize("spec, words", [
    ("vault_shell?depth=3", "unknown option 'depth=3'"),
    ("vault_shell?thickness=abc", "thickness must be a number"),
    ("vault_shell?thickness=9", "thickness must be"),
    ("lattice?cells=3&strut=14", "holes under one voxel"),
    ("cavity_solid?count=8&small=20&large=28", "do not fit"),
    ("touching_pair?gap=0.05", "below the tessellation"),
    ("spine_parts?count=2.5", "count must be an integer"),
])
def test_bad_parameters_are_one_line_naming_the_problem(spec, words):
    with pytest.raises(InputError, match=words.replace("?", r"\?")):
        get_phantom(spec)
    with pytest.raises(InputError):
        parse_anatomy_spec("blob?x=1")


def test_the_cached_spec_is_one_object_and_lists_its_parameters():
    ph = get_phantom("vault_shell?thickness=0.75&seed=1")
    assert get_phantom("vault_shell?thickness=0.75&seed=1") is ph
    assert ph.params["thickness"] == 0.75 and ph.params["seed"] == 1 and ph.params["foramina"] == 3
    assert is_phantom_name("vault_shell?thickness=0.75") and not is_phantom_name("vault_shell?bogus=1")


# ------------------------------------------------------------------------------------------------- degradations
def _grid_points(vol, idx):
    return vol.origin + idx * vol.spacing


def test_the_mask_is_the_exact_inside_at_the_voxel_centres(ph):
    vol = degrade(ph, "mask", N_TEST)
    assert vol.kind == "mask"
    rng = np.random.default_rng(0)
    idx = np.argwhere(np.ones(vol.shape, bool))[rng.choice(vol.raw.size, 3000, replace=False)]
    band = np.argwhere(np.abs(ph.volume(N_TEST).values) < 2 * vol.spacing[0])  # where a wrong side would show
    idx = np.concatenate([idx, band[rng.choice(len(band), min(3000, len(band)), replace=False)]])
    inside = ph.sdf(_grid_points(vol, idx)) < 0                 # the certified point query, not the grid's
    np.testing.assert_array_equal(vol.raw[tuple(idx.T)] > 0.5, inside)
    # counting voxels misjudges only voxels the surface cuts: within area × half the voxel diagonal
    h = vol.spacing[0]
    assert abs(vol.raw.sum() * h ** 3 - ph.solid_volume) <= ph.surface_area * h * math.sqrt(3) / 2


def test_the_partial_volume_sums_to_the_mesh_volume(ph):
    vol = degrade(ph, "partial_volume", N_TEST)
    assert vol.kind == "intensity" and vol.raw.min() >= 0 and vol.raw.max() <= 1
    total = vol.raw.sum() * np.prod(vol.spacing)
    # 4³ sub-samples per boundary voxel: the error per boundary voxel is within 1/64 of a voxel, random in sign
    assert abs(total / ph.solid_volume - 1) < 0.02
    assert np.array_equal(vol.values < 0, vol.raw > 0.5)


def test_thick_slices_sample_the_exact_inside_on_the_thick_grid(ph):
    k = 3
    vol = degrade(ph, f"thick_slices@{k}+mask", N_TEST)
    shape, origin, spacing, _ = thick_grid(N_TEST, 2.5, k)
    assert vol.shape == shape and np.allclose(vol.origin, origin) and np.allclose(vol.spacing, spacing)
    rng = np.random.default_rng(1)
    idx = np.argwhere(np.ones(vol.shape, bool))[rng.choice(vol.raw.size, 3000, replace=False)]
    np.testing.assert_array_equal(vol.raw[tuple(idx.T)] > 0.5, ph.sdf(_grid_points(vol, idx)) < 0)


def test_blur_and_label_noise_act_on_the_exact_image(ph):
    pv = degrade(ph, "partial_volume", N_TEST)
    blurred = degrade(ph, "blur@0.5+partial_volume", N_TEST)     # σ = 1 voxel blurs the vault away at N = 40
    # a Gaussian spread moves the amount, it does not change it (the shapes are far from the box's faces)
    assert blurred.raw.sum() == pytest.approx(pv.raw.sum(), rel=1e-6)
    assert ((blurred.raw > 0) & (blurred.raw < 1)).sum() > ((pv.raw > 0) & (pv.raw < 1)).sum()
    mask = degrade(ph, "mask", N_TEST).raw > 0.5
    noisy = degrade(ph, "mask+label_noise@0.2", N_TEST, seed=3).raw > 0.5
    assert np.array_equal(noisy, degrade(ph, "mask+label_noise@0.2", N_TEST, seed=3).raw > 0.5)
    from scipy import ndimage

    boundary = (ndimage.binary_dilation(mask) & ~mask) | (mask & ~ndimage.binary_erosion(mask, border_value=1))
    flipped = noisy != mask
    assert flipped.any() and not (flipped & ~boundary).any()     # only boundary voxels change
    assert 0.1 < flipped.sum() / boundary.sum() < 0.3


def test_noise_and_degradations_leave_the_truth_unchanged(ph):
    before = (ph.vertices.copy(), ph.faces.copy(), ph.solid_volume)
    clean = ph.volume(N_TEST)
    noisy, snr = add_noise(clean, "gaussian", 40.0, seed=0)
    assert snr == pytest.approx(40.0, abs=0.1)
    for d in ("mask", "partial_volume", "thick_slices@3+mask"):
        degrade(ph, d, N_TEST)
    assert np.array_equal(before[0], ph.vertices) and np.array_equal(before[1], ph.faces)
    assert ph.solid_volume == before[2]
    assert np.array_equal(ph.volume(N_TEST).values, clean.values)


# ------------------------------------------------------------------------------------------------- the metrics
@pytest.mark.parametrize("name", ["cavity_solid", "spine_parts", "touching_pair"])
def test_the_flags_read_a_multi_part_truth(name):
    """The flags compare a mesh with the truth's components and genus: the truth's own mesh is not flagged, a mesh
    that drops a part or merges two is."""
    from bench.metrics.flags import result_flags

    ph = get_phantom(name)
    chi = 2 * ph.n_components - 2 * ph.genus
    assert result_flags({"euler": chi, "components": ph.n_components, "coverage_pct": 100.0}, ph) == []
    dropped = result_flags({"euler": chi - 2, "components": ph.n_components - 1, "coverage_pct": 99.0}, ph)
    assert {"topology_mismatch", "dropped_components", "missing_parts"} <= set(dropped)
    assert "topology_mismatch" in result_flags({"euler": 2, "components": 1, "coverage_pct": 100.0}, ph)


def test_the_metrics_of_the_truth_mesh_itself_are_exact_and_unflagged():
    """The cavity solid's own mesh scored against it: every distance zero, the four components and genus 0
    read from the mesh, no flag (the inner surfaces face inward, and the metrics follow them)."""
    from bench.metrics import evaluate
    from bench.metrics.flags import result_flags

    ph = get_phantom("cavity_solid")
    row = evaluate(trimesh.Trimesh(ph.vertices, ph.faces, process=False), ph, spacing=ph.h, n_samples=2000)
    assert row["components"] == 4 and row["euler"] == 8
    assert row["hausdorff"] < 1e-9 and row["coverage_pct"] == 100.0
    assert result_flags(row, ph) == []


def test_the_anatomy_config_is_the_tier_times_four_inputs_times_seven_methods():
    """bench/configs/anatomy.toml validates and expands to 12 shape instances × 4 inputs × 7 methods, every
    instance an anatomy phantom whose shape kind the recommendation table can read."""
    from pathlib import Path

    from bench.config import load_config
    from bench.run.grid import expand_grid

    cfg = load_config(Path(__file__).resolve().parents[1] / "bench" / "configs" / "anatomy.toml")
    cfg.validate()
    cells = expand_grid(cfg)
    assert len(cells) == 12 * 4 * 7
    assert {c.method for c in cells} == {"marching_cubes", "surface_nets", "slicer", "mc_smoothed_mask", "zmesh",
                                         "poisson", "shape_gradient"}
    assert {(c.degrade, c.noise) for c in cells} == {(None, "gaussian"), ("mask", "none"), ("partial_volume", "none"),
                                                     ("thick_slices@3+mask", "none")}
    kinds = {getattr(get_phantom(p), "shape_kind", None) for p in cfg.phantoms}
    assert kinds == set(SHAPE_KINDS) - {"smooth solid"}
