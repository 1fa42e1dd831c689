"""Pictures of the report: meshes coloured by mean curvature, energy curves, PNG data URIs.

Meshes are drawn with faces coloured by mean curvature (paraboloid fit over a 2h neighbourhood, computed in
the worker) with a colour strip; the callers share the camera and the colour scale across a table row.
Rendering is an orthographic painter's algorithm filled by the compiled :func:`bench.report.picture.rasterize`
(much faster than matplotlib's Agg on large meshes) and stored as WebP; energy curves are SVG.
"""

from __future__ import annotations

import base64
import html
import io
import math

import numpy as np

__all__ = ["ELEV", "AZIM", "CMAP", "png_uri", "view_extent", "colour_range", "render_mesh", "render_energy"]

ELEV, AZIM = 20.0, -25.0   # one camera for every picture (y, the ellipsoid's long axis, across)
CMAP = "RdYlBu_r"          # blue = low, red = high mean curvature (as in the paper's figures)


def _pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def png_uri(fig) -> str:
    """The figure as a ``data:image/png;base64,...`` URI (the figure is closed)."""
    import matplotlib.pyplot as plt

    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=fig.dpi)
    plt.close(fig)
    return "data:image/png;base64," + base64.b64encode(buf.getvalue()).decode("ascii")


def _camera(elev: float = ELEV, azim: float = AZIM) -> np.ndarray:
    """Rows: screen x, screen y, towards the viewer (world z is up on screen)."""
    e, a = math.radians(elev), math.radians(azim)
    d = np.array([math.cos(e) * math.cos(a), math.cos(e) * math.sin(a), math.sin(e)])
    x = np.cross([0.0, 0.0, 1.0], d)
    x /= np.linalg.norm(x)
    y = np.cross(d, x)
    return np.stack([x, y, d])


def view_extent(meshes: list[np.ndarray], elev: float = ELEV, azim: float = AZIM) -> tuple[float, float, float]:
    """(centre x, centre y, half-width) on screen covering every vertex array in ``meshes``."""
    R = _camera(elev, azim)
    pts = [np.asarray(v, float) @ R[:2].T for v in meshes if v is not None and len(v)]
    if not pts:
        return 0.0, 0.0, 1.0
    p = np.concatenate(pts)
    lo, hi = p.min(0), p.max(0)
    c = (lo + hi) / 2
    return float(c[0]), float(c[1]), float(max(hi - lo) / 2 * 1.06 + 1e-9)


def colour_range(values: list[np.ndarray]) -> tuple[float, float]:
    """A robust shared colour scale (2nd–98th percentile) for per-vertex curvature arrays."""
    vals = [np.asarray(v, float).ravel() for v in values if v is not None and len(v)]
    vals = [v[np.isfinite(v)] for v in vals]
    vals = [v for v in vals if len(v)]
    if not vals:
        return -1.0, 1.0
    allv = np.concatenate(vals)
    lo, hi = np.percentile(allv, [2, 98])
    if hi - lo < 0.1 * max(abs(lo), abs(hi), 0.5):  # near-constant curvature: show a band around it
        mid = (lo + hi) / 2
        half = 0.05 * max(abs(mid), 1.0)
        lo, hi = mid - half, mid + half
    return float(lo), float(hi)


def _visible_faces(v: np.ndarray, f: np.ndarray, elev: float, azim: float):
    """(triangles in camera coordinates, their vertex indices, |normal·view|), far to near, back faces dropped."""
    p = v @ _camera(elev, azim).T
    tri = p[f]                                               # (F, 3, 3) in camera coordinates
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    nz = n[:, 2] / np.maximum(np.linalg.norm(n, axis=1), 1e-300)
    keep = nz > 0                                            # back faces of a closed outward mesh are hidden
    if keep.sum() < 0.2 * len(f):                            # inward-oriented or open: draw everything
        keep[:] = True
    tri, fi, nz = tri[keep], f[keep], np.abs(nz[keep])
    order = np.argsort(tri[:, :, 2].mean(1), kind="stable")  # far to near
    return tri[order], fi[order], nz[order]


def _image_uri(img: np.ndarray) -> str:
    """An RGB uint8 image as a ``data:image/webp`` URI (lossy, quality 60: ≈ 6 KB for a mesh picture, a tenth of
    the PNG); PNG where Pillow has no WebP."""
    from PIL import Image, features

    buf = io.BytesIO()
    pic = Image.fromarray(img, "RGB")
    if features.check("webp"):
        pic.save(buf, format="WEBP", quality=60, method=4)
        kind = "webp"
    else:  # pragma: no cover - Pillow wheels ship WebP
        pic.save(buf, format="PNG", optimize=True)
        kind = "png"
    return f"data:image/{kind};base64," + base64.b64encode(buf.getvalue()).decode("ascii")


