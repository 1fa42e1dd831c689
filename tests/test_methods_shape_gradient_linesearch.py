"""Tests of ``methods.shape_gradient.linesearch``: the capped Armijo line search (its trials, backtracks, floor and
memory of the last move), the L² fallback's direction and the clamped normal move, on a sphere's distance field
whose energy minimum is known (the unit sphere)."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from geometry.operators import MeshOperators
from geometry.sphere import fibonacci_sphere
from methods.shape_gradient import as_field, evaluate_state
from methods.shape_gradient.linesearch import LineSearch, clamped_move, l2_fallback_direction
from phantoms import Volume


@pytest.fixture(scope="module")
def sphere_case():
    """The distance to the unit sphere on a grid in [−2, 2]³, and a 400-vertex sphere of radius 0.6 on it: E(r) =
    4πα(r − 1)²r², which decreases outwards up to r = 1."""
    g = np.linspace(-2.0, 2.0, 41)
    p = np.stack(np.meshgrid(g, g, g, indexing="ij"), -1)
    field = as_field(Volume(np.linalg.norm(p, axis=-1) - 1.0, [-2.0] * 3, 0.1))
    x, f = fibonacci_sphere(400, 0.6)
    ops = MeshOperators(f, len(x))

    def evaluate(xe):
        return evaluate_state(field, ops, xe, 5.0, 0.0)
    return evaluate, evaluate(np.asarray(x, float))


def _outward(state):
    """The direction n (unit speed outwards at every vertex): the descent toward the unit sphere."""
    return state.geo.vertex_normals, 1.0


def test_the_first_trial_is_the_cap_and_a_too_long_step_is_halved_until_e_decreases(sphere_case):
    evaluate, state = sphere_case
    direction, vmax = _outward(state)
    slope = 1.0
    stats = SimpleNamespace(n_backtracks=0, n_rejected_folds=0)
    line = LineSearch(max_move=2.0, floor_move=1e-4)    # r = 2.6 leaves the box, 1.6 is past the target: E rises
    new, move, moved = line.search(evaluate, state, direction, None, vmax, slope, None, stats)
    assert new is not None and new.E < state.E
    assert move == 0.5 and stats.n_backtracks == 2 and stats.n_rejected_folds == 0
    assert moved == move                                  # no limit: the normal move is the trial move
    assert line.prev == move and line.grow is False        # not the first trial: the next starts from this move
    np.testing.assert_allclose(new.x, state.x + move * direction)      # each vertex moved by the trial move


def test_after_a_first_try_success_the_next_trial_doubles_up_to_the_cap(sphere_case):
    evaluate, state = sphere_case
    direction, vmax = _outward(state)
    stats = SimpleNamespace(n_backtracks=0, n_rejected_folds=0)
    line = LineSearch(max_move=0.4, floor_move=1e-4)
    line.prev, line.grow = 0.05, True
    new, move, _ = line.search(evaluate, state, direction, None, vmax, 1.0, None, stats)
    assert move == pytest.approx(0.1) and stats.n_backtracks == 0 and line.grow is True


def test_an_ascent_direction_ends_on_the_floor(sphere_case):
    evaluate, state = sphere_case
    direction, vmax = _outward(state)
    stats = SimpleNamespace(n_backtracks=0, n_rejected_folds=0)
    line = LineSearch(max_move=0.1, floor_move=0.01)
    new, move, moved = line.search(evaluate, state, -direction, None, vmax, 1.0, None, stats)   # inwards: E rises
    assert new is None and move == 0.1 / 16 and moved == 0.0 and stats.n_backtracks == 4
    assert line.prev == 0.1 and line.grow is True          # a failed search leaves the memory as it was


def test_restart_and_the_halved_cap():
    line = LineSearch(max_move=1.0, floor_move=0.1)
    line.prev, line.grow = 0.25, True
    line.restart()
    assert (line.prev, line.grow) == (1.0, False)
    line.halve_cap()
    assert line.max_move == 0.5 and line.prev == 0.5
    line.halve_cap()
    line.halve_cap()
    assert line.max_move == pytest.approx(0.4)             # never below 4 × the floor


def test_the_l2_fallback_follows_the_plain_gradient_within_the_same_limits():
    normals = np.eye(3)
    geo = SimpleNamespace(vertex_normals=normals, vertex_areas=np.array([1.0, 2.0, 1.0]))
    G = np.array([1.0, -0.5, 2.0])
    direction, vmax, slope = l2_fallback_direction(geo, G, None)
    np.testing.assert_allclose(direction, -G[:, None] * normals)
    assert vmax == 2.0 and slope == pytest.approx(1.0 + 2.0 * 0.25 + 4.0)
    direction, vmax, _ = l2_fallback_direction(geo, G, np.array([0.0, 1.0, 1.0]))   # vertex 0 may not go inwards
    assert direction[0].tolist() == [0.0, 0.0, 0.0] and vmax == 2.0
    assert l2_fallback_direction(geo, np.zeros(3), None) is None                    # no decrease predicted


def test_the_clamped_move_cuts_inward_parts_to_their_limit():
    geo = SimpleNamespace(vertex_normals=np.eye(3))
    direction = np.array([[-2.0, 0.3, 0], [0, -0.5, 0], [0.1, 0, 0.4]])      # inward 2, inward 0.5, outward 0.4
    assert clamped_move(geo, direction, 0.5, np.array([0.1, 1.0, 0.0])) == pytest.approx(0.25)
    assert clamped_move(geo, direction, 0.5, np.array([2.0, 1.0, 0.0])) == pytest.approx(1.0)
