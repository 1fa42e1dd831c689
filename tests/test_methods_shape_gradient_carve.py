"""Tests of ``methods.shape_gradient.carve`` (``hold_carved``): the flow may not retreat into the region no
outside sample's empty ball reaches, so a limb thinner than a voxel that the start has is not cut; the limits
are those of the balls, and the clamp cuts only the inward normal part of a step."""

from __future__ import annotations

import numpy as np
import pytest

from methods.shape_gradient import ShapeGradient
from methods.shape_gradient.carve import CarvedHull, ball_depth, ball_depth_numpy
from phantoms import Volume

from _shape_gradient_common import one_flow

_N, _LO = 32, -2.0
_H = 4.0 / (_N - 1)


def _grid():
    g = _LO + _H * np.arange(_N)
    return np.stack(np.meshgrid(g, g, g, indexing="ij"), -1)


@pytest.fixture(scope="module")
def limb():
    """A ball of radius 0.8 with a limb of radius 0.4 voxel (a capsule, its axis on a row of samples) out to
    x = 1.6, at N = 32: the samples on the axis read −0.4 voxel, all others are outside, so the start has the
    limb and φ interpolated between the samples is above 0 around it."""
    p = _grid()
    r, off = 0.4 * _H, _LO + 16 * _H               # the axis through the samples of index 16 in y and z
    a, b = np.array([0.0, off, off]), np.array([1.6, off, off])
    t = np.clip((p - a) @ (b - a) / ((b - a) @ (b - a)), 0.0, 1.0)
    capsule = np.linalg.norm(p - (a + t[..., None] * (b - a)), axis=-1) - r
    return Volume(np.minimum(np.linalg.norm(p, axis=-1) - 0.8, capsule), [_LO] * 3, _H), 1.6 + r


def test_a_sub_voxel_limb_is_kept_with_hold_carved_and_cut_without(limb):
    vol, tip = limb
    plain = ShapeGradient(start_choice="off", reach_samples=False).reconstruct(vol)   # the flow alone: no post-step
    held = one_flow(vol, {"hold_carved": True}, reach_samples=False)                  # reaching for the limb
    short_plain = (tip - plain.mesh.vertices[:, 0].max()) / _H
    short_held = (tip - held.mesh.vertices[:, 0].max()) / _H
    assert short_plain > 1.0                       # the flow shortens the limb by more than a voxel ...
    assert abs(short_held) < 0.5                   # ... and keeps it whole when it may not leave the balls
    assert held.info["carved_held"] > 0 and plain.info["carved_held"] is None
    assert held.info["parameters"]["hold_carved"] is True
    assert held.mesh.is_watertight and held.mesh.euler_number == 2


def test_ball_depth_is_the_depth_in_the_nearest_samples_balls():
    """On a sphere's distance volume b is the depth of x in the union of the balls: about the distance to the
    sphere outside it (the ball of the sample nearest x reaches the sphere), and below 0 inside."""
    p = _grid()
    vol = Volume(np.linalg.norm(p, axis=-1) - 1.0, [_LO] * 3, _H)
    rng = np.random.default_rng(0)
    u = rng.normal(size=(200, 3))
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    out = ball_depth(vol, 1.5 * u, 1.0)            # half a unit outside: b ≤ 0.5 and close to it
    assert np.all(out <= 0.5 + 1e-9) and np.all(out > 0.5 - 0.25 * _H)
    inside = ball_depth(vol, 0.9 * u, 1.0)         # inside the sphere: no ball reaches it
    assert np.all(inside < 0.0)


def test_the_clamp_cuts_only_the_inward_normal_part():
    normals = np.array([[1.0, 0.0, 0.0]] * 3)
    step = np.array([[-2.0, 1.0, 0.0], [-0.1, 0.0, 1.0], [3.0, 0.0, 0.0]])
    out = CarvedHull.clamp(step, normals, np.array([0.5, 0.5, 0.0]))
    assert np.allclose(out, [[-0.5, 1.0, 0.0], [-0.1, 0.0, 1.0], [3.0, 0.0, 0.0]])


def test_off_by_default_and_in_the_paper_preset(limb):
    vol, _ = limb
    assert ShapeGradient(max_iter=0).prepare(vol).carve is None
    assert ShapeGradient(preset="paper", max_iter=0).prepare(vol).carve is None
    assert ShapeGradient(max_iter=0).prepare(vol, start={"hold_carved": True}).carve is not None


def test_the_remesher_keeps_only_the_tips_the_carved_hull_holds():
    """With ``hold_carved`` alone a remesh keeps the sharply convex vertices whose inward move is 0 — the tips
    of a thin part no ball covers — and not those of a part that lies inside a ball (free to retreat)."""
    from types import SimpleNamespace

    import trimesh

    from geometry.operators import MeshOperators
    from methods.shape_gradient.carve import remesh_keep

    ico = trimesh.creation.icosphere(3, radius=2.0 * _H)          # mean curvature 0.5 per voxel: every vertex a tip
    x = np.asarray(ico.vertices, float)
    ops = MeshOperators(np.asarray(ico.faces), len(x))
    geo = ops.geometry(x)
    held = SimpleNamespace(limits=lambda p: np.where(p[:, 0] > 0, 0.0, 1.0))   # held on the side x > 0
    kept = remesh_keep(ops, geo, _H, held)
    assert len(kept) > 0 and np.all(x[kept, 0] > 0) and len(kept) == int((x[:, 0] > 0).sum())
    assert len(remesh_keep(ops, geo, _H, None)) == 0


