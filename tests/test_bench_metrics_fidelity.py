"""bench/metrics/fidelity.py: truth-free data-fidelity metrics against the volume, with known answers."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from bench.metrics import FIDELITY_NAMES, evaluate
from phantoms import add_noise, get_phantom


def _mc(vol):
    from skimage.measure import marching_cubes

    v, f, _, _ = marching_cubes(vol.values, 0.0, spacing=tuple(vol.spacing))
    return trimesh.Trimesh(v + vol.origin, f, process=False)


@pytest.fixture(scope="module")
def sphere():
    vol = get_phantom("sphere").volume(n=48)
    return vol, _mc(vol)


def test_a_mesh_on_the_zero_level_agrees_and_a_shifted_one_shows_its_offset(sphere):
    vol, mesh = sphere
    on = evaluate(mesh, None, vol.h, volume=vol, n_samples=20_000)
    assert on["phi_mean_h"] < 0.01 and on["sdf_rms_h"] < 0.05 and on["sign_err_pct"] == 0.0
    grown = trimesh.Trimesh(mesh.vertices * (1 + 1.0 * vol.h), mesh.faces, process=False)   # radius 1 + h
    off = evaluate(grown, None, vol.h, volume=vol, n_samples=20_000)
    assert off["phi_mean_h"] == pytest.approx(1.0, abs=0.02)
    assert off["sdf_rms_h"] == pytest.approx(1.0, abs=0.05) and off["sdf_p95_h"] == pytest.approx(1.0, abs=0.05)
    # the shell between radius 1 and 1 + h: its grid samples with |φ| > h/2 are on the wrong side
    pts = vol.grid_points().reshape(-1, 3)
    r = np.linalg.norm(pts, axis=1)
    expected = ((r > 1 + 0.5 * vol.h) & (r < 1 + vol.h)).sum() / (np.abs(r - 1) > 0.5 * vol.h).sum()
    assert off["sign_err_pct"] == pytest.approx(100 * expected, rel=0.1)


def test_a_dropped_part_shows_in_the_sign_and_the_sdf_agreement():
    ph = get_phantom("fused_spheres")
    vol = ph.volume(n=48)
    mesh = _mc(vol)
    top = mesh.split(only_watertight=False)
    whole = evaluate(mesh, None, vol.h, volume=vol, n_samples=20_000)
    upper = trimesh.creation.icosphere(subdivisions=4, radius=0.8)
    upper.apply_translation([0, 0, 0.7])                           # only one of the two balls
    part = evaluate(upper, None, vol.h, volume=vol, n_samples=20_000)
    assert len(top) == 1 and whole["sign_err_pct"] < 0.05
    assert part["sign_err_pct"] > 20 * max(whole["sign_err_pct"], 0.01)
    assert part["sdf_p95_h"] > 5 * whole["sdf_p95_h"]


def test_noisy_volume_reads_the_noise_and_without_a_volume_they_are_nan(sphere):
    vol, mesh = sphere
    noisy, _ = add_noise(vol, "gaussian", 20.0, seed=0)
    sigma_h = float(np.std(noisy.values - vol.values)) / vol.h
    got = evaluate(mesh, None, vol.h, volume=noisy, n_samples=20_000)
    assert got["sdf_rms_h"] == pytest.approx(sigma_h, rel=0.15)
    none = evaluate(mesh, get_phantom("sphere"), vol.h, n_samples=5_000)
    assert all(np.isnan(none[k]) for k in FIDELITY_NAMES)
