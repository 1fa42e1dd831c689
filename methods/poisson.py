"""Baseline: screened Poisson surface reconstruction (Kazhdan & Hoppe 2013) via pymeshlab.

The oriented point cloud is the zero level set found in the volume: the marching-cubes vertices (each lies
on a grid edge where the trilinear interpolant is exactly 0) with normals ∇φ/|∇φ| from the interpolated
central-difference gradient (points where |∇φ| ≈ 0 have no normal and are left out).  pymeshlab's
``generate_surface_reconstruction_screened_poisson`` fits the indicator function; its output is then cleaned:

* components whose mean Poisson sample density (pymeshlab's per-vertex scalar) lies more than ``trim``
  below the densest component's are dropped — the low-density skirt/bubble Poisson puts where it has no
  samples;
* with ``keep_largest`` only the largest remaining component (by area) is kept;
* duplicate vertices are merged, faces oriented outward.

``depth`` defaults to the smallest octree depth whose cells are at most half the grid spacing over the
point cloud's bounding box, so the output resolution follows the volume's.
"""

from __future__ import annotations

import math
import time

import numpy as np

from geometry.mesh import ScoredMesh, mesh_facts
from phantoms import InputError, Volume

from .base import Method, check_volume
from .contract import Reconstruction
from .params import Param
from .isosurface import clean_mesh, marching_cubes_mesh

__all__ = ["ScreenedPoisson", "zero_set_points"]

_SCALE = 1.1  # pymeshlab's default ratio of the reconstruction cube to the points' bounding cube


def zero_set_points(volume: Volume, name: str = "poisson") -> tuple[np.ndarray, np.ndarray]:
    """Points on φ = 0 (marching-cubes vertices) and unit normals ∇φ/|∇φ| (outward: φ < 0 inside)."""
    mesh = marching_cubes_mesh(volume, name=name)
    p = np.asarray(mesh.vertices, dtype=np.float64)
    g = volume.sample(p, derivatives=1, clamp=True).grad
    gn = np.linalg.norm(g, axis=1)
    ok = gn > 1e-12 * max(float(np.median(gn)), 1e-300)
    return p[ok], g[ok] / gn[ok, None]


class ScreenedPoisson(Method):
    name = "poisson"
    imports = ("pymeshlab",)
    relative_cost = 5.0
    description = ("screened Poisson reconstruction (pymeshlab) from the zero-set points with normals "
                   "∇φ/|∇φ|; low-density components trimmed, largest kept")
    params = {
        "depth": Param(None, "octree depth (default: cells <= h/2 over the points' bounding box)", type=int,
                       min=2, max=14),
        "samples_per_node": Param(1.5, "point density: minimum samples per octree node (larger = smoother, "
                                       "for noisy input)", type=float, min=1.0, max=50.0),
        "point_weight": Param(4.0, "screening weight of the point interpolation (0 = unscreened Poisson)",
                              type=float, min=0.0, max=1000.0),
        "trim": Param(1.0, "drop components whose mean density is this far below the densest "
                           "component's (0 = keep all)", type=float, min=0.0, max=100.0),
        "keep_largest": Param(True, "keep only the largest remaining component (by area)", type=bool),
        "threads": Param(1, "threads pymeshlab may use", type=int, min=1, max=256),
    }

    def _depth(self, points: np.ndarray, h: float) -> int:
        if self.config["depth"] is not None:
            return int(self.config["depth"])
        size = float((points.max(0) - points.min(0)).max()) * _SCALE
        return int(min(max(math.ceil(math.log2(max(size / (0.5 * h), 2.0))), 5), 11))

    def reconstruct(self, volume: Volume) -> Reconstruction:
        import pymeshlab

        check_volume(volume, self.name)
        cfg = self.config
        t0 = time.perf_counter()
        points, normals = zero_set_points(volume, self.name)
        if len(points) < 10:
            raise InputError(f"method {self.name!r}: only {len(points)} zero-set points with a defined normal; "
                             "too few for a Poisson reconstruction")
        depth = self._depth(points, volume.h)
        ms = pymeshlab.MeshSet()
        ms.add_mesh(pymeshlab.Mesh(vertex_matrix=points, v_normals_matrix=normals))
        try:
            ms.generate_surface_reconstruction_screened_poisson(
                depth=depth, fulldepth=min(5, depth), samplespernode=float(cfg["samples_per_node"]),
                pointweight=float(cfg["point_weight"]), scale=_SCALE, preclean=False,
                threads=int(cfg["threads"]))
        except pymeshlab.PyMeshLabException as exc:  # pragma: no cover - pymeshlab's own failure
            raise InputError(f"method {self.name!r}: pymeshlab screened Poisson failed: {exc}") from None
        out = ms.current_mesh()
        verts = np.asarray(out.vertex_matrix(), dtype=np.float64)
        faces = np.asarray(out.face_matrix(), dtype=np.int64)
        density = np.asarray(out.vertex_scalar_array(), dtype=np.float64) if out.has_vertex_scalar() else None
        t_poisson = time.perf_counter() - t0
        if not len(faces):
            raise InputError(f"method {self.name!r}: Poisson produced no surface (parameter 'depth'={depth})")

        # components, their median density and area
        raw = ScoredMesh(verts, faces)
        n_comp, labels = raw.face_components
        areas = np.bincount(labels, weights=raw.face_areas, minlength=n_comp)
        keep = np.ones(n_comp, dtype=bool)
        comp_density = None
        if density is not None and cfg["trim"] > 0 and n_comp > 1:
            face_density = density[faces].mean(1)
            counts = np.bincount(labels, minlength=n_comp)
            comp_density = np.bincount(labels, weights=face_density, minlength=n_comp) / np.maximum(counts, 1)
            keep &= comp_density >= comp_density.max() - cfg["trim"]
        n_trimmed = int((~keep).sum())
        if cfg["keep_largest"] and keep.sum() > 1:
            largest = int(np.argmax(np.where(keep, areas, -1.0)))
            keep[:] = False
            keep[largest] = True
        mesh = clean_mesh(verts, faces[keep[labels]])
        info = {
            "iterations": 0,
            "stop_reason": "done",
            "depth": depth,
            "points": int(len(points)),
            "raw_components": n_comp,
            "trimmed_components": n_trimmed,
            "kept_components": int(keep.sum()),
            "wall_poisson_s": t_poisson,
        }
        if density is not None and len(density):
            info["density_min"], info["density_median"] = float(density.min()), float(np.median(density))
        info.update({f"mesh_{k}": v for k, v in mesh_facts(mesh).items()})
        return Reconstruction(mesh, info)
