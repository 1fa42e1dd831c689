"""3D Slicer's newer label-map option and VTK's: SurfaceNets (Frisken, "SurfaceNets for multi-label
segmentations with preservation of sharp boundaries", JCGT 2022), VTK's ``vtkSurfaceNets3D`` (VTK ≥ 9.3).

One vertex per boundary cell of the label map (voxels are the grid points), placed at the cell's centre and
then moved by VTK's constrained smoothing — each vertex stays within a box of ``constraint_scale`` ×
``constraint_distance`` around its cell, so the surface cannot drift far from the voxels as unconstrained
smoothing does.  The label map is 1 on the volume's inside voxels (:attr:`phantoms.Volume.inside_raw`: ``raw >
level`` for a mask or an intensity image; for a signed distance the mask φ < 0), 0 elsewhere, padded by one
background voxel; only the boundary between label 1 and the background 0 is extracted, in world units (the real,
possibly anisotropic spacing), as triangles (VTK's default output is quads).  The defaults are VTK's (16
iterations, relaxation 0.5, constraint distance 0.001 and scale 2).

Making the mesh closed and manifold: where inside voxels touch only along an edge beside other inside voxels
(a speckled or noisy mask) VTK splits the shared vertices into copies and leaves a slit — a loop of four boundary
edges — between them.  Those loops are closed by fans (:func:`methods.labelmap.close_seams`; ``info
['seams_closed']``); if the mesh is still not closed and edge-manifold, the mask is remeshed with every such edge
contact filled by one voxel (:func:`methods.labelmap.fill_edge_contacts`; ``info['voxels_added']``, and a
warning).  The faces are then oriented outward.
"""

from __future__ import annotations

import time

import numpy as np

from phantoms import Volume

from .base import Method
from .contract import Reconstruction, ReconstructionFailed
from .params import Param
from .isosurface import closed_mesh, from_vtk, require_vtk, vtk_image
from .labelmap import close_seams, fill_edge_contacts, padded_labels

__all__ = ["SurfaceNets"]


class SurfaceNets(Method):
    name = "surface_nets"
    imports = ("vtkmodules.all", "vtkmodules.vtkFiltersCore")
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

    def _nets(self, labels: np.ndarray, origin, spacing) -> tuple[np.ndarray, np.ndarray]:
        """(vertices, triangles) of vtkSurfaceNets3D on ``labels``: label 1 against background 0, world units."""
        from vtkmodules.vtkFiltersCore import vtkSurfaceNets3D

        image = vtk_image(labels, origin, spacing)
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
        return from_vtk(nets.GetOutput())

    def _closed(self, labels: np.ndarray, origin, spacing):
        """(mesh, loops closed, is it closed and edge-manifold) of ``labels``."""
        vertices, faces = self._nets(labels, origin, spacing)
        if len(faces):
            faces, loops = close_seams(faces)
        else:
            loops = 0
        mesh = closed_mesh(vertices, faces, self.name, merge=False)
        return mesh, loops, bool(mesh.is_watertight and mesh.is_winding_consistent)

    def reconstruct(self, volume: Volume) -> Reconstruction:
        require_vtk(self.name)
        t0 = time.perf_counter()
        labels, origin = padded_labels(volume, self.name)
        mesh, loops, ok = self._closed(labels, origin, volume.spacing)
        added, warnings = 0, []
        if not ok:
            filled, added = fill_edge_contacts(labels)
            mesh, loops, ok = self._closed(filled, origin, volume.spacing)
            warnings.append(f"the mask's edge contacts left SurfaceNets' mesh open: {added} voxels were added "
                            f"({added / max(int(labels.sum()), 1):.2%} of the inside) to close it")
        if not ok:
            raise ReconstructionFailed(f"method {self.name!r}: VTK's SurfaceNets mesh is not closed and "
                                       "edge-manifold even after filling the mask's edge contacts")
        info = {"iterations": int(self.config["iterations"]) if self.config["smoothing"] else 0,
                "stop_reason": "done", "input_kind": volume.kind, "seams_closed": loops, "voxels_added": added,
                "wall_nets_s": time.perf_counter() - t0}
        if warnings:
            info["warnings"] = warnings
        return Reconstruction(mesh, info)
