"""Helpers shared by the shape-gradient tests (not collected: the name starts with an underscore)."""

from __future__ import annotations

import numpy as np

from phantoms import Sample
from methods.shape_gradient import ShapeGradient, face_energies, shape_gradient


def one_flow(volume, start: dict | None = None, **params):
    """The Reconstruction of one flow of ``ShapeGradient(**params)`` from the start ``start`` (the start's private
    settings, as a candidate of the start choice sets them; None: the usual start), without the choice."""
    return ShapeGradient(**params).prepare(volume, start=start).run().result()


class EllipsoidPolynomial:
    """The paper's ellipsoid level set φ = x²/a² + y²/b² + z²/c² − 1 with exact derivatives."""

    def __init__(self, axes=(1.0, 2.0, 1.0)):
        self.w = 1.0 / np.asarray(axes, float) ** 2

    def sample(self, points, derivatives=2, clamp=False):
        p = np.asarray(points, float)
        phi = (self.w * p * p).sum(1) - 1.0
        grad = 2.0 * self.w * p
        hess = np.broadcast_to(np.diag(2.0 * self.w), (len(p), 3, 3)).copy()
        return Sample(phi, grad, hess)


def fd_normal_derivative(field, vertices, faces, alpha, beta, eps=1e-6, density=0.0):
    """Central finite differences ∂E/∂(move of vertex i along its area-weighted normal), all i at once.

    Only the faces around vertex i change when it moves, so each (face, corner) pair is evaluated with
    that corner displaced by ±eps n_i: exact per-vertex differences of the full discrete energy
    E = Σ_f a_f g(centroid_f, n_f), vectorised over the faces.
    """
    from geometry.mesh import vertex_normals

    x = np.asarray(vertices, float)
    f = np.asarray(faces)
    n = vertex_normals(x, f)
    out = np.zeros(len(x))
    for k in range(3):           # the three corners of a face (not a loop over vertices or faces)
        v = f[:, k]
        res = []
        for sign in (1.0, -1.0):
            P = x[f].copy()                                  # (F, 3 corners, 3)
            P[:, k] += sign * eps * n[v]
            c = P.mean(axis=1)
            s = field.sample(c, derivatives=1)
            cross = np.cross(P[:, 1] - P[:, 0], P[:, 2] - P[:, 0])
            dbl = np.linalg.norm(cross, axis=1)
            nf = cross / dbl[:, None]
            Ef, _ = face_energies(np.asarray(s.phi), np.asarray(s.grad).T, nf.T, 0.5 * dbl, alpha, beta)
            res.append(Ef + density * 0.5 * dbl)
        out += np.bincount(v, weights=(res[0] - res[1]) / (2 * eps), minlength=len(x))
    return out


def gradient_fd_error(field, vertices, faces, alpha=5.0, beta=1.0, kind="full", density=0.0):
    """Relative L2 error ‖A·G − FD‖ / ‖FD‖ of the shape gradient against finite differences."""
    G, _, A = shape_gradient(field, vertices, faces, alpha, beta, kind=kind, density=density)
    fd = fd_normal_derivative(field, vertices, faces, alpha, beta, density=density)
    return float(np.linalg.norm(A * G - fd) / np.linalg.norm(fd))


# ---------------------------------------------------------------------------- reconstruction metrics
def hausdorff(mesh, phantom, n_samples: int = 20_000, seed: int = 0) -> float:
    """Symmetric Hausdorff distance (world units) of a mesh to the phantom's exact surface.

    recon → truth: the exact distance of every vertex and face centroid; truth → recon:
    ``trimesh.proximity.closest_point`` (exact point-to-triangle) of ``n_samples`` area-uniform truth samples.
    """
    import trimesh

    pts = np.concatenate([mesh.vertices, mesh.triangles_center])
    d_rt = float(phantom.distance(pts).max())
    samples, _ = phantom.sample_surface(n_samples, seed)
    _, d_tr, _ = trimesh.proximity.closest_point(mesh, samples)
    return max(d_rt, float(d_tr.max()))


def self_intersecting_faces(mesh) -> int:
    """Number of faces pymeshlab flags as intersecting another face."""
    import pymeshlab

    ms = pymeshlab.MeshSet()
    ms.add_mesh(pymeshlab.Mesh(np.asarray(mesh.vertices, float), np.asarray(mesh.faces, np.int32)))
    ms.compute_selection_by_self_intersections_per_face()
    return int(ms.current_mesh().selected_face_number())


