"""The HTML report of a run folder: ``index.html``, one self-contained file (pictures embedded as PNG).

Sections (``bench/templates/report.html``):

1. a summary table per phantom × noise setting (× variant × N): methods as rows, metrics as columns, the best
   value per column marked;
2. per phantom, the paper's table layout for the shape-gradient method: columns β = 0, β = 1, β = 1 with
   Gaussian noise; rows the initial surface, iteration 1, 50, 100 (whatever snapshots the run kept, e.g. 75
   and 150 for the fused spheres) and the energy curve;
3. galleries of the other methods (the paper's "Marching Cube" and "DistMesh" tables: phantoms × clean /
   Gaussian / uniform) and the paper's uniform-noise table for the shape gradient;
4. cost: time (``wall_s``) and peak memory (``peak_mem_mb``) per method per phantom, a table and a bar chart;
5. failed cells with their errors; 6. run metadata.

Meshes are drawn with faces coloured by mean curvature (paraboloid fit over a 2h neighbourhood, computed in
the worker) with a colour bar; every picture in a table row shares the camera and the colour scale.
Rendering is an orthographic painter's algorithm on a matplotlib (Agg) ``PolyCollection`` — much faster
than mplot3d for meshes of 10⁵ faces.
"""

from __future__ import annotations

import base64
import html
import io
import json
import math
from pathlib import Path
from typing import Any

import numpy as np

from .run.store import CELLS_DIR, load_cells

__all__ = ["write_report", "render_mesh", "render_energy", "summary_tables", "cost_section", "BEST_DIRECTION"]

TEMPLATE_DIR = Path(__file__).resolve().parent / "templates"

#: how a metric's best value is chosen: "min", "max", ("target", value) or absent (not marked)
BEST_DIRECTION: dict[str, Any] = {
    **{k: "min" for k in ("hausdorff", "hausdorff_95", "mean_dist", "rms_dist", "H_rms_err", "H_max_err",
                          "K_rms_err", "H_std", "roughness_deg", "pct_angle_lt_10", "self_intersections",
                          "wall_s", "peak_mem_mb")},
    **{k: "max" for k in ("normal_consistency", "fscore@h", "min_angle_deg", "watertight")},
    "components": ("target", 1),
    "euler": ("target", 2),  # replaced by 2 − 2·genus of the phantom
}

#: yes/no metrics (shown as yes/no, or the share of seeds)
BOOL_COLUMNS = {"watertight"}

ELEV, AZIM = 20.0, -25.0   # one camera for every picture (y, the ellipsoid's long axis, across)
CMAP = "RdYlBu_r"          # blue = low, red = high mean curvature (as in the paper's figures)


# ---------------------------------------------------------------------------------------------- pictures
def _png(fig) -> str:
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


def render_mesh(vertices, faces, H, *, vmin: float, vmax: float, extent: tuple[float, float, float],
                title: str | None = None, elev: float = ELEV, azim: float = AZIM, size: float = 2.7,
                dpi: int = 90) -> str:
    """PNG data URI of a mesh with faces coloured by the mean of their vertices' ``H`` and a colour bar."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.collections import PolyCollection
    from matplotlib.colors import Normalize

    v = np.asarray(vertices, float)
    f = np.asarray(faces, np.int64)
    R = _camera(elev, azim)
    p = v @ R.T
    tri = p[f]                                               # (F, 3, 3) in camera coordinates
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    nz = n[:, 2] / np.maximum(np.linalg.norm(n, axis=1), 1e-300)
    keep = nz > 0                                            # back faces of a closed outward mesh are hidden
    if keep.sum() < 0.2 * len(f):                            # inward-oriented or open: draw everything
        keep[:] = True
    tri, fi, nz = tri[keep], f[keep], np.abs(nz[keep])
    order = np.argsort(tri[:, :, 2].mean(1), kind="stable")  # far to near
    tri, fi, nz = tri[order], fi[order], nz[order]
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
    return _png(fig)


def render_energy(energy, *, marks: list[int] | None = None, ylim: tuple[float, float] | None = None,
                  title: str | None = None, size: float = 2.7, dpi: int = 90) -> str:
    """PNG data URI of an energy curve (log scale when positive) with the snapshot iterations marked."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

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
    return _png(fig)


