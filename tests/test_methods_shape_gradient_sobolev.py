"""The H¹ velocity (methods/shape_gradient/sobolev.py): the three solvers solve the same system (M + sK)V = MG,
the velocity is a smoothed descent direction, 'auto' picks by s and the mesh size, and reset forgets the mesh."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.sparse.linalg import spsolve

from geometry.operators import MeshOperators
from geometry.sphere import fibonacci_sphere
from methods.shape_gradient.sobolev import SobolevSolver


@pytest.fixture(scope="module")
def sphere():
    x, faces = fibonacci_sphere(2000, 1.0)
    ops = MeshOperators(faces, len(x))
    geo = ops.geometry(x)
    rng = np.random.default_rng(0)
    G = np.cos(3 * x[:, 2]) + 0.3 * rng.normal(size=len(x))          # a smooth field plus noise
    return ops, geo, G, geo.vertex_areas * G


@pytest.mark.parametrize("solver", ["direct", "amg", "cg"])
def test_every_solver_solves_the_h1_system(sphere, solver):
    ops, geo, G, b = sphere
    s = 0.01
    exact = spsolve(ops.h1_matrix(geo, s)[0].tocsc(), b)
    its: list = []
    V = SobolevSolver(solver).velocity(ops, geo, G, b, s, its)
    assert np.linalg.norm(V - exact) <= 5e-3 * np.linalg.norm(exact)
    assert float(b @ V) > 0                                           # a descent direction
    assert np.std(np.diff(V[np.argsort(geo.vertices[:, 2])])) < np.std(np.diff(G[np.argsort(geo.vertices[:, 2])]))
    assert (len(its) == 1) == (solver == "cg")


def test_auto_takes_cg_for_a_small_s_and_the_lu_for_a_large_one_and_reset_forgets(sphere):
    ops, geo, G, b = sphere
    small, large = SobolevSolver("auto"), SobolevSolver("auto")
    small.velocity(ops, geo, G, b, 1e-6, [])
    large.velocity(ops, geo, G, b, 1.0, [])
    assert small._choice == "cg" and large._choice == "direct" and large._factor is not None
    large.reset()
    assert large._choice is None and large._factor is None and large._V_prev is None
