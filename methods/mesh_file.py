"""A surface made elsewhere as a row: ``mesh_file`` reads a mesh file (an STL / OBJ / PLY export of 3D Slicer,
ITK-SNAP, your current pipeline) instead of computing one, so the grid scores it like every other method and
answers "is my current pipeline better than these?".

``path`` names the file; in a grid ``{phantom}`` in it is replaced by the name a user sees for each cell's
phantom — a ``volume:`` / ``mesh:`` file's stem (``volume:scans/ct.nii.gz?level=500`` → ``ct``), a glob's file
stem, a ``labels=`` phantom's ``STEM_labelL``, a built-in phantom's name (e.g.
``--add-method slicer_export=mesh_file:path=exports/{phantom}.stl`` reads ``exports/ct.stl``).  The mesh must
already be in the volume's world coordinates (RAS+ for a user's image) and closed; the suite's validity check then
judges it as it judges any method's output (outward orientation, on the zero set, inside the box).
"""

from __future__ import annotations

import stat
import time
from pathlib import Path

import numpy as np
import trimesh

from phantoms import InputError, Volume
from phantoms.frames import fitting_frame

from .base import Method
from .contract import Reconstruction
from .params import Param

__all__ = ["MeshFile"]


def _check_file(path: Path) -> None:
    """One line naming why ``path`` is not a mesh file to read: missing, a folder, or not a regular file (a FIFO
    would block the read, a device such as ``/dev/zero`` never ends)."""
    try:
        mode = path.stat().st_mode
    except FileNotFoundError:
        raise InputError(f"method 'mesh_file': no such mesh file {str(path)!r}") from None
    except OSError as exc:
        raise InputError(f"method 'mesh_file': cannot read {str(path)!r}: {exc.strerror or exc}") from None
    if stat.S_ISDIR(mode):
        raise InputError(f"method 'mesh_file': {str(path)!r} is a folder, not a mesh file")
    if not stat.S_ISREG(mode):
        kind = ("a FIFO" if stat.S_ISFIFO(mode) else "a device" if stat.S_ISCHR(mode) or stat.S_ISBLK(mode)
                else "a socket" if stat.S_ISSOCK(mode) else "not a regular file")
        raise InputError(f"method 'mesh_file': {str(path)!r} is {kind}, not a mesh file (a regular file is read)")


class MeshFile(Method):
    name = "mesh_file"
    description = "a surface exported by another tool, read from a file (path may hold {phantom})"
    params = {"path": Param("", "the mesh file (STL, OBJ, PLY, OFF ...); {phantom}: the phantom's file stem or name",
                            type=str)}
    relative_cost = 0.1
    imports_surface = True

    def reconstruct(self, volume: Volume) -> Reconstruction:
        t0 = time.perf_counter()
        text = self.config["path"]
        if not text:
            raise InputError("method 'mesh_file' needs path=FILE (e.g. path=exports/{phantom}.stl)")
        if "{phantom}" in text:
            raise InputError(f"method 'mesh_file': {text!r} still holds {{phantom}} (a grid fills it in per phantom; "
                             "give the file itself here)")
        path = Path(text).expanduser()
        _check_file(path)
        try:        # unprocessed: processing drops a NaN vertex with its faces, and the cause would read "not closed"
            mesh = trimesh.load(str(path), force="mesh", process=False)
        except Exception as exc:  # noqa: BLE001 — trimesh raises many kinds for a bad file
            raise InputError(f"method 'mesh_file': cannot read {str(path)!r} as a mesh: {exc}") from None
        if len(mesh.faces) == 0:
            raise InputError(f"method 'mesh_file': {str(path)!r} holds no triangles")
        bad = int((~np.isfinite(np.asarray(mesh.vertices, float))).any(axis=1).sum())
        if bad:
            raise InputError(f"method 'mesh_file': {str(path)!r} has {bad} vertices with a NaN or infinite "
                             "coordinate; the suite scores finite surfaces")
        mesh.process()
        mesh.merge_vertices()
        if not mesh.is_watertight:
            raise InputError(f"method 'mesh_file': {str(path)!r} is not a closed mesh (an edge in fewer or more than "
                             "two faces); the suite scores closed surfaces")
        v = np.asarray(mesh.vertices, float)
        f = np.asarray(mesh.faces, np.int64)
        frame = fitting_frame(v, volume)             # an LPS export or voxel indices: said as for a truth=
        if frame:
            raise InputError(f"method 'mesh_file': {str(path)!r} is not in the volume's world coordinates (RAS+); "
                             f"it fits the volume in {frame}")
        return Reconstruction(trimesh.Trimesh(v, f, process=False),
                              {"iterations": 0, "source_file": str(path), "read_s": time.perf_counter() - t0})