# ---------------------------------------------------------------------------------------------- data access
class _Artifacts:
    """Lazy access to the ``cells/<cell_id>.npz`` arrays."""

    def __init__(self, out: Path) -> None:
        self.dir = Path(out) / CELLS_DIR
        self._cache: dict[str, dict | None] = {}

    def get(self, cid: str) -> dict | None:
        if cid not in self._cache:
            p = self.dir / f"{cid}.npz"
            try:
                with np.load(p) as z:
                    self._cache[cid] = {k: z[k] for k in z.files}
            except (OSError, ValueError):
                self._cache[cid] = None
        return self._cache[cid]

    def mesh(self, cid: str, iteration: int | None = None):
        """(vertices, faces, H, label) of the final mesh or of a snapshot; None if not stored.

        A snapshot requested beyond the last iteration gives the final mesh with a note."""
        a = self.get(cid)
        if a is None or "vertices" not in a:
            return None
        if iteration is None:
            return a["vertices"], a["faces"], a.get("H"), None
        its = [int(i) for i in a.get("snapshot_iterations", [])]
        if iteration in its:
            v = a[f"snap{iteration}_vertices"]
            f = a.get(f"snap{iteration}_faces", a["faces"])
            return v, f, a.get(f"snap{iteration}_H"), None
        return None

    def energy(self, cid: str):
        a = self.get(cid)
        return None if a is None else a.get("energy_history")


def _params(row) -> dict:
    try:
        return json.loads(row.get("parameters") or "{}")
    except (TypeError, ValueError):
        return {}


def _fmt(v: Any, col: str) -> str:
    if v is None or (isinstance(v, float) and math.isnan(v)):
        return "–"
    if isinstance(v, (bool, np.bool_)):
        return "yes" if v else "no"
    if isinstance(v, (int, np.integer)):
        return str(int(v))
    if isinstance(v, (float, np.floating)):
        v = float(v)
        if col in BOOL_COLUMNS:  # a mean over seeds of a yes/no metric
            return "yes" if v == 1.0 else "no" if v == 0.0 else f"{100 * v:.0f} % yes"
        if col in ("euler", "components", "self_intersections", "n_vertices", "n_faces", "iterations") \
                and v.is_integer():
            return str(int(v))
        if math.isinf(v):
            return "∞" if v > 0 else "−∞"
        return f"{v:.4g}"
    return html.escape(str(v))


# ---------------------------------------------------------------------------------------------- summary tables
def _metric_columns(df) -> list[str]:
    try:
        from bench.metrics import METRIC_NAMES
        names = [m for m in METRIC_NAMES if m in df.columns]
    except ImportError:  # pragma: no cover
        names = []
    skip = {"cell_id", "phantom", "variant", "N", "noise", "snr_requested", "snr_achieved", "seed", "method",
            "label", "parameters", "status", "error", "stop_reason"}
    if not names:
        names = [c for c in df.columns if c not in skip]
    for extra in ("iterations", "energy_final", "wall_s", "peak_mem_mb"):
        if extra in df.columns and extra not in names:
            names.append(extra)
    return [c for c in names if c not in skip]


def _noise_title(noise: str, snr) -> str:
    if noise == "none":
        return "clean"
    return f"{noise} noise, SNR {float(snr):g} dB" if snr is not None and not _isnan(snr) else f"{noise} noise"


def _isnan(x) -> bool:
    try:
        return math.isnan(float(x))
    except (TypeError, ValueError):
        return False


