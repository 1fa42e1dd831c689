"""Helpers shared by the tests of the three peer adapters (reach_for_the_spheres, dual_contouring,
flying_edges); not collected (the name starts with an underscore).

* :func:`volume` – a phantom's clean sdf volume at N, built once per session;
* :func:`check_closed_outward` – watertight, one component, χ = 2, consistent winding, outward;
* :func:`edge_and_vertex_manifold` – every edge in two faces (once each way), every vertex's faces one disk;
* :func:`hausdorff_h` – the symmetric Hausdorff distance to the phantom's true surface in grid spacings,
  with the suite's own metric code (bench.metrics: the phantom's exact distance for mesh → truth, pymeshlab's
  exact point-to-triangle distance for truth → mesh);
* :func:`offcentre_sphere` – an exact sphere SDF on an anisotropic (three spacings), off-centre grid with
  three different sizes, for the world-coordinate checks.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from bench.metrics import point_mesh_distance, sample_mesh_surface
from geometry.mesh import mesh_facts
from phantoms import Volume, get_phantom

PAPER_PHANTOMS = ["sphere", "ellipsoid", "fused_spheres", "cylinder"]

#: the off-centre sphere: centre (distinct per axis), radius, spacing (distinct per axis)
CENTRE = np.array([0.31, -0.22, 0.13])
RADIUS = 0.7
SPACING = np.array([0.045, 0.06, 0.075])


@lru_cache(maxsize=None)
def volume(phantom: str, n: int) -> Volume:
    return get_phantom(phantom).volume(n=n)


def offcentre_sphere(coarsen: float = 1.0) -> Volume:
    """φ = |x − CENTRE| − RADIUS on a grid from CENTRE − (1.0, 1.1, 1.2) with SPACING · coarsen: shape
    (47, 36, 33) at coarsen = 1."""
    lo = CENTRE - np.array([1.0, 1.1, 1.2])
    hi = CENTRE + np.array([1.05, 1.0, 1.25])
    spacing = SPACING * coarsen
    shape = np.floor((hi - lo) / spacing).astype(int) + 1
    idx = np.indices(shape).reshape(3, -1).T
    pts = lo + idx * spacing
    values = (np.linalg.norm(pts - CENTRE, axis=1) - RADIUS).reshape(shape)
    return Volume(values, origin=lo, spacing=spacing)


def sphere_errors(mesh) -> tuple[float, np.ndarray]:
    """(max | |v − CENTRE| − RADIUS | over the vertices, the vertices' bounding-box centre − CENTRE)."""
    v = np.asarray(mesh.vertices)
    err = float(np.abs(np.linalg.norm(v - CENTRE, axis=1) - RADIUS).max())
    return err, 0.5 * (v.min(0) + v.max(0)) - CENTRE


def check_closed_outward(mesh, what: str) -> dict:
    facts = mesh_facts(mesh)
    assert facts["watertight"], f"{what}: not watertight"
    assert facts["components"] == 1, f"{what}: {facts['components']} components"
    assert facts["euler"] == 2, f"{what}: Euler characteristic {facts['euler']}"
    assert mesh.is_winding_consistent, f"{what}: inconsistent winding"
    assert facts["signed_volume"] > 0, f"{what}: faces point inward"
    return facts


def hausdorff_h(mesh, phantom: str, h: float, n_samples: int = 20000, seed: int = 0) -> float:
    """Symmetric Hausdorff distance / h between ``mesh`` and the phantom's true surface (vertices and
    area-uniform samples of the mesh → truth; samples of the truth → mesh)."""
    truth = get_phantom(phantom)
    v, f = np.asarray(mesh.vertices), np.asarray(mesh.faces)
    pts, _ = sample_mesh_surface(v, f, n_samples, seed)
    d_rt = max(float(truth.truth(v).distance.max()), float(truth.truth(pts).distance.max()))
    true_pts, _ = truth.sample_surface(n_samples, seed)
    d_tr = float(point_mesh_distance(true_pts, v, f).max())
    return max(d_rt, d_tr) / h


def edge_and_vertex_manifold(mesh) -> bool:
    """Every edge in exactly two faces, once in each direction, and every vertex's faces one fan (a disk)."""
    f = np.asarray(mesh.faces)
    directed = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
    if len(np.unique(directed, axis=0)) != len(directed):
        return False                                            # an edge twice in one direction
    und, counts = np.unique(np.sort(directed, axis=1), axis=0, return_counts=True)
    if not (counts == 2).all():
        return False
    nxt: dict = {}
    for a, b, c in f.tolist():
        for v, x, y in ((a, b, c), (b, c, a), (c, a, b)):
            nxt.setdefault(v, {})[x] = y
    for ring in nxt.values():                                   # each vertex's link: one cycle through all
        start = next(iter(ring))
        steps, cur = 1, ring[start]
        while cur != start and cur in ring and steps <= len(ring):
            cur, steps = ring[cur], steps + 1
        if cur != start or steps != len(ring):
            return False
    return True