def test_a_limb_between_sample_rows_enters_the_start_with_start_level_and_is_kept():
    """A limb of radius 0.35 voxel whose axis runs half-way between two rows of samples: every sample is outside
    (the nearest read +0.15 voxel), so the genus-0 start of φ < 0 has no limb and nothing holds it; grown from
    φ < 0.25 voxel the start has it, and with ``hold_carved`` the flow keeps it (without, it shortens it)."""
    p = _grid()
    r, off = 0.35 * _H, _LO + 16 * _H
    a, b = np.array([0.0, off + 0.5 * _H, off]), np.array([1.6, off + 0.5 * _H, off])
    t = np.clip((p - a) @ (b - a) / ((b - a) @ (b - a)), 0.0, 1.0)
    capsule = np.linalg.norm(p - (a + t[..., None] * (b - a)), axis=-1) - r
    values = np.minimum(np.linalg.norm(p, axis=-1) - 0.8, capsule)
    assert values[(p[..., 0] > 0.9) & (p[..., 0] < 1.5)].min() > 0.1 * _H      # no sample inside along the limb
    vol, tip = Volume(values, [_LO] * 3, _H), 1.6 + r
    plain = one_flow(vol, {"hold_carved": True}, reach_samples=False)        # the starts and the flow alone
    grown = one_flow(vol, {"hold_carved": True, "start_level": 0.25})
    assert (tip - plain.mesh.vertices[:, 0].max()) / _H > 4.0                   # no limb at all
    assert abs(tip - grown.mesh.vertices[:, 0].max()) / _H < 1.0                # the limb, within a voxel
    alone = one_flow(vol, {"start_level": 0.25}, reach_samples=False)
    assert (tip - alone.mesh.vertices[:, 0].max()) / _H > 1.5                   # without hold_carved: shortened
    assert grown.mesh.is_watertight and grown.mesh.euler_number == 2


def test_a_held_vertex_keeps_a_relaxation_that_does_not_leave_the_balls():
    """The relaxation of a vertex the hull holds is kept where it moves no farther from the balls (b does not
    fall) and dropped where it does; a vertex that may move inwards keeps its shift whatever it is."""
    z0 = _LO + 10.5 * _H                                     # a plane half-way between two rows of samples
    vol = Volume(_grid()[..., 2] - z0, [_LO] * 3, _H)
    hull = CarvedHull(vol, _H, np.zeros((1, 3)), np.array([[0.0, 0.0, 1.0]]), 0.0)
    c = _LO + 16.5 * _H                                      # the centre of a square of sample columns
    x = np.array([[c, c, z0 + 0.1 * _H]] * 3)                # just above the plane, between the balls
    b0 = ball_depth(vol, x[:1], hull.scale)[0]
    assert b0 < 0
    shift = np.array([[0.0, 0.0, 0.3 * _H], [0.0, 0.0, -0.3 * _H], [0.0, 0.0, -0.3 * _H]])
    out = hull.still(x, shift, np.array([0.0, 0.0, 1.0]))
    assert np.array_equal(out[0], shift[0])                   # towards the balls: kept
    assert np.array_equal(out[1], np.zeros(3))                # deeper into the uncovered region: dropped
    assert np.array_equal(out[2], shift[2])                   # not held: kept
    assert hull.still(x, None, np.zeros(3)) is None


def test_the_compiled_ball_depth_equals_the_numpy_gather():
    """Points near a sphere's surface, points off the grid and a few thousand of them (the kernel runs from
    geometry.compiled.MIN_SIZE on): the same depths bit for bit, −inf where no outside sample is near."""
    from geometry import compiled

    g = _LO + _H * np.arange(_N)
    p = np.stack(np.meshgrid(g, g, g, indexing="ij"), -1)
    vol = Volume(np.linalg.norm(p, axis=-1) - 0.8, [_LO] * 3, _H)
    rng = np.random.default_rng(0)
    pts = rng.uniform(-2.3, 2.3, size=(4000, 3))
    pts[:50] *= 0.1                                                      # deep inside: no outside sample near
    assert len(pts) >= compiled.MIN_SIZE
    fast, ref = ball_depth(vol, pts, 0.97), ball_depth_numpy(vol, pts, 0.97)
    assert np.array_equal(fast, ref)
    assert np.isneginf(ref[:50]).all() and np.isfinite(ref).sum() > 3000


def test_the_stop_test_reads_the_move_the_limits_let_through():
    """The clamped move is the largest normal move once each inward part is cut to its limit (outward parts
    whole); a carved start on a sphere, whose surface sits on the carved hull pushing inwards, is still within a
    few remeshes instead of running to max_iter (the uncut trial move never fell below move_tol)."""
    from types import SimpleNamespace

    from methods.shape_gradient.linesearch import clamped_move

    normals = np.array([[1.0, 0, 0], [0, 1.0, 0], [0, 0, 1.0]])
    direction = np.array([[-2.0, 0.3, 0], [0, -0.5, 0], [0.1, 0, 0.4]])      # inward 2, inward 0.5, outward 0.4
    geo = SimpleNamespace(vertex_normals=normals)
    assert clamped_move(geo, direction, 0.5, np.array([0.1, 1.0, 0.0])) == pytest.approx(0.25)
    assert clamped_move(geo, direction, 0.5, np.array([2.0, 1.0, 0.0])) == pytest.approx(1.0)
    n = 48                                                  # here the uncut move ran to max_iter
    g = _LO + (4.0 / (n - 1)) * np.arange(n)
    p = np.stack(np.meshgrid(g, g, g, indexing="ij"), -1)
    vol = Volume(np.linalg.norm(p, axis=-1) - 1.2, [_LO] * 3, 4.0 / (n - 1))
    rec = one_flow(vol, {"carved_start": True, "hold_carved": True, "carve_margin": 0.1}, max_iter=150)
    assert rec.info["stop_reason"] == "converged" and rec.info["iterations"] < 60
