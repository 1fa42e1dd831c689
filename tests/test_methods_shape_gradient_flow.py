"""Tests of ``methods.shape_gradient.flow``: :class:`ShapeGradientFlow` stepped by hand and run — the energy
never increasing, the stop reasons (:data:`STOP_REASONS`), snapshots and ``max_iter``, divergence (NaN
derivatives) and the curvature fallback."""

from __future__ import annotations


import numpy as np
import pytest

from _shape_gradient_common import SG
from geometry.operators import MeshOperators
from geometry.sphere import fibonacci_sphere
from methods import ReconstructionFailed
from methods.shape_gradient import STOP_REASONS, GridSampler, ShapeGradient, ShapeGradientFlow
from phantoms import InputError, get_phantom


@pytest.fixture(scope="module")
def sphere32():
    return get_phantom("sphere").volume(n=32)


def test_snapshots_and_max_iter(sphere32):
    r = SG(max_iter=5, tol=0, move_tol=0, snapshots="1, 3,5", projection="off", guard=False,
           reach_samples=False).reconstruct(sphere32)                  # no post-step moves the last snapshot
    # no convergence test (tol = move_tol = 0): the count is the design, not a cap hit
    assert r.info["stop_reason"] == "fixed_iterations" and r.info["iterations"] == 5
    assert sorted(r.info["snapshots"]) == [0, 1, 3, 5]
    np.testing.assert_allclose(r.info["snapshots"][5], r.mesh.vertices)
    assert len(r.info["energy_history"]) == 6
    r0 = SG(max_iter=0, guard=False).reconstruct(sphere32)
    assert r0.info["iterations"] == 0 and r0.info["stop_reason"] == "max_iter"     # a run with a test hit the cap
    with pytest.raises(ReconstructionFailed, match="did not reach φ = 0"):    # checked by default: not a result
        SG(max_iter=0).reconstruct(sphere32)
    assert SG(snapshots=[2]).config["snapshots"] == (2,)
    assert SG(snapshots="").config["snapshots"] == ()


def test_a_degenerate_initial_mesh_is_refused(sphere32):
    """One vertex ring collapsed: zero-area faces, refused up front."""
    v, f = fibonacci_sphere(400, 1.5)
    ops = MeshOperators(f, len(v))
    v = v.copy()
    ring = ops.ring[0][ops.ring[0] >= 0]
    v[ring] = v[0] + 1e-9 * (v[ring] - v[0])
    with pytest.raises(InputError):
        SG(init_mesh=(v, f)).reconstruct(sphere32)                # zero-area faces are refused


def test_nan_during_the_flow_stops_as_diverged_with_the_iteration(sphere32, monkeypatch):
    """Derivatives that turn NaN in iteration 3 end the run as 'diverged', keeping the last good mesh."""
    real = GridSampler.sample_t
    calls = {"n": 0}

    def flaky(self, xt, derivatives=2):
        out = real(self, xt, derivatives)
        if derivatives == 2:                       # the vertex samples of the gradient step
            calls["n"] += 1
            if calls["n"] == 4:                    # the first is the setup call
                out = out.copy()
                out[5, 7] = np.nan
        return out

    monkeypatch.setattr(GridSampler, "sample_t", flaky)
    r = SG(tol=0, move_tol=0).reconstruct(sphere32)
    assert r.info["stop_reason"] == "diverged"
    assert r.info["stop_message"].startswith("iteration 3:") and r.info["iterations"] == 2
    assert len(r.info["energy_history"]) == 3 and np.isfinite(r.mesh.vertices).all()


def test_undetermined_curvature_fit_falls_back_to_the_cotangent_curvature(sphere32, monkeypatch):
    real = MeshOperators.curvature

    def flaky(self, geo, **kw):
        H, K = real(self, geo, **kw)
        H = H.copy()
        H[5] = np.nan
        return H, K

    monkeypatch.setattr(MeshOperators, "curvature", flaky)
    r = SG(max_iter=5).reconstruct(sphere32)
    assert r.info["stop_reason"] != "diverged" and r.info["curvature_fallbacks"] >= 5


# ============================================================================ the flow stepped by hand
@pytest.fixture(scope="module")
def sphere24():
    return get_phantom("sphere").volume(n=24)


