"""Cost models: a method's run time estimated from the grid's size before it runs.

A method may override :meth:`methods.Method.estimate_seconds` (``None``: no model, the default); the grid runner
refuses a cell whose estimate exceeds its time limit (``bench.run.estimate``) instead of letting it run for an
hour to be killed.  The built-in models are :class:`PowerLaw` fits of run times (``python -m
bench.perf.cost_models`` measures them): a model is an order of magnitude, not a stopwatch — the measurements
behind them spread with the phantom and the machine's load.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["PowerLaw", "crossing_cells", "grid_points"]


def grid_points(shape) -> int:
    """The number of grid samples of a volume of ``shape``.

    Parameters
    ----------
    shape : int or tuple of int
        The grid's shape; an int N is the N³ grid.
    """
    if isinstance(shape, (int, np.integer)):
        return int(shape) ** 3
    return int(math.prod(int(s) for s in shape))


def crossing_cells(volume) -> int:
    """The grid cells whose eight corners do not all have the same sign (φ < 0 or not): the cells the zero
    level set crosses — about (surface area) / h² × 1.5 for a smooth surface.

    Parameters
    ----------
    volume : phantoms.Volume
        The sampled level-set function.
    """
    inside = np.asarray(volume.values) < 0
    lo = np.ones(tuple(s - 1 for s in inside.shape), dtype=bool)
    hi = np.zeros_like(lo)
    for dx in (0, 1):
        for dy in (0, 1):
            for dz in (0, 1):
                corner = inside[dx:dx + lo.shape[0], dy:dy + lo.shape[1], dz:dz + lo.shape[2]]
                lo &= corner
                hi |= corner
    return int((hi & ~lo).sum())


@dataclass(frozen=True)
class PowerLaw:
    """``seconds = floor + a · (M / 64³)^(p/3) · (C / C₀(M))^q``: M grid samples, C crossing cells.

    ``a`` is the time at 64³ on the reference phantom above a constant ``floor`` (the part that does not grow
    with the grid), ``p`` the exponent in N (M = N³), ``q`` the exponent in
    the surface's size relative to the reference phantom's, whose crossing cells are ``C₀ = c0 · (M / 64³)^(2/3)``
    (the sphere of radius 1 in the suite's [-2.5, 2.5]³ grid: c0 ≈ 3.0k; the bunny 2.9k).  Without C (the grid
    runner estimates before any volume exists) the reference surface is assumed.

    Parameters
    ----------
    a : float
        Seconds at 64³ on the reference phantom, above ``floor``.
    p : float
        Exponent in N.
    q : float
        Exponent in the surface's size relative to the reference phantom's.
    c0 : float
        The reference phantom's crossing cells at 64³.
    floor : float
        Seconds that do not grow with the grid.
    """

    a: float
    p: float
    q: float = 0.0
    c0: float = 3000.0
    floor: float = 0.0

    def seconds(self, shape, n_crossing_cells: int | None = None) -> float:
        m = grid_points(shape) / 64.0 ** 3
        t = self.a * m ** (self.p / 3.0)
        if n_crossing_cells and self.q:
            t *= (n_crossing_cells / (self.c0 * m ** (2.0 / 3.0))) ** self.q
        return float(self.floor + t)
