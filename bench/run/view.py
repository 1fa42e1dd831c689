"""The report's 3-D viewer mesh of a cell, made in the worker: the final mesh decimated (trimesh's quadric
decimation, ``fast_simplification``) to the fewest faces that still show its shape — :data:`VIEW_FACES`, doubled
until the full mesh's vertices lie within :data:`VIEW_TOLERANCE` of the box diagonal from the decimated one
(99th percentile of a seeded sample), at most :data:`MAX_VIEW_FACES` (a skull's thin bones need more faces than
a sphere) — with the colours the viewer
offers — the mean curvature H and the signed distance to the true surface in grid steps h (positive outside) —
taken from the full mesh's nearest vertex (the map shows the reconstruction's error, not the decimation's).

Done here, beside the other artifacts, so the report (one process, after the run) only packs the arrays: the
decimation's cost is spread over the cells instead of added to the report's.
"""

from __future__ import annotations

import numpy as np

__all__ = ["VIEW_FACES", "MAX_VIEW_FACES", "VIEW_TOLERANCE", "decimate", "decimate_to_tolerance", "view_arrays"]

#: faces of a decimated viewer mesh to start from
VIEW_FACES = 1000
#: ... and at most
MAX_VIEW_FACES = 32000
#: the decimated mesh is close enough when the full mesh's vertices lie within this share of the box diagonal
VIEW_TOLERANCE = 0.003
_SAMPLE = 2000


def decimate(v: np.ndarray, f: np.ndarray, faces: int = VIEW_FACES) -> tuple[np.ndarray, np.ndarray]:
    """``(vertices, faces)`` with at most ``faces`` faces (the mesh itself when it has no more, or when the
    decimator cannot take it)."""
    import trimesh

    if len(f) <= faces:
        return v, f
    m = trimesh.Trimesh(v, f, process=False)
    try:
        d = m.simplify_quadric_decimation(face_count=faces)
    except Exception:  # noqa: BLE001 — a mesh the decimator cannot take is shown in full
        return v, f
    return np.asarray(d.vertices), np.asarray(d.faces)


def decimate_to_tolerance(v: np.ndarray, f: np.ndarray, faces: int = VIEW_FACES, max_faces: int = MAX_VIEW_FACES,
                          tol: float = VIEW_TOLERANCE) -> tuple[np.ndarray, np.ndarray]:
    """:func:`decimate` to ``faces``, doubled until the 99th percentile of the distance from a seeded sample of
    the full mesh's vertices to the decimated mesh is within ``tol`` × the box diagonal (or ``max_faces``)."""
    from geometry.closest import point_mesh_distance

    v, f = np.asarray(v, float), np.asarray(f, np.int64)
    if len(v) == 0:
        return v, f
    diag = float(np.linalg.norm(np.ptp(v, axis=0)))
    rng = np.random.default_rng(0)
    sample = v[rng.choice(len(v), min(_SAMPLE, len(v)), replace=False)]
    n = faces
    while True:
        dv, df = decimate(v, f, n)
        if len(df) >= len(f) or n >= max_faces:
            return dv, df
        if float(np.percentile(point_mesh_distance(sample, dv, df), 99)) <= tol * diag:
            return dv, df
        n = min(2 * n, max_faces)


def view_arrays(vertices: np.ndarray, faces: np.ndarray, colours: dict[str, np.ndarray],
                n_faces: int = VIEW_FACES) -> dict[str, np.ndarray]:
    """``{"view_vertices", "view_faces", "view_<name>" ...}``: the decimated mesh (:func:`decimate_to_tolerance`)
    and each per-vertex array of ``colours`` (one value per vertex of the full mesh) at its vertices."""
    from scipy.spatial import cKDTree

    v0, f0 = np.asarray(vertices, float), np.asarray(faces, np.int64)
    v, f = decimate_to_tolerance(v0, f0, n_faces)
    idx = np.arange(len(v0)) if len(v) == len(v0) else cKDTree(v0).query(v)[1]
    out = {"view_vertices": v.astype(np.float32), "view_faces": f.astype(np.int32)}
    for name, values in colours.items():
        if values is not None and len(values) == len(v0):
            out[f"view_{name}"] = np.asarray(values, float)[idx].astype(np.float32)
    return out
