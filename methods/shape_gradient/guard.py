"""Keeping the evolving surface free of self-intersections (the paper's "diffeomorphic evolution", made true).

A check finds every face that intersects another one by two tests and takes both: MeshLab's AABB-tree test
(``pymeshlab``'s ``compute_selection_by_self_intersections_per_face``), which flags faces that only touch in a
plane, and the suite's exact pair test (:mod:`geometry.intersections`, the one the metrics count), which flags
faces that meet at coincident vertices MeshLab takes for shared ones.  A mesh the guard passes has no
intersections by either count.  The flow runs it at every remesh and before it
returns; on a hit it first *repairs* — the vertices of the intersecting faces and their 1-rings are moved toward
their ring centroids, a few rounds, re-checked — and when that does not clear it, *rolls back* to the last
checked intersection-free mesh and halves its step cap.
"""

from __future__ import annotations

import numpy as np

from geometry.intersections import self_intersection_pairs
from geometry.operators import MeshOperators

__all__ = ["count_intersections", "repair_intersections"]

_REPAIR_ROUNDS = 4


def count_intersections(x: np.ndarray, faces: np.ndarray) -> tuple[int, np.ndarray]:
    """(number of faces that intersect or touch another non-adjacent face, their indices)."""
    import pymeshlab

    ms = pymeshlab.MeshSet()
    ms.add_mesh(pymeshlab.Mesh(np.ascontiguousarray(x, dtype=np.float64), np.ascontiguousarray(faces, np.int32)))
    ms.compute_selection_by_self_intersections_per_face()
    bad = np.union1d(np.flatnonzero(ms.current_mesh().face_selection_array()),
                     np.unique(self_intersection_pairs(x, faces)))
    return int(len(bad)), bad


def repair_intersections(ops: MeshOperators, x: np.ndarray, bad_faces: np.ndarray) -> np.ndarray | None:
    """Smooth the neighbourhood of the intersecting faces until no pair intersects; None if it does not clear."""
    x = np.array(x, dtype=float)
    faces = ops.faces
    for _ in range(_REPAIR_ROUNDS):
        zone = np.unique(faces[bad_faces])
        ring = ops.ring[zone][ops.ring_valid[zone]]
        zone = np.unique(np.concatenate([zone, ring]))
        x[zone] = ops.ring_mean(x)[zone]
        n, bad_faces = count_intersections(x, faces)
        if n == 0:
            return x
    return None