def render_mesh(vertices, faces, H, *, vmin: float, vmax: float, extent: tuple[float, float, float],
                title: str | None = None, elev: float = ELEV, azim: float = AZIM, size: int = 180) -> str:
    """Image data URI of a mesh with faces coloured by the mean of their vertices' ``H`` (colour scale
    [vmin, vmax], drawn as the strip on the right: blue = vmin at the bottom, red = vmax at the top), gently
    shaded, the mesh lines drawn on coarse meshes; ``size`` pixels square plus the strip.  ``title`` is not drawn
    (the table's heads and captions say what is shown)."""
    from matplotlib import colormaps
    from matplotlib.colors import Normalize

    from .picture import rasterize

    v = np.asarray(vertices, float)
    tri, fi, nz = _visible_faces(v, np.asarray(faces, np.int64), elev, azim)
    cmap = colormaps[CMAP]
    norm = Normalize(vmin=vmin, vmax=vmax)
    h = np.asarray(H, float) if H is not None else np.full(len(v), np.nan)
    hf = h[fi].mean(1)
    rgba = cmap(norm(np.where(np.isfinite(hf), hf, 0.0)))
    rgba[~np.isfinite(hf)] = (0.6, 0.6, 0.6, 1.0)
    rgba[:, :3] *= (0.72 + 0.28 * nz)[:, None]               # gentle Lambert shading for the 3-D cue
    cx, cy, r = extent
    scale = size / (2.0 * r)
    xy = np.empty(tri.shape[:2] + (2,))
    xy[..., 0] = (tri[..., 0] - (cx - r)) * scale
    xy[..., 1] = (tri[..., 1] - (cy - r)) * scale
    # mesh lines where a face spans a few pixels or more (the paper's 1,896-vertex sphere), not on fine meshes
    edge = 0.35 if len(fi) and len(fi) <= 6000 else 0.0
    img = np.full((size, size + 18, 3), 255, np.uint8)
    img[:, :size] = rasterize(xy, rgba[:, :3], size, size, edge_px=edge, edge_rgb=(50, 50, 50))
    ramp = cmap(np.linspace(1.0, 0.0, int(size * 0.8)))[:, :3]
    top = int(size * 0.1)
    img[top:top + len(ramp), size + 6:size + 14] = np.round(ramp * 255).astype(np.uint8)[:, None, :]
    return _image_uri(img)


def _svg_uri(svg: str) -> str:
    return "data:image/svg+xml;base64," + base64.b64encode(svg.encode("utf-8")).decode("ascii")


def render_energy(energy, *, marks: list[int] | None = None, ylim: tuple[float, float] | None = None,
                  title: str | None = None, width: int = 250, height: int = 200) -> str:
    """SVG data URI of an energy curve (log scale when positive) with the snapshot iterations marked: vector
    graphics a few kB large, drawn in a millisecond."""
    e = np.asarray(energy, float)
    ok = np.isfinite(e)
    log = bool(len(e)) and bool(np.all(e[ok] > 0))
    y = np.where(ok, np.log10(np.where(ok & (e > 0), e, 1.0)) if log else e, np.nan)
    lo, hi = ((math.log10(ylim[0]), math.log10(ylim[1])) if (ylim and log) else
              (ylim if ylim else (float(np.nanmin(y)) if ok.any() else 0.0, float(np.nanmax(y)) if ok.any() else 1.0)))
    if not hi > lo:
        lo, hi = lo - 0.5, hi + 0.5
    L, R, T, B = 46, 8, 18 if title else 8, 30
    n = max(len(e) - 1, 1)

    def px(i, val):
        return L + (width - L - R) * i / n, T + (height - T - B) * (1.0 - (val - lo) / (hi - lo))

    pts = " ".join(f"{a:.1f},{b:.1f}" for a, b in (px(i, val) for i, val in enumerate(y) if np.isfinite(val)))
    parts = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{width}" height="{height}" font-family="sans-serif" '
             f'font-size="9"><rect width="100%" height="100%" fill="white"/>',
             f'<rect x="{L}" y="{T}" width="{width - L - R}" height="{height - T - B}" fill="none" stroke="#999"/>']
    ticks = range(math.floor(lo), math.ceil(hi) + 1) if log and hi - lo <= 12 else np.linspace(lo, hi, 5)
    for tv in ticks:
        if lo - 1e-9 <= tv <= hi + 1e-9:
            _, ty = px(0, tv)
            label = f"1e{int(tv)}" if log else f"{tv:.3g}"
            parts.append(f'<line x1="{L}" x2="{width - R}" y1="{ty:.1f}" y2="{ty:.1f}" stroke="#ddd"/>'
                         f'<text x="{L - 3}" y="{ty + 3:.1f}" text-anchor="end">{label}</text>')
    for tx in np.linspace(0, n, 5):
        x, _ = px(tx, lo)
        parts.append(f'<text x="{x:.1f}" y="{height - B + 12}" text-anchor="middle">{int(round(tx))}</text>')
    parts.append(f'<text x="{(L + width - R) / 2:.0f}" y="{height - 4}" text-anchor="middle">iteration</text>'
                 f'<text x="10" y="{(T + height - B) / 2:.0f}" text-anchor="middle" '
                 f'transform="rotate(-90 10 {(T + height - B) / 2:.0f})">energy E</text>')
    if pts:
        parts.append(f'<polyline points="{pts}" fill="none" stroke="#1f77b4" stroke-width="1.3"/>')
    for m in marks or []:
        if 0 <= m < len(e) and np.isfinite(y[m]):
            x, yy = px(m, y[m])
            parts.append(f'<circle cx="{x:.1f}" cy="{yy:.1f}" r="2.5" fill="#d62728"/>')
    if title:
        parts.append(f'<text x="{width / 2:.0f}" y="12" text-anchor="middle">{html.escape(title)}</text>')
    return _svg_uri("".join(parts) + "</svg>")