def _best_mask(series, rule) -> np.ndarray:
    import pandas as pd

    s = pd.to_numeric(series.map(lambda x: float(x) if isinstance(x, (bool, np.bool_)) else x), errors="coerce")
    vals = s.to_numpy(float)
    ok = np.isfinite(vals)
    if ok.sum() < 2:
        return np.zeros(len(vals), bool)
    if rule == "min":
        best = np.nanmin(np.where(ok, vals, np.nan))
        return ok & np.isclose(vals, best, rtol=1e-9, atol=0)
    if rule == "max":
        best = np.nanmax(np.where(ok, vals, np.nan))
        return ok & np.isclose(vals, best, rtol=1e-9, atol=0)
    if isinstance(rule, tuple) and rule[0] == "target":
        d = np.abs(vals - rule[1])
        best = np.nanmin(np.where(ok, d, np.nan))
        return ok & np.isclose(d, best, rtol=1e-9, atol=1e-12)
    return np.zeros(len(vals), bool)


def summary_tables(df) -> list[dict]:
    """One table per phantom × noise (× variant × N): ``[{"title", "key", "html", "n_methods"}, ...]``."""
    import pandas as pd

    from phantoms import get_phantom

    metrics = _metric_columns(df)
    tables = []
    keys = ["phantom", "noise", "snr_requested", "variant", "N"]
    d = df.copy()
    d["snr_requested"] = d["snr_requested"].astype(object).where(d["snr_requested"].notna(), None)
    groups: dict[tuple, list[int]] = {}
    for i, r in d.iterrows():
        groups.setdefault(tuple(r[k] for k in keys), []).append(i)
    multi_variant = d["variant"].nunique() > 1 or d["N"].nunique() > 1
    for key, idx in groups.items():
        phantom, noise, snr, variant, n = key
        sub = d.loc[idx]
        rows = []
        for label, g in sub.groupby("label", sort=False):
            ok = g[g["status"] == "ok"]
            rec: dict[str, Any] = {"method": label}
            for m in metrics:
                if m not in g.columns:
                    continue
                col = ok[m] if len(ok) else g[m]
                vals = pd.to_numeric(col.map(lambda x: float(x) if isinstance(x, (bool, np.bool_)) else x),
                                     errors="coerce")
                rec[m] = float(vals.mean()) if vals.notna().any() else np.nan
            statuses = g["status"].tolist()
            rec["status"] = statuses[0] if len(set(statuses)) == 1 else ", ".join(f"{s}×{statuses.count(s)}"
                                                                                 for s in sorted(set(statuses)))
            if len(g) > 1:
                rec["status"] += f" (mean of {len(ok)}/{len(g)} seeds)"
            rows.append(rec)
        t = pd.DataFrame(rows)
        try:
            genus = int(getattr(get_phantom(phantom), "genus", 0))
        except Exception:
            genus = 0
        shown = pd.DataFrame({"method": [html.escape(str(x)) for x in t["method"]]})
        for m in [c for c in metrics if c in t.columns]:
            rule = BEST_DIRECTION.get(m)
            if rule is None and m.endswith("_h") and BEST_DIRECTION.get(m[:-2]) == "min":
                rule = "min"
            if m == "euler":
                rule = ("target", 2 - 2 * genus)
            mask = _best_mask(t[m], rule) if rule is not None else np.zeros(len(t), bool)
            shown[m] = [f'<span class="best" title="best">{_fmt(v, m)}</span>' if b else _fmt(v, m)
                        for v, b in zip(t[m], mask)]
        shown["status"] = [html.escape(str(s)) for s in t["status"]]
        title = f"{phantom} — {_noise_title(noise, snr)}"
        if multi_variant:
            title += f" — {variant}, N = {n}"
        tables.append({
            "title": title, "phantom": phantom, "noise": noise,
            "html": shown.to_html(index=False, escape=False, classes="summary", border=0, na_rep="–"),
            "n_methods": len(t),
        })
    return tables


