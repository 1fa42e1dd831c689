"""Fill triangles into an RGB image (compiled with numba): the report's mesh pictures without a plotting library.

:func:`rasterize` paints screen-space triangles in the order given (far to near: the painter's algorithm), each
pixel whose centre lies inside a triangle (edge functions ≥ 0, either winding) taking its colour, optionally
darkened within ``edge_px`` pixels of the triangle's edges (the mesh lines of a coarse mesh).  Rendered at
``supersample``× the size and box-filtered down, the silhouettes are anti-aliased.  Much faster than
matplotlib's Agg for the same picture.
"""

from __future__ import annotations

import math

import numpy as np

from geometry.compiled import jit

__all__ = ["rasterize"]


@jit
def _fill(tri, colours, width, height, edge_px, edge_rgb, img):
    for t in range(tri.shape[0]):
        x0, y0, x1, y1, x2, y2 = tri[t, 0, 0], tri[t, 0, 1], tri[t, 1, 0], tri[t, 1, 1], tri[t, 2, 0], tri[t, 2, 1]
        area = (x1 - x0) * (y2 - y0) - (x2 - x0) * (y1 - y0)
        if area == 0.0:
            continue
        s = 1.0 if area > 0 else -1.0
        lx = (math.sqrt((x2 - x1) ** 2 + (y2 - y1) ** 2), math.sqrt((x0 - x2) ** 2 + (y0 - y2) ** 2),
              math.sqrt((x1 - x0) ** 2 + (y1 - y0) ** 2))
        i0 = max(int(math.floor(min(x0, x1, x2))), 0)
        i1 = min(int(math.ceil(max(x0, x1, x2))), width - 1)
        j0 = max(int(math.floor(min(y0, y1, y2))), 0)
        j1 = min(int(math.ceil(max(y0, y1, y2))), height - 1)
        for j in range(j0, j1 + 1):
            py = j + 0.5
            for i in range(i0, i1 + 1):
                px = i + 0.5
                w0 = s * ((x2 - x1) * (py - y1) - (y2 - y1) * (px - x1))
                w1 = s * ((x0 - x2) * (py - y2) - (y0 - y2) * (px - x2))
                w2 = s * ((x1 - x0) * (py - y0) - (y1 - y0) * (px - x0))
                if w0 < 0.0 or w1 < 0.0 or w2 < 0.0:
                    continue
                near = edge_px > 0.0 and (w0 < edge_px * lx[0] or w1 < edge_px * lx[1] or w2 < edge_px * lx[2])
                for c in range(3):
                    img[height - 1 - j, i, c] = edge_rgb[c] if near else colours[t, c]


@jit
def _box_down(img, k, out):
    """``out`` = the mean of each k × k block of ``img`` (rounded)."""
    for j in range(out.shape[0]):
        for i in range(out.shape[1]):
            for c in range(3):
                acc = 0
                for dj in range(k):
                    for di in range(k):
                        acc += img[j * k + dj, i * k + di, c]
                out[j, i, c] = (2 * acc + k * k) // (2 * k * k)


def rasterize(triangles: np.ndarray, colours: np.ndarray, width: int, height: int, *, background=(255, 255, 255),
              edge_px: float = 0.0, edge_rgb=(60, 60, 60), supersample: int = 2) -> np.ndarray:
    """An (height, width, 3) uint8 image of the triangles.

    Parameters
    ----------
    triangles : (F, 3, 2) float
        Screen coordinates in pixels of the final image, x to the right, y up; painted in this order.
    colours : (F, 3) float in [0, 1] or uint8
        One colour per triangle.
    edge_px : float
        Pixels (of the final image) along each triangle's edges drawn in ``edge_rgb`` (0: no edges).
    """
    k = max(int(supersample), 1)
    tri = np.ascontiguousarray(np.asarray(triangles, np.float64) * k)
    col = np.asarray(colours)
    if col.dtype != np.uint8:
        col = np.clip(np.round(np.asarray(col, float) * 255.0), 0, 255).astype(np.uint8)
    img = np.empty((height * k, width * k, 3), np.uint8)
    img[:] = np.asarray(background, np.uint8)
    _fill(tri, np.ascontiguousarray(col[:, :3]), width * k, height * k, float(edge_px) * k,
          np.asarray(edge_rgb, np.uint8), img)
    if k == 1:
        return img
    out = np.empty((height, width, 3), np.uint8)
    _box_down(img, k, out)
    return out
