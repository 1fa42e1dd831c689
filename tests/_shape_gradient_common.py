"""Helpers shared by the shape-gradient tests (not collected: the name starts with an underscore)."""

from __future__ import annotations

import numpy as np

from phantoms import Sample
from methods.shape_gradient import face_energies, shape_gradient


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


def fd_normal_derivative(field, vertices, faces, alpha, beta, eps=1e-6):
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
            res.append(Ef)
        out += np.bincount(v, weights=(res[0] - res[1]) / (2 * eps), minlength=len(x))
    return out


def gradient_fd_error(field, vertices, faces, alpha=5.0, beta=1.0, kind="full"):
    """Relative L2 error ‖A·G − FD‖ / ‖FD‖ of the shape gradient against finite differences."""
    G, _, A = shape_gradient(field, vertices, faces, alpha, beta, kind=kind)
    fd = fd_normal_derivative(field, vertices, faces, alpha, beta)
    return float(np.linalg.norm(A * G - fd) / np.linalg.norm(fd))
