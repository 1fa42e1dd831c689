"""Curvature accuracy and smoothness (docs/METRICS.md): ``H_rms_err``, ``H_max_err``, ``K_rms_err``, ``H_std``,
``roughness_deg``.

Per-vertex H and K come from the one shared estimator, :func:`geometry.paraboloid_curvature` (the
paraboloid fit of docs/METHOD.md, with the linear terms), over a neighbourhood of fixed physical size:
:func:`geometry.radius_neighbors` with radius 2h (every vertex within 2h, at least the 1-ring, at most
k = :data:`geometry.MAX_NEIGHBORS` = 96: the 1-ring, then the nearest others), and area-weighted vertex normals
(:func:`geometry.vertex_normals`).  Marching cubes at N = 48..96 puts ≤ 24 vertices in a 2h ball, so k binds
only on meshes far denser than their grid, where it bounds the cost: :func:`geometry.radius_curvature` queries
and fits block by block, O(V · k) time and O(block · k) memory whatever the density.  The mesh is
made outward-facing first (normals flipped when its enclosed signed volume is negative), so H > 0 on a convex
surface whatever the method's winding.

Regions of constant true curvature (for ``H_std``), by phantom:

===============  ============================================================================
sphere           the whole surface (true H = 1/r)
fused_spheres    the two spherical caps: true H = 1/r and ≥ ``crease_band`` from the crease
cylinder         the side: true H = 1/(2r) and ≥ ``crease_band`` from the rims (the flat caps,
                 H = 0, are a different constant and are not mixed in)
ellipsoid, torus none: H varies everywhere → ``H_std`` is NaN
other phantoms   the whole surface outside the crease band if its true H is one constant there,
                 otherwise none (NaN)
no truth         all vertices (a curvature statistic of the mesh, for user volumes)
===============  ============================================================================

A vertex belongs to the region when the true H at its closest true point equals the constant (relative
tolerance 1e-9) and that point is at least ``crease_band`` from a crease.  Vertices whose fit is
undetermined (NaN) are left out of every curvature statistic.
"""

from __future__ import annotations

import numpy as np

from geometry import radius_curvature
from geometry.mesh import scored_mesh

__all__ = ["vertex_curvature", "constant_curvature_value", "curvature_metrics", "roughness_deg",
           "CONSTANT_CURVATURE"]

#: phantom name -> function of the phantom giving the true H of its constant-curvature region
CONSTANT_CURVATURE = {
    "sphere": lambda ph: 1.0 / ph.radius,
    "fused_spheres": lambda ph: 1.0 / ph.radius,
    "cylinder": lambda ph: 1.0 / (2.0 * ph.radius),
}

_NO_CONSTANT = {"ellipsoid", "torus"}


