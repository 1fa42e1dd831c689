"""Reach for the Spheres (gpytoolbox): closed, outward, χ = 2 and within 1.5 h (symmetric Hausdorff, the suite's
metric code) on the four paper phantoms and the bunny at N = 48; world coordinates on an anisotropic,
off-centre grid; the stop reason and iteration count; the sample selection; parameter checks.

The sphere, the ellipsoid and the off-centre sphere run by default (a few seconds each); the fused spheres, the
cylinder and the bunny (14–22 s each on a loaded 2-core machine) are marked slow."""

from __future__ import annotations

import numpy as np
import pytest

from methods import get_method
from methods.reach_for_the_spheres import grid_samples
from phantoms import InputError

from _peers_common import (CENTRE, PAPER_PHANTOMS, RADIUS, check_closed_outward, hausdorff_h,
                           offcentre_sphere, sphere_errors, volume)

N = 48
# sphere and ellipsoid: 2–3 s each; fused spheres, cylinder, bunny: 14–22 s each (loaded 2-core machine) → slow
CASES = [p if p in ("sphere", "ellipsoid") else pytest.param(p, marks=pytest.mark.slow)
         for p in PAPER_PHANTOMS + ["bunny"]]


@pytest.mark.parametrize("phantom", CASES)
def test_closed_outward_and_close(phantom):
    vol = volume(phantom, N)
    rec = get_method("reach_for_the_spheres").reconstruct(vol)
    check_closed_outward(rec.mesh, f"reach_for_the_spheres on {phantom}")
    assert hausdorff_h(rec.mesh, phantom, vol.h) <= 1.5
    info = rec.info
    assert info["stop_reason"] == "converged" and 0 < info["iterations"] < 2000
    # the target edge length is refined (halved when progress stalls) but never below edge_length = 2 h
    assert 2.0 - 1e-9 <= info["final_edge_target_h"] < 5.0


def test_world_coordinates_anisotropic_offcentre():
    vol = offcentre_sphere()
    rec = get_method("reach_for_the_spheres").reconstruct(vol)
    check_closed_outward(rec.mesh, "reach_for_the_spheres on the off-centre sphere")
    err, centre_offset = sphere_errors(rec.mesh)
    h = vol.spacing.min()
    assert err < 0.5 * h, err / h
    assert np.abs(centre_offset).max() < 0.25 * h
    assert rec.mesh.volume == pytest.approx(4 / 3 * np.pi * RADIUS**3, rel=0.03)


def test_iteration_cap_is_reported():
    rec = get_method("reach_for_the_spheres", max_iter=3).reconstruct(volume("sphere", 32))
    assert rec.info["iterations"] == 3 and rec.info["stop_reason"] == "max_iter"
    assert rec.mesh.is_watertight


def test_sample_selection():
    vol = offcentre_sphere()
    U, S = grid_samples(vol, "all", 4.0)
    assert len(U) == vol.values.size
    # positions are world coordinates of the samples: φ there is the exact sphere distance
    assert np.allclose(np.linalg.norm(U - CENTRE, axis=1) - RADIUS, S)
    Ub, Sb = grid_samples(vol, "band", 2.0)
    assert (Sb < 2.0 * vol.h).all() and (Sb < 0).sum() == (vol.values < 0).sum()
    assert len(Ub) == ((vol.values < 2.0 * vol.h)).sum() < len(U)
    with pytest.raises(InputError, match="parameter 'samples'"):
        get_method("reach_for_the_spheres", samples="some")
    with pytest.raises(InputError, match="parameter 'edge_length'.*below the minimum"):
        get_method("reach_for_the_spheres", edge_length=0.0)


def test_vertex_guard_stops_a_growing_mesh():
    """The guard against a crumpling flow: past max_vertices the run stops as 'diverged' and says why."""
    rec = get_method("reach_for_the_spheres", max_vertices=100).reconstruct(volume("sphere", 32))
    assert rec.info["stop_reason"] == "diverged" and "max_vertices = 100" in rec.info["stop_message"]
    # the remesher first coarsens the 162-vertex icosphere, then refines past 100 as the edge target halves
    assert rec.info["iterations"] >= 1 and len(rec.mesh.vertices) > 100
