"""Peer: OpenVDB's volume-to-mesh (Museth, "VDB: High-resolution sparse volumes with dynamic topology", ACM
ToG 2013; ``openvdb::tools::volumeToMesh``), through the OpenVDB that ``adobe-lagrange`` bundles
(``lagrange.volume.Grid.to_mesh``) — the mesher of film and simulation pipelines.

A dual method: one vertex per voxel the surface crosses, placed from the grid-edge crossings, joined by one
quad per crossed grid edge; with ``adaptivity`` > 0 flat regions are merged into larger polygons (OpenVDB's
adaptive meshing; 1 simplifies the most).  The result is quads (``adaptivity`` = 0) or quads and triangles;
the adapter splits each quad along its shorter diagonal (as for dual contouring), so the suite's validity
check sees a triangle mesh.  OpenVDB's quads are consistently oriented and closed, and stay so after the split.

Input: lagrange has no dense-array constructor, so every grid sample becomes an active voxel
(``Grid.from_points`` with the index coordinates and φ, float64), the background (the value of the
inactive voxels outside the grid) is set positive — outside — and the grid class to level set; the
index-to-world transform is ``origin + index · spacing``, so anisotropic spacing and the origin are the
volume's and the vertices come out in world coordinates.  Exact zeros are nudged outside, as for marching
cubes.  Nothing else of the library's call is changed.

The package is an optional dependency: ``pip install adobe-lagrange`` (or the ``peers`` extra); without it
the method is listed as unavailable and ``reconstruct`` fails in one line.
"""

from __future__ import annotations

import time

import numpy as np
import trimesh

from phantoms import InputError, Volume

from .base import Method, check_volume
from .contract import Reconstruction
from .params import Param
from .cost_model import PowerLaw
from .dual_contouring import split_quads
from .isosurface import nudge_zeros, orient_outward

__all__ = ["VDB", "vdb_polygons"]

INSTALL = 'pip install adobe-lagrange (or pip install -e ".[peers]")'


def _faces(mesh) -> np.ndarray:
    """Triangles of a lagrange SurfaceMesh of triangles and quads (quads split along the shorter diagonal)."""
    vertices = np.asarray(mesh.vertices, dtype=np.float64)
    if mesh.num_facets == 0:
        return np.zeros((0, 3), np.int64)
    if mesh.is_regular:
        polys = np.asarray(mesh.facets, dtype=np.int64)
        groups = {polys.shape[1]: polys}
    else:
        corner_vertex = np.asarray(mesh.attribute(mesh.attr_id_corner_to_vertex).data, dtype=np.int64)
        first = np.asarray(mesh.attribute(mesh.attr_id_facet_to_first_corner).data, dtype=np.int64)
        sizes = np.diff(np.append(first, len(corner_vertex)))
        if not np.isin(sizes, (3, 4)).all():
            raise InputError(f"method 'vdb': OpenVDB returned polygons of {sorted(set(sizes.tolist()))} sides")
        groups = {s: corner_vertex[first[sizes == s][:, None] + np.arange(s)] for s in (3, 4)}
    tris = [groups.get(3, np.zeros((0, 3), np.int64))]
    if 4 in groups:
        tris.append(split_quads(vertices, groups[4]))
    return np.concatenate(tris)


def vdb_polygons(volume: Volume, adaptivity: float = 0.0):
    """OpenVDB's mesh of ``volume``'s zero level set: (vertices (V, 3) world, triangles (F, 3), facts).

    lagrange bundles a newer TBB than pymeshlab: in a process where pymeshlab was loaded first, the dynamic
    linker has bound ``libtbb.so.12`` to pymeshlab's copy and lagrange's import fails on a missing symbol — the
    mesh is then made in a fresh interpreter (:func:`_in_fresh_process`)."""
    try:
        from lagrange import volume as lvol
    except ImportError as exc:
        if "undefined symbol" not in str(exc):
            raise
        return _in_fresh_process(volume, adaptivity)

    values = nudge_zeros(volume.values)
    index = np.indices(values.shape, dtype=np.int32).reshape(3, -1).T.copy()
    grid = lvol.Grid.from_points(index, np.ascontiguousarray(values.reshape(-1), dtype=np.float64),
                                 dtype=np.float64)
    transform = np.eye(4)
    transform[:3, :3] = np.diag(np.asarray(volume.spacing, dtype=np.float64))
    transform[:3, 3] = volume.origin
    grid.transform = transform
    grid.background = float(max(np.abs(values).max(), volume.h))      # outside the grid is outside
    grid.grid_class = lvol.GridClass.LevelSet
    mesh = grid.to_mesh(isovalue=0.0, adaptivity=float(adaptivity))
    vertices = np.asarray(mesh.vertices, dtype=np.float64).reshape(-1, 3)
    faces = _faces(mesh)
    facts = {"polygons": int(mesh.num_facets), "quads_split": int(len(faces) - mesh.num_facets)}
    return vertices, faces, facts


