"""Tests of ``bench.report.picture``: :func:`rasterize` paints triangles in order, the pixels inside each,
anti-aliased by supersampling, with optional edges."""

from __future__ import annotations

import numpy as np

from bench.report.picture import rasterize


def test_rasterize_fills_the_pixels_inside_the_triangles_in_order():
    # a 10 × 10 pixel square of two triangles at (5, 5)-(15, 15) in a 20 × 20 image, then a red triangle on top
    sq = np.array([[[5, 5], [15, 5], [15, 15]], [[5, 5], [15, 15], [5, 15]], [[0, 0], [4, 0], [0, 4]]], float)
    col = np.array([[0, 0, 1], [0, 0, 1], [1, 0, 0]], float)
    img = rasterize(sq, col, 20, 20, supersample=1)
    blue = (img[..., 2] == 255) & (img[..., 0] == 0)
    assert blue.sum() == 100 and blue[5:15, 5:15].all()          # y up: pixel rows 19 - 14 .. 19 - 5
    red = (img[..., 0] == 255) & (img[..., 2] == 0)
    assert 6 <= red.sum() <= 10 and red[19, 0]                   # ~8 px below the diagonal x + y = 4
    smooth = rasterize(sq, col, 20, 20, supersample=2)
    assert ((smooth[..., 2] > 0) & (smooth[..., 2] < 255)).any()  # anti-aliased borders


def test_rasterize_background_colour_and_edges():
    tri = np.array([[[2, 2], [18, 2], [10, 18]]], float)
    plain = rasterize(tri, np.array([[0, 255, 0]], np.uint8), 20, 20, background=(10, 20, 30), supersample=1)
    assert plain.shape == (20, 20, 3) and plain.dtype == np.uint8
    assert tuple(plain[0, 0]) == (10, 20, 30)                   # outside: the background
    green = (plain == [0, 255, 0]).all(axis=2)
    assert 100 < green.sum() < 160                              # ~ the triangle's area, 128 px
    edged = rasterize(tri, np.array([[0, 255, 0]], np.uint8), 20, 20, edge_px=1.5, edge_rgb=(0, 0, 0),
                      supersample=1)
    dark = (edged == 0).all(axis=2)
    assert dark.sum() > 0 and (dark & ~green).sum() == 0        # the edges are drawn inside the triangle
    assert (edged == [0, 255, 0]).all(axis=2).sum() < green.sum()
