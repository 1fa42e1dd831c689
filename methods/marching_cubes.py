"""Baseline: marching cubes (scikit-image) at level 0.

The zero level set of the trilinear interpolant is triangulated cell by cell; vertices are put in world
coordinates (``origin + index * spacing``), exact duplicates are merged and degenerate faces dropped so a
closed level set gives a watertight mesh, and faces are oriented outward (φ < 0 inside, so the normals point
up the gradient; checked by the sign of the enclosed volume): :func:`methods.isosurface.marching_cubes_mesh`,
which other adapters start from too.
"""

from __future__ import annotations

import time

from geometry.mesh import mesh_facts
from phantoms import Volume

from .base import Method, check_volume
from .contract import Reconstruction
from .params import Param
from .isosurface import marching_cubes_mesh

__all__ = ["MarchingCubes"]


class MarchingCubes(Method):
    name = "marching_cubes"
    imports = ("skimage.measure",)
    description = ("scikit-image marching cubes at level 0: world coordinates, duplicate vertices merged, "
                   "faces outward")
    params = {
        "method": Param("lewiner", "marching-cubes variant of scikit-image", type=str,
                        choices=("lewiner", "lorensen")),
        "step_size": Param(1, "grid step in voxels (1 = full resolution; larger is coarser and faster)",
                           type=int, min=1, max=64),
    }

    def reconstruct(self, volume: Volume) -> Reconstruction:
        check_volume(volume, self.name)
        t0 = time.perf_counter()
        mesh = marching_cubes_mesh(volume, method=self.config["method"], step_size=self.config["step_size"],
                                   name=self.name)
        info = {"iterations": 0, "stop_reason": "done", "wall_mc_s": time.perf_counter() - t0}
        info.update({f"mesh_{k}": v for k, v in mesh_facts(mesh).items()})
        return Reconstruction(mesh, info)