def _in_fresh_process(volume: Volume, adaptivity: float):
    """:func:`vdb_polygons` run by ``python -m methods.vdb`` on the volume saved to a temporary folder."""
    import json
    import subprocess
    import sys
    import tempfile
    from pathlib import Path

    with tempfile.TemporaryDirectory() as tmp:
        src, dst = Path(tmp) / "in.npz", Path(tmp) / "out.npz"
        np.savez(src, values=np.asarray(volume.values), origin=np.asarray(volume.origin),
                 spacing=np.asarray(volume.spacing), adaptivity=float(adaptivity))
        res = subprocess.run([sys.executable, "-m", "methods.vdb", str(src), str(dst)], capture_output=True,
                             text=True)
        if res.returncode != 0 or not dst.is_file():
            last = (res.stderr.strip().splitlines() or ["(no message)"])[-1]
            raise RuntimeError(f"OpenVDB in a fresh process failed (exit {res.returncode}): {last}")
        with np.load(dst) as out:
            return np.asarray(out["vertices"]), np.asarray(out["faces"]), json.loads(str(out["facts"]))


def _main(src: str, dst: str) -> None:
    import json

    with np.load(src) as a:
        vol = Volume(np.array(a["values"]), a["origin"], a["spacing"])
        v, f, facts = vdb_polygons(vol, float(a["adaptivity"]))
    np.savez(dst, vertices=v, faces=f, facts=json.dumps(facts))


class VDB(Method):
    name = "vdb"
    description = ("OpenVDB's volume-to-mesh (Museth 2013; adobe-lagrange's bundled OpenVDB): dual quads, "
                   "optional adaptivity; quads split")
    params = {
        "adaptivity": Param(0.0, "OpenVDB's surface adaptivity: 0 = one quad per crossed grid edge, up to 1 = "
                                 "flat regions merged the most", type=float, min=0.0, max=1.0),
    }
    requires = {"lagrange": INSTALL}

    #: the cost model: CPU seconds, fitted to the clean sphere and bunny at N = 32–96 together
    #: (``python -m bench.perf.cost_models``)
    COST = PowerLaw(a=0.012, p=1.6)

    def estimate_seconds(self, shape, n_crossing_cells: int | None = None) -> float | None:
        """The fit above; adaptivity changes the cost little."""
        return self.COST.seconds(shape, n_crossing_cells)

    def reconstruct(self, volume: Volume) -> Reconstruction:
        self.require()
        check_volume(volume, self.name)
        t0 = time.perf_counter()
        vertices, faces, facts = vdb_polygons(volume, self.config["adaptivity"])
        if len(faces) == 0 or not np.isfinite(vertices).all():
            raise InputError(f"method {self.name!r}: OpenVDB returned "
                             f"{'no faces' if len(faces) == 0 else 'non-finite vertices'}")
        mesh = trimesh.Trimesh(vertices, faces, process=False)
        mesh.remove_unreferenced_vertices()
        orient_outward(mesh)
        info = {"iterations": 0, "stop_reason": "done", **facts, "wall_vdb_s": time.perf_counter() - t0}
        return Reconstruction(mesh, info)


if __name__ == "__main__":      # the fresh process of _in_fresh_process
    import sys

    _main(sys.argv[1], sys.argv[2])
