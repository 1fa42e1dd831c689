"""The genus-0 start (init='genus0', the default): a closed genus-0 surface of the volume itself, on targets
with and without one genus-0 surface, clean and noisy (methods/shape_gradient/start.py)."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from geometry.intersections import self_intersection_pairs
from methods.shape_gradient import ShapeGradient
from methods.shape_gradient.remesh import is_sphere_like
from methods.shape_gradient.start import genus0_surface
from phantoms import InputError, add_noise, get_phantom
from phantoms.base import grid_volume

from _shape_gradient_common import one_flow


def test_the_start_of_a_torus_is_the_torus_cut_open():
    ph = get_phantom("torus")
    vol = ph.volume(n=40)
    x, f, facts = genus0_surface(vol, vol.values)
    assert is_sphere_like(f, len(x))
    assert trimesh.Trimesh(x, f).volume > 0                              # outward
    assert facts["left_out_samples"] > 0 and facts["solid_samples"] + facts["left_out_samples"] == \
        facts["inside_samples"]
    d = np.abs(ph.sdf(x))
    assert np.median(d) < 0.05 * vol.h and np.mean(d > 0.5 * vol.h) < 0.05   # on the torus except at the cut


def test_the_start_of_a_sphere_is_on_the_sphere_and_in_world_coordinates():
    # anisotropic, off-centre: the start must be in world units (origin + index · spacing)
    from phantoms import Volume
    n = (30, 36, 26)
    spacing = np.array([0.09, 0.07, 0.1])
    origin = np.array([-1.0, -1.5, -0.9])
    idx = np.stack(np.meshgrid(*[np.arange(k) for k in n], indexing="ij"), axis=-1)
    p = origin + idx * spacing
    c = np.array([0.3, -0.2, 0.35])
    vol = Volume(np.linalg.norm(p - c, axis=-1) - 0.7, origin, spacing)
    x, f, facts = genus0_surface(vol, vol.values)
    assert facts["left_out_samples"] == 0 and facts["disambiguation"] == "gentle"
    assert np.abs(np.linalg.norm(x - c, axis=1) - 0.7).max() < 0.02


def test_no_inside_sample_is_a_clear_error():
    # inside only on the box's outer layer (x = −2.5): nothing a closed surface in the box can enclose (the method
    # itself refuses such a volume earlier, as an open level set)
    vol = grid_volume(lambda p: p[:, 0] + 2.4, n=16)
    with pytest.raises(InputError, match="no sample of the volume is inside"):
        genus0_surface(vol, vol.values)
    with pytest.raises(InputError, match="open"):
        ShapeGradient().reconstruct(vol)


def test_two_spheres_give_one_of_them_and_say_so():
    def two(p):
        return np.minimum(np.linalg.norm(p - [0.9, 0, 0], axis=1) - 0.7, np.linalg.norm(p + [0.9, 0, 0], axis=1) - 0.5)
    vol = grid_volume(two, n=40)
    r = ShapeGradient().reconstruct(vol)
    assert not r.info["topology"]["compatible"] and r.info["init"]["kind"] == "genus0"
    c = r.mesh.vertices.mean(axis=0)
    assert c[0] > 0.7                                               # the larger sphere
    assert np.abs(np.linalg.norm(r.mesh.vertices - [0.9, 0, 0], axis=1) - 0.7).max() < 0.5 * vol.h


def test_a_very_noisy_volume_starts_from_the_smoothed_samples():
    ph = get_phantom("sphere")
    vol, _ = add_noise(ph.volume(n=40), "gaussian", 20.0, seed=1)     # noise ≈ 1.3 voxels
    plain = genus0_surface(vol, vol.values)
    r = ShapeGradient(max_iter=20, start_choice="off").reconstruct(vol)
    assert r.info["presmooth_used"] > 0 and r.info["start_smooth_used"] > 0
    v0, f0 = r.info["snapshots"][0]
    # the smoothed start has fewer vertices and is smoother than the start from the raw noisy samples
    assert len(v0) < len(plain[0])
    assert np.std(ph.sdf(v0)) < np.std(ph.sdf(plain[0]))
    assert is_sphere_like(f0, len(v0)) and len(self_intersection_pairs(v0, f0)) == 0


def test_a_mildly_noisy_volume_starts_from_its_own_samples():
    """Noise below a voxel: the start keeps the data's values (smoothing would erase voxel-thin parts)."""
    vol, _ = add_noise(get_phantom("sphere").volume(n=40), "gaussian", 40.0, seed=1)
    r = ShapeGradient(max_iter=3).reconstruct(vol)
    assert 0.05 < r.info["noise_estimate_voxels"] < 1.0
    assert r.info["start_smooth_used"] == 0.0 and r.info["presmooth_used"] > 0
    plain = genus0_surface(vol, vol.values)
    v0, f0 = r.info["snapshots"][0]                      # the start before its first remesh
    assert len(v0) == len(plain[0]) and np.array_equal(f0, plain[1])


