"""Isotropic remeshing during the flow (Botsch & Kobbelt 2004, via ``gpytoolbox.remesh_botsch``).

Split edges longer than 4/3 ℓ, collapse those shorter than 4/5 ℓ, flip toward valence 6, relax tangentially and
project back onto the mesh as it was: the surface keeps its shape while its triangles stay near ℓ, so a sphere
shrinking onto a bunny gains vertices where it must reach into the ears and never stretches or crumples.
The result is checked — one closed, consistently oriented genus-0 surface — and refused otherwise (the flow
then keeps its mesh).  Vertices passed as ``keep`` are the remesher's feature vertices: never collapsed or moved
(the flow passes the held tips of sharply convex parts, which the collapses otherwise shorten on a thin limb).
"""

from __future__ import annotations

import warnings

import numpy as np

from geometry.topology import is_sphere_like

__all__ = ["remesh", "is_sphere_like", "needs_remesh"]

#: a periodic remesh is due when more than this share of the edges is longer than 4/3 of the target (what the
#: remesher splits) ...
LONG_EDGE_SHARE = 0.01
#: ... or more than this share shorter than 4/5 of it (what the remesher collapses; a fresh remesh leaves 5–10 %) ...
SHORT_EDGE_SHARE = 0.2
#: ... or a triangle has an angle below this many degrees
MIN_ANGLE_DEGREES = 30.0


def _botsch(V: np.ndarray, F: np.ndarray, iterations: int, edge_length: float, gpytoolbox, closed: bool = False,
            keep: np.ndarray | None = None):
    """gpytoolbox's Botsch–Kobbelt remesher.  The flow's meshes are closed and manifold (checked after every
    remesh), so its C++ kernel is called directly when this gpytoolbox has the known one: the public wrapper's
    input checks (boundary vertices, non-manifold edges: two ``np.unique`` over all edges) cost a third of the
    remesh at 34k vertices.  Any other input, or another gpytoolbox, goes through the public wrapper.  ``keep``: the
    feature vertices (the kernel wants them first: the mesh is reordered so, as the wrapper does)."""
    keep = np.zeros(0, dtype=np.int32) if keep is None else np.unique(np.asarray(keep, dtype=np.int32))
    if len(keep):
        order = np.concatenate([keep, np.delete(np.arange(len(V), dtype=np.int32), keep)])
        rank = np.empty(len(V), dtype=np.int32)
        rank[order] = np.arange(len(V), dtype=np.int32)
        V, F = np.ascontiguousarray(V[order]), np.ascontiguousarray(rank[F])
        keep = np.arange(len(keep), dtype=np.int32)
    try:
        from gpytoolbox_bindings import _remesh_botsch_cpp_impl
    except ImportError:
        _remesh_botsch_cpp_impl = None
    if _remesh_botsch_cpp_impl is not None and (closed or is_sphere_like(F, len(V))):
        try:
            return _remesh_botsch_cpp_impl(V, F, iterations, edge_length, keep,
                                           np.zeros((0, 2), dtype=np.int32), True)
        except TypeError:     # another signature: use the public function
            pass
    return gpytoolbox.remesh_botsch(V, F, iterations, edge_length, True, feature=keep)


def remesh(vertices: np.ndarray, faces: np.ndarray, edge_length: float, iterations: int = 3, *,
           closed: bool = False, keep: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray] | None:
    """The mesh remeshed toward edge length ``edge_length`` (world units), or None when the remesher's output
    is not sphere-like (:func:`is_sphere_like`) and the caller should keep its mesh.  ``closed=True``: the
    caller knows the input is one closed manifold surface (the flow's meshes are), so it is not re-checked.
    ``keep``: indices of vertices the remesher must keep where they are (they come first in the output)."""
    with warnings.catch_warnings():      # gpytoolbox's own imports use deprecated numpy paths
        warnings.simplefilter("ignore", DeprecationWarning)
        import gpytoolbox

    V = np.ascontiguousarray(vertices, dtype=np.float64)
    F = np.ascontiguousarray(faces, dtype=np.int32)
    try:
        U, G = _botsch(V, F, int(iterations), float(edge_length), gpytoolbox, closed, keep)
    except ValueError:  # the remesher refuses non-manifold input
        return None
    U = np.asarray(U, dtype=np.float64)
    G = np.asarray(G, dtype=np.int64)
    if not np.isfinite(U).all() or not is_sphere_like(G, len(U)):
        return None
    return U, G


def needs_remesh(vertices: np.ndarray, faces: np.ndarray, edge_length: float) -> bool:
    """Whether the mesh has drifted from the isotropic mesh the remesher makes: more than :data:`LONG_EDGE_SHARE`
    of its edges longer than 4/3 ``edge_length`` (the remesher's split threshold), more than
    :data:`SHORT_EDGE_SHARE` shorter than 4/5 of it (its collapse threshold: a shrinking surface), or an angle below
    :data:`MIN_ANGLE_DEGREES`.  A flow whose surface moves a fraction of a voxel keeps its triangles; a remesh
    of such a mesh moves every vertex a little and costs as much as several iterations, for nothing."""
    P = vertices[faces]
    E = np.stack([P[:, 2] - P[:, 1], P[:, 0] - P[:, 2], P[:, 1] - P[:, 0]], axis=1)     # edge opposite corner k
    L2 = np.einsum("fkd,fkd->fk", E, E)
    if np.mean(L2 > (4.0 / 3.0 * edge_length) ** 2) > LONG_EDGE_SHARE:   # each edge counted from both faces
        return True
    if np.mean(L2 < (0.8 * edge_length) ** 2) > SHORT_EDGE_SHARE:
        return True
    # the angle at corner k: cos = −(e_{k+1} · e_{k+2}) / (|e_{k+1}| |e_{k+2}|)
    dots = -np.einsum("fkd,fkd->fk", np.roll(E, -1, axis=1), np.roll(E, -2, axis=1))
    cos = dots / np.sqrt(np.roll(L2, -1, axis=1) * np.roll(L2, -2, axis=1))
    return bool(np.nanmax(cos) > np.cos(np.radians(MIN_ANGLE_DEGREES)))
