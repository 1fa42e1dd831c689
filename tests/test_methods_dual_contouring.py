"""Dual contouring of signed distance data (gpytoolbox): closed, outward, χ = 2 and within 1.5 h (symmetric
Hausdorff, the suite's metric code) on the four paper phantoms and the bunny at N = 24 (the implementation is
slow: ≈ 0.5 s per outer iteration at this size); world coordinates on an anisotropic, off-centre grid; the quad
split; the band of samples."""

from __future__ import annotations

import numpy as np
import pytest

from methods import get_method
from methods.dual_contouring import band_box, split_quads
from phantoms import InputError

from _peers_common import (PAPER_PHANTOMS, RADIUS, check_closed_outward, hausdorff_h, offcentre_sphere,
                           sphere_errors, volume)

N = 24
CASES = [p if p in ("sphere", "bunny") else pytest.param(p, marks=pytest.mark.slow)
         for p in PAPER_PHANTOMS + ["bunny"]]


@pytest.mark.parametrize("phantom", CASES)
def test_closed_outward_and_close(phantom):
    vol = volume(phantom, N)
    rec = get_method("dual_contouring", iterations=3).reconstruct(vol)
    check_closed_outward(rec.mesh, f"dual_contouring on {phantom}")
    assert hausdorff_h(rec.mesh, phantom, vol.h) <= 1.5
    assert rec.info["iterations"] == 3 and rec.info["stop_reason"] == "done"
    assert len(rec.mesh.faces) == 2 * rec.info["quads"]


def test_world_coordinates_anisotropic_offcentre():
    vol = offcentre_sphere()
    rec = get_method("dual_contouring", iterations=1).reconstruct(vol)
    check_closed_outward(rec.mesh, "dual_contouring on the off-centre sphere")
    err, centre_offset = sphere_errors(rec.mesh)
    h = vol.spacing.min()
    assert err < 0.25 * h, err / h
    assert np.abs(centre_offset).max() < 0.1 * h
    assert rec.mesh.volume == pytest.approx(4 / 3 * np.pi * RADIUS**3, rel=0.02)
    # the band is a sub-box of the grid: fewer samples than the grid, the same surface within 0.1 h
    assert rec.info["samples_used"] < vol.values.size
    full = get_method("dual_contouring", iterations=1, samples="all").reconstruct(vol)
    assert full.info["samples_used"] == vol.values.size
    assert len(full.mesh.vertices) == len(rec.mesh.vertices)
    assert sphere_errors(full.mesh)[0] < 0.25 * h


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
