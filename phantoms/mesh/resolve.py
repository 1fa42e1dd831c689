"""A closed mesh whose sheets cross or nest, resolved to the boundary of the solid it encloses.

A closed, consistently oriented triangle mesh assigns every point of space an integer winding number ``w``: 1 inside
and 0 outside where it bounds one solid.  Where its parts cross (a posed body's thighs, a leg through a shell) or a
closed sheet lies inside another with the same orientation, some regions have ``w = 2`` and sheets lie inside the
solid; the closest sheet to a point there may be an inner one, so a pseudonormal sign reads *outside* in the body.

The suite takes the solid ``{w ≥ ½}`` (for a closed mesh: ``w ≥ 1``) — the inside of a generalised winding number,
the convention of the field's many-shape experiments — and its boundary as the truth.  The boundary is built by
libigl's exact mesh boolean (through pymeshlab's ``generate_boolean_union``), which splits every crossing exactly,
labels each cell of space with its winding number and keeps the faces between ``w ≥ 1`` and ``w < 1``.  The union
is taken with a tiny tetrahedron far from the mesh (a union needs two operands; a far one changes nothing), whose
faces are then dropped.  The result is checked closed, consistently oriented and free of crossings; where it is not,
:func:`solid_boundary` refuses the mesh, naming what failed.

Regions of negative winding number (an inward-oriented part outside everything) enclose nothing in this convention:
their sheets vanish from the resolved surface.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from geometry.arrays import unique_ints
from geometry.errors import InputError
from geometry.intersections import crossing_pairs
from geometry.mesh import signed_volume
from geometry.topology import connected_components, directed_edge_repeats, edge_face_counts

from .closest import winding_number

__all__ = ["Resolution", "winding_layers", "solid_boundary", "resolve_if_needed"]


@dataclass(frozen=True)
class Resolution:
    """What resolving a mesh to its ``w ≥ ½`` solid changed.

    crossing_faces : faces of the input that cross a face they share no vertex with
    nested_components : closed components of the input lying inside another with the same orientation (w = 2)
    faces_in, faces_out : face counts before and after
    volume_in : ∫ w dV of the input (its signed volume: overlaps counted as often as they are wound)
    volume_out : the volume of the resolved solid
    """

    crossing_faces: int
    nested_components: int
    faces_in: int
    faces_out: int
    volume_in: float
    volume_out: float

    @property
    def volume_change(self) -> float:
        """(volume_out − volume_in) / volume_in: the share of the signed volume that was overlap."""
        return (self.volume_out - self.volume_in) / self.volume_in

    def note(self) -> str:
        """One line for a phantom's description and the ``info`` command."""
        why = []
        if self.crossing_faces:
            why.append(f"{self.crossing_faces:,} crossing faces")
        if self.nested_components:
            why.append(f"{self.nested_components} nested shell{'s' if self.nested_components > 1 else ''}")
        return (f"resolved to the boundary of its winding-number ≥ ½ solid ({', '.join(why)}; "
                f"{self.faces_in:,} → {self.faces_out:,} faces; volume {100 * self.volume_change:+.3g} % "
                "against the signed volume of the input)")

    def as_dict(self) -> dict:
        return {"crossing_faces": self.crossing_faces, "nested_components": self.nested_components,
                "faces_in": self.faces_in, "faces_out": self.faces_out,
                "volume_change": round(float(self.volume_change), 8)}