def _lobes(n: int, gap_voxels: float | None, neck_voxels: float = 0.0):
    """(volume, sdf, h): two balls of radius 0.7 on the x axis, ``gap_voxels`` apart (None: centres at ±0.9, 3
    voxels apart at n = 40), joined by a cylinder ``neck_voxels`` thick along the axis (0: no neck).  The axis
    lies half-way between sample rows (n even), so a neck thinner than √2 voxels holds no sample of φ < 0."""
    h = 5.0 / (n - 1)
    c = 0.9 if gap_voxels is None else 0.7 + 0.5 * gap_voxels * h
    rn = 0.5 * neck_voxels * h

    def sdf(p):
        balls = np.minimum(np.linalg.norm(p - [c, 0, 0], axis=1), np.linalg.norm(p + [c, 0, 0], axis=1)) - 0.7
        if rn == 0:
            return balls
        radial, axial = np.linalg.norm(p[:, 1:], axis=1) - rn, np.abs(p[:, 0]) - c
        outside = np.linalg.norm(np.stack([np.maximum(radial, 0), np.maximum(axial, 0)], axis=1), axis=1)
        return np.minimum(balls, np.minimum(np.maximum(radial, axial), 0) + outside)
    return grid_volume(sdf, n=n), sdf, h, (c, rn)


def _pieces(values: np.ndarray) -> int:
    """26-connected pieces of values < 0."""
    from scipy import ndimage
    return int(ndimage.label(values < 0, structure=np.ones((3, 3, 3)))[1])


def _truth_samples(sdf, c: float, rn: float, count: int = 20000) -> np.ndarray:
    """Points of the lobes' true surface: the balls' spheres and the neck's side, where the union's SDF is 0."""
    from geometry.sphere import fibonacci_sphere
    s, _ = fibonacci_sphere(count, 0.7, (0.0, 0.0, 0.0))
    t = np.linspace(-c, c, 400)
    a = np.linspace(0, 2 * np.pi, 24, endpoint=False)
    neck = np.stack([np.repeat(t, len(a)), rn * np.tile(np.cos(a), len(t)), rn * np.tile(np.sin(a), len(t))], 1)
    pts = np.concatenate([s + [c, 0, 0], s - [c, 0, 0], neck])
    return pts[np.abs(sdf(pts)) < 1e-9]


def _hausdorff_h(mesh, sdf, h, c, rn) -> float:
    """Symmetric Hausdorff distance (in h) between the mesh and the lobes' true surface."""
    from geometry.closest import point_mesh_distance
    on_mesh = np.concatenate([mesh.vertices, trimesh.sample.sample_surface(mesh, 20000, seed=0)[0]])
    to_truth = np.abs(sdf(on_mesh)).max()
    to_mesh = point_mesh_distance(_truth_samples(sdf, c, rn), mesh.vertices, mesh.faces).max()
    return float(max(to_truth, to_mesh) / h)


def test_two_balls_joined_by_a_neck_thinner_than_a_voxel_give_one_surface_with_the_neck():
    """A neck 0.6 voxel thick between two balls: φ < 0 is two pieces at grid resolution (their saddle, the
    lowest φ between them, is 0.41 voxel).  The start joins them through the saddle, and the default flow returns
    one genus-0 surface with the neck, within a voxel of the truth everywhere, with no topology warning; without
    the join (join_below = 0) the start keeps one ball and the other is lost."""
    vol, sdf, h, (c, rn) = _lobes(40, None, 0.6)
    assert _pieces(vol.values) == 2
    r = ShapeGradient(start_choice="off").reconstruct(vol)          # the usual start: the join
    m = r.mesh
    assert r.info["warnings"] == [] and r.info["init"]["kind"] == "genus0"
    assert r.info["init"]["pieces"] == 2 and r.info["init"]["joined_pieces"] == 1
    assert 0.35 < r.info["init"]["join_saddles_voxels"][0] < 0.45
    assert is_sphere_like(m.faces, len(m.vertices)) and len(self_intersection_pairs(m.vertices, m.faces)) == 0
    assert np.any(np.abs(m.vertices[:, 0]) < h)                                    # the neck is there
    assert _hausdorff_h(m, sdf, h, c, rn) <= 1.0
    lone = ShapeGradient(join_below=0.0, start_choice="off").reconstruct(vol)
    assert lone.info["init"]["joined_pieces"] == 0 and _hausdorff_h(lone.mesh, sdf, h, c, rn) > 5.0