# ---------------------------------------------------------------------------------------------- paper tables
def _pick(df, *, method: str | None = None, label_not: str | None = None, noise: str, phantom: str,
          beta: float | None = None, labels: list[str] | None = None):
    """The first matching ok-or-not row (a dict) or None."""
    sub = df[(df["phantom"] == phantom) & (df["noise"] == noise)]
    if method is not None:
        sub = sub[sub["method"] == method]
    if labels is not None:
        sub = sub[sub["label"].isin(labels)]
    for _, r in sub.iterrows():
        r = r.to_dict()
        if beta is not None:
            b = _params(r).get("beta")
            try:
                if b is None or not math.isclose(float(b), beta):
                    continue
            except (TypeError, ValueError):
                continue
        return r
    return None


def _primary(df):
    """Restrict to the first variant, the first N and the first seed of each noise (the paper's layout)."""
    if df.empty:
        return df
    d = df[(df["variant"] == df["variant"].iloc[0]) & (df["N"] == df["N"].iloc[0])]
    first_seed = d.groupby("noise")["seed"].transform("min")
    return d[d["seed"] == first_seed]


def _iteration_rows(cells: list[dict | None], arts: _Artifacts) -> list[int]:
    its: set[int] = set()
    for r in cells:
        if r is None:
            continue
        a = arts.get(r["cell_id"])
        if a is not None and "snapshot_iterations" in a:
            its.update(int(i) for i in a["snapshot_iterations"])
        snaps = _params(r).get("snapshots")
        if isinstance(snaps, list):
            its.update(int(s) for s in snaps if isinstance(s, (int, float)))
    its.add(0)
    return sorted(its)


def _cell_picture(arts: _Artifacts, r: dict | None, iteration: int | None):
    """(vertices, faces, H, note) for a table entry, the note saying what is shown or why nothing is."""
    if r is None:
        return None, "not in this run"
    if r.get("status") != "ok" and arts.get(r["cell_id"]) is None:
        return None, f"{r.get('status')}: {r.get('error', '')}"
    if iteration is None:
        m = arts.mesh(r["cell_id"])
        return (m, None) if m else (None, "no mesh stored")
    m = arts.mesh(r["cell_id"], iteration)
    if m is not None:
        return m, None
    last = r.get("iterations")
    try:
        last = int(float(last))
    except (TypeError, ValueError):
        last = None
    if last is not None and iteration > last:
        fm = arts.mesh(r["cell_id"])
        if fm is not None:
            why = r.get("stop_reason") or "stopped"
            return fm, f"final mesh: {why} at iteration {last}"
    return None, f"iteration {iteration} not kept"


def _picture_row(entries: list[tuple[dict | None, int | None]], arts: _Artifacts) -> list[dict]:
    """Render one table row with a shared camera and colour scale."""
    got = [_cell_picture(arts, r, it) for r, it in entries]
    meshes = [g[0] for g in got if g[0] is not None]
    if not meshes:
        return [{"img": None, "note": g[1]} for g in got]
    # one camera for the row, framed on the meshes of ordinary size: a blown-up reconstruction
    # (e.g. a diverged mesh) is drawn with the same camera, cut by the frame, instead of shrinking the rest
    sizes = [view_extent([m[0]])[2] for m in meshes]
    typical = float(np.median(sizes))
    framed = [m for m, sz in zip(meshes, sizes) if sz <= 1.5 * typical]
    ext = view_extent([m[0] for m in framed])
    vmin, vmax = colour_range([m[2] for m in framed])
    out = []
    for m, note in got:
        if m is None:
            out.append({"img": None, "note": note})
            continue
        v, f, H, _ = m
        if view_extent([v])[2] > 1.5 * typical:
            note = (note + "; " if note else "") + "extends far beyond the frame shared by this row"
        out.append({"img": render_mesh(v, f, H, vmin=vmin, vmax=vmax, extent=ext),
                    "note": note, "caption": f"{len(v):,} vertices, {len(f):,} faces"})
    return out


