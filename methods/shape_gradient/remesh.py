"""Isotropic remeshing during the flow (Botsch & Kobbelt 2004, via ``gpytoolbox.remesh_botsch``).

Split edges longer than 4/3 ℓ, collapse those shorter than 4/5 ℓ, flip toward valence 6, relax tangentially and
project back onto the mesh as it was: the surface keeps its shape while its triangles stay near ℓ, so a sphere
shrinking onto a bunny gains vertices where it must reach into the ears and never stretches or crumples.
The result is checked — one closed, consistently oriented genus-0 surface — and refused otherwise (the flow
then keeps its mesh).  A mesh whose edges are still the remesher's but which has a few small angles is *touched up*
instead (:func:`touch_up`): only patches around those triangles are remeshed, their rims held.  Vertices passed as
``keep`` are the remesher's feature vertices: never collapsed or moved (the flow passes the held tips of sharply
convex parts, which the collapses otherwise shorten on a thin limb).
"""

from __future__ import annotations

import warnings

import numpy as np

from geometry.mesh import corner_angles
from geometry.topology import edge_face_counts, is_sphere_like

__all__ = ["remesh", "is_sphere_like", "drift", "touch_up", "smallest_angle"]

#: a periodic remesh is due when more than this share of the edges is longer than 4/3 of the target (what the
#: remesher splits) ...
LONG_EDGE_SHARE = 0.01
#: ... or more than this share shorter than 4/5 of it (what the remesher collapses; a fresh remesh leaves 5–10 %) ...
SHORT_EDGE_SHARE = 0.2
#: ... or a triangle has an angle below this many degrees
MIN_ANGLE_DEGREES = 30.0
#: a touch-up remeshes the triangles with an angle below this (a margin over :data:`MIN_ANGLE_DEGREES`: a patch
#: remeshed only up to it leaves its neighbours just above it) ...
TOUCH_UP_ANGLE_DEGREES = 33.0
#: ... with this many rings of faces around them (a narrower patch's held rim makes slivers of its own) ...
TOUCH_UP_RINGS = 3
#: ... and again, up to this many passes, while an angle below MIN_ANGLE_DEGREES is left
TOUCH_UP_PASSES = 3
#: a mesh with more than this share of its faces to touch up is remeshed whole
TOUCH_UP_MAX_SHARE = 0.01
#: the remesher's rounds on a touched-up patch (a patch is small: the rounds cost nothing)
TOUCH_UP_ROUNDS = 3


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


