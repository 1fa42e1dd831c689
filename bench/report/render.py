"""Pictures of the report: meshes coloured by mean curvature, energy curves, PNG data URIs.

Meshes are drawn with faces coloured by mean curvature (paraboloid fit over a 2h neighbourhood, computed in
the worker) with a colour bar; the callers share the camera and the colour scale across a table row.
Rendering is an orthographic painter's algorithm on a matplotlib (Agg) ``PolyCollection`` — much faster
than mplot3d for meshes of 10⁵ faces.
"""

from __future__ import annotations

import base64
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


def render_mesh(vertices, faces, H, *, vmin: float, vmax: float, extent: tuple[float, float, float],
                title: str | None = None, elev: float = ELEV, azim: float = AZIM, size: float = 2.7,
                dpi: int = 90) -> str:
    """PNG data URI of a mesh with faces coloured by the mean of their vertices' ``H`` and a colour bar."""
    plt = _pyplot()
    from matplotlib.collections import PolyCollection
    from matplotlib.colors import Normalize

    v = np.asarray(vertices, float)
    tri, fi, nz = _visible_faces(v, np.asarray(faces, np.int64), elev, azim)
    cmap = plt.get_cmap(CMAP)
    norm = Normalize(vmin=vmin, vmax=vmax)
    h = np.asarray(H, float) if H is not None else np.full(len(v), np.nan)
    hf = h[fi].mean(1)
    rgba = cmap(norm(np.where(np.isfinite(hf), hf, 0.0)))
    rgba[~np.isfinite(hf)] = (0.6, 0.6, 0.6, 1.0)
    shade = 0.72 + 0.28 * nz                                 # gentle Lambert shading for the 3-D cue
    rgba[:, :3] *= shade[:, None]

    fig = plt.figure(figsize=(size * 1.18, size), dpi=dpi)
    ax = fig.add_axes((0.0, 0.0, 0.76, 0.9 if title else 1.0))
    many = len(fi) > 6000
    coll = PolyCollection(tri[:, :, :2], facecolors=rgba,
                          edgecolors="face" if many else (0.15, 0.15, 0.15, 0.35),
                          linewidths=0.15 if not many else 0.05, antialiased=not many)
    ax.add_collection(coll)
    cx, cy, r = extent
    ax.set_xlim(cx - r, cx + r)
    ax.set_ylim(cy - r, cy + r)
    ax.set_aspect("equal")
    ax.axis("off")
    if title:
        fig.text(0.38, 0.97, title, ha="center", va="top", fontsize=7)
    cax = fig.add_axes((0.79, 0.12, 0.035, 0.72))
    sm = plt.cm.ScalarMappable(norm=norm, cmap=cmap)
    cb = fig.colorbar(sm, cax=cax)
    cb.ax.tick_params(labelsize=6)
    cb.set_label("H", fontsize=7)
    return png_uri(fig)


def render_energy(energy, *, marks: list[int] | None = None, ylim: tuple[float, float] | None = None,
                  title: str | None = None, size: float = 2.7, dpi: int = 90) -> str:
    """PNG data URI of an energy curve (log scale when positive) with the snapshot iterations marked."""
    plt = _pyplot()

    e = np.asarray(energy, float)
    fig, ax = plt.subplots(figsize=(size * 1.18, size), dpi=dpi)
    it = np.arange(len(e))
    ax.plot(it, e, lw=1.2, color="C0")
    for m in marks or []:
        if 0 <= m < len(e):
            ax.plot([m], [e[m]], "o", ms=3, color="C3")
    if len(e) and np.all(e[np.isfinite(e)] > 0):
        ax.set_yscale("log")
    if ylim:
        ax.set_ylim(*ylim)
    ax.set_xlabel("iteration", fontsize=7)
    ax.set_ylabel("energy E", fontsize=7)
    ax.tick_params(labelsize=6)
    ax.grid(alpha=0.3)
    if title:
        ax.set_title(title, fontsize=7)
    fig.subplots_adjust(left=0.2, right=0.96, bottom=0.17, top=0.93 if title else 0.96)
    return png_uri(fig)
