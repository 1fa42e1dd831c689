"""Noise pinholes in a grown genus-0 solid: inside samples the homotopic growth had to leave out because one
sample just above the level, in the middle of a thin sheet, would have closed a handle.

Why: in a part a voxel or two thick (an ear, a wing), noise lifts single samples of φ above 0.  The sheet then has a
pinhole, the inside samples on its rim would close a loop around it, and the growth
(:func:`methods.shape_gradient.digital.homotopic_growth`) stops there — the start loses the tip beyond it, and a flow
that never moves far from its start loses it too (the bunny's ear at N = 64, 40 dB: 1.49 h instead of marching cubes'
0.92 h).  The object has no hole there: the pinhole is one sample, within noise of the level.

:func:`close_pinholes` fills such holes and no others:

1. the samples just above the level (below ``close_below``, e.g. one noise std) next to the left-out inside
   samples of the solid's own piece become candidates, and the growth is run again over the inside samples
   and the candidates (a candidate is then added before the left-out samples whose loop it fills);
2. the candidates that were added are thinned away again
   (:func:`methods.shape_gradient.digital.homotopic_thinning`) where they are not needed: what remains are the
   samples that close a hole;
3. a hole counts as a *pinhole* when its group (remaining candidates and the left-out samples they touch) has
   at most ``max_plate`` candidate samples; the growth is run a last time with the pinholes' candidates only.
   A wider gap (two sulcal banks touching over a line of samples) needs a larger plate and stays open:
   the growth still stops there.

The result is again a topological ball (the growth guarantees it whatever it is given).
"""

from __future__ import annotations

import numpy as np
from scipy import ndimage

from .digital import homotopic_growth, homotopic_thinning

__all__ = ["close_pinholes"]

_CUBE = np.ones((3, 3, 3), bool)


def close_pinholes(phi: np.ndarray, solid: np.ndarray, level: float, close_below: float,
                   max_plate: int = 1) -> tuple[np.ndarray, dict]:
    """(solid, facts): ``solid`` (a :func:`~methods.shape_gradient.digital.homotopic_growth` of ``phi < level``)
    with its noise pinholes closed (see the module docstring); facts: ``left_out_before``, ``left_out``,
    ``pinholes`` (holes closed), ``pinhole_samples`` (samples above the level now in the solid).

    ``close_below`` ≤ ``level`` (then the left-out counts are not computed: 0) or nothing left out: ``solid``
    unchanged."""
    phi = np.asarray(phi, dtype=np.float64)
    solid = np.asarray(solid, bool)
    inside = phi < level
    facts = {"left_out_before": 0, "left_out": 0, "pinholes": 0, "pinhole_samples": 0}
    if not solid.any() or close_below <= level:          # (clean volumes: nothing to do, nothing labelled)
        return solid, facts
    labels, _ = ndimage.label(inside, structure=_CUBE)
    piece = labels == labels[tuple(np.argwhere(solid)[0])]
    left = piece & ~solid
    facts["left_out_before"] = facts["left_out"] = int(left.sum())
    if not left.any():
        return solid, facts
    interior = np.zeros(phi.shape, bool)
    interior[1:-1, 1:-1, 1:-1] = True
    cand = ndimage.binary_dilation(left, _CUBE) & ~inside & (phi < close_below) & interior
    grown = homotopic_growth(np.where(piece | cand, phi, np.inf), close_below)
    needed = homotopic_thinning(grown, phi, grown & cand)
    plates = needed & cand
    groups, n_groups = ndimage.label(plates | left, structure=_CUBE)
    size = np.bincount(groups[plates], minlength=n_groups + 1)
    accept = (size >= 1) & (size <= int(max_plate))
    accept[0] = False
    pins = plates & accept[groups]
    if not pins.any():
        return solid, facts
    out = homotopic_growth(np.where(piece | pins, phi, np.inf), close_below)
    facts.update(left_out=int((piece & ~out).sum()), pinholes=int(accept.sum()),
                 pinhole_samples=int((out & ~inside).sum()))
    return out, facts
