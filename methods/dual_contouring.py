"""Peer: dual contouring of signed distance data (Carrera, Wang, Batty, Stein & Sellán 2026) —
``gpytoolbox.dual_contouring_of_signed_distance_data`` — made manifold (Schaefer, Ju & Warren 2007).

The library puts one vertex in every grid cell the surface crosses, placed by a quadratic error function
built from the SDF samples themselves (no gradients): the outer iterations alternate a global solve for the
vertex positions with an update of the Hermite data (points and normals) from the current mesh;
``iterations = 0`` is the initial mesh (each vertex the mean of its cell's edge crossings).

One vertex per cell cannot carry two sheets: where a part thinner than a cell (the bunny's ears at N = 24–48,
the cortex) or noise puts two sheets in one cell, the library's mesh has non-manifold edges and vertices.
So the adapter keeps the library's vertices (row r of its output is the r-th crossed cell, first axis
fastest) and builds the faces itself (``methods/dc_manifold.py``): each crossed cell's sign-changing edges
are grouped into its marching-cubes patches, each patch has its own vertex, and the quad around a
sign-changing grid edge uses, in each of its four cells, the vertex of the patch holding that edge.

* A cell with one patch keeps the library's vertex exactly: where every cell has one patch the mesh is the
  library's (same vertices in the same order, same quads), only wound from the sign change of each edge.
* A cell with several patches gets one vertex per patch: the mean of the patch's edge crossings (the
  library's starting vertex restricted to the patch), moved onto φ = 0 by 3 Newton steps inside the cell.
  The library's iterations do not move these vertices: they optimise the library's one-vertex mesh, not
  this one, so a split cell's vertices are the same for any ``iterations``.
* Ambiguous faces join the inside corners, opposite inside corners of a cell are joined by a tube
  (``info["tunnels"]``), and two patches sharing two contour segments get a vertex per segment on their
  common face (``info["segment_vertices"]``): the surface bounds the 26-connected inside samples and is a
  closed, consistently oriented 2-manifold.  ``info``: ``split_cells``, ``patch_vertices``, ``quads``,
  ``library_quads``, ``wall_dc_s`` (the library), ``wall_manifold_s`` (the rest: a small share of the library's
  time, growing with the split cells — 869 / 8027 for the torus with 20 dB noise at N = 48 / 96).

Each quad (or the polygon of a quad with a segment vertex) is split into triangles along its shorter
diagonal (a fan from the segment vertex).

Cost.  gpytoolbox's implementation is slow: its default 100 outer iterations take minutes on a 32³ grid,
growing with the samples and the surface.  Two settings keep it usable:

* ``iterations`` (default 10, the library's 100 is allowed): on the suite's phantoms the vertex error is
  settled after a few iterations (the iterations move the 95th-percentile distance by a few hundredths of h);
* ``samples = "band"`` (default): the method sees only the sub-box of the grid that holds every sample with
  |φ| < ``band`` · h (plus one sample of margin) — the cells away from the surface carry no vertex, so it
  is several times faster.  The optimisation does read the samples of that box, so the band changes the result
  slightly (a few hundredths of h at N = 24–48); ``samples = "all"`` gives the whole grid as the paper does.

Coordinates: the grid vertices are passed in world coordinates (``origin + index · spacing``, anisotropic
spacing included) in the library's order (first axis fastest), so the output is in world coordinates.  Exact
zeros in the grid are moved a hair outside (as for marching cubes) so that every sample is inside or out.
"""

from __future__ import annotations

import time

import numpy as np
import trimesh

from geometry.levelset import newton_project
from geometry.mesh import mesh_facts
from phantoms import InputError, Volume

from .base import Method, check_volume
from .contract import Reconstruction, ReconstructionFailed
from .params import Param
from .cost_model import PowerLaw
from .dc_manifold import (
    TUNNEL_CUBES,
    bridge_tunnels,
    cell_patches,
    dual_quads,
    fan_triangles,
    patch_centroids,
    split_double_edges,
)
from .isosurface import nudge_zeros, orient_outward

__all__ = ["DualContouring", "split_quads", "band_box", "library_grid"]


