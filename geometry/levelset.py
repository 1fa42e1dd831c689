"""Projection of points onto the zero level set of a sampled field φ."""

from __future__ import annotations

import numpy as np

__all__ = ["newton_project"]


def _sqnorm(v: np.ndarray, coords_first: bool) -> np.ndarray:
    # each layout's own fast |v|²: the three coordinate rows summed, or row dot products by einsum
    # (einsum may round differently from the explicit sum: each caller keeps its arithmetic bit for bit)
    if coords_first:
        return v[0] * v[0] + v[1] * v[1] + v[2] * v[2]
    return np.einsum("ij,ij->i", v, v)


def newton_project(sample, x, steps: int, *, max_step: float = np.inf, flat_g2: float = 0.0, box=None,
                   coords_first: bool = False) -> tuple[np.ndarray, dict]:
    """``steps`` Newton projections onto φ = 0 along ∇φ: x ← x − φ∇φ/|∇φ|² (DistMesh's projection).

    ``sample(x) -> (phi (P,), grad)`` evaluates φ and ∇φ at the points, ``grad`` in the layout of ``x``:
    (P, 3), or (3, P) with ``coords_first``.  Per step and point:

    * where |∇φ|² < ``flat_g2`` the point does not move (no usable direction: a flat or vanishing
      gradient would send it arbitrarily far);
    * a step longer than ``max_step`` is shortened to ``max_step`` (the linearisation holds only
      nearby; far from the surface a full step can overshoot into another part of the level set);
    * with ``box = (lower, upper)`` the points are clamped into the box after the step.

    Returns the projected points (a new array, layout of ``x``) and counts over all steps:
    ``{"flat": points left in place, "capped": steps shortened}``.
    """
    p = np.array(x, dtype=np.float64)
    if box is not None:
        lo, hi = (np.asarray(b, float) for b in box)
        if coords_first:
            lo, hi = lo[:, None], hi[:, None]
    n_flat = n_capped = 0
    for _ in range(steps):
        phi, grad = sample(p)
        g2 = _sqnorm(grad, coords_first)
        flat = g2 < flat_g2
        n_flat += int(flat.sum())
        coef = phi / np.where(flat, 1.0, g2)
        if coords_first:
            step = coef[None, :] * grad
            step[:, flat] = 0.0
        else:
            step = coef[:, None] * grad
            step[flat] = 0.0
        slen2 = _sqnorm(step, coords_first)
        big = slen2 > max_step * max_step
        if big.any():
            n_capped += int(big.sum())
            shrink = max_step / np.sqrt(slen2[big])
            if coords_first:
                step[:, big] *= shrink[None, :]
            else:
                step[big] *= shrink[:, None]
        p = p - step
        if box is not None:
            np.clip(p, lo, hi, out=p)
    return p, {"flat": n_flat, "capped": n_capped}
