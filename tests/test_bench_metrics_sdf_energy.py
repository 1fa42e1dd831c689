"""The papers' SDF energy (bench/metrics/sdf_energy.py) against an independent full-grid computation."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from bench.metrics import evaluate
from bench.metrics.sdf_energy import ENERGY_POINTS, energy_query, sdf_energy
from phantoms import add_noise, get_phantom


def _mc(vol):
    from skimage.measure import marching_cubes

    v, f, _, _ = marching_cubes(vol.values, 0.0, spacing=tuple(vol.spacing))
    v += vol.origin
    return v, np.ascontiguousarray(f[:, ::-1]).astype(np.int32)


def _papers_energy(U, S, v, f):
    """Reach for the Arcs' ``our_energy``: 1000 · Σ (|S| − √d²)² / #U, d² from gpytoolbox (libigl's AABB)."""
    import gpytoolbox as gpy

    d2 = gpy.squared_distance(U, v, f, use_cpp=True, use_aabb=True)[0]
    g = np.abs(S) - np.sqrt(d2)
    return 1000 * np.sum(g ** 2) / U.shape[0], 1000 * g ** 2


def _grid_points(n, extent):
    ax = np.linspace(-extent, extent, n)
    return np.stack(np.meshgrid(ax, ax, ax, indexing="ij"), -1).reshape(-1, 3)


def test_known_answer_and_abs_of_S():
    assert sdf_energy([-1.0, 2.0], [0.5, 2.0]) == pytest.approx(1000 * (0.25 + 0.0) / 2)
    assert sdf_energy([1.0, -2.0], [0.5, 2.0]) == sdf_energy([-1.0, 2.0], [0.5, 2.0])
    assert np.isnan(sdf_energy([], []))


def test_every_grid_point_at_small_n_equals_gpytoolbox():
    """N = 20 (8,000 ≤ ENERGY_POINTS grid points): the whole grid, as the papers take it; S the sphere's exact
    signed distance on an independently built grid — equal to rounding."""
    ph = get_phantom("sphere")
    vol = ph.volume(n=20)
    assert 20 ** 3 <= ENERGY_POINTS
    v, f = _mc(vol)
    U = _grid_points(20, 2.5)
    ref, _ = _papers_energy(U, np.linalg.norm(U, axis=1) - 1.0, v, f)
    ours = evaluate(trimesh.Trimesh(v, f, process=False), ph, vol.h, clean=vol, n_samples=2000)["sdf_energy"]
    assert ours == pytest.approx(ref, rel=1e-9)
    assert ref > 0


def test_a_subset_estimates_the_full_grid_within_its_standard_error():
    """N = 48 (110,592 points): the seeded subset of ENERGY_POINTS points against every point of the grid
    (gpytoolbox): within 4 standard errors √(var(g²) (1 − m/M) / m), and that error is below 3 % of the value."""
    ph = get_phantom("torus")
    vol = ph.volume(n=48)
    v, f = _mc(vol)
    U = _grid_points(48, 2.5)
    ref, g2 = _papers_energy(U, vol.values.reshape(-1), v, f)
    m, M = ENERGY_POINTS, len(U)
    se = np.std(g2) * np.sqrt((1 - m / M) / m)
    assert se < 0.03 * ref
    ours = evaluate(trimesh.Trimesh(v, f, process=False), ph, vol.h, clean=vol, n_samples=2000)["sdf_energy"]
    assert abs(ours - ref) <= 4 * se, (ours, ref, se)


def test_the_subset_is_seeded_and_uniform():
    vol = get_phantom("sphere").volume(n=40)
    a, pa = energy_query(vol, seed=3)
    b, _ = energy_query(vol, seed=3)
    c, _ = energy_query(vol, seed=4)
    assert len(a) == ENERGY_POINTS == len(np.unique(a)) and (a == b).all() and not (a == c).all()
    np.testing.assert_allclose(pa, vol.index_to_world(np.stack(np.unravel_index(a, vol.shape), 1)))


def test_reads_the_clean_S_not_the_noisy_input():
    """With noise, |S| is the clean grid's (the papers' S is the exact SDF), whatever volume the method was given;
    without ``clean`` there is no energy (the noisy φ would score the noise)."""
    ph = get_phantom("sphere")
    vol = ph.volume(n=24)
    noisy, _ = add_noise(vol, "gaussian", 20.0, seed=0)
    mesh = trimesh.Trimesh(*_mc(vol), process=False)
    clean = evaluate(mesh, ph, vol.h, clean=vol, n_samples=2000)["sdf_energy"]
    given = evaluate(mesh, ph, vol.h, volume=noisy, n_samples=2000, clean=vol)["sdf_energy"]
    assert given == pytest.approx(clean, rel=1e-12) and clean > 0
    assert np.isnan(evaluate(mesh, ph, vol.h, volume=noisy, n_samples=2000)["sdf_energy"])


def test_no_truth_no_energy():
    ph = get_phantom("sphere")
    vol = ph.volume(n=24)
    row = evaluate(trimesh.Trimesh(*_mc(vol), process=False), None, vol.h, volume=vol, n_samples=2000, clean=vol)
    assert "sdf_energy" not in row
