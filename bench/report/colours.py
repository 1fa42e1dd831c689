"""One colour per method label, the same in every chart of every report: the built-in methods have fixed
colours, any other label gets one from its name's hash (stable across runs and machines)."""

from __future__ import annotations

import hashlib

__all__ = ["method_colour", "PALETTE"]

#: Tableau-20-like palette: the first entries go to the built-in methods, by name
PALETTE = ("#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2", "#7f7f7f", "#bcbd22",
           "#17becf", "#393b79", "#637939", "#8c6d31", "#843c39", "#7b4173", "#3182bd", "#e6550d", "#31a354",
           "#756bb1", "#636363")
_FIXED = {"shape_gradient": 0, "marching_cubes": 1, "mc_taubin": 2, "distmesh": 3, "poisson": 4, "flying_edges": 5,
          "reach_for_the_spheres": 6, "dual_contouring": 7, "shape_gradient[paper]": 8,
          "shape_gradient[paper+fixes]": 9, "reach_for_the_arcs": 10}


def method_colour(label: str) -> str:
    """The colour of a method label (hex): fixed for the built-ins, else from a hash of the label."""
    label = str(label)
    if label in _FIXED:
        return PALETTE[_FIXED[label]]
    digest = int(hashlib.sha1(label.encode()).hexdigest(), 16)
    return PALETTE[len(_FIXED) + digest % (len(PALETTE) - len(_FIXED))]
