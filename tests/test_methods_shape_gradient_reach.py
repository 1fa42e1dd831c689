"""Tests of ``methods.shape_gradient.reach``: where band samples say the surface is nearer than the mesh, the
mesh's closest points move to it — a dent is pulled back to the analytic sphere, a right mesh does not move, a
body the mesh lost is not bridged, a refused round changes nothing."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh
from _shape_gradient_common import far_limb_volume

from geometry.operators import MeshOperators
from methods.shape_gradient import ShapeGradient
from methods.shape_gradient.choose import data_errors
from methods.shape_gradient.reach import REACH_MAX_VOXELS, reach_samples
from methods.shape_gradient.post import keep_back
from phantoms import add_noise, get_phantom, grid_volume

N = 40


@pytest.fixture(scope="module")
def ball():
    """A ball of radius 1 as a signed distance at N = 40 and a fine icosphere on it."""
    vol = grid_volume(lambda p: np.linalg.norm(p, axis=-1) - 1.0, n=N)
    m = trimesh.creation.icosphere(subdivisions=5, radius=1.0)
    return vol, np.asarray(m.vertices, float), np.asarray(m.faces)


def _run(vol, x, f, noise_voxels=0.0, guard=True):
    ops = MeshOperators(f, len(x))
    keep = (lambda xq, x0: keep_back(ops, xq, x0, local=True, halve=3)) if guard else (lambda xq, x0: (xq, 0, True))
    return reach_samples(vol, x, f, ops.geometry(x).vertex_normals, noise_voxels, keep)


def test_a_dent_is_pulled_back_to_the_sphere(ball):
    """A cap of the sphere pushed 2 voxels in: the samples above it (|φ| < 1.5 voxels, 2 voxels from the mesh)
    pull their closest vertices back to the sphere — one vertex per sample, so on a mesh this much finer than the
    grid the cap's points of the true sphere come within 1.5 voxels of it (they were 2 voxels from it, the points
    between the pulled vertices stay farthest) — no vertex goes past the sphere, and the mesh away from the cap
    stays where it was."""
    vol, x, f = ball
    h = vol.h
    cap = x[:, 2] > np.cos(np.radians(20))
    dented = x.copy()
    dented[cap] *= (1.0 - 2.0 * h)
    out, stats = _run(vol, dented, f)
    truth = trimesh.creation.icosphere(subdivisions=5, radius=1.0).vertices
    truth = truth[truth[:, 2] > np.cos(np.radians(15))]

    def truth_to_mesh(v):
        return trimesh.proximity.ProximityQuery(trimesh.Trimesh(v, f, process=False)).on_surface(truth)[1].max() / h

    assert truth_to_mesh(dented) > 1.9 and truth_to_mesh(out) < 1.5
    assert np.linalg.norm(out, axis=1).max() < 1.0 + 0.05 * h
    assert stats["flagged"] > 0 and stats["moved"] > 0 and stats["max_move_voxels"] <= REACH_MAX_VOXELS + 1e-9
    away = x[:, 2] < np.cos(np.radians(35))
    np.testing.assert_array_equal(out[away], dented[away])
    assert np.abs(data_errors(vol, out, f)).max() < np.abs(data_errors(vol, dented, f)).max()


def test_a_mesh_that_agrees_with_every_sample_does_not_move(ball):
    vol, x, f = ball
    out, stats = _run(vol, x, f)
    assert stats["flagged"] == 0 and stats["moved"] == 0
    np.testing.assert_array_equal(out, x)


def test_under_noise_a_right_mesh_barely_moves(ball):
    """At 40 dB the limit is half a voxel plus three noise stds: the true sphere's mesh moves at few vertices,
    none by more than a voxel."""
    vol, x, f = ball
    noisy, _ = add_noise(vol, "gaussian", 40.0, seed=0)
    sigma = float(np.std(np.asarray(noisy.values) - np.asarray(vol.values))) / vol.h
    out, stats = _run(noisy, x, f, noise_voxels=sigma)
    assert sigma > 0.05 and stats["limit_voxels"] == pytest.approx(0.5 + 3 * sigma)
    assert stats["moved"] <= 0.01 * len(x)
    assert np.linalg.norm(out - x, axis=1).max() <= vol.h


def test_a_body_the_mesh_lost_is_not_bridged():
    """Two balls 4 voxels apart, a mesh of one: the other's samples are farther than REACH_MAX_VOXELS — no
    vertex reaches for it."""
    h = 5.0 / (N - 1)
    c = np.array([1.0 + 2.0 * h, 0, 0])
    vol = grid_volume(lambda p: np.minimum(np.linalg.norm(p + c, axis=-1), np.linalg.norm(p - c, axis=-1)) - 1.0,
                     n=N)
    m = trimesh.creation.icosphere(subdivisions=4, radius=1.0)
    x = np.asarray(m.vertices, float) - c
    out, stats = _run(vol, x, np.asarray(m.faces))
    assert np.linalg.norm(out - x, axis=1).max() <= REACH_MAX_VOXELS * vol.h + 1e-9
    assert out[:, 0].max() < x[:, 0].max() + 0.5 * vol.h


def test_a_round_the_guard_cannot_repair_is_undone(ball):
    vol, x, f = ball
    dented = x.copy()
    dented[x[:, 2] > 0.95] *= 0.9
    ops = MeshOperators(f, len(x))
    out, stats = reach_samples(vol, dented, f, ops.geometry(dented).vertex_normals, 0.0,
                               lambda xq, x0: (xq, 0, False))
    np.testing.assert_array_equal(out, dented)
    assert stats["rounds"] == 1 and stats["moved"] == 0


def test_the_method_runs_the_step_by_default_and_the_paper_presets_leave_it_off():
    vol = get_phantom("sphere").volume(n=24)
    r = ShapeGradient(max_iter=5).reconstruct(vol)
    assert r.info["reach"]["used"] and r.info["reach"]["moved"] == 0
    assert not ShapeGradient(max_iter=5, reach_samples=False).reconstruct(vol).info["reach"]["used"]
    assert not ShapeGradient(preset="paper", max_iter=2, guard=False).reconstruct(vol).info["reach"]["used"]
    assert not ShapeGradient(preset="paper+fixes", max_iter=2, guard=False).reconstruct(vol).info["reach"]["used"]


def test_the_start_choice_scores_each_flow_before_the_reach():
    """A limb every sample misses: the usual start loses it, and the reach alone would bring its stump 3 voxels
    out — enough to hide the loss from a score read after it.  The choice reads each flow's result before the
    reach (``before_reach``), so the usual result still disagrees, the carved starts run and the limb is kept."""
    vol, tip = far_limb_volume()
    rec = ShapeGradient().reconstruct(vol)
    choice = rec.info["start_choice"]
    assert len(choice["candidates"]) == 3 and choice["chosen"] != "usual"
    assert choice["candidates"]["usual"]["largest_error_voxels"] > 4.0
    assert abs(tip - rec.mesh.vertices[:, 0].max()) / vol.h < 1.0
    flow = ShapeGradient(start_choice="off").prepare(vol)
    flow.run()
    usual = flow.result()
    assert usual.info["reach"]["moved"] > 0
    assert not np.array_equal(flow.before_reach, usual.mesh.vertices)
    assert (usual.mesh.vertices[:, 0].max() - flow.before_reach[:, 0].max()) / vol.h > 1.0   # the stump came out


def test_on_noisy_volumes_a_lone_sample_does_not_pull(ball):
    """One sample 1.2 voxels outside made to read 0.1 voxel — the surface a voxel out, where the mesh is right: on
    a clean volume it pulls its vertex out; read as a noisy volume (``lone=False``) a sample with no flagged
    neighbour does not."""
    vol, x, f = ball
    values = np.array(vol.values)
    i, j, k = np.unravel_index(np.argmin(np.abs(values - 1.2 * vol.h)), values.shape)
    values[i, j, k] = 0.1 * vol.h
    odd = type(vol)(values, vol.origin, vol.spacing)
    ops = MeshOperators(f, len(x))
    keep = lambda xq, x0: keep_back(ops, xq, x0, local=True, halve=3)      # noqa: E731
    _, lone = reach_samples(odd, x, f, ops.geometry(x).vertex_normals, 0.0, keep, lone=True)
    out, alone = reach_samples(odd, x, f, ops.geometry(x).vertex_normals, 0.0, keep, lone=False)
    assert lone["flagged"] == 1 and lone["moved"] == 1
    assert alone["flagged"] == 0 and alone["moved"] == 0
    np.testing.assert_array_equal(out, x)
