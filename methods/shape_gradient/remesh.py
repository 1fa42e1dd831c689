"""Isotropic remeshing during the flow (Botsch & Kobbelt 2004, via ``gpytoolbox.remesh_botsch``).

Split edges longer than 4/3 ℓ, collapse those shorter than 4/5 ℓ, flip toward valence 6, relax tangentially and
project back onto the mesh as it was: the surface keeps its shape while its triangles stay near ℓ, so a sphere
shrinking onto a bunny gains vertices where it must reach into the ears and never stretches or crumples.
The result is checked — one closed, consistently oriented genus-0 surface — and refused otherwise (the flow
then keeps its mesh).
"""

from __future__ import annotations

import warnings

import numpy as np

from geometry.topology import is_sphere_like

__all__ = ["remesh", "is_sphere_like"]


def remesh(vertices: np.ndarray, faces: np.ndarray, edge_length: float, iterations: int = 3
           ) -> tuple[np.ndarray, np.ndarray] | None:
    """The mesh remeshed toward edge length ``edge_length`` (world units), or None when the remesher's output
    is not sphere-like (:func:`is_sphere_like`) and the caller should keep its mesh."""
    with warnings.catch_warnings():      # gpytoolbox's own imports use deprecated numpy paths
        warnings.simplefilter("ignore", DeprecationWarning)
        import gpytoolbox

    try:
        U, G = gpytoolbox.remesh_botsch(np.ascontiguousarray(vertices, dtype=np.float64),
                                        np.ascontiguousarray(faces, dtype=np.int32), int(iterations),
                                        float(edge_length), True)
    except ValueError:  # the remesher refuses non-manifold input
        return None
    U = np.asarray(U, dtype=np.float64)
    G = np.asarray(G, dtype=np.int64)
    if not np.isfinite(U).all() or not is_sphere_like(G, len(U)):
        return None
    return U, G
