"""The step of the flow: a capped Armijo backtracking line search along the descent direction, its L² fallback, and
the normal move a carve-limited step makes (what the stop test reads)."""

from __future__ import annotations

from typing import Callable

import numpy as np

from geometry.operators import dot

from .carve import CarvedHull
from .energy import no_fold

__all__ = ["LineSearch", "l2_fallback_direction", "clamped_move", "ARMIJO"]

ARMIJO = 1e-4             # sufficient-decrease constant of the backtracking line search


class LineSearch:
    """The capped backtracking search of one flow and what it carries from step to step.

    A trial moves the vertex that moves most by ``move`` (world units), starting from twice the last accepted
    move after a first-try success, else the same move again, never above the cap ``max_move``; it is halved until
    the energy decreases by the Armijo condition and no face normal turns by more than 60° (no fold), first with
    the tangential relaxation shift, then without it, down to ``floor_move``.

    Parameters
    ----------
    max_move : float
        The step cap, world units (halved by a rollback of the intersection guard, :meth:`halve_cap`).
    floor_move : float
        The search gives up when the trial move falls below this, world units.
    """

    def __init__(self, max_move: float, floor_move: float):
        self.max_move, self.floor_move = float(max_move), float(floor_move)
        self.prev, self.grow = self.max_move, True      # the last accepted move; whether it was the first trial

    def restart(self) -> None:
        """A new mesh or stage: the next search starts from the cap, without doubling."""
        self.prev, self.grow = self.max_move, False

    def halve_cap(self) -> None:
        """After a rollback: halve the cap (not below 4 × the floor) and the next first trial with it."""
        self.max_move = max(0.5 * self.max_move, 4.0 * self.floor_move)
        self.prev = min(self.prev, self.max_move)

    def search(self, evaluate: Callable, state, direction: np.ndarray, shift: np.ndarray | None, vmax: float,
               slope: float, limit: np.ndarray | None, stats) -> tuple[object | None, float, float]:
        """(new state, trial move, normal move) of the search along ``direction`` (V, 3; its largest vertex speed
        ``vmax``, ``slope`` = −dE/dτ at τ = 0), or ``(None, move, 0)`` when no move down to the floor decreases E.

        ``evaluate(x)`` is the state at ``x``; ``limit``: each vertex's largest inward move (the carve limit) or
        None; ``stats`` counts the backtracks and the decreases rejected for a fold.  The normal move is the
        trial move, or with a limit the largest normal move once cut to it (:func:`clamped_move`)."""
        geo, new = state.geo, None
        first = min(self.max_move, (2.0 if self.grow else 1.0) * self.prev)
        for with_shift in ((True, False) if shift is not None else (False,)):
            move = first
            while True:
                tau = move / vmax
                x_new = state.x + (tau * direction if limit is None
                                   else CarvedHull.clamp(tau * direction, geo.vertex_normals, limit))
                if with_shift:
                    x_new += shift
                cand = evaluate(x_new)
                decrease = np.isfinite(cand.E) and cand.E <= state.E - ARMIJO * tau * slope
                if decrease and no_fold(geo, cand.geo):
                    new = cand
                    break
                stats.n_rejected_folds += decrease
                stats.n_backtracks += 1
                move *= 0.5
                if move < self.floor_move:
                    break
            if new is not None:
                break
        if new is None:
            return None, move, 0.0
        self.grow, self.prev = move == first, move
        return new, move, (move if limit is None else clamped_move(geo, direction, move / vmax, limit))


def l2_fallback_direction(geo, G: np.ndarray, limit: np.ndarray | None) -> tuple[np.ndarray, float, float] | None:
    """The L² fallback: (direction, its largest speed, its slope) along the plain shape gradient ``G`` — with the
    same carve ``limit`` as the H¹ direction — or None where it predicts no decrease.  Tried where the line search
    along the H¹ direction finds none (under noise that direction is the pre-smoothed field's)."""
    V = G if limit is None else CarvedHull.stopped(G, limit)
    vmax, slope = float(np.abs(V).max()), dot(geo.vertex_areas * G, V)
    if not (vmax > 0 and slope > 0):
        return None
    return -V[:, None] * geo.vertex_normals, vmax, slope


def clamped_move(geo, direction: np.ndarray, tau: float, limit: np.ndarray) -> float:
    """The largest normal move the step ``tau`` · ``direction`` makes once each vertex's inward part is cut to its
    ``limit``: the move the stop test reads.  The uncut trial move stays large while a held vertex pushes against
    its limit, so a flow whose surface has stopped on the carved hull would never read as still."""
    outward = tau * np.einsum("vd,vd->v", direction, geo.vertex_normals)       # < 0: inward
    moved = np.where(outward >= 0.0, outward, np.minimum(-outward, limit))
    return float(moved.max()) if len(moved) else 0.0
