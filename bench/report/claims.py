"""The paper's claims, checked against this run's own cells.

Each claim of the paper (``docs``: docs/GUIDE.md "The report") gets a verdict computed here from the results
table and, where needed, the cells' arrays — ``holds``, ``partly``, ``does not hold`` or ``not measured`` (the
run has no cells that can test it) — with the numbers behind it and the cells used.  Nothing is decided in
advance: a run without noisy cells cannot say anything about noise, and says so.

Every claim is judged once per **variant** of the shape-gradient method (:data:`VARIANTS`, read from the row's
resolved ``preset``): ``printed`` — the paper's algorithm as printed (``preset=paper``), the one the paper ran;
``corrected`` — the same experiment run by the suite's corrected flow (``preset=paper+fixes``); ``default`` —
the suite's default (any other settings).  Where the verdicts differ, :data:`WHY` says in one line what in the
variants makes the difference.  Within a variant, its ``shape_gradient`` cells with β > 0 are "SG", its β = 0
cells the ablation.  A result counts only when it is valid and unflagged (status ``ok``, no flags; for the paper's
two variants a ``not_converged`` flag from their fixed iteration count or the line search's end does not count) —
a method's own "converged" is not evidence.  Definitions (the thresholds are part of the claim's test and are
printed with it):

* ``smoother`` — the β-term makes the surface smoother: in every (phantom, N, noise, seed) with both an SG cell
  and a β = 0 cell, SG's ``roughness_deg`` is lower.
* ``robust_noise`` — robust to noise: every noisy SG cell valid, unflagged, ``hausdorff_h`` ≤ 1.
* ``beats_mc`` — more accurate than marching cubes: SG's ``mean_dist_h`` below marching cubes' in every shared
  setting, SG valid and unflagged.
* ``noise_vs_mc_distmesh`` — handles noise better than marching cubes and DistMesh: in every noisy setting SG's
  ``hausdorff_h`` below both (a peer that is invalid or flagged loses that comparison).
* ``energy`` — the energy decreases smoothly to zero: every SG energy history (as the cell stored it) never
  rises by more than 1e-6 of its start from one entry to the next and ends below 5 % of its start.
* ``diffeomorphic`` — no self-intersection during the evolution: every SG cell's final mesh has
  ``self_intersections`` = 0 and no ``self_intersecting`` flag (the snapshots are checked by the method's guard;
  the final mesh by the suite).
* ``distmesh_unstable`` — DistMesh is unstable under noise: every noisy DistMesh cell is invalid, flagged, failed,
  or more than twice as far (``hausdorff_h``) as its clean cell.
* ``ellipsoid_K`` — the reconstructed ellipsoid's Gaussian curvature stays within [1/4, 4] (the true range):
  at least 99 % of the vertices of every clean SG ellipsoid within the range (``partly`` from 90 %).
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

__all__ = ["Claim", "Verdict", "CLAIMS", "VARIANTS", "WHY", "ClaimsSection", "check_claims", "claims_section",
           "is_paper_grid", "variant_of"]

HOLDS, PARTLY, NO, UNMEASURED = "holds", "partly", "does not hold", "not measured"

#: (id, the claim as the paper makes it)
CLAIMS = (
    ("smoother", "The β-term (curvature regularisation) makes the reconstructed surface smoother."),
    ("robust_noise", "The method is robust to noise."),
    ("beats_mc", "The method is more accurate than marching cubes."),
    ("noise_vs_mc_distmesh", "The method handles noise better than marching cubes and DistMesh."),
    ("energy", "The energy decreases smoothly to zero."),
    ("diffeomorphic", "The evolution is diffeomorphic: the surface never intersects itself."),
    ("distmesh_unstable", "DistMesh is unstable under noise."),
    ("ellipsoid_K", "The reconstructed ellipsoid's Gaussian curvature stays within [1/4, 4]."),
)


#: (key, column title, the ``preset`` that selects it) — in the order of the claims table's columns
VARIANTS = (("printed", "printed (the paper's algorithm, preset=paper)", "paper"),
            ("corrected", "corrected (the paper's experiment + the suite's fixes, preset=paper+fixes)", "paper+fixes"),
            ("default", "suite default", None))

#: claims that do not depend on the shape-gradient variant (one verdict for the run)
SHARED = {"distmesh_unstable"}

#: per claim and variant: what in that variant bears on the claim (shown where the verdicts differ)
WHY = {
    "smoother": {"printed": "its gradient drops the β-term's divergence −2β div_Γ(φ_n∇_Γφ)",
                 "corrected": "the full gradient; H¹ smoothing and relaxation smooth at β = 0 too",
                 "default": "the default has no β = 0 cells (and starts at the surface)"},
    "robust_noise": {"printed": "no preconditioner and no pre-smoothing: the noisy ∇φ and D²φ drive every step",
                     "corrected": "the H¹ preconditioner smooths the noisy gradient",
                     "default": "β drops to 0.01 and ∇φ is pre-smoothed on noise; it starts at the surface"},
    "beats_mc": {"printed": "1,896 fixed vertices from the radius-2 sphere, the printed gradient unpreconditioned",
                 "corrected": "1,896 fixed vertices from the radius-2 sphere against marching cubes' 5,000–11,000",
                 "default": "the default starts at marching cubes' surface (genus-0 start) and refines it"},
    "noise_vs_mc_distmesh": {"printed": "no preconditioner: the noise drives every step",
                             "corrected": "H¹ preconditioning, fixed 1,896-vertex connectivity",
                             "default": "pre-smoothed ∇φ and β = 0.01 on noise, a ½-voxel remeshed surface"},
    "energy": {"printed": "from the far sphere; the printed gradient is not E's derivative, backtracking keeps E down",
               "corrected": "from the far sphere; the exact gradient and backtracking: E never rises",
               "default": "the default starts at the surface, so E starts near its floor and remeshing moves it"},
    "diffeomorphic": {"printed": "no intersection guard",
                      "corrected": "the guard repairs or rolls back intersecting steps",
                      "default": "the guard repairs or rolls back intersecting steps"},
    "ellipsoid_K": {"printed": "the printed paraboloid fit and no relaxation on 1,896 vertices",
                    "corrected": "1,896 vertices stretched over the ellipsoid",
                    "default": "a ½-voxel remeshed surface (≈ 35,000 vertices)"},
}


@dataclass
class Verdict:
    """One variant's verdict on a claim, the numbers behind it and the cells used."""

    verdict: str = UNMEASURED
    numbers: str = ""
    cells: list[str] = field(default_factory=list)


