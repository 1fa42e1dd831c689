"""Marching cubes of the Gaussian-blurred mask at 0.5 — what PyMCubes' ``smooth`` and many scripts do to take
the staircase off a segmentation before meshing it.

The volume's ``raw`` image (a mask: 0/1; an intensity: its values, meshed at its ``level``; a signed distance:
the mask φ < 0) is padded by one outside voxel, blurred with a Gaussian of ``sigma`` voxels along each axis
(``scipy.ndimage.gaussian_filter``; σ in voxels of each axis, as those scripts do, so a thick-slice scan is
blurred over more millimetres along its slices) and meshed by scikit-image's marching cubes at the level, with
the real spacing.  A blur moves the 0.5 level inward where the surface curves (a ball shrinks): the volume-error
column shows by how much.
"""

from __future__ import annotations

import time

import numpy as np
from scipy import ndimage

from phantoms import InputError, Volume

from .base import Method
from .contract import Reconstruction
from .params import Param
from .isosurface import closed_mesh

__all__ = ["MCSmoothedMask"]


class MCSmoothedMask(Method):
    name = "mc_smoothed_mask"
    imports = ("skimage.measure",)
    description = "marching cubes at 0.5 of the mask blurred by a Gaussian of sigma voxels (PyMCubes' smooth)"
    params = {"sigma": Param(1.0, "Gaussian sigma in voxels of each axis (0: marching cubes of the raw mask)",
                             type=float, min=0.0, max=10.0)}
    relative_cost = 0.5

    def reconstruct(self, volume: Volume) -> Reconstruction:
        from skimage.measure import marching_cubes

        t0 = time.perf_counter()
        if volume.kind == "sdf":
            image, level = (volume.values < 0).astype(np.float64), 0.5
        else:
            image, level = np.asarray(volume.raw, np.float64), float(volume.level)
        inside = image > level
        if not inside.any() or inside.all():
            raise InputError(f"method {self.name!r}: the mask has no {'inside' if not inside.any() else 'outside'} "
                             "voxels")
        outside = float(min(image.min(), level - 1.0))
        image = np.pad(image, 1, constant_values=outside)
        sigma = float(self.config["sigma"])
        if sigma > 0:
            image = ndimage.gaussian_filter(image, sigma, mode="nearest")
        if not (image.min() < level < image.max()):
            raise InputError(f"method {self.name!r}: nothing is left above the level {level:g} after the blur "
                             f"(sigma = {sigma:g} voxels); a smaller sigma")
        verts, faces, _, _ = marching_cubes(image, level=level, spacing=tuple(float(s) for s in volume.spacing),
                                            allow_degenerate=False)
        mesh = closed_mesh(verts + volume.origin - volume.spacing, faces, self.name)
        return Reconstruction(mesh, {"iterations": 0, "stop_reason": "done", "input_kind": volume.kind,
                                     "wall_mc_s": time.perf_counter() - t0})
