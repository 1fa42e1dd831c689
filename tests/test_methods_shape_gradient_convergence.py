"""Tests of ``methods.shape_gradient.convergence``: the two ``converged`` tests (patience, reset, held) and the
stages (β and edge length per stage, where each began)."""

from __future__ import annotations

import pytest

from methods.shape_gradient.convergence import PATIENCE, ConvergenceTest, Stages
from methods.shape_gradient.settings import Stage


def test_a_flat_energy_converges_after_the_patience_and_a_change_restarts_the_count():
    test = ConvergenceTest(tol=1e-3, move_tol=0.1, move_tol_voxels=1.0)
    assert [test.observe(1e-4, 1.0) for _ in range(PATIENCE - 1)] == [None] * (PATIENCE - 1)
    assert test.observe(1e-2, 1.0) is None                  # one large change: counting starts again
    for _ in range(PATIENCE - 1):
        assert test.observe(1e-4, 1.0) is None
    assert test.observe(1e-4, 1.0) == f"relative energy change below tol = 0.001 for {PATIENCE} iterations"


def test_a_still_surface_converges_by_its_move():
    test = ConvergenceTest(tol=0.0, move_tol=0.05, move_tol_voxels=0.5)   # tol = 0: the energy test is off
    reasons = [test.observe(0.0, 0.01) for _ in range(PATIENCE)]
    assert reasons[:-1] == [None] * (PATIENCE - 1)
    assert reasons[-1] == f"largest normal move below move_tol = 0.5 voxels for {PATIENCE} iterations"


def test_nothing_counts_while_held_and_a_reset_keeps_the_hold_unless_told():
    test = ConvergenceTest(tol=1e-3, move_tol=0.1, move_tol_voxels=1.0)
    test.reset(held=True)
    assert all(test.observe(0.0, 0.0) is None for _ in range(2 * PATIENCE))
    test.reset()
    assert test.held and test.observe(0.0, 0.0) is None
    test.reset(held=False)
    assert [test.observe(0.0, 0.0) for _ in range(PATIENCE)][-1] is not None


def test_the_stages_carry_beta_and_the_edge_length_in_world_units():
    stages = Stages((Stage(1.0, 0.5), Stage(0.01, 1.0)), h=0.2)
    assert stages.beta == 1.0 and stages.edge_length == pytest.approx(0.1) and stages.more()
    stages.enter(17)
    assert stages.beta == 0.01 and stages.edge_length == pytest.approx(0.2) and not stages.more()
    assert stages.starts == [{"iteration": 0, "beta": 1.0, "edge_length_voxels": 0.5},
                             {"iteration": 17, "beta": 0.01, "edge_length_voxels": 1.0}]
