"""zmesh (Seung lab, PyPI ``zmesh``): multi-label marching cubes on a label map, with optional quadric
simplification — what connectomics pipelines (Igneous, CloudVolume) mesh segmentations with.

The label map is 1 on the volume's inside voxels (:attr:`phantoms.Volume.inside_raw`: ``raw > level`` for a mask
or an intensity image; for a signed distance the mask φ < 0), padded by one background voxel and meshed with
``zmesh.Mesher(spacing)`` (the real, possibly anisotropic spacing: zmesh's vertices are padded index × spacing,
``voxel_centered`` off, so the volume's origin minus one voxel is added).  The surface lies half-way between
inside and outside voxel centres (a staircase, as marching cubes of the mask).  ``reduction_factor`` 0 (zmesh's
default) keeps every triangle; above 0 zmesh simplifies towards 1/factor of the triangles within ``max_error``
world units (auto: zmesh's, about one voxel).  The faces are oriented outward.
"""

from __future__ import annotations

import time

import numpy as np

from phantoms import InputError, Volume

from .base import Method
from .contract import Reconstruction
from .params import Param
from .isosurface import closed_mesh
from .labelmap import padded_labels

__all__ = ["ZMesh"]


class ZMesh(Method):
    name = "zmesh"
    imports = ("zmesh",)
    description = "zmesh: marching cubes of the label map (connectomics' mesher), optional simplification"
    params = {
        "reduction_factor": Param(0, "simplify to about 1/factor of the triangles (0: none, zmesh's default)",
                                  type=int, min=0, max=1000),
        "max_error": Param(None, "largest vertex displacement of the simplification, world units (auto: zmesh's)",
                           type=float, min=0.0, max=1e6),
    }
    relative_cost = 0.5

    def reconstruct(self, volume: Volume) -> Reconstruction:
        try:
            import zmesh
        except ImportError:
            raise InputError(f"method {self.name!r} needs zmesh, which is not installed: pip install zmesh") from None
        t0 = time.perf_counter()
        labels, origin = padded_labels(volume, self.name)
        mesher = zmesh.Mesher(tuple(float(s) for s in volume.spacing))
        mesher.mesh(labels, close=False)
        got = mesher.get(1, normals=False, reduction_factor=int(self.config["reduction_factor"]),
                         max_error=self.config["max_error"], voxel_centered=False)
        mesher.clear()
        vertices = np.asarray(got.vertices, np.float64) + origin
        mesh = closed_mesh(vertices, np.asarray(got.faces, np.int64), self.name, merge=False)
        info = {"iterations": 0, "stop_reason": "done", "input_kind": volume.kind,
                "wall_zmesh_s": time.perf_counter() - t0}
        if not (mesh.is_watertight and mesh.is_winding_consistent):
            info["warnings"] = ["zmesh's mesh is not closed and edge-manifold on this mask"]
        return Reconstruction(mesh, info)
