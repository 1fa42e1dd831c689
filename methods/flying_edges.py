"""Peer: Flying Edges (Schroeder, Maynard & Geveci, "Flying Edges: A High-Performance Scalable Isocontouring
Algorithm", IEEE LDAV 2015) — VTK's ``vtkFlyingEdges3D``.

A multi-pass, cache-friendly marching-cubes equivalent: the same vertices (linear interpolation on the grid
edges) and the same case tables as marching cubes, computed edge row by edge row.  The surface is the
``level`` set of the trilinear interpolant, like :mod:`methods.marching_cubes`.

No copy of the volume: VTK orders points with x fastest, a C-ordered ``values[i, j, k]`` (axis 0 = x) has z
fastest, so the array is handed to VTK as it is (``numpy_to_vtk`` without ``deep``) as an image of
dimensions (nz, ny, nx) with the spacing and origin reversed; the output points' columns are swapped back
(z, y, x → x, y, z), which mirrors the mesh, so the faces are reversed once.  Flying Edges already shares each
edge's vertex between its cells, so no vertex merging is needed (only exact zeros are nudged, as for
marching cubes, so no vertex sits on a grid point shared by several edges).

VTK is a core dependency; were it missing, :meth:`reconstruct` fails with one line saying so.
"""

from __future__ import annotations

import time

import numpy as np
import trimesh

from phantoms import InputError, Volume

from .base import Method, Param, Reconstruction, check_volume
from .marching_cubes import _nudge_zeros, orient_outward

__all__ = ["FlyingEdges", "flying_edges_arrays", "VTK_MISSING"]

VTK_MISSING = 'method {name!r} needs VTK, which is not installed: pip install "vtk>=9.3"'


def _vtk_modules(name: str):
    """VTK's data model, numpy bridge and the Flying Edges filter; InputError naming the extra when absent."""
    try:
        from vtkmodules.util import numpy_support
        from vtkmodules.vtkCommonDataModel import vtkImageData
        from vtkmodules.vtkFiltersCore import vtkFlyingEdges3D
    except ImportError:
        raise InputError(VTK_MISSING.format(name=name)) from None
    return numpy_support, vtkImageData, vtkFlyingEdges3D


def flying_edges_arrays(volume: Volume, level: float = 0.0, name: str = "flying_edges"
                        ) -> tuple[np.ndarray, np.ndarray]:
    """Flying Edges of ``volume`` at ``level``: (vertices (V, 3) in world coordinates, faces (F, 3)), faces
    in VTK's winding mirrored back (orientation not yet checked)."""
    numpy_support, vtkImageData, vtkFlyingEdges3D = _vtk_modules(name)
    values = volume.values - level if level != 0.0 else volume.values
    values = np.ascontiguousarray(_nudge_zeros(values))   # no copy unless shifted or nudged
    nx, ny, nz = values.shape
    image = vtkImageData()
    image.SetDimensions(nz, ny, nx)                       # VTK's x = our z (the fastest axis in memory)
    image.SetSpacing(*(float(s) for s in volume.spacing[::-1]))
    image.SetOrigin(*(float(o) for o in volume.origin[::-1]))
    scalars = numpy_support.numpy_to_vtk(values.reshape(-1), deep=False)   # a view: VTK reads numpy's buffer
    scalars.SetName("phi")
    image.GetPointData().SetScalars(scalars)
    fe = vtkFlyingEdges3D()
    fe.SetInputData(image)
    fe.SetValue(0, 0.0)
    fe.ComputeNormalsOff()
    fe.ComputeGradientsOff()
    fe.ComputeScalarsOff()
    fe.InterpolateAttributesOff()
    fe.Update()
    out = fe.GetOutput()
    if out.GetNumberOfPoints() == 0:
        raise InputError(f"method {name!r}: Flying Edges found no surface at level {level}")
    pts = numpy_support.vtk_to_numpy(out.GetPoints().GetData())
    vertices = np.ascontiguousarray(pts[:, ::-1], dtype=np.float64)     # (z, y, x) → (x, y, z)
    conn = numpy_support.vtk_to_numpy(out.GetPolys().GetConnectivityArray())
    faces = conn.reshape(-1, 3)[:, ::-1].astype(np.int64)              # the axis swap is a mirror: re-wind
    del values, scalars                                                 # VTK is done with the buffer
    return vertices, faces


class FlyingEdges(Method):
    name = "flying_edges"
    imports = ("vtkmodules.util.numpy_support", "vtkmodules.vtkCommonDataModel", "vtkmodules.vtkFiltersCore")
    description = ("Flying Edges (Schroeder et al. 2015, VTK vtkFlyingEdges3D): marching-cubes vertices, "
                   "several times faster")
    params = {
        "level": Param(0.0, "the iso-value extracted (0 = the zero level set; the surface must stay closed "
                            "inside the grid)", type=float, min=-1e6, max=1e6),
    }

    def reconstruct(self, volume: Volume) -> Reconstruction:
        check_volume(volume, self.name)
        level = self.config["level"]
        if level != 0.0 and not (volume.values.min() < level < volume.values.max()):
            raise InputError(f"method {self.name!r}, parameter 'level': {level!r} is outside the volume's "
                             f"values [{volume.values.min():.4g}, {volume.values.max():.4g}]")
        t0 = time.perf_counter()
        vertices, faces = flying_edges_arrays(volume, level, self.name)
        mesh = trimesh.Trimesh(vertices, faces, process=False)
        f = mesh.faces
        keep = (f[:, 0] != f[:, 1]) & (f[:, 1] != f[:, 2]) & (f[:, 2] != f[:, 0])
        if not keep.all():       # degenerate triangles (none expected after the zero nudge)
            mesh.update_faces(keep)
            mesh.remove_unreferenced_vertices()
        orient_outward(mesh)
        # no mesh_facts() here: its connected components cost ≈ 5× the extraction at N = 192,
        # and `reconstruct` / the grid compute watertightness, χ and components themselves
        info = {"iterations": 0, "stop_reason": "done", "wall_fe_s": time.perf_counter() - t0}
        return Reconstruction(mesh, info)