@dataclass
class Claim:
    """A claim with one :class:`Verdict` per variant (``by_variant``); ``verdict``/``numbers``/``cells`` are those
    of the first variant the run measured it for (printed, corrected, default); ``why`` is set where the
    variants' verdicts differ."""

    id: str
    text: str
    verdict: str = UNMEASURED
    numbers: str = ""
    cells: list[str] = field(default_factory=list)
    by_variant: dict[str, Verdict] = field(default_factory=dict)
    why: str = ""
    shared: bool = False


def variant_of(r: dict) -> str | None:
    """``printed`` / ``corrected`` / ``default`` for a shape-gradient row (its resolved ``preset``), else None."""
    if r.get("method") != "shape_gradient":
        return None
    try:
        p = json.loads(r["parameters"]) if isinstance(r.get("parameters"), str) else dict(r.get("parameters") or {})
    except (TypeError, ValueError):
        p = {}
    preset = p.get("preset") if isinstance(p, dict) else None
    return next((key for key, _, pre in VARIANTS if pre is not None and pre == preset), "default")


def _beta(params) -> float | None:
    try:
        p = json.loads(params) if isinstance(params, str) else dict(params or {})
        if p.get("beta") == "auto":      # shape_gradient's default: 1 on clean volumes, 0.01 on noisy ones (> 0)
            return 1.0
        return float(p.get("beta"))
    except (TypeError, ValueError, AttributeError):
        return None


def _clean(r: dict) -> bool:
    """Valid and unflagged — except that the paper's variants may stop on ``not_converged``: the paper runs a
    fixed number of iterations (``fixed_iterations``, never flagged) and the printed loop ends where its line
    search finds no decrease (``line_search_floor``); any other flag still disqualifies."""
    flags = r.get("flags")
    text = "" if flags is None or (isinstance(flags, float) and math.isnan(flags)) else str(flags)
    left = {f for f in text.split(";") if f.strip()}
    if variant_of(r) in ("printed", "corrected") and r.get("stop_reason") in ("fixed_iterations", "max_iter",
                                                                               "line_search_floor"):
        left.discard("not_converged")
    return r.get("status") == "ok" and not left