def test_shape_gradient_flow_stepped_by_hand_never_increases_the_energy(sphere24):
    flow = SG().prepare(sphere24)
    assert isinstance(flow, ShapeGradientFlow)
    assert flow.iteration == 0 and flow.stop is None and flow.history == [flow.state.E]
    energies = [flow.state.E]
    going = True
    while going:
        before = flow.iteration
        going = flow.step()
        assert flow.iteration == before + 1                    # every call did one iteration, the last one too
        energies.append(flow.state.E)
        assert flow.iteration <= 200
    assert flow.stop in STOP_REASONS and flow.stop == "converged" and flow.message
    assert flow.step() is False and flow.iteration == len(energies) - 1   # ended: no further iteration
    rec = flow.result()
    E = rec.info["energy_history"]
    assert E == pytest.approx(energies)
    assert all(b <= a for a, b in zip(E, E[1:]))               # the backtracking line search: E never increases
    assert E[-1] < 1e-2 * E[0]
    assert rec.info["iterations"] == flow.iteration and rec.info["stop_reason"] == flow.stop
    assert rec.info["energy_final"] == E[-1]
    mesh = rec.mesh
    assert mesh.is_watertight and mesh.volume > 0              # closed, outward
    r = np.linalg.norm(mesh.vertices, axis=1)
    assert np.abs(r - 1.0).max() < 0.25 * sphere24.h           # on the unit sphere


def test_run_ends_where_stepping_by_hand_ends(sphere24):
    by_hand = SG().prepare(sphere24)
    while by_hand.step():
        pass
    run = SG().prepare(sphere24).run()
    assert run.iteration == by_hand.iteration and run.stop == by_hand.stop
    np.testing.assert_allclose(run.result().mesh.vertices, by_hand.result().mesh.vertices)


def test_max_iter_ends_the_hand_stepped_flow(sphere24):
    flow = ShapeGradient(init="sphere", remesh_every=0, max_iter=3, tol=0, move_tol=0).prepare(sphere24)
    assert [flow.step() for _ in range(4)] == [True, True, True, False]
    assert flow.iteration == 3 and flow.stop == "fixed_iterations" and "fixed count of 3" in flow.message
    assert len(flow.history) == 4
    capped = ShapeGradient(init="sphere", remesh_every=0, max_iter=3, tol=1e-12, move_tol=0).prepare(sphere24)
    while capped.step():
        pass
    assert capped.stop == "max_iter" and "max_iter = 3" in capped.message      # a test that never held: the cap


def test_the_plain_gradient_step_carries_the_flow_past_the_line_search_floor():
    """A noisy sphere (N = 48, 35 dB) stops on the line-search floor along the H¹ direction;
    with ``l2_fallback`` (the default) a search along the plain gradient finds a decrease there and the flow
    converges, as close to the sphere as before."""
    from phantoms.noise import add_noise

    ph = get_phantom("sphere")
    vol, _ = add_noise(ph.volume(n=48), "gaussian", 35.0, seed=0)
    plain = ShapeGradient(start_choice="off", l2_fallback=False).reconstruct(vol)
    fell_back = ShapeGradient(start_choice="off").reconstruct(vol)                  # the default
    assert plain.info["stop_reason"] == "line_search_floor" and plain.info["n_l2_fallbacks"] == 0
    assert fell_back.info["stop_reason"] == "converged" and fell_back.info["n_l2_fallbacks"] >= 1
    err = [np.abs(np.linalg.norm(r.mesh.vertices, axis=1) - ph.params["radius"]).max() for r in (plain, fell_back)]
    assert err[1] <= 1.1 * err[0]


def test_the_counters_are_one_stats_record_the_result_reports(sphere32):
    flow = SG(max_iter=6, tol=0, move_tol=0).prepare(sphere32)
    info = flow.run().result().info
    st = flow.stats
    assert len(st.moves) == info["iterations"] == 6 and st.n_backtracks >= 0
    for key in ("n_backtracks", "n_rejected_folds", "n_l2_fallbacks", "curvature_fallbacks", "cg_iterations",
                "remesh_refused"):
        assert info[key] == getattr(st, key), key
    assert info["move_history_voxels"] == [m / sphere32.h for m in st.moves]
    assert info["intersection_repairs"] == st.repairs and info["intersection_rollbacks"] == st.rollbacks
    assert info["intersections"] == [list(r) for r in st.intersections] and st.intersections[-1][0] == 6
