"""Peer: Flying Edges (Schroeder, Maynard & Geveci, "Flying Edges: A High-Performance Scalable Isocontouring
Algorithm", IEEE LDAV 2015) — VTK's ``vtkFlyingEdges3D``.

A multi-pass, cache-friendly marching-cubes equivalent: the same vertices (linear interpolation on the grid
edges) and the same case tables as marching cubes, computed edge row by edge row.  The surface is the
``level`` set of the trilinear interpolant, like :mod:`methods.marching_cubes`.

No copy of the volume: it is handed to VTK as it is and the output read back in our axis order
(:func:`methods.isosurface.vtk_image`, :func:`methods.isosurface.from_vtk`).  Flying Edges already shares each
edge's vertex between its cells, so no vertex merging is needed (only exact zeros are nudged, as for
marching cubes, so no vertex sits on a grid point shared by several edges).

VTK is a core dependency; were it missing, :meth:`reconstruct` fails with one line saying so.
"""

from __future__ import annotations

import time

import numpy as np
import trimesh

from phantoms import InputError, Volume

from .base import Method, check_volume
from .contract import Reconstruction
from .params import Param
from .isosurface import from_vtk, nudge_zeros, orient_outward, require_vtk, vtk_image

__all__ = ["FlyingEdges", "flying_edges_arrays"]


def flying_edges_arrays(volume: Volume, level: float = 0.0, name: str = "flying_edges"
                        ) -> tuple[np.ndarray, np.ndarray]:
    """Flying Edges of ``volume`` at ``level``: (vertices (V, 3) in world coordinates, faces (F, 3)), faces
    in VTK's winding mirrored back (orientation not yet checked)."""
    vtkFlyingEdges3D = require_vtk(name, "vtkmodules.vtkFiltersCore").vtkFlyingEdges3D
    values = volume.values - level if level != 0.0 else volume.values
    values = nudge_zeros(values)                          # no copy unless shifted or nudged
    image = vtk_image(values, volume.origin, volume.spacing, scalars="phi")   # alive until VTK's output is read
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
    return from_vtk(out)


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