def _num(r: dict | None, col: str) -> float:
    try:
        v = float((r or {}).get(col))
    except (TypeError, ValueError):
        return math.nan
    return v


def _snr(r: dict) -> float | None:
    v = _num(r, "snr_requested")
    return None if math.isnan(v) else v


def _key(r: dict) -> tuple:
    return (r.get("phantom"), r.get("variant"), r.get("N"), r.get("noise"), _snr(r), r.get("seed"))


def _has(col: str, *rows: dict) -> bool:
    """Every row can be judged on ``col``: a value, or a status that is itself the verdict (failed, invalid); an
    ok row without the value (no ground truth) cannot be judged — its claim is "not measured", never "does not
    hold"."""
    return all(r.get("status") != "ok" or math.isfinite(_num(r, col)) for r in rows)


def _where(r: dict) -> str:
    """``phantom/noise[ SNR dB] N`` — how a cell is named in the numbers."""
    snr = _snr(r)
    return f"{r.get('phantom')}/{r.get('noise')}" + (f" {snr:g} dB" if snr is not None else "") + f" N={r.get('N')}"


def _verdict(good: int, total: int, partial: int | None = None) -> str:
    """All good: holds; some good (or, where the claim has a weaker level, some at that level): partly."""
    if total == 0:
        return UNMEASURED
    return HOLDS if good == total else (PARTLY if good or partial else NO)


def _groups(rows: list[dict], variant: str) -> dict[str, list[dict]]:
    sg = [r for r in rows if variant_of(r) == variant]
    return {"sg": [r for r in sg if (_beta(r.get("parameters")) or 0.0) > 0],
            "sg0": [r for r in sg if _beta(r.get("parameters")) == 0.0],
            "mc": [r for r in rows if r.get("method") == "marching_cubes"],
            "dm": [r for r in rows if r.get("method") == "distmesh"]}


def _pairs(a: list[dict], b: list[dict]) -> list[tuple[dict, dict]]:
    by = {}
    for r in b:
        by.setdefault(_key(r), r)
    return [(r, by[_key(r)]) for r in a if _key(r) in by]


def _smoother(g) -> tuple:
    pairs = [p for p in _pairs(g["sg"], g["sg0"]) if _has("roughness_deg", *p)]
    good = [p for p in pairs if _num(p[0], "roughness_deg") < _num(p[1], "roughness_deg")]
    nums = "; ".join(f"{_where(p[0])}: {_num(p[0], 'roughness_deg'):.2f}° vs "
                     f"{_num(p[1], 'roughness_deg'):.2f}° (β = 0)" for p in pairs)
    return len(good), len(pairs), nums, [c["cell_id"] for p in pairs for c in p]


def _robust(g) -> tuple:
    noisy = [r for r in g["sg"] if r.get("noise") not in (None, "none") and _has("hausdorff_h", r)]
    good = [r for r in noisy if _clean(r) and _num(r, "hausdorff_h") <= 1.0]
    nums = "; ".join(f"{_where(r)}: {_num(r, 'hausdorff_h'):.2f} h, {r.get('status')}"
                     + (f" ⚑{r['flags']}" if not _clean(r) and r.get("status") == "ok" else "") for r in noisy)
    return len(good), len(noisy), nums, [r["cell_id"] for r in noisy]


def _beats_mc(g) -> tuple:
    pairs = [p for p in _pairs(g["sg"], g["mc"]) if _has("mean_dist_h", *p)]
    good = [p for p in pairs if _clean(p[0]) and _num(p[0], "mean_dist_h") < _num(p[1], "mean_dist_h")]
    nums = "; ".join(f"{_where(p[0])}: {_num(p[0], 'mean_dist_h'):.3f} h vs "
                     f"{_num(p[1], 'mean_dist_h'):.3f} h" for p in pairs)
    return len(good), len(pairs), nums, [c["cell_id"] for p in pairs for c in p]