def topology(mesh) -> dict:
    return {"watertight": bool(mesh.is_watertight), "euler": int(mesh.euler_number),
            "self_intersections": self_intersecting_faces(mesh)}


def h_std(mesh, phantom, h: float, band: float = 0.1) -> float:
    """Std of the paraboloid-fit H over vertices in regions of constant true curvature (METRICS.md).

    Neighbourhood: every vertex within 2h (at least the 1-ring), the suite's estimator.
    """
    from geometry.curvature import paraboloid_curvature
    from geometry.mesh import radius_neighbors, vertex_normals

    v, f = np.asarray(mesh.vertices, float), np.asarray(mesh.faces)
    H, _ = paraboloid_curvature(v, vertex_normals(v, f), radius_neighbors(v, f, 2 * h), linear=True)
    t = phantom.truth(v)
    ok = (t.crease_distance >= band) & np.isfinite(t.H) & np.isfinite(H)
    if phantom.name == "cylinder":
        ok &= np.isclose(t.H, 1.25)                       # the side
    elif phantom.name not in ("sphere", "fused_spheres"):
        raise ValueError(f"no constant-curvature region defined for {phantom.name}")
    return float(np.std(H[ok]))


def roughness_deg(mesh, phantom, band: float = 0.1) -> float:
    """Mean angle (degrees) between the normals of faces sharing an edge, edges near creases left out."""
    ok_v = phantom.truth(np.asarray(mesh.vertices, float)).crease_distance >= band
    pairs = mesh.face_adjacency
    edges = mesh.face_adjacency_edges
    keep = ok_v[edges].all(1)
    n = mesh.face_normals
    c = np.clip(np.einsum("ij,ij->i", n[pairs[keep, 0]], n[pairs[keep, 1]]), -1.0, 1.0)
    return float(np.degrees(np.arccos(c)).mean())


def marching_cubes(volume):
    """Marching cubes at level 0 (scikit-image), world coordinates, outward, duplicates merged."""
    import trimesh
    from skimage.measure import marching_cubes as mc

    verts, faces, _, _ = mc(volume.values, level=0.0, spacing=tuple(volume.spacing))
    m = trimesh.Trimesh(verts + volume.origin, faces, process=True)
    if m.volume < 0:
        m.invert()
    return m


def SG(**params) -> ShapeGradient:
    """The flow with the paper's fixed connectivity (the Fibonacci sphere, no remeshing): what the tests of
    the energy, the gradient and the line search are about; remeshing and the enclosing start are tested in
    test_methods_shape_gradient_remesh.py."""
    params.setdefault("init", "sphere")
    params.setdefault("remesh_every", 0)
    return ShapeGradient(**params)


FAR_LIMB_N, FAR_LIMB_LO = 32, -2.0
FAR_LIMB_H = 4.0 / (FAR_LIMB_N - 1)


def far_limb_volume():
    """(volume, the limb tip's x): a ball of radius 0.8 with a limb of radius 0.3 voxel whose axis runs through
    the centres of the squares of four sample rows — the nearest samples read +0.41 voxel, so φ < 0 (and φ below
    a quarter voxel) has no limb; only the carved hull does."""
    from phantoms import Volume

    g = FAR_LIMB_LO + FAR_LIMB_H * np.arange(FAR_LIMB_N)
    p = np.stack(np.meshgrid(g, g, g, indexing="ij"), -1)
    r, off = 0.3 * FAR_LIMB_H, FAR_LIMB_LO + 16.5 * FAR_LIMB_H
    a, b = np.array([0.0, off, off]), np.array([1.6, off, off])
    t = np.clip((p - a) @ (b - a) / ((b - a) @ (b - a)), 0.0, 1.0)
    capsule = np.linalg.norm(p - (a + t[..., None] * (b - a)), axis=-1) - r
    values = np.minimum(np.linalg.norm(p, axis=-1) - 0.8, capsule)
    assert values[(p[..., 0] > 0.9) & (p[..., 0] < 1.5)].min() > 0.4 * FAR_LIMB_H
    return Volume(values, [FAR_LIMB_LO] * 3, FAR_LIMB_H), 1.6 + r