def test_the_crease_polish_does_not_snap_onto_the_far_meeting_point_at_a_saddle():
    """The neck's start from the carved hull (which holds the neck, no join needed): at the saddle between the two
    lobes the ring's planes are nearly parallel and meet far out — a crease point 2 voxels off the surface; the
    polish does not snap a vertex there (|φ| > a voxel), so the surface stays within a voxel of the truth."""
    vol, sdf, h, (c, rn) = _lobes(40, None, 0.6)
    r = one_flow(vol, {"carved_start": True, "hold_carved": True, "carve_margin": 0.1, "start_level": 0.25})
    assert r.info["init"]["carved"]["used"] and r.info["polish"]["off_zero_set"] > 0
    assert is_sphere_like(r.mesh.faces, len(r.mesh.vertices)) and _hausdorff_h(r.mesh, sdf, h, c, rn) <= 1.0


def test_two_balls_five_voxels_apart_are_not_joined_and_say_so():
    vol, sdf, h, _ = _lobes(40, 5.0)
    r = ShapeGradient().reconstruct(vol)
    assert r.info["init"]["pieces"] == 2 and r.info["init"]["joined_pieces"] == 0
    assert not r.info["topology"]["compatible"]
    assert len(r.info["warnings"]) == 1 and "2 separate components" in r.info["warnings"][0]
    assert is_sphere_like(r.mesh.faces, len(r.mesh.vertices))
    assert np.abs(np.abs(sdf(r.mesh.vertices))).max() < 0.5 * h                     # one of the balls, whole



def test_under_noise_the_join_threshold_is_lowered_by_the_noise():
    """A saddle read through noise is lower by about a noise std (the lowest of many paths' highest samples), so
    under noise the pieces are joined below join_below − σ̂: speckles of heavy noise are never joined."""
    vol, _, _, _ = _lobes(40, None, 0.6)
    assert ShapeGradient(max_iter=2).reconstruct(vol).info["parameters"]["join_below_used"] == 0.5
    for snr in (40.0, 25.0):
        noisy, _ = add_noise(vol, "gaussian", snr, seed=0)
        info = ShapeGradient(max_iter=2).reconstruct(noisy).info
        used, sigma = info["parameters"]["join_below_used"], info["noise_estimate_voxels"]
        assert used == pytest.approx(max(0.5 - sigma, 0.0))
        if snr == 25.0:
            assert sigma > 0.5 and used == 0.0 and info["init"]["joined_pieces"] == 0
        else:
            assert 0.0 < used < 0.5


def test_a_noise_pinhole_in_a_thin_sheet_does_not_cut_the_start():
    # a ball with a sheet one sample thick; one sample of the sheet lifted to +0.1 voxel (what 40 dB noise does to
    # the bunny's ear at N = 64): the growth stops at it and the start is slit open behind it, unless it is closed
    import sys
    from pathlib import Path

    from phantoms import Volume
    sys.path.insert(0, str(Path(__file__).parent))
    from test_methods_shape_gradient_pinholes import ball_with_sheet
    phi, _ = ball_with_sheet()
    h = 0.05
    vol = Volume(phi * h, np.zeros(3), np.full(3, h))
    behind = np.array([[i, 15, 15] for i in range(20, 25)]) * h      # the sheet's samples behind the pinhole
    for below, n_left, covered in ((0.0, 5, 0), (0.25, 0, 5)):
        x, f, facts = genus0_surface(vol, vol.values, 0.0, pinhole_below=below)
        assert is_sphere_like(f, len(x)) and facts["left_out_samples"] == n_left
        assert trimesh.Trimesh(x, f).contains(behind).sum() == covered
    assert facts["pinholes"] == 1 and facts["pinhole_samples"] == 1
    assert not self_intersection_pairs(x, f).size


def test_pinholes_are_closed_on_noisy_volumes_only():
    ph = get_phantom("bunny")
    clean = ph.volume(n=40)
    noisy, _ = add_noise(clean, "gaussian", 40.0, seed=0)
    assert ShapeGradient().prepare(clean).init_facts["pinhole_below_voxels"] == 0.0
    facts = ShapeGradient().prepare(noisy).init_facts
    assert facts["pinhole_below_voxels"] >= 0.25 and "pinholes" in facts
    assert ShapeGradient(close_pinholes=False).prepare(noisy).init_facts["pinhole_below_voxels"] == 0.0


