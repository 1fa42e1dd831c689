"""The sign guard: the flow must not put grid samples that are clearly inside or outside the object on the wrong
side of its surface — more than its (genus-0) start did.

Why: on coarse grids a part a voxel or two thick (the bunny's ears at N = 32) is shortened step by step by the
remesher's collapses at its tip and by the alignment term (∇φ across a voxel-thin plate is not normal to it); φ at
the retracted surface stays small, so neither the energy nor |φ| at the vertices shows it.  The samples inside the
lost part do: they are now outside the surface.  At every remesh the guard reads which samples with
h/4 < |φ| < 3 h the surface encloses (its winding number on the grid by scan conversion,
:func:`geometry.raster.grid_winding`: a tenth of the time gpytoolbox's fast winding number takes at the same
samples) and counts those on the wrong side: inside samples (φ < 0) the surface covered and no longer
covers — a cut — and outside samples it covers.  Inside samples its start did not cover are not counted: a flow
may grow into a part its start missed, and that growth does not earn it the right to cut another part.  When
the count exceeds the start's by more than 2 + 0.1 % of the samples, the flow stops (``stop_reason =
"sign_guard"``) and goes back to the accepted checkpoint with the fewest samples on the wrong side, the latest
among equals: a flow that cuts a part does so over several checks, each within the allowance, so the last
checkpoint has already lost some of it — on coarse grids the start itself is usually the best of them.  The
choice reads only the volume.
"""

from __future__ import annotations

import numpy as np

from geometry.raster import grid_winding

__all__ = ["SignGuard", "MARGIN_VOXELS"]

MARGIN_VOXELS = 0.25   # samples with |φ| above this many voxels are clearly inside/outside ...
BAND_VOXELS = 3.0      # ... and those within this many voxels of φ = 0 are checked ...
SLACK = (2, 1e-3)      # ... and the flow may put at most 2 + 0.1 % of them more on the wrong side than its start


class SignGuard:
    """Checkpoints of a flow, kept while it cuts no more clearly-inside samples, and covers no more
    clearly-outside ones, than allowed; on a failed check, the one with the fewest samples on the wrong side.

    A *cut* sample is a clearly-inside sample the surface covered (its start, or an accepted checkpoint) and no
    longer covers.  Inside samples the start did not cover (the tip of a part the start missed) count neither
    way: a flow that grows into them is not stopped, and growing there gives no allowance to cut elsewhere.
    A clearly-outside sample counts while the surface covers it, against the start's count of those.
    """

    def __init__(self, volume, h: float, x: np.ndarray, faces: np.ndarray, ops) -> None:
        v = volume.values
        self.grid = (volume.origin, volume.spacing, volume.shape)
        self.sel = (np.abs(v) > MARGIN_VOXELS * h) & (np.abs(v) < BAND_VOXELS * h)
        self.n_points = int(np.count_nonzero(self.sel))
        self.inside = v[self.sel] < 0
        cover = self._cover(x, faces)
        self.covered = self.inside & cover          # the inside samples that must stay covered
        start = self._count(cover)                  # the outside samples the start covers
        self.log: list[tuple[int, int]] = [(0, start)]
        self.allowed = start + SLACK[0] + int(SLACK[1] * self.n_points)
        self.checkpoint = (0, x.copy(), ops)
        self.best = (start, self.checkpoint)        # the accepted checkpoint with the fewest wrong-side samples
        self.message = ""

    def _cover(self, x: np.ndarray, faces: np.ndarray) -> np.ndarray:
        """Which checked samples the closed mesh (x, faces) encloses."""
        if self.n_points == 0:
            return np.zeros(0, bool)
        return grid_winding(x, faces, *self.grid)[self.sel] >= 1

    def _count(self, cover: np.ndarray) -> int:
        return int(np.count_nonzero(self.covered & ~cover) + np.count_nonzero(~self.inside & cover))

    def wrong_side(self, x: np.ndarray, faces: np.ndarray) -> int:
        """How many checked samples the closed mesh (x, faces) puts on the wrong side: inside samples cut
        (covered before, not now) and outside samples covered."""
        return self._count(self._cover(x, faces))

    def check(self, it: int, x: np.ndarray, ops, keep: bool = True) -> tuple[np.ndarray, object] | None:
        """None when the mesh is within the allowance (with ``keep``, it becomes the checkpoint and the inside
        samples it covers join those that must stay covered); else the checkpoint's (vertices, operators) to
        go back to, with :attr:`message` saying why."""
        cover = self._cover(x, ops.faces)
        wrong = self._count(cover)
        self.log.append((it, wrong))
        if wrong <= self.allowed:
            if keep:
                self.checkpoint = (it, x.copy(), ops)
                self.covered |= self.inside & cover
                if wrong <= self.best[0]:
                    self.best = (wrong, self.checkpoint)
            return None
        fewest, (back, xb, opsb) = self.best
        self.message = (f"iteration {it}: the surface put {wrong} samples with |φ| > {MARGIN_VOXELS:g} voxel on the "
                        f"wrong side (its start: {self.log[0][1]}, allowed {self.allowed}); rolled back to "
                        f"iteration {back}, the checkpoint with the fewest ({fewest})")
        return xb, opsb
