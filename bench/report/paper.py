"""The paper's picture tables: per phantom, columns side by side (e.g. β = 0, β = 1, β = 1 with Gaussian
noise) with rows the initial surface, the kept iterations and the energy curve; galleries of the other methods'
final meshes (phantoms × noise settings); the uniform-noise table of one label.

Which columns stand side by side is the run config's business, not the report's: ``config["report"]
["paper_columns"]`` (a list of ``{"title", "label", "noise"}``) and ``config["report"]["uniform_label"]``.
Without that section every (label, noise) whose cells kept snapshot meshes is a column, in the order of the
results.  The rows come from the snapshots the cells stored; every picture in a row shares the camera and the
colour scale.
"""

from __future__ import annotations

import json
import os
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import numpy as np

from .artifacts import Artifacts
from .render import colour_range, render_energy, render_mesh, view_extent
from .tables import is_nan, noise_title

__all__ = ["Column", "PaperLayout", "paper_layout", "paper_tables", "gallery_tables", "variant_of", "VARIANTS"]

#: names of the galleries (the paper's "Marching Cube" and "DistMesh" tables), by label or method
GALLERY_TITLES = {"marching_cubes": "Marching Cube", "distmesh": "DistMesh", "mc_taubin": "Marching cubes + Taubin",
                  "poisson": "Screened Poisson", "shape_gradient": "Shape gradient"}
NOISE_ORDER = {"none": 0, "gaussian": 1, "uniform": 2}


@dataclass(frozen=True)
class Column:
    """One column of the paper tables: the cells of ``label`` at ``noise``; ``title`` empty → derived."""

    label: str
    noise: str = "none"
    title: str = ""


@dataclass(frozen=True)
class PaperLayout:
    columns: tuple[Column, ...]
    uniform_labels: tuple[str, ...] = ()

    @property
    def labels(self) -> set[str]:
        return {c.label for c in self.columns}


# ---------------------------------------------------------------------------------------------- choosing cells
def primary(df):
    """Restrict to the first variant, the first N and the first seed of each noise (the paper's layout)."""
    if df.empty:
        return df
    d = df[(df["variant"] == df["variant"].iloc[0]) & (df["N"] == df["N"].iloc[0])]
    first_seed = d.groupby("noise")["seed"].transform("min")
    return d[d["seed"] == first_seed]


def pick(df, *, label: str, noise: str, phantom: str) -> dict | None:
    """The first row (a dict, whatever its status) of ``label`` at ``noise`` on ``phantom``, or None."""
    sub = df[(df["phantom"] == phantom) & (df["noise"] == noise) & (df["label"] == label)]
    return sub.iloc[0].to_dict() if len(sub) else None


def _configured_columns(section: dict) -> tuple[Column, ...] | None:
    cols = section.get("paper_columns")
    if not isinstance(cols, list):
        return None
    return tuple(Column(label=str(c["label"]), noise=str(c.get("noise") or "none"), title=str(c.get("title") or ""))
                 for c in cols if isinstance(c, dict) and c.get("label"))


def _snapshot_columns(df, arts: Artifacts) -> tuple[Column, ...]:
    d = primary(df)
    with_snaps = {lab for lab, g in d.groupby("label", sort=False)
                  if any(arts.has_snapshots(cid) for cid in g["cell_id"])}
    pairs = dict.fromkeys(zip(d["label"], d["noise"]))
    return tuple(Column(label=lab, noise=nz) for lab, nz in pairs if lab in with_snaps)


def paper_layout(config: dict | None, df, arts: Artifacts) -> PaperLayout:
    """The run config's ``report`` section: ``paper_columns`` and ``uniform_label``, each when present.
    Without ``paper_columns``, one column per (label, noise) of the labels whose cells kept snapshots, in the
    order of the rows; without ``uniform_label``, no uniform-noise table."""
    section = (config or {}).get("report") or {}
    section = section if isinstance(section, dict) else {}
    columns = _configured_columns(section)
    uniform = section.get("uniform_label")
    uniform = [uniform] if isinstance(uniform, str) else (uniform if isinstance(uniform, list) else [])
    return PaperLayout(columns if columns is not None else _snapshot_columns(df, arts),
                       tuple(str(u) for u in uniform if u))


# ---------------------------------------------------------------------------------------------- picture rows
def _last_iteration(r: dict) -> int | None:
    try:
        return int(float(r.get("iterations")))
    except (TypeError, ValueError, OverflowError):
        return None


def _cell_picture(arts: Artifacts, r: dict | None, iteration: int | None):
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
    last = _last_iteration(r)
    if last is not None and iteration > last:
        fm = arts.mesh(r["cell_id"])
        if fm is not None:
            why = r.get("stop_reason") or "stopped"
            return fm, f"final mesh: {why} at iteration {last}"
    return None, f"iteration {iteration} not kept"