def _energy_row(cells: list[dict | None], arts: _Artifacts, marks: list[int]) -> list[dict]:
    curves = [arts.energy(r["cell_id"]) if r is not None else None for r in cells]
    finite = [np.asarray(c, float) for c in curves if c is not None and len(c)]
    ylim = None
    if finite:
        allv = np.concatenate([c[np.isfinite(c)] for c in finite])
        if len(allv) and np.all(allv > 0):
            ylim = (float(allv.min()) / 1.5, float(allv.max()) * 1.5)
    out = []
    for r, c in zip(cells, curves):
        if c is None or not len(c):
            out.append({"img": None, "note": "not in this run" if r is None else "no energy history"})
        else:
            out.append({"img": render_energy(c, marks=marks, ylim=ylim), "note": None})
    return out


def paper_tables(df, arts: _Artifacts) -> list[dict]:
    """Per phantom: columns β=0, β=1, β=1 + Gaussian noise; rows initial/iterations/energy."""
    d = _primary(df)
    out = []
    for phantom in dict.fromkeys(d["phantom"]):
        sg = d[(d["phantom"] == phantom) & (d["method"] == "shape_gradient")]
        if sg.empty:
            continue
        cols = [
            _pick(d, method="shape_gradient", noise="none", phantom=phantom, beta=0.0),
            _pick(d, method="shape_gradient", noise="none", phantom=phantom, beta=1.0),
            _pick(d, method="shape_gradient", noise="gaussian", phantom=phantom, beta=1.0),
        ]
        heads = []
        for r, base in zip(cols, ["α = 5, β = 0", "α = 5, β = 1", "α = 5, β = 1, Gaussian noise"]):
            p = _params(r) if r is not None else {}
            alpha = p.get("alpha")
            head = base if alpha is None else base.replace("α = 5", f"α = {float(alpha):g}")
            if r is not None and r.get("noise") != "none" and r.get("snr_requested") is not None \
                    and not _isnan(r.get("snr_requested")):
                head += f", SNR {float(r['snr_requested']):g} dB"
            heads.append(head + (f" [{r['label']}]" if r is not None else ""))
        iterations = _iteration_rows(cols, arts)
        rows = []
        for it in iterations:
            name = "Initial surface Γ₀" if it == 0 else f"Iteration {it}"
            rows.append({"name": name, "cells": _picture_row([(r, it) for r in cols], arts)})
        rows.append({"name": "Energy", "cells": _energy_row(cols, arts, [i for i in iterations if i > 0])})
        out.append({"phantom": phantom, "heads": heads, "rows": rows})
    return out


def gallery_tables(df, arts: _Artifacts) -> list[dict]:
    """Per non-shape-gradient method: phantoms × noise settings of final meshes (the paper's MC / DistMesh
    tables); plus the paper's uniform-noise table for the shape gradient (β = 1)."""
    d = _primary(df)
    noises = list(dict.fromkeys(d["noise"]))
    order = {"none": 0, "gaussian": 1, "uniform": 2}
    noises.sort(key=lambda n: order.get(n, 9))
    titles = {"marching_cubes": "Marching Cube", "distmesh": "DistMesh", "mc_taubin": "Marching cubes + Taubin",
              "poisson": "Screened Poisson"}
    out = []
    labels = [lab for lab, m in dict.fromkeys(zip(d["label"], d["method"])) if m != "shape_gradient"]
    for label in labels:
        rows = []
        for phantom in dict.fromkeys(d["phantom"]):
            entries = [(_pick(d, labels=[label], noise=nz, phantom=phantom), None) for nz in noises]
            if all(e[0] is None for e in entries):
                continue
            rows.append({"name": phantom, "cells": _picture_row(entries, arts)})
        method = d[d["label"] == label]["method"].iloc[0]
        out.append({"title": titles.get(label, titles.get(method, label)) + (f" [{label}]" if label != method else ""),
                    "heads": [_noise_title(nz, None) for nz in noises], "rows": rows})
    # uniform noise, shape gradient with the tangential term
    if "uniform" in noises:
        rows = []
        for phantom in dict.fromkeys(d["phantom"]):
            r = _pick(d, method="shape_gradient", noise="uniform", phantom=phantom, beta=1.0)
            if r is None:
                continue
            pic = _picture_row([(r, None)], arts)
            en = _energy_row([r], arts, [])
            name = phantom
            if r.get("snr_requested") is not None and not _isnan(r.get("snr_requested")):
                name += f" (SNR {float(r['snr_requested']):g} dB)"
            rows.append({"name": name, "cells": pic + en})
        if rows:
            out.append({"title": "Shape gradient (α = 5, β = 1) on uniform noise", "heads": ["final mesh", "energy"],
                        "rows": rows})
    return out


