"""The report's 3-D viewer mesh of a cell, made in the worker: the final mesh decimated to at most
:data:`VIEW_FACES` faces (trimesh's quadric decimation, ``fast_simplification``) with the colours the viewer
offers — the mean curvature H and the signed distance to the true surface in grid steps h (positive outside) —
taken from the full mesh's nearest vertex (the map shows the reconstruction's error, not the decimation's).

Done here, beside the other artifacts, so the report (one process, after the run) only packs the arrays: the
decimation costs ≈ 30 ms a cell, ≈ 3 s of report time for the paper's grid.
"""

from __future__ import annotations

import numpy as np

__all__ = ["VIEW_FACES", "decimate", "view_arrays"]

#: faces of a decimated viewer mesh
VIEW_FACES = 1000


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


def view_arrays(vertices: np.ndarray, faces: np.ndarray, colours: dict[str, np.ndarray],
                n_faces: int = VIEW_FACES) -> dict[str, np.ndarray]:
    """``{"view_vertices", "view_faces", "view_<name>" ...}``: the decimated mesh and each per-vertex array of
    ``colours`` (one value per vertex of the full mesh) at its vertices."""
    from scipy.spatial import cKDTree

    v0, f0 = np.asarray(vertices, float), np.asarray(faces, np.int64)
    v, f = decimate(v0, f0, n_faces)
    idx = np.arange(len(v0)) if len(v) == len(v0) else cKDTree(v0).query(v)[1]
    out = {"view_vertices": v.astype(np.float32), "view_faces": f.astype(np.int32)}
    for name, values in colours.items():
        if values is not None and len(values) == len(v0):
            out[f"view_{name}"] = np.asarray(values, float)[idx].astype(np.float32)
    return out