def picture_row(entries: list[tuple[dict | None, int | None]], arts: Artifacts) -> list[dict]:
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
        out.append({"mesh": (v, f, H), "note": note,
                    "caption": f"{len(v):,} vertices, {len(f):,} faces; H {vmin:.3g} … {vmax:.3g}"})
    drawn = [e for e in out if "mesh" in e]
    # the rasteriser and the WebP encoder release the GIL: a row's pictures are drawn side by side on the cores
    with ThreadPoolExecutor(max_workers=min(4, len(drawn), os.cpu_count() or 1)) as pool:
        imgs = list(pool.map(lambda e: render_mesh(*e["mesh"], vmin=vmin, vmax=vmax, extent=ext), drawn))
    for e, img in zip(drawn, imgs):
        del e["mesh"]
        e["img"] = img
    return out


def energy_row(cells: list[dict | None], arts: Artifacts, marks: list[int]) -> list[dict]:
    """Energy curves of a row's cells on one y-range, the snapshot iterations marked."""
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


# ---------------------------------------------------------------------------------------------- paper tables
def _head(col: Column, r: dict | None) -> str:
    snr = r.get("snr_requested") if r is not None else None
    if not col.title:
        return f"{col.label}, {noise_title(col.noise, snr)}"
    head = col.title
    if r is not None and r.get("noise") != "none" and snr is not None and not is_nan(snr):
        head += f", SNR {float(snr):g} dB"
    return head + (f" [{r['label']}]" if r is not None else "")


def _iteration_rows(cells: list[dict | None], arts: Artifacts) -> list[int]:
    """The initial surface and every iteration some cell of the row kept a snapshot of."""
    its = {0}
    for r in cells:
        if r is not None:
            its.update(arts.snapshot_iterations(r["cell_id"]))
    return sorted(its)


def _final_shown(r: dict | None, arts: Artifacts, iterations: list[int]) -> bool:
    """Whether the iteration rows already show the cell's final mesh (or it has none to show)."""
    if r is None or arts.mesh(r["cell_id"]) is None:
        return True
    last = _last_iteration(r)
    if last is None:
        return False
    return last in arts.snapshot_iterations(r["cell_id"]) or any(it > last for it in iterations)


def _final_row(cells: list[dict | None], arts: Artifacts) -> dict:
    pics = picture_row([(r, None) for r in cells], arts)
    for pic, r in zip(pics, cells):
        last = _last_iteration(r) if r is not None else None
        if pic.get("img") and last is not None:
            why = f"{r.get('stop_reason') or 'stopped'} at iteration {last}"
            pic["note"] = f"{pic['note']}; {why}" if pic.get("note") else why
    return {"name": "Final surface", "cells": pics}


#: what a shape-gradient row is, by its resolved ``preset`` (the report names it in the tables' captions)
VARIANTS = {"paper": "the paper's algorithm as printed (preset=paper)",
            "paper+fixes": "the paper's experiment with the suite's corrections (preset=paper+fixes: full "
                           "gradient, H¹ preconditioning, capped backtracking; same Γ₀ and iterations)",
            "none": "the suite's default (genus-0 start, remeshing, guards)"}
#: why a run stopped, in words (``stop_reason`` → text)
STOP_WORDS = {"line_search_floor": "the line search found no decrease of the energy down to a 10⁻⁴-voxel step",
              "converged": "the energy or the surface stopped changing (tolerance)",
              "diverged": "the step became non-finite or left the grid",
              "sign_guard": "the sign guard rolled back a step that cut the object",
              "fixed_iterations": "its fixed iteration count (no convergence test, by design)",
              "max_iter": "the iteration limit"}


def variant_of(r: dict | None) -> str | None:
    """The ``preset`` a shape-gradient row ran with ("paper", "paper+fixes", "none"), None for other methods."""
    if r is None or r.get("method") != "shape_gradient":
        return None
    try:
        params = json.loads(r.get("parameters") or "{}")
    except (TypeError, ValueError):
        params = {}
    return str(params.get("preset") or "none") if isinstance(params, dict) else "none"


