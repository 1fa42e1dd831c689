"""Is a method's output a reconstruction at all?  The suite checks every mesh before it scores it.

A method's own report of success is not evidence: an open mesh, an inward-facing one, one left in voxel-index
coordinates or one that collapsed can score well on some metrics (an inward mesh scores exactly like the correct
one on distances).  :func:`check_mesh` returns the reasons a mesh is *invalid* — an empty list when it is valid:

* ``empty``: no vertices or no faces;
* ``non-finite``: NaN or infinite vertex coordinates;
* ``bad indices``: faces that index vertices that do not exist;
* ``outside the volume``: vertices more than ``box_margin`` grid steps outside the volume's box (world
  coordinates are expected; a mesh in voxel-index coordinates fails here or on the zero set);
* ``open``: an edge in fewer than two faces (not watertight);
* ``non-manifold``: an edge in more than two faces;
* ``inconsistently oriented``: two faces traverse a shared edge in the same direction;
* ``inward``: negative enclosed volume (faces oriented inward);
* ``off the zero set``: the median |φ| at the vertices above ``phi_tolerance`` grid steps (wrong coordinates,
  collapse, a surface that never reached the level set).  With a noisy input, ``given`` is the volume the method
  was given and ``volume`` the clean one: a vertex's |φ| is the smaller of the two, so a mesh on the noisy zero
  set (marching cubes) and one near the true surface (a smoothing method) both count as on the zero set — how
  far either is from the truth is the distances' business, not validity's.  |φ| of the given volume is counted
  in its own grid steps, those of its coarsest axis: on a thick-slice scan a surface half a slice off is on it.

Degenerate faces (a repeated vertex index) are ignored, as the metrics ignore them.
"""

from __future__ import annotations

import numpy as np

from geometry.mesh import signed_volume
from geometry.topology import edge_face_counts, is_oriented

__all__ = ["check_mesh", "REASONS"]

REASONS = ("empty", "non-finite", "bad indices", "outside the volume", "open", "non-manifold",
           "inconsistently oriented", "inward", "off the zero set")


def _arrays(mesh) -> tuple[np.ndarray, np.ndarray]:
    v = np.asarray(getattr(mesh, "vertices", np.zeros((0, 3))), dtype=np.float64).reshape(-1, 3)
    f = np.asarray(getattr(mesh, "faces", np.zeros((0, 3))), dtype=np.int64).reshape(-1, 3)
    return v, f


def _geometry_reasons(v: np.ndarray, f: np.ndarray, volume, box_margin: float, phi_tolerance: float,
                      given=None) -> list[str]:
    """Where the vertices are: inside the box, on the zero set."""
    reasons = []
    h = float(volume.h)
    below = volume.lower - box_margin * h - v
    above = v - volume.upper - box_margin * h
    out = np.maximum(below, above).max(axis=1) > 0
    if out.any():
        reasons.append(f"outside the volume: {int(out.sum())} of {len(v)} vertices more than {box_margin:g} grid "
                       f"steps outside the box [{np.round(volume.lower, 4).tolist()}, "
                       f"{np.round(volume.upper, 4).tolist()}] (world coordinates expected)")
        return reasons
    steps = np.abs(volume.sample(v, clamp=True).phi) / h
    if given is not None:      # in the given volume's own steps: its coarsest axis (a thick-slice scan's slices)
        steps = np.minimum(steps, np.abs(given.sample(v, clamp=True).phi) / float(given.spacing.max()))
    med = float(np.median(steps))
    if med > phi_tolerance:
        reasons.append(f"off the zero set: median |φ| at the vertices is {med:.3g} grid steps (> {phi_tolerance:g})")
    return reasons


def check_mesh(mesh, volume, *, box_margin: float = 3.0, phi_tolerance: float = 0.5, given=None) -> list[str]:
    """The reasons ``mesh`` (vertices, faces) is not a valid reconstruction of ``volume``'s zero set; [] if valid.

    ``given``: the (noisy) volume the method was given, when ``volume`` is the clean one (see the module
    docstring: on the zero set of either counts)."""
    v, f = _arrays(mesh)
    if len(v) == 0 or len(f) == 0:
        return ["empty: the mesh has no vertices or no faces"]
    if not np.isfinite(v).all():
        return [f"non-finite: {int((~np.isfinite(v).all(axis=1)).sum())} vertices have NaN or infinite coordinates"]
    if f.min() < 0 or f.max() >= len(v):
        return ["bad indices: faces index vertices that do not exist"]
    f = f[(f[:, 0] != f[:, 1]) & (f[:, 1] != f[:, 2]) & (f[:, 2] != f[:, 0])]
    if len(f) == 0:
        return ["empty: every face repeats a vertex"]
    reasons = _geometry_reasons(v, f, volume, box_margin, phi_tolerance, given)
    _, counts = edge_face_counts(f, len(v))
    if np.any(counts < 2):
        reasons.append(f"open: {int((counts < 2).sum())} boundary edges (not watertight)")
    if np.any(counts > 2):
        reasons.append(f"non-manifold: {int((counts > 2).sum())} edges in more than two faces")
    if not is_oriented(f, len(v)):
        reasons.append("inconsistently oriented: neighbouring faces disagree on the orientation")
    enclosed = signed_volume(v, f)
    if enclosed < 0:
        reasons.append(f"inward: the enclosed volume is negative ({enclosed:.4g}); faces must face outward")
    return reasons