def vertex_curvature(vertices, faces: np.ndarray | None, spacing: float, outward: bool = True
                     ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Mean and Gaussian curvature and unit normal per vertex, by the shared estimator over the 2h neighbourhood.

    At most :data:`geometry.MAX_NEIGHBORS` = 96 neighbours per vertex, the 1-ring first, then the nearest (see
    the module doc): O(V · 96) time and bounded memory.

    Parameters
    ----------
    vertices : geometry.mesh.ScoredMesh or numpy.ndarray, shape (V, 3)
        The mesh (its cached vertex normals and edges are used), or its vertices.
    faces : numpy.ndarray of int, shape (F, 3) or None
        The triangles, with a vertex array; None with a ScoredMesh.
    spacing : float
        The grid spacing h; the neighbourhood radius is 2h.
    outward : bool
        Whether the winding faces outward: True takes the normals as wound, False flips them (for a mesh wound
        inward), which flips the sign of H.  Pass ``mesh.outward`` to orient by the enclosed volume.

    Returns
    -------
    H, K : numpy.ndarray, shape (V,)
    normals : numpy.ndarray, shape (V, 3)
    """
    m = scored_mesh(vertices, faces)
    # the cached normals face outward by the signed volume; as wound they differ in sign when that is negative
    normals = m.vertex_normals if m.outward == bool(outward) else -m.vertex_normals
    # a vertex whose faces all have zero area has no normal: its H, K come out NaN (by design, quietly)
    with np.errstate(invalid="ignore", divide="ignore"):
        H, K = radius_curvature(m.vertices, m.faces, 2.0 * float(spacing), normals, linear=True, edges=m.edges)
    return H, K, normals


def constant_curvature_value(phantom, H_true: np.ndarray, ok: np.ndarray) -> float | None:
    """The true H of the phantom's constant-curvature region, the reference of ``H_std`` (see the module doc).

    Parameters
    ----------
    phantom : phantoms.Phantom
        The phantom; a named one is looked up in :data:`CONSTANT_CURVATURE`.
    H_true : numpy.ndarray, shape (P,)
        The true mean curvature at the vertices' closest true points.
    ok : numpy.ndarray of bool, shape (P,)
        The vertices to consider (outside the crease band); any other phantom has a constant-curvature region
        when ``H_true`` is one constant over them.

    Returns
    -------
    float or None
        None when the phantom has no such region.
    """
    name = getattr(phantom, "name", "")
    if name in CONSTANT_CURVATURE:
        return float(CONSTANT_CURVATURE[name](phantom))
    if name in _NO_CONSTANT:
        return None
    h = H_true[ok & np.isfinite(H_true)]
    if len(h) and np.allclose(h, h[0], rtol=1e-9, atol=1e-12):
        return float(h[0])
    return None


def _rms(x: np.ndarray) -> float:
    return float(np.sqrt(np.mean(x * x))) if len(x) else float("nan")


def curvature_metrics(H: np.ndarray, K: np.ndarray, truth=None, phantom=None,
                      crease_band: float = 0.1) -> dict:
    """Curvature errors against the truth at the vertices' closest true points, and ``H_std``.

    ``truth`` is the :class:`phantoms.Truth` of the vertices (None → only ``H_std`` over all vertices).
    """
    fin = np.isfinite(H)
    if truth is None:
        return {"H_std": float(np.std(H[fin])) if fin.any() else float("nan")}
    away = truth.crease_distance >= crease_band
    mh = away & fin & np.isfinite(truth.H)
    mk = away & np.isfinite(K) & np.isfinite(truth.K)
    eh = H[mh] - truth.H[mh]
    ek = K[mk] - truth.K[mk]
    out = {
        "H_rms_err": _rms(eh),
        "H_max_err": float(np.max(np.abs(eh))) if len(eh) else float("nan"),
        "K_rms_err": _rms(ek),
    }
    hc = constant_curvature_value(phantom, truth.H, away)
    if hc is None:
        out["H_std"] = float("nan")
    else:
        region = mh & np.isclose(truth.H, hc, rtol=1e-9, atol=1e-12)
        out["H_std"] = float(np.std(H[region])) if region.any() else float("nan")
    return out


def roughness_deg(vertices, faces: np.ndarray | None = None, face_normals: np.ndarray | None = None,
                  vertex_ok: np.ndarray | None = None) -> float:
    """Mean angle (degrees) between the normals of the two faces of every edge shared by exactly two
    faces; edges touching a vertex with ``vertex_ok`` False (near a crease) and faces of zero area are
    left out.

    Parameters
    ----------
    vertices : geometry.mesh.ScoredMesh or numpy.ndarray, shape (V, 3)
        The mesh (its cached edge → face adjacency is used), or its vertices.
    faces : numpy.ndarray of int, shape (F, 3), optional
        The triangles, with a vertex array.
    face_normals : numpy.ndarray, shape (F, 3), optional
        Unit face normals; default the mesh's outward ones.
    vertex_ok : numpy.ndarray of bool, shape (V,), optional
        The vertices whose edges count; default all.

    Returns
    -------
    float
        NaN when no edge counts.
    """
    m = scored_mesh(vertices, faces)
    face_normals = m.face_normals if face_normals is None else face_normals
    pairs, ev = m.edge_face_pairs
    nonzero = np.linalg.norm(face_normals, axis=1) > 0
    keep = nonzero[pairs[:, 0]] & nonzero[pairs[:, 1]]
    if vertex_ok is not None:
        keep &= vertex_ok[ev[:, 0]] & vertex_ok[ev[:, 1]]
    if not keep.any():
        return float("nan")
    n1, n2 = face_normals[pairs[keep, 0]], face_normals[pairs[keep, 1]]
    # atan2 form: accurate for small angles (arccos loses half the digits near 0)
    ang = np.arctan2(np.linalg.norm(np.cross(n1, n2), axis=1), np.einsum("ij,ij->i", n1, n2))
    return float(np.degrees(ang).mean())
