"""3D Slicer's newer label-map option and VTK's: SurfaceNets (Frisken, "SurfaceNets for multi-label
segmentations with preservation of sharp boundaries", JCGT 2022), VTK's ``vtkSurfaceNets3D``.

One vertex per boundary cell of the label map (voxels are the grid points), placed at the cell's centre and
then moved by VTK's constrained smoothing — each vertex stays within a box of ``constraint_scale`` ×
``constraint_distance`` around its cell, so the surface cannot shrink away from the voxels as unconstrained
smoothing does.  The mask is the volume's ``raw`` image at its ``level`` (a signed distance: φ < 0), padded by
one outside voxel; the filter works in world units (the real, possibly anisotropic spacing); quads are output
as triangles.  The defaults are VTK's (16 iterations, relaxation 0.5, constraint distance 0.001 and scale 2).
"""

from __future__ import annotations

import time

import numpy as np

from phantoms import Volume

from .base import Method, Param, Reconstruction
from .labelmap import closed_mesh, from_vtk, padded_labels, vtk_image, vtk_modules

__all__ = ["SurfaceNets"]


class SurfaceNets(Method):
    name = "surface_nets"
    description = "VTK's SurfaceNets of the mask (vtkSurfaceNets3D, constrained smoothing): a mask-native mesher"
    params = {
        "smoothing": Param(True, "VTK's constrained smoothing of the vertices (off: the cell centres, a staircase)",
                           type=bool),
        "iterations": Param(16, "smoothing iterations (VTK's default 16)", type=int, min=0, max=1000),
        "relaxation": Param(0.5, "smoothing relaxation factor (VTK's 0.5)", type=float, min=0.0, max=1.0),
        "constraint_distance": Param(0.001, "how far a vertex may leave its cell, relative (VTK's 0.001)",
                                     type=float, min=0.0, max=10.0),
        "constraint_scale": Param(2.0, "the constraint box's scale (VTK's 2)", type=float, min=0.0, max=100.0),
    }
    relative_cost = 0.5

    def reconstruct(self, volume: Volume) -> Reconstruction:
        vtk_modules(self.name)
        from vtkmodules.vtkFiltersCore import vtkSurfaceNets3D

        t0 = time.perf_counter()
        labels, origin = padded_labels(volume, self.name)
        image = vtk_image(labels, origin, volume.spacing)
        nets = vtkSurfaceNets3D()
        nets.SetInputData(image)
        nets.SetNumberOfLabels(1)
        nets.SetLabel(0, 1)
        nets.SetBackgroundLabel(0)
        nets.SetOutputMeshTypeToTriangles()
        nets.SetSmoothing(bool(self.config["smoothing"]))
        nets.SetNumberOfIterations(int(self.config["iterations"]))
        nets.SetRelaxationFactor(float(self.config["relaxation"]))
        nets.SetConstraintDistance(float(self.config["constraint_distance"]))
        nets.SetConstraintScale(float(self.config["constraint_scale"]))
        nets.Update()
        vertices, faces = from_vtk(nets.GetOutput())
        mesh = closed_mesh(vertices, faces, self.name)
        del image, labels
        return Reconstruction(mesh, {"iterations": int(self.config["iterations"]) if self.config["smoothing"] else 0,
                                     "stop_reason": "done", "input_kind": volume.kind,
                                     "wall_nets_s": time.perf_counter() - t0})