# ---------------------------------------------------------------------------------------------- cost
COST_COLUMNS = (("wall_s", "time (s)"), ("peak_mem_mb", "memory (MiB)"))


def _cost_frame(df):
    """Mean ``wall_s`` and ``peak_mem_mb`` of the ok cells per method label × phantom (× N when the run has
    several): a DataFrame with columns label, where, wall_s, peak_mem_mb, cells."""
    import pandas as pd

    if df.empty or not any(c in df.columns for c, _ in COST_COLUMNS):
        return pd.DataFrame(columns=["label", "where", "wall_s", "peak_mem_mb", "cells"])
    d = df[df["status"] == "ok"].copy()
    many_n = "N" in d.columns and d["N"].nunique() > 1
    d["where"] = d["phantom"].astype(str) + (", N = " + d["N"].astype(str) if many_n else "")
    for c, _ in COST_COLUMNS:
        d[c] = pd.to_numeric(d[c], errors="coerce") if c in d.columns else np.nan
    g = d.groupby(["label", "where"], sort=False)
    out = g[[c for c, _ in COST_COLUMNS]].mean()
    out["cells"] = g.size()
    return out.reset_index()


def _render_cost_chart(cf, labels: list[str], places: list[str], dpi: int = 90) -> str | None:
    """Grouped bars: time and memory, one group per phantom, one bar per method (log scale when the values
    span more than 30×)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    if cf.empty:
        return None
    fig, axes = plt.subplots(1, 2, figsize=(max(6.0, 1.2 * len(places) * max(1, len(labels)) ** 0.5 + 3.5), 3.0),
                             dpi=dpi)
    width = 0.8 / max(1, len(labels))
    x = np.arange(len(places))
    for ax, (col, name) in zip(axes, COST_COLUMNS):
        vals_all = []
        for k, lab in enumerate(labels):
            vals = []
            for p in places:
                sel = cf[(cf["label"] == lab) & (cf["where"] == p)][col]
                vals.append(float(sel.iloc[0]) if len(sel) and np.isfinite(sel.iloc[0]) else np.nan)
            vals_all += [v for v in vals if np.isfinite(v) and v > 0]
            ax.bar(x - 0.4 + (k + 0.5) * width, np.nan_to_num(vals, nan=0.0), width, label=lab, color=f"C{k % 10}")
        if vals_all and max(vals_all) / min(vals_all) > 30:
            ax.set_yscale("log")
        ax.set_xticks(x, places, fontsize=7, rotation=20 if len(places) > 3 else 0)
        ax.set_title(name, fontsize=8)
        ax.tick_params(labelsize=7)
        ax.grid(axis="y", alpha=0.3)
    axes[1].legend(fontsize=6, loc="upper left", bbox_to_anchor=(1.01, 1.0), frameon=False)
    fig.tight_layout()
    return _png(fig)


def cost_section(df) -> dict:
    """The report's cost section: ``{"html": table, "chart": PNG data URI or None, "n_cells": int}``.

    Rows are method labels, columns phantoms (× N), each with the mean time and peak memory of its ok cells
    (over noise settings and seeds); the lowest per phantom is marked."""
    cf = _cost_frame(df)
    if cf.empty:
        return {"html": "", "chart": None, "n_cells": 0}
    labels = list(dict.fromkeys(cf["label"]))
    places = list(dict.fromkeys(cf["where"]))
    head1 = "".join(f'<th colspan="{len(COST_COLUMNS)}">{html.escape(p)}</th>' for p in places)
    head2 = "".join(f"<th>{html.escape(n)}</th>" for _ in places for _, n in COST_COLUMNS)
    best = {}
    for p in places:
        for c, _ in COST_COLUMNS:
            col = cf[cf["where"] == p].set_index("label")[c]
            best[(p, c)] = float(col.min()) if col.notna().sum() >= 2 else None
    body = []
    for lab in labels:
        cells = []
        for p in places:
            r = cf[(cf["label"] == lab) & (cf["where"] == p)]
            for c, _ in COST_COLUMNS:
                v = float(r[c].iloc[0]) if len(r) else np.nan
                text = _fmt(v, c)
                if len(r) and best[(p, c)] is not None and np.isfinite(v) and np.isclose(v, best[(p, c)]):
                    text = f'<span class="best" title="lowest">{text}</span>'
                cells.append(f"<td>{text}</td>")
        body.append(f"<tr><td>{html.escape(str(lab))}</td>{''.join(cells)}</tr>")
    table = (f'<table class="summary cost"><thead><tr><th rowspan="2">method</th>{head1}</tr><tr>{head2}</tr>'
             f"</thead><tbody>{''.join(body)}</tbody></table>")
    return {"html": table, "chart": _render_cost_chart(cf, labels, places), "n_cells": int(cf["cells"].sum())}


# ---------------------------------------------------------------------------------------------- the page
def write_report(out: str | Path) -> Path:
    """Render ``out/index.html`` from ``out/results.csv``, ``out/cells`` and ``out/run.json``."""
    import matplotlib

    matplotlib.use("Agg")
    import pandas as pd
    from jinja2 import Environment, FileSystemLoader, select_autoescape

    out = Path(out)
    df = pd.read_csv(out / "results.csv", keep_default_na=True)
    for col in ("error", "label", "method", "noise", "phantom", "variant", "status", "parameters", "cell_id"):
        if col in df.columns:
            df[col] = df[col].astype(object).where(df[col].notna(), "").astype(str)
    meta: dict = {}
    if (out / "run.json").exists():
        try:
            meta = json.loads((out / "run.json").read_text())
        except ValueError:
            meta = {}
    records = load_cells(out)
    arts = _Artifacts(out)

    failed = []
    for _, r in df[df["status"] != "ok"].iterrows():
        rec = records.get(r["cell_id"], {})
        failed.append({"cell_id": r["cell_id"], "label": r["label"], "status": r["status"], "error": r["error"],
                       "traceback": rec.get("traceback")})
    counts = df["status"].value_counts().to_dict() if len(df) else {}
    config = meta.get("config") or {}
    total = (meta.get("cells") or {}).get("total", len(df))
    context = {
        "title": f"levelset-bench — {config.get('name', 'run')}",
        "config_name": config.get("name", "run"),
        "description": config.get("description", ""),
        "n_rows": len(df), "n_total": total, "counts": counts,
        "summaries": summary_tables(df) if len(df) else [],
        "paper_tables": paper_tables(df, arts) if len(df) else [],
        "galleries": gallery_tables(df, arts) if len(df) else [],
        "cost": cost_section(df) if len(df) else {"html": "", "chart": None, "n_cells": 0},
        "failed": failed,
        "meta": meta,
        "config_json": json.dumps(config, indent=1),
        "deps": (meta.get("dependencies") or {}),
        "git": meta.get("git"), "machine": meta.get("machine") or {},
        "sessions": meta.get("sessions") or [],
        "best_rules": {k: (v if isinstance(v, str) else f"closest to {v[1]}") for k, v in BEST_DIRECTION.items()},
    }
    env = Environment(loader=FileSystemLoader(str(TEMPLATE_DIR)), autoescape=select_autoescape(["html"]))
    page = env.get_template("report.html").render(**context)
    path = out / "index.html"
    tmp = out / ".index.html.tmp"
    tmp.write_text(page, encoding="utf-8")
    tmp.replace(path)
    return path