def test_the_noisy_bunnys_ear_tip_is_in_the_start():
    # 40 dB at N = 64: noise lifts one sample of an ear above 0 and the growth stopped there, 1.49 h short of the
    # true tip (1.30 h before the remesh); with the pinhole closed the start reaches marching cubes' 0.92 h
    ph = get_phantom("bunny")
    vol, _ = add_noise(ph.volume(n=64), "gaussian", 40.0, seed=0)
    pts, _ = ph.sample_surface(20_000, seed=0)
    far = {}
    for close in (False, True):
        flow = ShapeGradient(close_pinholes=close, max_iter=0).prepare(vol)
        x, f = flow.snapshots[0]
        far[close] = float(trimesh.proximity.closest_point(trimesh.Trimesh(x, f, process=False), pts)[1].max()
                           / vol.h)
        assert flow.init_facts["left_out_samples"] == (0 if close else 3)
    assert far[False] > 1.2 and far[True] < 1.0


def _shell_with_openings(openings: int, noise_voxels: float, n: int = 64):
    """A CT-skull-like solid: a spherical shell 4 voxels thick with ``openings`` round holes 5 voxels across
    (a solid of genus openings − 1), plus i.i.d. Gaussian noise."""
    from phantoms import Volume

    x = np.linspace(-1.0, 1.0, n)
    p = np.stack(np.meshgrid(x, x, x, indexing="ij"), axis=-1)
    r = np.linalg.norm(p, axis=-1)
    phi = np.maximum(r - 0.85, 0.72 - r)
    rng = np.random.default_rng(1)
    axes = rng.normal(size=(openings, 3))
    for u in axes / np.linalg.norm(axes, axis=1, keepdims=True):
        t = p @ u
        phi = np.maximum(phi, np.where(t > 0, 0.08 - np.linalg.norm(p - t[..., None] * u, axis=-1), -1.0))
    h = x[1] - x[0]
    return Volume(phi + rng.normal(scale=noise_voxels * h, size=phi.shape), [-1.0] * 3, h)


@pytest.mark.parametrize("openings, noise", [(12, 0.3), (30, 1.0)])
def test_a_noisy_shell_with_many_openings_is_refused_before_any_iteration(openings, noise):
    """A genus ≫ 0 solid (a CT skull's kind) is refused up front with the reading that decided it — the flow
    would spend minutes evolving one genus-0 surface it cannot follow — unless max_topology_gap allows it."""
    import time

    from methods.shape_gradient.field import estimate_noise
    from methods.shape_gradient.start import denoised_topology, topology_gap

    vol = _shell_with_openings(openings, noise)
    assert topology_gap(denoised_topology(vol, estimate_noise(vol))) > 5
    t0 = time.process_time()
    with pytest.raises(InputError, match=r"far from one genus-0 surface .*max_topology_gap = 5") as err:
        ShapeGradient().reconstruct(vol)
    assert "\n" not in str(err.value) and time.process_time() - t0 < 10.0     # up front: no iteration ran


def test_few_openings_are_not_refused():
    from methods.shape_gradient.field import estimate_noise
    from methods.shape_gradient.start import denoised_topology, topology_gap

    vol = _shell_with_openings(3, 0.3)
    assert 0 < topology_gap(denoised_topology(vol, estimate_noise(vol))) <= 5


@pytest.mark.parametrize("name, degradation", [("bunny", "gaussian@20"), ("cortex", "gaussian@30"),
                                               ("ellipsoid", "mask+label_noise@0.1"), ("torus", "gaussian@30")])
def test_genus_0_shapes_under_noise_and_label_noise_read_near_genus_0(name, degradation):
    """What the refusal must never catch: additive noise (20–30 dB) and a mask's label noise make hundreds of
    speckle components and tunnels in the plain reading (level 0; a mask's reading half a voxel inside is its
    erosion, which may already read 0); smoothed (σ ≥ 1 voxel) they read 0 (the torus 1)."""
    from methods.shape_gradient.field import estimate_noise
    from methods.shape_gradient.start import denoised_topology, target_topology, topology_gap
    from phantoms.degrade import degrade

    ph = get_phantom(name)
    if degradation.startswith("gaussian"):
        vol = add_noise(ph.volume(n=64), "gaussian", snr=float(degradation.split("@")[1]))[0]
    else:
        vol = degrade(ph, degradation, 64)
    raw = target_topology(vol)                                         # the plain reading would refuse it
    assert raw["components"] - 1 + abs(raw["euler_solid"] - 1) > 5
    assert topology_gap(denoised_topology(vol, estimate_noise(vol))) == (1 if name == "torus" else 0)
