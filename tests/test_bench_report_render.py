"""The report's pictures (bench.report.render): framing, shared colour scale, PNG data URIs."""

from __future__ import annotations

import base64

import numpy as np
import pytest

from bench.report.render import colour_range, render_energy, render_mesh, view_extent

TETRA_V = np.array([[1, 1, 1], [1, -1, -1], [-1, 1, -1], [-1, -1, 1]], float)
TETRA_F = np.array([[0, 1, 2], [0, 3, 1], [0, 2, 3], [1, 3, 2]])


def _png_bytes(uri: str) -> bytes:
    assert uri.startswith("data:image/png;base64,")
    data = base64.b64decode(uri.split(",", 1)[1])
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    return data


def test_view_extent_covers_every_mesh_and_scales_with_it():
    cx, cy, r = view_extent([TETRA_V])
    cx2, cy2, r2 = view_extent([TETRA_V, 3 * TETRA_V])
    assert r2 == pytest.approx(3 * r, rel=1e-6)
    assert view_extent([]) == (0.0, 0.0, 1.0)


def test_colour_range_is_robust_and_widens_a_constant():
    vals = [np.r_[np.linspace(0, 1, 1000), 1e6], None, np.array([np.nan])]
    lo, hi = colour_range(vals)
    assert 0.0 <= lo < 0.05 and 0.95 < hi < 1.1                  # the outlier does not set the scale
    lo, hi = colour_range([np.full(10, 2.0)])
    assert lo < 2.0 < hi                                          # a band around a constant curvature
    assert colour_range([]) == (-1.0, 1.0)


def test_render_mesh_and_energy_give_png_data_uris():
    img = render_mesh(TETRA_V, TETRA_F, np.arange(4.0), vmin=0, vmax=3, extent=view_extent([TETRA_V]),
                      title="t")
    assert len(_png_bytes(img)) > 1000
    assert _png_bytes(render_mesh(TETRA_V, TETRA_F, None, vmin=0, vmax=1, extent=(0, 0, 2))) != _png_bytes(img)
    assert len(_png_bytes(render_energy([3.0, 2.0, 1.5], marks=[1], ylim=(1, 4)))) > 1000