def _noise_vs(g) -> tuple:
    noisy = [r for r in g["sg"] if r.get("noise") not in (None, "none")]
    mc, dm = {_key(r): r for r in g["mc"]}, {_key(r): r for r in g["dm"]}
    trios = [(r, mc[_key(r)], dm[_key(r)]) for r in noisy if _key(r) in mc and _key(r) in dm]
    trios = [t for t in trios if _has("hausdorff_h", *t)]

    def wins(s, o):
        return _clean(s) and (not _clean(o) or _num(s, "hausdorff_h") < _num(o, "hausdorff_h"))

    good = [t for t in trios if wins(t[0], t[1]) and wins(t[0], t[2])]
    nums = "; ".join(f"{_where(t[0])}: SG {_num(t[0], 'hausdorff_h'):.2f} h, MC "
                     f"{_num(t[1], 'hausdorff_h'):.2f} h, DistMesh {_num(t[2], 'hausdorff_h'):.2f} h"
                     + ("" if _clean(t[2]) else f" ({t[2].get('status')} {t[2].get('flags') or ''})".rstrip())
                     for t in trios)
    return len(good), len(trios), nums, [c["cell_id"] for t in trios for c in t]


def _energy(g, arrays) -> tuple:
    good, total, parts, cells = 0, 0, [], []
    for r in g["sg"]:
        e = np.asarray((arrays(r["cell_id"]) or {}).get("energy_history", []), dtype=float)
        if e.size < 2 or not np.isfinite(e).all() or e[0] <= 0:
            continue
        total += 1
        cells.append(r["cell_id"])
        rises = int((np.diff(e) > 1e-6 * e[0]).sum())
        ratio = e[-1] / e[0]
        good += rises == 0 and ratio < 0.05
        parts.append(f"{_where(r)}: end/start {ratio:.2g}, {rises} rise(s) in {e.size - 1} steps")
    return good, total, "; ".join(parts), cells


def _diffeo(g) -> tuple:
    rows = g["sg"] + g["sg0"]
    good = [r for r in rows if _num(r, "self_intersections") == 0 and "self_intersecting" not in str(r.get("flags"))]
    bad = [r for r in rows if r not in good]
    nums = f"{len(good)} of {len(rows)} shape-gradient meshes free of self-intersections" + (
        "; intersecting: " + ", ".join(f"{_where(r)} ({_num(r, 'self_intersections'):.0f} pairs)"
                                       for r in bad) if bad else "")
    return len(good), len(rows), nums, [r["cell_id"] for r in rows]


def _distmesh(g) -> tuple:
    clean = {(r["phantom"], r.get("N"), r.get("seed")): r for r in g["dm"] if r.get("noise") == "none"}
    noisy = [r for r in g["dm"] if r.get("noise") not in (None, "none") and _has("hausdorff_h", r)]

    def unstable(r):
        c = clean.get((r["phantom"], r.get("N"), r.get("seed")))
        worse = c is not None and _num(r, "hausdorff_h") > 2 * _num(c, "hausdorff_h")
        return not _clean(r) or worse

    good = [r for r in noisy if unstable(r)]
    nums = "; ".join(f"{_where(r)}: {r.get('status')}"
                     + (f" ⚑{r['flags']}" if r.get("flags") and str(r.get("flags")) != "nan" else "")
                     + f", {_num(r, 'hausdorff_h'):.2f} h" for r in noisy)
    return len(good), len(noisy), nums, [r["cell_id"] for r in noisy]


def _ellipsoid_K(g, arrays, extent: float) -> tuple:
    from ..metrics.curvature import vertex_curvature

    good, partial, total, parts, cells = 0, 0, 0, [], []
    for r in g["sg"]:
        if r.get("phantom") != "ellipsoid" or r.get("noise") != "none":
            continue
        a = arrays(r["cell_id"]) or {}
        if "vertices" not in a or "faces" not in a:
            continue
        try:
            h = 2.0 * extent / (float(r["N"]) - 1)          # the grid spacing of a cubic ±extent grid
        except (TypeError, ValueError, ZeroDivisionError):
            continue
        K = np.asarray(a["K"], float) if len(a.get("K", ())) == len(a["vertices"]) else \
            vertex_curvature(np.asarray(a["vertices"], float), np.asarray(a["faces"], np.int64), h)[1]
        K = K[np.isfinite(K)]
        if K.size == 0:
            continue
        total += 1
        cells.append(r["cell_id"])
        share = float(((K >= 0.25) & (K <= 4.0)).mean())
        good += share >= 0.99
        partial += share >= 0.90
        parts.append(f"N = {r['N']}: {100 * share:.1f} % of vertices with K in [1/4, 4] (1st–99th percentile "
                     f"{np.percentile(K, 1):.3f}–{np.percentile(K, 99):.3f})")
    return good, total, "; ".join(parts), cells, partial


