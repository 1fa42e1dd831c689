"""Dual contouring of signed distance data (gpytoolbox): closed, outward, χ = 2 and within 1.5 h (symmetric
Hausdorff, the suite's metric code) on the four paper phantoms at N = 24 (the implementation is slow: ≈ 0.5 s
per outer iteration at this size); on the bunny close but with non-manifold edges (a limit of one vertex per
cell); world coordinates on an anisotropic, off-centre grid; the quad split; reversed quads; the band."""

from __future__ import annotations

import numpy as np
import pytest

from methods import get_method
from methods.dual_contouring import band_box, split_quads
from phantoms import InputError

from _peers_common import (PAPER_PHANTOMS, RADIUS, check_closed_outward, hausdorff_h, offcentre_sphere,
                           sphere_errors, volume)

N = 24
CASES = PAPER_PHANTOMS        # 3 outer iterations: 1–2 s each


@pytest.mark.parametrize("phantom", CASES)
def test_closed_outward_and_close(phantom):
    vol = volume(phantom, N)
    rec = get_method("dual_contouring", iterations=3).reconstruct(vol)
    check_closed_outward(rec.mesh, f"dual_contouring on {phantom}")
    assert hausdorff_h(rec.mesh, phantom, vol.h) <= 1.5
    assert rec.info["iterations"] == 3 and rec.info["stop_reason"] == "done"
    assert len(rec.mesh.faces) == 2 * rec.info["quads"]


def test_reversed_quads_are_flipped_back():
    """After a few outer iterations the library returns some quads reversed (the cylinder at N = 24 after 3);
    the adapter's mesh is consistently wound all the same, and says how many triangles it flipped."""
    from bench.metrics.validity import check_mesh

    vol = volume("cylinder", N)
    rec = get_method("dual_contouring", iterations=3).reconstruct(vol)
    assert rec.info["triangles_flipped"] > 0
    assert check_mesh(rec.mesh, vol) == []
    check_closed_outward(rec.mesh, "dual_contouring on the cylinder")


def test_bunny_is_close_but_not_manifold():
    """One vertex per cell cannot carry two sheets: where a grid cell's inside samples touch only diagonally
    (the bunny's ears and other features thinner than a cell, at N = 24 and still at 48), dual contouring
    joins four quads at one edge.  The result is close to the surface but not a closed 2-manifold, and the
    suite's validity check says so (the grid records the cell as invalid, never as a good result)."""
    from bench.metrics.validity import check_mesh

    vol = volume("bunny", N)
    # the default 10 iterations: the vertex error is not monotone in them (0: 1.3 h, 1: 2.1 h, 3: 1.3 h, 10: 0.8 h)
    rec = get_method("dual_contouring").reconstruct(vol)
    assert hausdorff_h(rec.mesh, "bunny", vol.h) <= 1.5
    reasons = check_mesh(rec.mesh, vol)
    assert any(r.startswith("non-manifold") for r in reasons), reasons
    assert rec.mesh.volume > 0


def test_world_coordinates_anisotropic_offcentre():
    vol = offcentre_sphere(coarsen=2.0)          # (24, 18, 17) samples: two outer iterations in a few seconds
    assert len(set(vol.shape)) == 3 and len(set(vol.spacing)) == 3
    rec = get_method("dual_contouring", iterations=2).reconstruct(vol)
    check_closed_outward(rec.mesh, "dual_contouring on the off-centre sphere")
    err, centre_offset = sphere_errors(rec.mesh)
    h = vol.spacing.min()
    assert err < 0.25 * h, err / h
    assert np.abs(centre_offset).max() < 0.1 * h
    assert rec.mesh.volume == pytest.approx(4 / 3 * np.pi * RADIUS**3, rel=0.03)


def test_band_changes_nothing_before_the_iterations():
    """The initial dual-contouring mesh (iterations = 0) uses each crossed cell's own samples: the band's
    sub-box gives exactly the mesh of the whole grid, from fewer samples."""
    vol = offcentre_sphere()
    band = get_method("dual_contouring", iterations=0).reconstruct(vol)
    full = get_method("dual_contouring", iterations=0, samples="all").reconstruct(vol)
    assert full.info["samples_used"] == vol.values.size > band.info["samples_used"]
    assert np.array_equal(np.sort(band.mesh.vertices, axis=0), np.sort(full.mesh.vertices, axis=0))
    err, _ = sphere_errors(band.mesh)
    assert err < 0.25 * vol.spacing.min()


def test_band_box_holds_the_surface():
    vol = offcentre_sphere()
    lo, hi = band_box(vol, 1.0)
    sub = vol.values[lo[0]:hi[0], lo[1]:hi[1], lo[2]:hi[2]]
    # every sign change of the grid lies inside the box, with one sample of margin where the grid allows
    assert (vol.values < 0).sum() == (sub < 0).sum()
    inside = np.argwhere(vol.values < 0)
    assert ((inside.min(0) - lo >= 2) | (lo == 0)).all() and ((hi - 1 - inside.max(0) >= 2) | (hi == vol.shape)).all()


def test_split_quads_keeps_winding_and_takes_the_short_diagonal():
    V = np.array([[0, 0, 0], [2, 0, 0], [2.2, 1, 0], [0, 1, 0]], float)   # diagonal 1–3 is the shorter
    T = split_quads(V, np.array([[0, 1, 2, 3]]))
    assert sorted(map(tuple, np.sort(T, axis=1))) == [(0, 1, 3), (1, 2, 3)]
    n = np.cross(V[T[:, 1]] - V[T[:, 0]], V[T[:, 2]] - V[T[:, 0]])
    assert (n[:, 2] > 0).all()          # the quad's counter-clockwise winding is kept


def test_parameters_checked():
    with pytest.raises(InputError, match="parameter 'iterations'.*below the minimum"):
        get_method("dual_contouring", iterations=-1)
    with pytest.raises(InputError, match="parameter 'samples'"):
        get_method("dual_contouring", samples="half")
