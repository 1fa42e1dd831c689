"""The report's pictures (bench.report.render): framing, shared colour scale, PNG data URIs."""

from __future__ import annotations

import base64

import numpy as np
import pytest

from bench.report.render import colour_range, render_energy, render_mesh, view_extent

TETRA_V = np.array([[1, 1, 1], [1, -1, -1], [-1, 1, -1], [-1, -1, 1]], float)
TETRA_F = np.array([[0, 1, 2], [0, 3, 1], [0, 2, 3], [1, 3, 2]])


def _image(uri: str) -> np.ndarray:
    """The RGB pixels of a ``data:image/webp`` (or png) URI."""
    import io

    from PIL import Image

    assert uri.startswith(("data:image/webp;base64,", "data:image/png;base64,"))
    return np.asarray(Image.open(io.BytesIO(base64.b64decode(uri.split(",", 1)[1]))).convert("RGB"))


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


def test_render_mesh_draws_the_mesh_and_its_colour_strip_and_energy_is_svg():
    img = render_mesh(TETRA_V, TETRA_F, np.arange(4.0), vmin=0, vmax=3, extent=view_extent([TETRA_V]),
                      title="t")
    px = _image(img)
    assert px.shape == (180, 198, 3)
    mesh = px[:, :180]
    covered = (np.abs(mesh.astype(int) - 255).sum(axis=2) > 30).mean()
    assert 0.2 < covered < 0.95                                  # the tetrahedron fills its frame, not all of it
    strip = px[20:160, 186:194].astype(int)
    assert strip[0, 0, 0] > strip[0, 0, 2] and strip[-1, 0, 2] > strip[-1, 0, 0]   # red on top, blue below
    grey = _image(render_mesh(TETRA_V, TETRA_F, None, vmin=0, vmax=1, extent=(0, 0, 2)))
    assert np.abs(grey.astype(int) - px.astype(int)).mean() > 1
    svg = base64.b64decode(render_energy([3.0, 2.0, 1.5], marks=[1], ylim=(1, 4)).split(",", 1)[1]).decode()
    assert svg.startswith("<svg") and "<polyline" in svg and svg.count("<circle") == 1 and "1e0" in svg