def winding_layers(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """For a closed, oriented mesh that does not cross itself: the winding number of the *other* components at each
    component (``(C,)`` integers; 0 for a component outside all others).  Such a mesh bounds one solid exactly when
    every component's two sides have winding numbers 0 and 1: an outward component (positive signed volume) needs
    0 here, an inward one (a cavity's wall) 1.

    Each component lies in one cell of the others (no crossings), so one of its vertices tells: the winding number
    of the whole mesh there (gpytoolbox's fast winding number) less the component's own (exact), rounded.
    """
    v = np.asarray(vertices, float)
    f = np.asarray(faces, np.int64)
    _, labels = connected_components(f, len(v), by="vertex")
    face_label = labels[f[:, 0]]
    comps = unique_ints(face_label)
    if len(comps) < 2:
        return np.zeros(len(comps), np.int64)
    from gpytoolbox import fast_winding_number
    first_face = np.searchsorted(np.sort(face_label), comps)
    order = np.argsort(face_label, kind="stable")
    points = v[f[order[first_face], 0]]
    total = fast_winding_number(points, v, f.astype(np.int32))
    own = np.array([winding_number(v, f[face_label == c], points[i:i + 1])[0] for i, c in enumerate(comps)])
    return np.rint(total - own).astype(np.int64)


def _nested_components(v: np.ndarray, f: np.ndarray) -> int:
    """How many components have a side whose winding number is outside {0, 1} (see :func:`winding_layers`)."""
    layers = winding_layers(v, f)
    if len(layers) < 2:
        return 0
    _, labels = connected_components(f, len(v), by="vertex")
    face_label = labels[f[:, 0]]
    comps = unique_ints(face_label)
    own = np.array([np.sign(signed_volume(v, f[face_label == c])) for c in comps])
    inner = layers + own
    return int(np.count_nonzero((layers < 0) | (layers > 1) | (inner < 0) | (inner > 1)))


def solid_boundary(vertices: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The boundary of ``{w ≥ ½}`` of a closed, outward-oriented mesh (see the module docstring), checked closed,
    consistently oriented and free of crossings.

    Raises
    ------
    InputError
        When the boolean fails or its result is not such a surface, naming why.
    """
    import pymeshlab

    v = np.asarray(vertices, float)
    f = np.asarray(faces, np.int64)
    lo, hi = v.min(axis=0), v.max(axis=0)
    size = float((hi - lo).max())
    far = hi + 4.0 * size                                    # beyond every vertex on all three axes
    tet_v = far + 1e-3 * size * np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], float)
    tet_f = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]], np.int64)
    ms = pymeshlab.MeshSet()
    ms.add_mesh(pymeshlab.Mesh(v, f.astype(np.int32)))
    ms.add_mesh(pymeshlab.Mesh(tet_v, tet_f.astype(np.int32)))
    try:
        ms.generate_boolean_union(first_mesh=0, second_mesh=1)
    except Exception as exc:  # noqa: BLE001 — pymeshlab raises its own PyMeshLabException and others
        raise InputError(f"resolving its crossings failed: the mesh boolean (libigl through pymeshlab) raised "
                         f"{type(exc).__name__}: {exc}") from None
    out = ms.current_mesh()
    rv = np.asarray(out.vertex_matrix(), float)
    rf = np.asarray(out.face_matrix(), np.int64)
    keep = ~(rv[rf] > hi + 2.0 * size).all(axis=(1, 2))      # the tetrahedron's faces are all beyond 2 · size
    if (~keep).sum() != 4:
        raise InputError(f"resolving its crossings failed: the boolean's result holds {(~keep).sum()} faces of the "
                         "far tetrahedron instead of 4")
    rf = rf[keep]
    used = unique_ints(rf.ravel())
    remap = np.full(len(rv), -1, np.int64)
    remap[used] = np.arange(len(used))
    rv, rf = rv[used], remap[rf]
    if len(rf) < 4:
        raise InputError("resolving its crossings left no surface: the mesh encloses no region of winding "
                         "number ≥ 1 (is it oriented inward where its parts cross?)")
    _, counts = edge_face_counts(rf, len(rv))
    if (counts != 2).any() or directed_edge_repeats(rf, len(rv)):
        raise InputError(f"resolving its crossings failed: the boolean's result is not closed and consistently "
                         f"oriented ({int((counts != 2).sum())} edges not in exactly two faces)")
    left = crossing_pairs(rv, rf)
    if len(left) and _meshlab_crossing_faces(rv, rf):
        raise InputError(f"resolving its crossings failed: {len(unique_ints(left))} faces of the boolean's result "
                         "still cross")
    return rv, rf


def _meshlab_crossing_faces(v: np.ndarray, f: np.ndarray) -> int:
    """MeshLab's count of self-intersecting faces: the second opinion on the boolean's result where the suite's
    test (:func:`geometry.intersections.crossing_pairs`, a floating-point test whose shrink is relative to each
    triangle) still finds pairs — slivers the exact boolean leaves where sheets met can touch without crossing."""
    import pymeshlab

    ms = pymeshlab.MeshSet()
    ms.add_mesh(pymeshlab.Mesh(v, f.astype(np.int32)))
    ms.compute_selection_by_self_intersections_per_face()
    return int(ms.current_mesh().selected_face_number())


def resolve_if_needed(vertices: np.ndarray, faces: np.ndarray, n_components: int | None = None
                      ) -> tuple[np.ndarray, np.ndarray, Resolution | None]:
    """``(vertices, faces, None)`` for a closed, outward-oriented mesh that bounds one solid as it is; else the
    boundary of its ``w ≥ ½`` solid (:func:`solid_boundary`) and what changed.  The crossing test always runs; the
    nesting test only for a mesh of several components; the boolean only when one of them finds something."""
    v = np.asarray(vertices, float)
    f = np.asarray(faces, np.int64)
    pairs = crossing_pairs(v, f)
    n_cross = len(unique_ints(pairs)) if len(pairs) else 0
    nested = 0
    if not n_cross and (n_components is None or n_components > 1):
        nested = _nested_components(v, f)
    if not n_cross and not nested:
        return v, f, None
    rv, rf = solid_boundary(v, f)
    res = Resolution(n_cross, nested, len(f), len(rf), float(signed_volume(v, f)), float(signed_volume(rv, rf)))
    return rv, rf, res
