"""The initial surface: the paper's sphere or a user's closed genus-0 mesh, checked; the snapshot list."""

from __future__ import annotations

import numpy as np
import trimesh

from geometry.sphere import fibonacci_sphere
from geometry.topology import connected_components, edge_face_counts, euler_characteristic, genus, is_oriented
from phantoms import InputError, Volume

__all__ = ["parse_snapshots", "prepare_init_mesh", "initial_surface"]


def parse_snapshots(value) -> tuple[int, ...]:
    if value is None or (isinstance(value, str) and value.strip().lower() in ("", "none")):
        return ()
    if isinstance(value, str):
        items = [v for v in value.replace(";", ",").replace(" ", ",").split(",") if v]
    elif isinstance(value, (int, np.integer)):
        items = [value]
    else:
        try:
            items = list(value)
        except TypeError:
            raise InputError(f"method 'shape_gradient', parameter 'snapshots': expected iteration numbers, "
                             f"got {value!r}") from None
    out = []
    for v in items:
        try:
            f = float(v)
        except (TypeError, ValueError):
            raise InputError(f"method 'shape_gradient', parameter 'snapshots': {v!r} is not an iteration "
                             "number") from None
        if f != int(f) or f < 0:
            raise InputError(f"method 'shape_gradient', parameter 'snapshots': {v!r} is not an iteration "
                             "number (>= 0)")
        out.append(int(f))
    return tuple(sorted(set(out)))


def prepare_init_mesh(mesh) -> tuple[np.ndarray, np.ndarray, bool]:
    """Validate a user's initial mesh: (vertices, faces, flipped).

    Accepts a ``trimesh.Trimesh``, a ``(vertices, faces)`` pair or a path trimesh can load.  Raises
    InputError unless the mesh is a single closed, consistently oriented, genus-0 surface without
    degenerate faces; an inward-oriented mesh is flipped (``flipped`` = True).
    """
    where = "method 'shape_gradient', parameter 'init_mesh'"
    if isinstance(mesh, str):
        try:
            mesh = trimesh.load(mesh, force="mesh", process=False)
        except Exception as exc:  # noqa: BLE001 - any loader failure is a user error here
            raise InputError(f"{where}: cannot load {mesh!r}: {exc}") from None
    if isinstance(mesh, trimesh.Trimesh):
        v, f = np.asarray(mesh.vertices, float), np.asarray(mesh.faces)
    else:
        try:
            v, f = mesh
            v = np.asarray(v, dtype=float)
            f = np.asarray(f)
        except (TypeError, ValueError):
            raise InputError(f"{where}: expected a trimesh.Trimesh, a (vertices, faces) pair or a path; "
                             f"got {type(mesh).__name__}") from None
    if v.ndim != 2 or v.shape[1] != 3 or f.ndim != 2 or f.shape[1] != 3 or len(f) == 0:
        raise InputError(f"{where}: vertices must be (V, 3) and faces (F, 3); got {v.shape} and {f.shape}")
    if not np.issubdtype(f.dtype, np.integer):
        if not np.all(f == np.round(f)):
            raise InputError(f"{where}: faces must hold integer vertex indices")
        f = f.astype(np.int64)
    f = f.astype(np.int64)
    if not np.isfinite(v).all():
        raise InputError(f"{where}: vertices contain NaN or inf")
    if f.min() < 0 or f.max() >= len(v):
        raise InputError(f"{where}: face indices out of range [0, {len(v) - 1}]")
    used = np.unique(f)
    if len(used) != len(v):
        raise InputError(f"{where}: {len(v) - len(used)} vertices are not used by any face")
    if np.any((f[:, 0] == f[:, 1]) | (f[:, 1] == f[:, 2]) | (f[:, 0] == f[:, 2])):
        raise InputError(f"{where}: some faces repeat a vertex")
    # every undirected edge in exactly two faces, once in each direction (closed and consistently oriented)
    _, counts = edge_face_counts(f, len(v))
    if np.any(counts != 2):
        bad = int((counts != 2).sum())
        raise InputError(f"{where}: the mesh is not closed — {bad} edges are not shared by exactly two faces "
                         "(the method needs a closed surface)")
    if not is_oriented(f, len(v)):
        raise InputError(f"{where}: the faces are not consistently oriented")
    euler = euler_characteristic(f, len(v))
    n_comp, _ = connected_components(f, len(v), by="face")
    if n_comp != 1:
        raise InputError(f"{where}: the mesh has {n_comp} connected components; the method needs one surface")
    if euler != 2:
        raise InputError(f"{where}: the mesh has Euler characteristic {euler} (genus {genus(euler)}); "
                         "the method needs a genus-0 (sphere-like) surface")
    cross = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    dbl = np.linalg.norm(cross, axis=1)
    if np.any(dbl <= 1e-12 * max(1.0, float(np.ptp(v, axis=0).max())) ** 2):
        raise InputError(f"{where}: {int((dbl <= 0).sum()) or 'some'} faces are degenerate (zero area)")
    signed_volume = float(np.einsum("ij,ij->i", v[f[:, 0]], cross).sum() / 6.0)
    flipped = signed_volume < 0
    if flipped:
        f = f[:, ::-1].copy()
    return v.copy(), np.ascontiguousarray(f), flipped




def initial_surface(cfg: dict, volume: Volume):
    """(vertices, faces, flipped) of the initial surface the config asks for, checked to lie in the grid."""
    flipped = False
    if cfg["init_mesh"] is not None:
        x, faces, flipped = prepare_init_mesh(cfg["init_mesh"])
    else:
        center = cfg["init_center"]
        if center is None:
            center = 0.5 * (volume.lower + volume.upper)
        x, faces = fibonacci_sphere(cfg["init_vertices"], cfg["init_radius"], center)
    inside = volume.contains(x)
    if not inside.all():
        raise InputError(
            f"method 'shape_gradient': {int((~inside).sum())} of {len(x)} vertices of the initial surface "
            f"lie outside the volume box [{volume.lower.round(4).tolist()}, {volume.upper.round(4).tolist()}]"
            " — the volume must contain the initial surface (pass a smaller init_radius or init_mesh)")
    return x, faces, flipped
