"""Reach for the Arcs (gpytoolbox): closed, outward and within a stated Hausdorff distance of the truth (the suite's
metric code) on the sphere at N = 20 and, heavy, on the bunny at N = 32 (within 2 h) and the off-centre,
anisotropic sphere (world coordinates); with ``clamp = 0`` and ``psr_depth = 10`` the adapter returns exactly the
library's ``reach_for_the_arcs``; the clamped samples and the auto PSR depth; one-line parameter errors.

The sphere runs in a few seconds; the bunny, the world-coordinate and the library-equivalence cases take 10–60 s
each on a loaded 2-core machine and are marked heavy."""

from __future__ import annotations

import numpy as np
import pytest

from methods import get_method
from methods.reach_for_the_arcs import PSR_DEPTHS, auto_psr_depth, clamped_samples
from phantoms import InputError

from _peers_common import CENTRE, RADIUS, check_closed_outward, hausdorff_h, offcentre_sphere, sphere_errors, volume


def test_sphere_closed_outward_and_close():
    vol = volume("sphere", 20)
    rec = get_method("reach_for_the_arcs").reconstruct(vol)
    check_closed_outward(rec.mesh, "reach_for_the_arcs on the sphere")
    assert hausdorff_h(rec.mesh, "sphere", vol.h) <= 1.0
    info = rec.info
    assert info["stop_reason"] == "converged" and info["iterations"] == 1
    assert info["fine_tuned_points"] >= info["cloud_points"] > 100
    assert PSR_DEPTHS[0] <= info["psr_depth"] <= PSR_DEPTHS[1]


@pytest.mark.heavy
def test_bunny_n32_within_2h():
    vol = volume("bunny", 32)
    rec = get_method("reach_for_the_arcs").reconstruct(vol)
    check_closed_outward(rec.mesh, "reach_for_the_arcs on the bunny")
    assert hausdorff_h(rec.mesh, "bunny", vol.h) <= 2.0


@pytest.mark.heavy
def test_world_coordinates_anisotropic_offcentre():
    vol = offcentre_sphere(coarsen=1.5)
    rec = get_method("reach_for_the_arcs").reconstruct(vol)
    check_closed_outward(rec.mesh, "reach_for_the_arcs on the off-centre sphere")
    err, centre_offset = sphere_errors(rec.mesh)
    h = vol.spacing.min()
    assert err < 1.0 * h, err / h
    assert np.abs(centre_offset).max() < 0.5 * h
    assert rec.mesh.volume == pytest.approx(4 / 3 * np.pi * RADIUS**3, rel=0.05)


@pytest.mark.heavy
def test_unclamped_depth_10_is_the_library():
    """The adapter's steps are the library's, seeds included: without the two cost knobs its mesh is the one
    ``gpytoolbox.reach_for_the_arcs`` returns (with its CPU rasteriser)."""
    import gpytoolbox as gpy

    vol = volume("sphere", 10)
    rec = get_method("reach_for_the_arcs", clamp=0.0, psr_depth=10, rasterization=0.0,
                     fine_tune_iters=3, batch_size=10000).reconstruct(vol)
    U, S, cap = clamped_samples(vol, 0.0)
    V, F = gpy.reach_for_the_arcs(U, S, force_cpu=True)
    assert cap == np.inf and rec.info["psr_depth"] == 10
    assert len(rec.mesh.vertices) == len(V)
    assert np.allclose(np.sort(rec.mesh.vertices, axis=0), np.sort(V, axis=0), atol=1e-9)


def test_clamped_samples():
    vol = offcentre_sphere(coarsen=2.0)
    U, S, cap = clamped_samples(vol, 3.0)
    assert len(U) == vol.values.size and cap == pytest.approx(3.0 * vol.h)
    exact = np.linalg.norm(U - CENTRE, axis=1) - RADIUS          # world positions: φ there is the sphere's SDF
    assert np.allclose(S, np.clip(exact, -cap, cap))
    assert np.abs(S).max() == pytest.approx(cap)
    U0, S0, cap0 = clamped_samples(vol, 0.0)
    assert cap0 == np.inf and np.allclose(S0, exact) and np.array_equal(U0, U)


def test_auto_psr_depth():
    pts = np.random.default_rng(0).random((100, 3))               # bounding cube ≈ 1.1
    assert auto_psr_depth(pts, 1.1 / 64 * 3) == 6                # a cell of h/3 needs 64 cells
    assert auto_psr_depth(pts, 1.1 / 65 * 3) == 7
    assert auto_psr_depth(pts, 1.0) == PSR_DEPTHS[0] and auto_psr_depth(pts, 1e-6) == PSR_DEPTHS[1]


@pytest.mark.parametrize("key, value, match", [
    ("clamp", -1.0, "parameter 'clamp'.*below the minimum"),
    ("psr_depth", 20, "parameter 'psr_depth'.*above the maximum"),
    ("rasterizer", "gpu", "parameter 'rasterizer'"),
    ("fine_tune_iters", 1.5, "parameter 'fine_tune_iters'"),
])
def test_parameter_errors_are_one_line(key, value, match):
    with pytest.raises(InputError, match=match) as err:
        get_method("reach_for_the_arcs", **{key: value})
    assert "\n" not in str(err.value) and "reach_for_the_arcs" in str(err.value)