def _caption(layout: PaperLayout, cells: list[dict | None], iterations: list[int]) -> str:
    """Which variant each column's label is, and where a column's run stopped before the last row."""
    parts, seen = [], set()
    for c, r in zip(layout.columns, cells):
        v = variant_of(r)
        if r is not None and c.label not in seen and v in VARIANTS:
            seen.add(c.label)
            parts.append(f"{c.label}: {VARIANTS[v]}")
    text = "Columns drawn from " + "; ".join(parts) + "." if parts else ""
    last = max(iterations) if iterations else 0
    stops = []
    for c, r in zip(layout.columns, cells):
        it = _last_iteration(r) if r is not None else None
        if it is not None and it < last:
            why = r.get("stop_reason") or "stopped"
            stops.append(f"{c.title or c.label} stopped at iteration {it} ({why}: {STOP_WORDS.get(why, why)})")
    if stops:
        text += (" " if text else "") + "Rows past the stop show the final mesh: " + "; ".join(stops) + "."
    return text


def paper_tables(df, arts: Artifacts, layout: PaperLayout | None = None) -> list[dict]:
    """Per phantom: the layout's columns; rows the initial surface, the kept iterations, the final surface
    when no iteration row shows it, and the energy curves."""
    layout = layout if layout is not None else paper_layout(None, df, arts)
    d = primary(df)
    out = []
    for phantom in dict.fromkeys(d["phantom"]):
        cells = [pick(d, label=c.label, noise=c.noise, phantom=phantom) for c in layout.columns]
        if all(r is None for r in cells):
            continue
        iterations = _iteration_rows(cells, arts)
        rows = [{"name": "Initial surface Γ₀" if it == 0 else f"Iteration {it}",
                 "cells": picture_row([(r, it) for r in cells], arts)} for it in iterations]
        if not all(_final_shown(r, arts, iterations) for r in cells):
            rows.append(_final_row(cells, arts))
        rows.append({"name": "Energy", "cells": energy_row(cells, arts, [i for i in iterations if i > 0])})
        out.append({"phantom": phantom, "heads": [_head(c, r) for c, r in zip(layout.columns, cells)],
                    "rows": rows, "caption": _caption(layout, cells, iterations)})
    return out


# ---------------------------------------------------------------------------------------------- galleries
def _gallery_title(label: str, method: str) -> str:
    return GALLERY_TITLES.get(label, GALLERY_TITLES.get(method, label)) + (f" [{label}]" if label != method else "")


def _uniform_table(d, arts: Artifacts, layout: PaperLayout) -> dict | None:
    """Per phantom, the final mesh and the energy curve of each of the layout's uniform labels."""
    labels = [lab for lab in layout.uniform_labels if (d["label"] == lab).any()]
    rows = []
    for phantom in dict.fromkeys(d["phantom"]):
        cells = [pick(d, label=lab, noise="uniform", phantom=phantom) for lab in labels]
        r = next((c for c in cells if c is not None), None)
        if r is None:
            continue
        name = phantom
        if r.get("snr_requested") is not None and not is_nan(r.get("snr_requested")):
            name += f" (SNR {float(r['snr_requested']):g} dB)"
        pics = picture_row([(c, None) for c in cells], arts)
        curves = energy_row(cells, arts, [])
        rows.append({"name": name, "cells": [x for pair in zip(pics, curves) for x in pair]})
    if not rows:
        return None
    titles = []
    for lab in labels:
        clean = [c.title for c in layout.columns if c.label == lab and c.noise == "none" and c.title]
        titles.append(_gallery_title(lab, d[d["label"] == lab]["method"].iloc[0])
                      + (f" ({clean[0]})" if clean else ""))
    heads = [h for lab in labels for h in ((f"final mesh [{lab}]", f"energy [{lab}]") if len(labels) > 1
                                           else ("final mesh", "energy"))]
    return {"title": " and ".join(titles) + " on uniform noise", "heads": heads, "rows": rows}


def gallery_tables(df, arts: Artifacts, layout: PaperLayout | None = None) -> list[dict]:
    """Per label not in the paper tables: phantoms × noise settings of final meshes (the paper's MC /
    DistMesh tables); plus the uniform-noise table of the layout's ``uniform_labels``."""
    layout = layout if layout is not None else paper_layout(None, df, arts)
    d = primary(df)
    noises = sorted(dict.fromkeys(d["noise"]), key=lambda n: NOISE_ORDER.get(n, 9))
    out = []
    for label in dict.fromkeys(d["label"]):
        if label in layout.labels:
            continue
        method = d[d["label"] == label]["method"].iloc[0]
        rows = []
        for phantom in dict.fromkeys(d["phantom"]):
            entries = [(pick(d, label=label, noise=nz, phantom=phantom), None) for nz in noises]
            if all(e[0] is None for e in entries):
                continue
            rows.append({"name": phantom, "cells": picture_row(entries, arts)})
        out.append({"title": _gallery_title(label, method), "heads": [noise_title(nz, None) for nz in noises],
                    "rows": rows})
    if layout.uniform_labels and "uniform" in noises:
        table = _uniform_table(d, arts, layout)
        if table is not None:
            out.append(table)
    return out