def band_box(volume: Volume, band: float) -> tuple[np.ndarray, np.ndarray]:
    """Index bounds ``(lo, hi)`` (hi exclusive) of the sub-box holding every sample with |φ| < band·h and
    every sample next to a sign change, widened by one sample (clipped to the grid)."""
    v = volume.values
    near = np.abs(v) < band * volume.h
    for axis in range(3):  # both ends of every grid edge the surface crosses
        cross = np.diff(np.signbit(v), axis=axis)
        lo_idx = [slice(None)] * 3
        hi_idx = [slice(None)] * 3
        lo_idx[axis], hi_idx[axis] = slice(0, -1), slice(1, None)
        near[tuple(lo_idx)] |= cross
        near[tuple(hi_idx)] |= cross
    idx = np.argwhere(near)
    lo = np.maximum(idx.min(axis=0) - 1, 0)
    hi = np.minimum(idx.max(axis=0) + 2, np.asarray(v.shape))
    return lo, hi


def library_grid(volume: Volume, lo, hi) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The sub-box ``[lo, hi)`` of the grid as gpytoolbox's dual contouring takes it: (the box's values with
    exact zeros nudged outside, S (M,) first axis fastest, GV (M, 3) the samples' world coordinates)."""
    values = nudge_zeros(volume.values[lo[0]:hi[0], lo[1]:hi[1], lo[2]:hi[2]])
    S = values.ravel(order="F")            # first axis fastest, as the library wants
    axes = [volume.origin[d] + volume.spacing[d] * np.arange(lo[d], hi[d]) for d in range(3)]
    GV = np.empty((S.size, 3))
    for d, g in enumerate(np.meshgrid(*axes, indexing="ij")):
        GV[:, d] = g.ravel(order="F")
    return values, S, GV


def split_quads(vertices: np.ndarray, quads: np.ndarray) -> np.ndarray:
    """Triangles of ``quads`` (Q, 4), each split along its shorter diagonal (winding kept)."""
    q = np.asarray(quads, dtype=np.int64)
    d02 = np.linalg.norm(vertices[q[:, 0]] - vertices[q[:, 2]], axis=1)
    d13 = np.linalg.norm(vertices[q[:, 1]] - vertices[q[:, 3]], axis=1)
    use02 = d02 <= d13
    a = np.where(use02[:, None], q[:, [0, 1, 2]], q[:, [0, 1, 3]])
    b = np.where(use02[:, None], q[:, [0, 2, 3]], q[:, [1, 2, 3]])
    return np.concatenate([a, b])


class DualContouring(Method):
    name = "dual_contouring"
    imports = ("gpytoolbox",)
    description = ("dual contouring of signed distance data (Carrera et al. 2026, gpytoolbox), manifold: one "
                   "vertex per marching-cubes patch of a crossed cell; quads split; slow")
    params = {
        "iterations": Param(10, "outer iterations (global vertex solve + Hermite update); 0 = the initial "
                                "dual-contouring mesh; the library's default is 100", type=int, min=0, max=1000),
        "inner_iterations": Param(100, "inner iterations of each outer one (local energy minimisation)",
                                  type=int, min=0, max=1000),
        "samples": Param("band", "which grid samples the method gets: 'all' (the whole grid) or 'band' (the "
                                 "sub-box around |φ| < band·h; faster)", type=str, choices=("all", "band")),
        "band": Param(3.0, "half-width of the band in grid spacings h (with samples = 'band')", type=float,
                      min=1.0, max=100.0),
    }

    #: the cost model: CPU seconds, fitted to the clean sphere and bunny at
    #: N = 24–64 (the vertices, and the global solve, grow with the crossed cells: q = 1 is assumed, not fitted)
    COST = PowerLaw(a=52.6, p=2.67, q=1.0)

    def estimate_seconds(self, shape, n_crossing_cells: int | None = None) -> float | None:
        """The fit of the default 10 iterations, scaled by (iterations + 1) / 11 (the initial mesh and each
        outer iteration cost alike); None with ``samples = 'all'``, which was not measured."""
        if self.config["samples"] != "band":
            return None
        return self.COST.seconds(shape, n_crossing_cells) * (self.config["iterations"] + 1) / 11.0

    def reconstruct(self, volume: Volume) -> Reconstruction:
        from gpytoolbox import dual_contouring_of_signed_distance_data

        check_volume(volume, self.name)
        cfg = self.config
        if cfg["samples"] == "band":
            lo, hi = band_box(volume, cfg["band"])
        else:
            lo, hi = np.zeros(3, dtype=int), np.asarray(volume.shape)
        values, S, GV = library_grid(volume, lo, hi)
        nx, ny, nz = values.shape
        t0 = time.perf_counter()
        V, Q = dual_contouring_of_signed_distance_data(S, GV, nx, ny, nz, outer_iters=cfg["iterations"],
                                                       inner_iters=cfg["inner_iterations"])
        wall = time.perf_counter() - t0
        V = np.asarray(V, dtype=np.float64)
        if len(Q) == 0 or not np.isfinite(V).all():
            raise InputError(f"method {self.name!r}: dual contouring returned "
                             f"{'no faces' if len(Q) == 0 else 'non-finite vertices'}")
        t1 = time.perf_counter()
        mesh, facts = _manifold_mesh(volume, values, lo, V)
        orient_outward(mesh)
        # a fixed count of iterations: the library has no stop test
        info = {"iterations": int(cfg["iterations"]), "stop_reason": "done", "samples_used": int(S.size),
                "library_quads": int(len(Q)), **facts, "wall_dc_s": wall,
                "wall_manifold_s": time.perf_counter() - t1}
        info.update({f"mesh_{k}": v for k, v in mesh_facts(mesh).items()})
        return Reconstruction(mesh, info)


