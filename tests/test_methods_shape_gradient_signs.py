"""The sign guard (methods/shape_gradient/signs.py): counts clearly-inside/outside samples on the wrong side of a
surface, and stops a flow that cuts parts of the object."""

from __future__ import annotations

import numpy as np
import trimesh

from methods.shape_gradient import ShapeGradient
from methods.shape_gradient.signs import SignGuard
from phantoms import add_noise, get_phantom


def test_counts_on_a_sphere_with_known_answers():
    vol = get_phantom("sphere").volume(n=32)
    h = vol.h
    exact = trimesh.creation.icosphere(5, radius=1.0)                      # the sphere phantom has radius 1
    ops = type("Ops", (), {"faces": exact.faces})()
    g = SignGuard(vol, h, exact.vertices, exact.faces, ops)
    assert g.log == [(0, 0)] and g.allowed == 2 + int(1e-3 * g.n_points)
    # shrunk by 0.6 h: every checked inside sample between radius 1 − 0.6 h and 1 − 0.25 h is now outside it
    small = exact.vertices * (1 - 0.6 * h)
    r = np.linalg.norm(vol.index_to_world(np.argwhere(g.sel)), axis=1)
    expected = int(np.count_nonzero((r > 1 - 0.6 * h) & (r < 1 - 0.25 * h)))
    assert abs(g.wrong_side(small, exact.faces) - expected) <= 0.02 * expected and expected > 100
    back = g.check(5, small, ops)
    assert back is not None and np.array_equal(back[0], exact.vertices) and "rolled back to iteration 0" in g.message
    assert g.check(6, exact.vertices, ops) is None and g.checkpoint[0] == 6


def test_the_sign_guard_stops_the_flow_cutting_the_bunnys_ears_at_n32():
    """At N = 32 the bunny's ears are a voxel or two thick; remeshing plus the alignment term shorten them step by
    step (5.2 h without the guard, from a 0.8 h start).  The guard counts clearly-inside/outside samples on the
    wrong side at every remesh and rolls back when the count rises."""
    from bench.metrics import evaluate
    ph = get_phantom("bunny")
    vol = ph.volume(n=32)
    r = ShapeGradient(start_choice="off", reach_samples=False).reconstruct(vol)   # the usual start and the flow
    log = r.info["sign_guard"]
    assert r.info["stop_reason"] == "sign_guard" and "rolled back" in r.info["stop_message"]
    assert log[0] == [0, 0] and log[-1][1] > log[-2][1]
    assert evaluate(r.mesh, ph, vol.h, n_samples=20000)["hausdorff_h"] < 1.5
    off = ShapeGradient(sign_guard=False, start_choice="off", reach_samples=False).reconstruct(vol)
    assert off.info["sign_guard"] == [] and evaluate(off.mesh, ph, vol.h, n_samples=20000)["hausdorff_h"] > 3.0


def test_the_sign_guard_is_off_on_noisy_volumes_and_other_starts():
    ph = get_phantom("sphere")
    noisy, _ = add_noise(ph.volume(n=32), "gaussian", 30.0, seed=1)
    assert ShapeGradient().reconstruct(noisy).info["sign_guard"] == []
    assert ShapeGradient(init="auto").reconstruct(ph.volume(n=32)).info["sign_guard"] == []
    clean = ShapeGradient().reconstruct(ph.volume(n=32))
    assert clean.info["sign_guard"][0] == [0, 0] and clean.info["stop_reason"] != "sign_guard"


def _capped(vertices: np.ndarray, axis_sign: float, depth: float) -> np.ndarray:
    """The unit sphere's vertices with the cap beyond 1 − depth on the side ``axis_sign`` (of x) cut flat."""
    v = vertices.copy()
    v[:, 0] = np.minimum(v[:, 0], 1 - depth) if axis_sign > 0 else np.maximum(v[:, 0], -(1 - depth))
    return v


def test_growing_into_samples_the_start_missed_is_no_cut_and_earns_no_allowance():
    """Only clearly-inside samples that the surface covered and no longer covers are a cut.  A start missing the
    +x cap (as a genus-0 start missing a part): the flow growing it back is not stopped; growing it back then
    cutting the −x cap is stopped, although fewer samples are outside the surface than at the start (the count
    the guard used to compare, which let a flow trade a grown part for a cut one); cutting the grown-back cap
    again is a cut too."""
    vol = get_phantom("sphere").volume(n=32)
    h = vol.h
    exact = trimesh.creation.icosphere(5, radius=1.0)
    ops = type("Ops", (), {"faces": exact.faces})()
    start = _capped(exact.vertices, +1, 3 * h)
    g = SignGuard(vol, h, start, exact.faces, ops)
    r = np.linalg.norm(vol.index_to_world(np.argwhere(g.sel)), axis=1)
    x = vol.index_to_world(np.argwhere(g.sel))[:, 0]
    missed = int(np.count_nonzero((r < 1 - 0.25 * h) & (x > 1 - 3 * h)))
    cut = int(np.count_nonzero((r < 1 - 0.25 * h) & (x < -(1 - 2 * h))))
    assert missed > cut > g.allowed + 20 and g.log == [(0, 0)]
    assert g.check(5, exact.vertices, ops) is None and g.log[-1] == (5, 0)          # grown back: no cut
    assert g.check(10, _capped(exact.vertices, -1, 2 * h), ops) is not None          # ... then cut elsewhere
    assert abs(g.log[-1][1] - cut) <= 0.05 * cut and g.checkpoint[0] == 5
    assert g.check(15, start, ops) is not None and g.log[-1][1] >= 0.95 * missed     # the grown part cut again


def test_a_failed_check_goes_back_to_the_checkpoint_with_the_fewest_wrong_samples():
    """A flow that cuts a part does so over several checks, each within the allowance: the guard goes back to
    the accepted checkpoint with the fewest samples on the wrong side (the latest of equals), not the last."""
    vol = get_phantom("sphere").volume(n=32)
    h = vol.h
    exact = trimesh.creation.icosphere(5, radius=1.0)
    ops = type("Ops", (), {"faces": exact.faces})()
    g = SignGuard(vol, h, exact.vertices * 1.0, exact.faces, ops)
    u = np.array([0.3, 0.5, 0.81]) / np.linalg.norm([0.3, 0.5, 0.81])
    nicked = exact.vertices.copy()
    nicked[nicked @ u > np.cos(0.15)] *= 1 - 1.0 * h                         # a dent a voxel deep ...
    assert 0 < g.wrong_side(nicked, exact.faces) <= g.allowed                # ... within the allowance
    assert g.check(5, exact.vertices, ops) is None and g.check(8, exact.vertices, ops) is None
    assert g.check(10, nicked, ops) is None and g.checkpoint[0] == 10 and g.log[-1][1] > 0
    back = g.check(15, exact.vertices * (1 - 0.6 * h), ops)
    assert back is not None and np.array_equal(back[0], exact.vertices)
    assert "rolled back to iteration 8, the checkpoint with the fewest (0)" in g.message


def test_the_remesher_keeps_the_vertices_it_is_told_to_keep():
    """The remesher's ``keep`` (what ``hold_carved`` passes for the held tips): those vertices stay in place."""
    from methods.shape_gradient.remesh import remesh
    s = trimesh.creation.icosphere(3)
    keep = np.array([5, 17, 40])
    u, _ = remesh(s.vertices, s.faces, 0.3, 2, closed=True, keep=keep)
    assert np.allclose(u[:3], s.vertices[keep])                 # kept in place, first in the output