def _edge_lengths2(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """The squared lengths of each face's three edges (F, 3)."""
    P = vertices[faces]
    E = P[:, [1, 2, 0]] - P
    return np.einsum("fkd,fkd->fk", E, E)


def smallest_angle(vertices: np.ndarray, faces: np.ndarray) -> float:
    """The mesh's smallest corner angle, in degrees."""
    return float(corner_angles(vertices, faces).min()) if len(faces) else 180.0


def drift(vertices: np.ndarray, faces: np.ndarray, edge_length: float) -> str | None:
    """How the mesh has drifted from the isotropic mesh the remesher makes: ``"edges"`` when more than
    :data:`LONG_EDGE_SHARE` of its edges are longer than 4/3 ``edge_length`` (the remesher's split threshold) or
    more than :data:`SHORT_EDGE_SHARE` shorter than 4/5 of it (its collapse threshold: a shrinking surface);
    ``"angles"`` when only some triangle has an angle below :data:`MIN_ANGLE_DEGREES`; None when it has not.  A
    flow whose surface moves a fraction of a voxel keeps its triangles; a remesh of such a mesh moves every vertex
    a little and costs as much as several iterations, for nothing."""
    L2 = _edge_lengths2(vertices, faces)
    if np.mean(L2 > (4.0 / 3.0 * edge_length) ** 2) > LONG_EDGE_SHARE:   # each edge counted from both faces
        return "edges"
    if np.mean(L2 < (0.8 * edge_length) ** 2) > SHORT_EDGE_SHARE:
        return "edges"
    return "angles" if smallest_angle(vertices, faces) < MIN_ANGLE_DEGREES else None


def touch_up(vertices: np.ndarray, faces: np.ndarray, edge_length: float, keep: np.ndarray | None = None
             ) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """(vertices, faces, the kept vertices' new indices) with the triangles that have an angle below
    :data:`TOUCH_UP_ANGLE_DEGREES` remeshed in patches (:data:`TOUCH_UP_RINGS` rings of faces around them, the
    patches' rims and ``keep`` held), pass after pass while an angle below :data:`MIN_ANGLE_DEGREES` is left; None
    when that does not clear them, when more than :data:`TOUCH_UP_MAX_SHARE` of the faces would be touched (the
    caller remeshes the whole mesh), or when the result is not sphere-like.  On a mesh of half a million faces a
    few triangles under 30° are always there; remeshing it whole for them costs seconds."""
    x = np.ascontiguousarray(vertices, dtype=np.float64)
    f = np.asarray(faces, dtype=np.int64)
    keep = np.zeros(0, dtype=np.int64) if keep is None else np.asarray(keep, dtype=np.int64)
    small = corner_angles(x, f).min(axis=1)                 # each face's smallest angle
    for _ in range(TOUCH_UP_PASSES):
        if small.min() >= MIN_ANGLE_DEGREES:
            break
        bad = small < TOUCH_UP_ANGLE_DEGREES
        if bad.mean() > TOUCH_UP_MAX_SHARE:
            return None
        out = _remesh_patches(x, f, bad, edge_length, keep)
        if out is None:
            return None
        x, f, keep, outside = out
        # the faces outside the patches come first, unchanged: only the patches' angles are new
        small = np.concatenate([small[outside], corner_angles(x, f[int(outside.sum()):]).min(axis=1)])
    if small.min() < MIN_ANGLE_DEGREES:
        return None
    if not np.isfinite(x).all() or not is_sphere_like(f, len(x)):
        return None
    return x, f, keep


def _remesh_patches(x: np.ndarray, f: np.ndarray, bad: np.ndarray, edge_length: float, keep: np.ndarray):
    """One touch-up pass: the faces within :data:`TOUCH_UP_RINGS` rings of the ``bad`` ones remeshed as one open
    mesh, its rim vertices and ``keep`` held (the remesher's feature vertices: they come first in its output), and
    stitched back in place of the patch.  (vertices, faces — those outside the patch first, in their order —,
    keep's new indices, the mask of the faces outside the patch), or None."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        import gpytoolbox

    grown = np.zeros(len(x), dtype=bool)
    grown[f[bad].ravel()] = True
    for _ in range(TOUCH_UP_RINGS):
        grown[f[grown[f].any(axis=1)].ravel()] = True
    in_patch = grown[f].all(axis=1)
    patch = f[in_patch]
    used = np.unique(patch)
    local = np.full(len(x), -1, dtype=np.int64)
    local[used] = np.arange(len(used))
    pf = local[patch]
    edges, on_faces = edge_face_counts(pf, len(used))       # the rim: the patch's edges on one patch face only
    rim = np.unique(edges[on_faces == 1])
    held_local = np.unique(np.concatenate([rim, local[keep][local[keep] >= 0]]))
    try:
        U, G = _botsch(x[used], pf.astype(np.int32), TOUCH_UP_ROUNDS, float(edge_length), gpytoolbox, True,
                       held_local)
    except ValueError:
        return None
    U, G = np.asarray(U, dtype=np.float64), np.asarray(G, dtype=np.int64)
    n_held = len(held_local)
    if len(U) < n_held or not np.array_equal(U[:n_held], x[used[held_local]]):   # the rim must stay put
        return None
    # stitched: every vertex outside the patch's interior keeps its place (renumbered), the new interior appended
    stays = np.ones(len(x), dtype=bool)
    stays[used] = False
    stays[used[held_local]] = True
    new_index = np.full(len(x), -1, dtype=np.int64)
    new_index[stays] = np.arange(int(stays.sum()))
    to_new = np.concatenate([new_index[used[held_local]], int(stays.sum()) + np.arange(len(U) - n_held)])
    X = np.concatenate([x[stays], U[n_held:]])
    F = np.concatenate([new_index[f[~in_patch]], to_new[G]])
    return X, F, new_index[keep], ~in_patch
