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

import os
from concurrent.futures import ThreadPoolExecutor

import numpy as np
from scipy.spatial import cKDTree

from geometry.arrays import unique_ints
from geometry.intersections import self_intersection_pairs
from geometry.operators import MeshOperators

__all__ = ["count_intersections", "repair_intersections"]

_REPAIR_ROUNDS = 8     # smoothing rounds of a repair, the zone growing by a ring each (4 left the remeshed start of
                       # the noisy cortex at N = 96, two sheets a slit apart, with 12 faces crossing; 8 clear it)
_POOL = ThreadPoolExecutor(max_workers=1, thread_name_prefix="meshlab-intersections")


def _new_pool() -> None:
    """A fresh pool in a forked child: the parent's worker thread does not exist there, and a job submitted to
    the inherited pool would wait for it forever (the local executor forks every cell from a warmed server)."""
    global _POOL
    _POOL = ThreadPoolExecutor(max_workers=1, thread_name_prefix="meshlab-intersections")


os.register_at_fork(after_in_child=_new_pool)


def _meshlab_faces(x: np.ndarray, faces: np.ndarray) -> np.ndarray:
    import pymeshlab

    ms = pymeshlab.MeshSet()
    ms.add_mesh(pymeshlab.Mesh(np.ascontiguousarray(x, dtype=np.float64), np.ascontiguousarray(faces, np.int32)))
    ms.compute_selection_by_self_intersections_per_face()
    return np.flatnonzero(ms.current_mesh().face_selection_array())


def count_intersections(x: np.ndarray, faces: np.ndarray, moved: np.ndarray | None = None
                        ) -> tuple[int, np.ndarray]:
    """(number of faces that intersect or touch another non-adjacent face, their indices).

    MeshLab's test runs in a second thread (it releases the GIL) while the exact test runs here: the check
    costs the slower of the two, not their sum.  ``moved`` (vertex indices): the mesh was intersection-free
    before only these vertices moved, so only faces near them are checked (a local patch, as in the polish).
    """
    faces = np.asarray(faces)
    ids = None
    if moved is not None:
        ids = _faces_near(x, faces, moved)
        faces = faces[ids]
        if len(faces) < 2:
            return 0, np.zeros(0, dtype=np.int64)
    import pymeshlab  # noqa: F401  (loaded on this thread: its first load in the pool's thread, after the
    #                   metrics' worker thread had run, corrupted the heap — glibc aborted at exit)
    job = _POOL.submit(_meshlab_faces, x, faces)
    bad = self_intersection_pairs(x, faces).ravel()
    bad = unique_ints(np.concatenate([job.result(), bad]))
    if ids is not None:
        bad = ids[bad]
    return int(len(bad)), bad


def _faces_near(x: np.ndarray, faces: np.ndarray, moved: np.ndarray) -> np.ndarray:
    """Indices of the faces whose bounding boxes overlap the box of the faces touching ``moved`` vertices,
    grown by the longest edge: every face a moved face could now intersect."""
    hit = np.zeros(len(x), dtype=bool)
    hit[np.asarray(moved, dtype=np.int64)] = True
    near = hit[faces].any(axis=1)
    if not near.any():
        return np.zeros(0, dtype=np.int64)
    if near.mean() > 0.2:                  # most of the mesh moved: check all of it
        return np.arange(len(faces))
    tri = x[faces]
    lo, hi = tri.min(axis=1), tri.max(axis=1)
    c = 0.5 * (lo + hi)
    half = 0.5 * np.linalg.norm(hi - lo, axis=1)          # two boxes can only meet within their half-diagonals
    idx = cKDTree(c).query_ball_point(c[near], (half[near] + half.max()) * (1 + 1e-9), return_sorted=False)
    out = np.zeros(len(faces), dtype=bool)
    out[np.concatenate([np.asarray(i, dtype=np.int64) for i in idx])] = True
    return np.flatnonzero(out | near)


def repair_intersections(ops: MeshOperators, x: np.ndarray, bad_faces: np.ndarray) -> np.ndarray | None:
    """Smooth the neighbourhood of the intersecting faces until no pair intersects; None if it does not clear.
    Each re-check looks at the smoothed patch only: every pair that met had a face in it, and no other face moved."""
    x = np.array(x, dtype=float)
    faces = ops.faces
    for _ in range(_REPAIR_ROUNDS):
        zone = unique_ints(faces[bad_faces])
        ring = ops.ring[zone][ops.ring_valid[zone]]
        zone = unique_ints(np.concatenate([zone, ring]))
        x[zone] = ops.ring_mean(x)[zone]
        n, bad_faces = count_intersections(x, faces, moved=zone)
        if n == 0:
            return x
    return None