def _project(volume: Volume, points: np.ndarray, box_lo: np.ndarray, box_hi: np.ndarray) -> np.ndarray:
    """Three Newton steps onto the trilinear φ = 0 (each ≤ h/2), kept inside the given boxes (world)."""
    def sample(p):
        s = volume.sample(p, derivatives=1, clamp=True)
        return s.phi, s.grad

    if len(points) == 0:
        return points
    out, _ = newton_project(sample, points, 3, max_step=0.5 * volume.h, flat_g2=1e-12, box=(box_lo, box_hi))
    return out


def _manifold_mesh(volume: Volume, values: np.ndarray, lo: np.ndarray, V: np.ndarray):
    """The library's vertices in cells with one patch, a vertex per patch elsewhere, the quads around the
    sign changes (module :mod:`methods.dc_manifold`); returns (triangle mesh, facts for ``info``)."""
    patches = cell_patches(values)
    if len(patches.cells) != len(V):
        raise ReconstructionFailed(f"method 'dual_contouring': the library returned {len(V)} vertices for "
                                   f"{len(patches.cells)} crossed cells")
    to_world = lambda idx: volume.origin + (lo + idx) * volume.spacing      # noqa: E731
    multi = np.flatnonzero(patches.count > 1)
    cell_vertex = np.full((len(V), 4), -1, np.int64)
    cell_vertex[:, 0] = np.arange(len(V))
    pts = patch_centroids(values, patches, multi)                 # (R, 4, 3), NaN where no patch
    have = ~np.isnan(pts[..., 0])
    ids = len(V) + np.cumsum(have.ravel()) - 1
    cell_vertex[multi] = np.where(have, ids.reshape(have.shape), -1)
    cells = patches.cells[multi][:, None, :].repeat(4, axis=1)[have]
    patch_v = _project(volume, to_world(pts[have]), to_world(cells), to_world(cells + 1))
    quads, edges, flipped = dual_quads(values, patches, cell_vertex)
    first = len(V) + len(patch_v)
    polys, replaced, seg_pts, boxes = split_double_edges(values, quads, edges, flipped, first)
    seg_v = _project(volume, to_world(seg_pts), to_world(boxes[:, 0]), to_world(boxes[:, 1]))
    vertices = np.concatenate([V, patch_v, seg_v])
    keep = np.ones(len(quads), bool)
    keep[replaced] = False
    faces = np.concatenate([split_quads(vertices, quads[keep]), fan_triangles(polys, first)])
    cubes = patches.cube[multi]
    tunnel = np.isin(cubes, TUNNEL_CUBES)
    faces, tubes = bridge_tunnels(vertices, faces, cell_vertex[multi[tunnel]][:, :2])
    mesh = trimesh.Trimesh(vertices, faces, process=False)
    mesh.remove_unreferenced_vertices()
    facts = {"quads": int(len(quads)), "split_cells": int(len(multi)), "patch_vertices": int(len(patch_v)),
             "segment_vertices": int(len(seg_v)), "tunnels": int(tubes)}
    return mesh, facts