def _checks(g: dict, arrays, extent: float) -> dict[str, Callable]:
    return {"smoother": lambda: _smoother(g), "robust_noise": lambda: _robust(g),
            "beats_mc": lambda: _beats_mc(g), "noise_vs_mc_distmesh": lambda: _noise_vs(g),
            "energy": lambda: _energy(g, arrays), "diffeomorphic": lambda: _diffeo(g),
            "distmesh_unstable": lambda: _distmesh(g), "ellipsoid_K": lambda: _ellipsoid_K(g, arrays, extent)}


def _why(cid: str, by: dict[str, Verdict]) -> str:
    """One line on what differs, where the variants' verdicts do (variants that measured nothing aside)."""
    measured = {k: v.verdict for k, v in by.items() if v.verdict != UNMEASURED}
    if len(set(by[k].verdict for k in by)) < 2:
        return ""
    parts = [f"{k}: {WHY.get(cid, {}).get(k, '')}" for k in measured]
    parts += [f"{k}: no cell of this variant can test it" for k in by if k not in measured]
    return "; ".join(p for p in parts if not p.endswith(": "))


def check_claims(rows: list[dict], arrays: Callable[[str], dict | None] = lambda cell_id: None, *,
                 extent: float = 2.5) -> list[Claim]:
    """The verdicts of every claim of :data:`CLAIMS`, one per variant of :data:`VARIANTS`, from the results rows
    (results.csv as dicts), ``arrays(cell_id)`` (the cell's ``.npz`` contents, or None) and the grid's
    half-width ``extent``."""
    checks = {key: _checks(_groups(rows, key), arrays, extent) for key, _, _ in VARIANTS}
    out = []
    for cid, text in CLAIMS:
        by: dict[str, Verdict] = {}
        for key, _, _ in VARIANTS:
            if cid in SHARED and by:
                by[key] = by[next(iter(by))]
                continue
            good, total, numbers, cells, *partial = checks[key][cid]()
            by[key] = Verdict(_verdict(good, total, *partial),
                              f"{good} of {total} — {numbers}" if total else
                              "the run has no cells that can test this claim", cells)
        first = next((v for v in by.values() if v.verdict != UNMEASURED), next(iter(by.values())))
        out.append(Claim(cid, text, first.verdict, first.numbers, first.cells, by,
                         "" if cid in SHARED else _why(cid, by), cid in SHARED))
    return out


@dataclass
class ClaimsSection:
    """The report's claims section: ``claims`` to show, whether the run's grid is the paper's (``paper_grid``: every
    claim is shown), and the ids of the claims left out because no cell of the run can test them (``untested``)."""

    claims: list[Claim]
    paper_grid: bool
    untested: list[str] = field(default_factory=list)


def is_paper_grid(config: dict | None) -> bool:
    """Whether a run's config (``run.json``'s ``config``) computes the paper's grid: the same phantoms, variants,
    N, extent, seeds, noise and degradations as the shipped ``paper`` config — not whether it is named so."""
    from ..config import builtin_config

    grid = (config or {}).get("grid")
    return isinstance(grid, dict) and grid == builtin_config("paper").to_dict()["grid"]


def claims_section(rows: list[dict], arrays: Callable[[str], dict | None] = lambda cell_id: None, *,
                   config: dict | None = None, extent: float = 2.5) -> ClaimsSection:
    """The claims the report shows: on the paper's grid every claim of :func:`check_claims`; on any other grid (a
    custom run, e.g. a label map) only those some cell of the run can test, naming the rest (``untested``) — an
    empty ``claims`` when it can test none, so the section is left out."""
    claims = check_claims(rows, arrays, extent=extent)
    if is_paper_grid(config):
        return ClaimsSection(claims, True)
    measured = [c for c in claims if any(v.verdict != UNMEASURED for v in c.by_variant.values())]
    return ClaimsSection(measured, False, [c.id for c in claims if c not in measured])
