"""The post-steps of the final mesh: crease polish, Newton projection onto φ = 0, tip extension, reach to the
samples.

Each is a geometric step on the flow's last iterate (nothing here changes where the flow went).  With the guard on,
a step that makes faces meet keeps those faces' vertices back (the projection; the tip extension halves their moves
first) or is dropped (the polish: kept back in part, it did worse than dropped).
"""

from __future__ import annotations

import time
from typing import Callable

import numpy as np

from geometry.arrays import unique_ints
from geometry.operators import MeshOperators

from .field import CLEAN_NOISE_VOXELS
from .guard import count_intersections
from .polish import crease_polish, newton_project
from .settings import FlowSettings
from .reach import reach_samples
from .tips import extend_tips

__all__ = ["post_steps", "reach_step", "keep_back"]

_PROJECTION_STEPS = 3          # final Newton projection onto φ = 0: steps ...
_PROJECTION_MAX_VOXELS = 0.5   # ... each capped at this many voxels
_REVERT_ROUNDS = 4             # rounds of putting back the vertices whose move made faces intersect
_TIP_HALVINGS = 3              # the tip extension first halves such moves, up to this many times


def keep_back(ops: MeshOperators, xq: np.ndarray, x: np.ndarray, *, local: bool = False, halve: int = 0
              ) -> tuple[np.ndarray, int, bool]:
    """(xq, vertices kept back, intersection-free): where moving x (intersection-free) to xq made faces meet,
    their vertices and 1-rings stay at x, a few rounds (putting back can expose more); the first ``halve``
    rounds only halve those vertices' moves.  ``local``: only the moved patch is checked (a step that moved few
    vertices).  After the first check only the patch put back is checked again: every pair that met had a face
    in it, and no other face moved."""
    changed = np.flatnonzero(np.any(xq != x, axis=1)) if local else None
    xq, kept = xq.copy(), 0
    for round_ in range(_REVERT_ROUNDS + halve):
        n, bad = count_intersections(xq, ops.faces, moved=changed)
        if n == 0:
            return xq, kept, True
        back = unique_ints(ops.faces[bad])
        changed = back = unique_ints(np.concatenate([back, ops.ring[back][ops.ring_valid[back]]]))
        if round_ < halve:
            xq[back] = 0.5 * (xq[back] + x[back])
            continue
        kept += int(np.any(xq[back] != x[back], axis=1).sum())
        xq[back] = x[back]
    return xq, kept, count_intersections(xq, ops.faces, moved=changed)[0] == 0   # the last repair is checked too


def post_steps(field, ops: MeshOperators, x: np.ndarray, h: float, st: FlowSettings, *, guard: bool,
               energy: Callable[[np.ndarray], float], timings: dict) -> tuple[np.ndarray, dict, dict, dict]:
    """(vertices, info['polish'], info['projection'], info['tips']) after the post-steps the settings ask for,
    in this order: the polish (clean volumes) and the projection put vertices on φ = 0, the tip extension then
    moves sharply convex parts out to the samples' empty balls (tips.py).  The reach to the samples comes after
    them (:func:`reach_step`)."""
    polish = {"used": st.polish}
    if polish["used"]:
        t0 = time.perf_counter()
        xp, stats = crease_polish(field, ops, x, h)
        polish.update(stats)
        moved = np.flatnonzero(np.any(xp != x, axis=1))        # x was checked: only the polished patch can meet
        if guard and stats["zone_vertices"] and count_intersections(xp, ops.faces, moved=moved)[0]:
            polish["rejected"] = "it made faces intersect"
        else:
            x = xp
        polish["energy"] = float(energy(x)) if stats["zone_vertices"] else None   # None: the flow's own
        timings["polish"] = timings.get("polish", 0.0) + time.perf_counter() - t0
    projection = {"used": st.projection}
    if projection["used"]:
        t0 = time.perf_counter()
        xq, _ = newton_project(field, x, steps=_PROJECTION_STEPS, max_step=_PROJECTION_MAX_VOXELS * h)
        xq = np.where(np.isfinite(xq).all(axis=1, keepdims=True), xq, x)
        x, projection = _kept(ops, xq, x, h, guard, projection, local=False)
        timings["projection"] = timings.get("projection", 0.0) + time.perf_counter() - t0
    tips = {"used": st.extend_tips and hasattr(field, "volume")}     # it reads the samples: not on a callable field
    if tips["used"]:
        t0 = time.perf_counter()
        xt, stats = extend_tips(field, ops, x, h)
        tips.update(stats)
        x, tips = _kept(ops, xt, x, h, guard, tips, local=True, halve=_TIP_HALVINGS)
        timings["tips"] = timings.get("tips", 0.0) + time.perf_counter() - t0
    return x, polish, projection, tips


def reach_step(field, ops: MeshOperators, x: np.ndarray, h: float, st: FlowSettings, *, guard: bool,
               timings: dict, noise: float) -> tuple[np.ndarray, dict]:
    """(vertices, info['reach']) after the reach to the samples (reach.py), where the settings ask for it and the
    field samples a signed distance; ``noise`` is the volume's estimated noise std (world units)."""
    volume = getattr(field, "volume", None)
    reach = {"used": st.reach_samples and volume is not None and volume.kind == "sdf"}
    if reach["used"]:
        t0 = time.perf_counter()
        keep = ((lambda xq, x0: keep_back(ops, xq, x0, local=True, halve=_TIP_HALVINGS)) if guard
                else (lambda xq, x0: (xq, 0, True)))
        noise_voxels = float(noise) / h if np.isfinite(noise) else 0.0
        x, stats = reach_samples(volume, x, ops.faces, ops.geometry(x).vertex_normals, noise_voxels, keep,
                                 lone=noise_voxels < CLEAN_NOISE_VOXELS)
        reach.update(stats)
        timings["reach"] = timings.get("reach", 0.0) + time.perf_counter() - t0
    return x, reach


def _kept(ops, xq, x, h, guard, info, *, local, halve=0):
    """xq with what made faces meet kept back (guard on), else x if that fails; the step's info updated."""
    xq, info["kept_back"], ok = keep_back(ops, xq, x, local=local, halve=halve) if guard else (xq, 0, True)
    info["max_move_voxels"] = float(np.linalg.norm(xq - x, axis=1).max() / h) if ok and len(x) else 0.0
    if not ok:
        info["rejected"] = "it made faces intersect"
    return (xq if ok else x), info
